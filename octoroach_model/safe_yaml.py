"""
YAML from files this package did not write, read within a size and without aliases.

A bag's metadata.yaml, a channel's QoS text, a study spec, a looks file, the file
$OCTOROACH_MODEL_TABLE2 names.

`yaml.safe_load` builds no objects, but it still expands aliases: a 2 KB document of nested
aliases ("billion laughs") expands to gigabytes. rosbag2 never writes aliases and a spec
needs none, so the loader here refuses them, and reads no more than `limits.MAX_YAML_BYTES`
of a file (its stated size says nothing of /dev/zero or a pipe) before parsing it. The
caller names the error its readers expect (a bag's BagError, a spec's ParameterError).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from octoroach_model.errors import BagError, OctoroachError
from octoroach_model.limits import MAX_YAML_BYTES, size_words

__all__ = ['load_yaml_file', 'load_yaml_text']


class _NoAliasLoader(yaml.SafeLoader):
    """SafeLoader that refuses an alias (``*name``) where the document would reuse a node."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(
                None, None, 'YAML aliases are not accepted here', event.start_mark)
        return super().compose_node(parent, index)


def load_yaml_text(text: str, where: str, error: type[OctoroachError] = BagError) -> Any:
    """Parse untrusted YAML text; `error` (one line, no content quoted) if it is refused."""
    if len(text) > MAX_YAML_BYTES:
        raise error(f'{where}: larger than the {size_words(MAX_YAML_BYTES)} a YAML file '
                    'may have here')
    try:
        return yaml.load(text, Loader=_NoAliasLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.composer.ComposerError as problem:
        if 'aliases' in str(problem.problem):
            alias_line = problem.problem_mark.line + 1 if problem.problem_mark is not None else 0
            raise error(f'{where}: YAML aliases are not accepted (line {alias_line})') from None
        raise error(f'{where}: not valid YAML') from None
    except yaml.MarkedYAMLError as problem:
        line = f' (line {problem.problem_mark.line + 1})' if problem.problem_mark else ''
        raise error(f'{where}: not valid YAML{line}') from None
    except (yaml.YAMLError, RecursionError):
        raise error(f'{where}: not valid YAML') from None


def load_yaml_file(path: Path, error: type[OctoroachError] = BagError,
                   where: str | None = None) -> Any:
    """Read and parse an untrusted YAML file, never more of it than the limit."""
    where = where or str(path)
    try:
        with path.open('rb') as handle:
            data = handle.read(MAX_YAML_BYTES + 1)
    except OSError as problem:
        raise error(f'{where}: cannot read: {problem.strerror or problem}') from None
    if len(data) > MAX_YAML_BYTES:
        raise error(f'{where}: larger than the {size_words(MAX_YAML_BYTES)} a YAML file may '
                    'have here')
    return load_yaml_text(data.decode('utf-8', errors='replace'), where, error)
