"""
The package's architecture: no import cycle, the fitting floor below, no module loaded by name.

The graph is built from the source with `ast`, every import counted: at module level, under
TYPE_CHECKING and inside functions (a lazy import still ties two modules together).
"""
from __future__ import annotations

import ast
from pathlib import Path

from octoroach_model.recordings.poses.readers import POSE_READERS
from octoroach_model.recordings.sources import InputKind

PACKAGE = 'octoroach_model'
ROOT = Path(__file__).resolve().parents[1] / PACKAGE
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


def module_name(path: Path) -> str:
    """Return the dotted name of a module file of the package."""
    parts = list(path.relative_to(ROOT.parent).with_suffix('').parts)
    if parts[-1] == '__init__':
        parts.pop()
    return '.'.join(parts)


def imported_modules(path: Path, name: str, modules: set[str]) -> set[str]:
    """Return the package's `modules` that module `name` (at `path`) imports, wherever."""
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                anchor = package.split('.')[:len(package.split('.')) - node.level + 1]
                base = '.'.join(anchor + ([base] if base else []))
            targets = [f'{base}.{alias.name}' for alias in node.names] + [base]
        else:
            continue
        for target in targets:
            # `from a.b import c`: c is a module of the package or a name in a.b
            while target and target not in modules:
                target = target.rpartition('.')[0]
            if target and target != name:
                found.add(target)
    return found


def import_graph() -> dict[str, set[str]]:
    """Return {module: the package's modules it imports} for every module of the package."""
    files = {module_name(path): path for path in ROOT.rglob('*.py')}
    modules = set(files)
    return {name: imported_modules(path, name, modules) for name, path in files.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """Return one cycle of `graph` as [a, b, ..., a], or None (depth-first search)."""
    state: dict[str, int] = {}          # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_architecture_a_cycle_in_a_made_up_graph_is_found_and_named():
    graph = {'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}
    assert find_cycle(graph) == ['a', 'b', 'c', 'a']
    assert find_cycle({'a': {'b'}, 'b': set()}) is None


def test_architecture_an_import_under_type_checking_or_in_a_function_counts(tmp_path):
    source = tmp_path / 'probe.py'
    source.write_text('from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n'
                      '    from octoroach_model.paths import Paths\n'
                      'def f():\n    import octoroach_model.errors\n')
    modules = {'octoroach_model.paths', 'octoroach_model.errors', 'octoroach_model'}
    found = imported_modules(source, 'octoroach_model.probe', modules)
    assert found == {'octoroach_model.paths', 'octoroach_model.errors'}


def test_architecture_the_package_import_graph_has_no_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, 'import cycle: ' + ' -> '.join(cycle or [])


def test_architecture_the_fitting_package_imports_neither_validation_nor_diagnosis():
    graph = import_graph()
    fitting = {name for name in graph if name.startswith(f'{PACKAGE}.fitting')}
    assert fitting, 'the fitting package is missing'
    upward = sorted((name, target) for name in fitting for target in graph[name]
                    if target.startswith((f'{PACKAGE}.validation', f'{PACKAGE}.diagnosis')))
    assert not upward, f'fitting imports from above: {upward}'


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
    users = importlib_users(ROOT)
    assert not [user for user in users if user.startswith('octoroach_model/recordings/')]
    assert set(users) <= LOADS_BY_NAME


def test_every_kind_of_pose_input_has_a_reader() -> None:
    assert set(POSE_READERS) == set(InputKind) - NOT_POSE_STREAMS
