"""
The commits that benchmarks compare with this checkout, named and copied out in one place.

`commit_of` turns what a user typed (a hash, a tag, HEAD~3) into the commit it names, or stops
the benchmark with a one-line error: anything that is not a commit, an option among it.
`export` writes a commit's files into a folder of the benchmark's own (`git archive`): no
worktree is registered in the repository, so a benchmark stopped half-way leaves nothing
behind but its temporary folder.
"""
from __future__ import annotations

import io
from pathlib import Path
import subprocess
import tarfile

REPO = Path(__file__).resolve().parents[1]


def commit_of(revision: str) -> str:
    """Return the commit a revision names; anything else (an option, say) stops the bench."""
    found = subprocess.run(['git', '-C', str(REPO), 'rev-parse', '--verify', '--quiet',
                            '--end-of-options', f'{revision}^{{commit}}'],
                           capture_output=True, text=True, check=False)
    if revision.startswith('-') or found.returncode != 0:
        raise SystemExit(f'error: {revision!r} names no commit of this repository')
    return found.stdout.strip()


def export(commit: str, folder: Path, paths: tuple[str, ...] = ()) -> Path:
    """Write `commit`'s files (only `paths` where given) into the new `folder`; return it."""
    folder.mkdir()
    archive = subprocess.run(['git', '-C', str(REPO), 'archive', '--format=tar', commit,
                              '--', *paths], capture_output=True, check=True).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter='data')
    return folder
