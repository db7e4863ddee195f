"""
The one conversion of results to JSON: numbers, lists and objects only.

Policy for values JSON has no word for: NaN and +-infinity become null (a missing or
unbounded value: the field's description says which); numpy scalars and arrays become numbers
and lists; dataclasses (the typed results) become objects of their fields, in field order,
except fields marked ``metadata={'json': False}`` (and ``{'json_omit_none': True}`` where
None); ``{'json_name': key}`` writes a field under another key, ``{'json_inline': True}`` a
record's fields in its place; enums become their values; paths become strings. Anything else is a
programming error and raises TypeError, so a live object never slips into a report.
"""
from __future__ import annotations

from collections.abc import Mapping
import dataclasses
from enum import Enum
import json
import math
import os
from typing import Any

import numpy as np

__all__ = ['OMIT_NONE', 'dumps', 'jsonable']

OMIT_NONE = {'json_omit_none': True}     # a field's metadata: left out of the JSON while None


def jsonable(value: Any) -> Any:
    """`value` as plain JSON data (dict, list, str, int, float, bool, None)."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, np.bool_):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        return number if math.isfinite(number) else None
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        if hasattr(value, 'to_json'):
            return value.to_json()
        return fields_jsonable(value)
    if isinstance(value, Mapping):
        return {str(key): jsonable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [jsonable(item) for item in value]
    if isinstance(value, Enum):
        return jsonable(value.value)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f'cannot write {type(value).__name__} as JSON')


def fields_jsonable(record: Any) -> dict[str, Any]:
    """Return a dataclass's fields as a JSON object (the default `to_json` of a typed result)."""
    plain: dict[str, Any] = {}
    for field in dataclasses.fields(record):
        value = getattr(record, field.name)
        if not field.metadata.get('json', True) \
                or value is None and field.metadata.get('json_omit_none', False):
            continue
        if field.metadata.get('json_inline', False):
            plain.update(jsonable(value))
        else:
            plain[field.metadata.get('json_name', field.name)] = jsonable(value)
    return plain


def dumps(value: Any, *, indent: int | None = None) -> str:
    """Strict JSON text of `value` (never NaN or Infinity tokens)."""
    return json.dumps(jsonable(value), indent=indent, allow_nan=False)
