"""
`colcon build` installs the package the way `ros2 run octoroach_model X` expects.

Runs colcon from the venv on the checkout, into a temporary build/install/log base so the
tree is left alone, then looks at the install space: executables in lib/<package>, the ament
index marker, package.xml, the Table II config, the nodes' params files and the launch file in
share/<package> (every file the launch file names resolves there), the PEP 561 marker
py.typed beside the modules; and runs one installed
executable against the installed copy (AMENT_PREFIX_PATH, PYTHONPATH) to see it find them.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import pytest

from ros_helpers import read_launch_file

REPO = Path(__file__).resolve().parents[1]
PACKAGE = 'octoroach_model'
EXECUTABLES = ('simulator', 'recorder', 'validator', 'replay')
PARAMS_FILES = tuple(f'config/{name}.yaml' for name in EXECUTABLES)
LAUNCH_FILES = ('launch/octoroach.launch.xml',)


def test_colcon_build_installs_executables_index_and_share_files(tmp_path):
    bin_dir = Path(sys.executable).parent
    colcon = bin_dir / 'colcon'
    if not colcon.exists():
        pytest.skip(f'colcon is not installed next to {sys.executable}')
    env = dict(os.environ, PATH=f'{bin_dir}{os.pathsep}{os.environ.get("PATH", "")}')
    build = subprocess.run(
        [str(colcon), '--log-base', str(tmp_path / 'log'), 'build', '--base-paths', str(REPO),
         '--build-base', str(tmp_path / 'build'), '--install-base', str(tmp_path / 'install'),
         '--event-handlers', 'console_direct-'],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert build.returncode == 0, build.stdout + build.stderr

    install = tmp_path / 'install'
    prefix = install / PACKAGE if (install / PACKAGE).is_dir() else install  # isolated/merged
    for name in EXECUTABLES:
        executable = prefix / 'lib' / PACKAGE / name
        assert executable.is_file() and os.access(executable, os.X_OK), executable
    assert (prefix / 'share/ament_index/resource_index/packages' / PACKAGE).is_file()
    assert (prefix / 'share' / PACKAGE / 'package.xml').is_file()
    share = prefix / 'share' / PACKAGE
    for name in ('config/table2.yaml', *PARAMS_FILES, *LAUNCH_FILES):
        assert (share / name).is_file(), name
        assert (share / name).read_bytes() == (REPO / name).read_bytes(), name
    for node in read_launch_file(share / LAUNCH_FILES[0], share):
        assert node.executable in EXECUTABLES, node
        named = [Path(arg) for arg in node.arguments if arg.startswith(str(share))]
        assert named and all(path.is_file() for path in named), node

    site = next(prefix.glob('lib/python3*/site-packages'))
    assert (site / PACKAGE / 'py.typed').is_file()     # PEP 561: users' mypy sees the types
    run_env = dict(env, AMENT_PREFIX_PATH=str(prefix), PYTHONPATH=str(site))
    helped = subprocess.run(
        [str(prefix / 'lib' / PACKAGE / 'simulator'), '--help'], cwd=tmp_path, env=run_env,
        capture_output=True, text=True, timeout=60)
    assert helped.returncode == 0, helped.stderr
    assert 'stride_frequency' in helped.stdout
    found = subprocess.run(
        [sys.executable, '-c', 'import octoroach_model.model.parameters as p; '
         'print(p.config_path())'], cwd=tmp_path, env=run_env, capture_output=True, text=True,
        timeout=60)
    assert found.returncode == 0, found.stderr
    assert Path(found.stdout.strip()) == prefix / 'share' / PACKAGE / 'config/table2.yaml'
