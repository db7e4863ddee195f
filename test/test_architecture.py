"""The package's structure: no module loaded by name, and a reader for every kind of input."""
import ast
from pathlib import Path

from octoroach_model.recordings.poses.readers import POSE_READERS
from octoroach_model.recordings.sources import InputKind

PACKAGE = Path(__file__).resolve().parents[1] / 'octoroach_model'
# The modules that still load others by name, outside recordings/: the package's and the
# programs' lazy loading (so that `import octoroach_model` and --help stay quick), the nodes'
# message classes named by a bag's type names, and the studies' MIN_RUNS. A module may leave
# this list; none may join it.
LOADS_BY_NAME = {'octoroach_model/__init__.py', 'octoroach_model/cli.py',
                 'octoroach_model/commands/__init__.py', 'octoroach_model/nodes/recorder.py',
                 'octoroach_model/nodes/replay.py', 'octoroach_model/studies/spec.py'}
# Whose modules are not pose streams: a data set holds runs (load_measured reads it); an
# unknown file is refused.
NOT_POSE_STREAMS = {InputKind.DATASET, InputKind.UNKNOWN}


def importlib_users(folder: Path) -> list[str]:
    """Modules under `folder` that import importlib (an import hides what the graph shows)."""
    users = []
    for path in sorted(folder.rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = [alias.name for alias in node.names] if isinstance(node, ast.Import) \
                else [node.module or ''] if isinstance(node, ast.ImportFrom) else []
            if any(name.split('.')[0] == 'importlib' for name in names):
                users.append(str(path.relative_to(folder.parent)))
                break
    return users


def test_no_module_imports_importlib_but_those_known() -> None:
    users = importlib_users(PACKAGE)
    assert not [user for user in users if user.startswith('octoroach_model/recordings/')]
    assert set(users) <= LOADS_BY_NAME


def test_every_kind_of_pose_input_has_a_reader() -> None:
    assert set(POSE_READERS) == set(InputKind) - NOT_POSE_STREAMS
