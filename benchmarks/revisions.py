"""
The commits that benchmarks compare with this checkout, named once.

`commit_of` turns what a user typed (a hash, a tag, HEAD~3) into the commit it names, or stops
the benchmark with a one-line error: anything that is not a commit, an option among it.
"""
from __future__ import annotations

from pathlib import Path
import subprocess

REPO = Path(__file__).resolve().parents[1]


def commit_of(revision: str) -> str:
    """Return the commit a revision names; anything else (an option, say) stops the bench."""
    found = subprocess.run(['git', '-C', str(REPO), 'rev-parse', '--verify', '--quiet',
                            '--end-of-options', f'{revision}^{{commit}}'],
                           capture_output=True, text=True, check=False)
    if revision.startswith('-') or found.returncode != 0:
        raise SystemExit(f'error: {revision!r} names no commit of this repository')
    return found.stdout.strip()
