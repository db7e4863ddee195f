"""
YAML from files this package did not write (a bag's metadata.yaml, a channel's QoS text).

`yaml.safe_load` builds no objects, but it still expands aliases: a 2 KB document of nested
aliases ("billion laughs") expands to gigabytes. rosbag2 never writes aliases, so the loader
here refuses them, and refuses a text over `limits.MAX_YAML_BYTES` before parsing it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from octoroach_model.errors import BagError
from octoroach_model.limits import MAX_YAML_BYTES, size_words

__all__ = ['load_yaml_file', 'load_yaml_text']


class _NoAliasLoader(yaml.SafeLoader):
    """SafeLoader that refuses an alias (``*name``) where the document would reuse a node."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(
                None, None, 'YAML aliases are not accepted in bag metadata', event.start_mark)
        return super().compose_node(parent, index)


def load_yaml_text(text: str, where: str) -> Any:
    """Parse untrusted YAML text; BagError (one line, no content quoted) if it is refused."""
    if len(text) > MAX_YAML_BYTES:
        raise BagError(f'{where}: larger than the {size_words(MAX_YAML_BYTES)} a YAML file '
                       'may have here')
    try:
        return yaml.load(text, Loader=_NoAliasLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.composer.ComposerError as error:
        if 'aliases' in str(error.problem):
            line = error.problem_mark.line + 1 if error.problem_mark is not None else 0
            raise BagError(f'{where}: YAML aliases are not accepted (line {line})') from None
        raise BagError(f'{where}: not valid YAML') from None
    except (yaml.YAMLError, RecursionError):
        raise BagError(f'{where}: not valid YAML') from None


def load_yaml_file(path: Path) -> Any:
    """Read and parse an untrusted YAML file, checking its size before reading it."""
    try:
        size = path.stat().st_size
        if size > MAX_YAML_BYTES:
            raise BagError(f'{path}: larger than the {size_words(MAX_YAML_BYTES)} a YAML file '
                           'may have here')
        text = path.read_text(encoding='utf-8', errors='replace')
    except OSError as error:
        raise BagError(f'{path}: cannot read: {error.strerror or error}') from None
    return load_yaml_text(text, str(path))
