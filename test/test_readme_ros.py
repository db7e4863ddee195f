"""
README's "With ROS" walk-through works as written, top to bottom.

The test takes the first ```bash block of the section from README.md itself (so the README and
the test cannot drift apart), runs it unchanged with bash in an empty folder whose `.venv` is
this interpreter's virtual environment, on a ROS domain of its own, and checks what a reader
is promised: the recorder got every run, the validator answered with an accepted-or-rejected
verdict on 48 runs, the bag is closed, the replay played it.
"""
from __future__ import annotations

import json
from pathlib import Path
import re
import subprocess
import sys

import pytest

from ros_helpers import fresh_domain, REPO, ros_env

SECTION = '## With ROS'


def walk_through() -> str:
    """Return the first ```bash block of README's "With ROS" section."""
    text = (REPO / 'README.md').read_text()
    start = text.index(SECTION + '\n')
    end = text.find('\n## ', start + len(SECTION))
    section = text[start:end if end >= 0 else len(text)]
    block = re.search(r'^```bash\n(.*?)^```', section, re.S | re.M)
    assert block, f'no ```bash block in README section {SECTION!r}'
    return block.group(1)


def test_the_walk_through_names_the_venv_and_waits_for_the_recorder():
    script = walk_through()
    assert script.startswith('. .venv/bin/activate')
    lines = [line for line in script.splitlines() if 'octoroach_model' in line]
    assert 'recorder' in lines[0] and 'simulator' in lines[1]       # recorder first
    assert 'wait_subscribers:=1' in lines[1]


@pytest.mark.long
def test_the_walk_through_runs_as_written(tmp_path):
    venv = Path(sys.prefix)
    if not (venv / 'bin' / 'activate').is_file():
        pytest.skip(f'{sys.executable} is not in a virtual environment with bin/activate')
    (tmp_path / '.venv').symlink_to(venv, target_is_directory=True)
    script = tmp_path / 'walk_through.sh'
    script.write_text(walk_through())
    log = tmp_path / 'walk_through.log'
    with log.open('wb') as stderr:
        done = subprocess.run(['bash', str(script)], cwd=tmp_path, stdout=subprocess.PIPE,
                              stderr=stderr, stdin=subprocess.DEVNULL,
                              env=ros_env(fresh_domain()), timeout=240)
    logs = log.read_text(errors='replace')
    output = done.stdout.decode(errors='replace')
    assert done.returncode == 0, f'{output}\n{logs}'

    # --call prints the answer indented: from a line '{' to a line '}'
    answers = re.findall(r'^\{$.*?^\}$', output, flags=re.MULTILINE | re.DOTALL)
    assert len(answers) == 1, f'{output}\n{logs}'
    result = json.loads(answers[0])
    assert 'error' not in result, f'{result}\n{logs}'
    assert (result['paths_available'], result['paths_used']) == (48, 44)
    assert (result['n'], result['k']) == (11, 4)
    assert isinstance(result['accepted'], bool) and result['sources'] == ['my_runs']
    assert (tmp_path / 'my_runs' / 'metadata.yaml').is_file(), logs   # closed cleanly
    messages = 12 * 4 * (251 + 1)                                      # poses and markers
    assert f'bag my_runs closed: {messages} messages' in logs, logs
    assert f'published {messages} messages' in logs, logs
    assert 'Traceback' not in logs, logs
