"""
The tidy table of a study (one row per diagnosed data set) and its manifest.

`table.csv` is appended one row at a time, each row flushed to disk as it arrives, so a study
that is stopped keeps every row it finished; a row cut off by a kill (no line end) is dropped
when the table is read. When the study completes, the table is rewritten in the design's
canonical order. `study.json` (the manifest) holds the normalised spec and its hash, which
`--resume` compares before adding rows.

Cells: numbers as Python writes them (they read back bit for bit), booleans true/false, lists
of causes joined by ';', an empty cell for a missing value (NaN, None).
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
import csv
import io
import json
import math
import os
from pathlib import Path
from typing import Any

from octoroach_model.errors import DataError
from octoroach_model.fileio import atomic_file, write_text_atomic
from octoroach_model.studies.terms import column, TERMS

TABLE_NAME = 'table.csv'
MANIFEST_NAME = 'study.json'
MANIFEST_FORMAT = 1

# (column, type); docs/studies.md says what each holds
_FIXED: tuple[tuple[str, type], ...] = (
    ('key', str), ('arm', str), ('kind', str), ('replicate', int), ('seed', int),
    ('runs', int), ('size', float), ('limit_multiple', float),
    ('leg_length_cm', float), ('hip_distance_cm', float),
    ('touchdown_1_deg', float), ('touchdown_2_deg', float), ('touchdown_3_deg', float),
    ('touchdown_4_deg', float), ('stride_frequency_hz', float), ('cycles', float),
    ('sample_rate_hz', float), ('spread_scale', float), ('sigma1_rad', float),
    ('sigma2_rad', float), ('duration_s', float), ('runs_cut', int), ('frames_dropped', int),
    ('true_causes', str), ('named', str), ('false_causes', str), ('all_true_named', bool),
    ('adequate', bool), ('unexplained', str), ('baseline_adequate', bool), ('undecided', str),
)
_PER_CAUSE: tuple[tuple[str, type], ...] = (
    ('true', float), ('named', bool), ('estimate', float), ('low', float), ('high', float),
    ('rel_error', float), ('limit', float),
)
_TAIL: tuple[tuple[str, type], ...] = (('status', str), ('note', str), ('elapsed_s', float))
COLUMNS: tuple[tuple[str, type], ...] = (
    _FIXED + tuple((f'{prefix}_{column(term)}', kind) for term in TERMS
                   for prefix, kind in _PER_CAUSE) + _TAIL)
COLUMN_NAMES = tuple(name for name, _ in COLUMNS)
# columns that depend on the machine rather than the spec (left out when tables are compared)
TIMING_COLUMNS = ('elapsed_s',)


def format_cell(value: Any) -> str:
    """Format one cell as text (see the module docstring)."""
    if value is None:
        return ''
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ''
    if isinstance(value, (list, tuple)):
        return ';'.join(str(item) for item in value)
    return ' '.join(str(value).split())       # one line, whatever the text held


def parse_cell(text: str, kind: type) -> Any:
    """Parse one cell written by `format_cell`."""
    if kind is str:
        return text
    if text == '':
        return math.nan if kind is float else None
    if kind is bool:
        return text == 'true'
    return kind(text)


def typed_row(row: Mapping[str, Any]) -> dict[str, Any]:
    """
    Return a row exactly as it reads back from the table.

    Lists become ';'-joined text and missing numbers NaN: the one in-memory form of a row,
    whether just computed or read.
    """
    return {name: parse_cell(format_cell(row[name]), kind) for name, kind in COLUMNS}


def cell(row: Mapping[str, Any], prefix: str, term: str) -> Any:
    """Return a row's per-term cell: `prefix` such as 'named', `term` a cause or term."""
    return row[f'{prefix}_{column(term)}']


def causes_of(cell: str) -> list[str]:
    """Split a cell such as `named` into its causes ('' for none)."""
    return [cause for cause in cell.split(';') if cause]


def row_line(row: Mapping[str, Any]) -> str:
    """Format a row as one CSV line (with its line end), columns in table order."""
    missing = [name for name in COLUMN_NAMES if name not in row]
    if missing:
        raise ValueError(f'row lacks column {missing[0]}')
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator='\n').writerow(
        [format_cell(row[name]) for name in COLUMN_NAMES])
    return buffer.getvalue()


def header_line() -> str:
    return ','.join(COLUMN_NAMES) + '\n'


def start_table(path: Path) -> None:
    """Start a new table with its header only (a name that exists is an OutputError)."""
    write_text_atomic(path, header_line(), what='study table')


def append_row(path: Path, row: Mapping[str, Any]) -> None:
    """Add one row at the end, on disk before returning (flush and fsync); no link followed."""
    descriptor = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_NOFOLLOW | os.O_CLOEXEC)
    with os.fdopen(descriptor, 'a', encoding='utf-8') as stream:
        stream.write(row_line(row))
        stream.flush()
        os.fsync(stream.fileno())


def write_table(path: Path, rows: Iterable[Mapping[str, Any]]) -> None:
    """Write the whole table at once, replacing the study's own file atomically."""
    with atomic_file(path, replace=True, what='study table') as stream:
        stream.write(header_line().encode('utf-8'))
        for row in rows:
            stream.write(row_line(row).encode('utf-8'))


def read_table(path: Path, earlier: bool = False) -> tuple[list[dict[str, Any]], int]:
    """
    Read a table: its rows and how many cut-off lines were dropped (interrupted writes).

    With `earlier`, a table an earlier version wrote (some of today's columns, none unknown)
    is read too, the columns it lacks empty: to summarize it, never to add rows to it.
    """
    try:
        text = path.read_text(encoding='utf-8')
    except OSError as error:
        raise DataError(f'cannot read {path}: {error.strerror or error}') from None
    lines = text.splitlines(keepends=True)
    names = next(csv.reader(lines[:1]), []) if lines else []
    kinds = dict(COLUMNS)
    if not lines or (lines[0] != header_line() and not (
            earlier and names and all(name in kinds for name in names))):
        raise DataError(f'{path} does not start with the columns this version writes; '
                        f'start a new study directory')
    dropped = 0
    if lines[-1] and not lines[-1].endswith('\n'):
        lines, dropped = lines[:-1], 1
    rows = []
    for cells in csv.reader(lines[1:]):
        if len(cells) != len(names):
            dropped += 1
            continue
        given = dict(zip(names, cells))
        rows.append({name: parse_cell(given.get(name, ''), kind) for name, kind in COLUMNS})
    return rows, dropped


def write_manifest(directory: Path, spec_json: Mapping[str, Any], spec_hash: str,
                   tasks: int) -> None:
    """Write study.json: what the directory holds, so --resume can check the study."""
    from octoroach_model import __version__
    from octoroach_model.jsonio import dumps

    manifest = {'format': MANIFEST_FORMAT, 'spec_hash': spec_hash, 'tasks': tasks,
                'package_version': __version__, 'spec': spec_json}
    write_text_atomic(directory / MANIFEST_NAME, dumps(manifest, indent=2) + '\n',
                      what='study manifest')


def read_manifest(directory: Path) -> dict[str, Any]:
    """Read the manifest of a study directory (DataError when missing or unreadable)."""
    path = directory / MANIFEST_NAME
    try:
        manifest = json.loads(path.read_text())
    except OSError:
        raise DataError(f'{directory} holds no {MANIFEST_NAME}: it is not a study directory '
                        f'to resume') from None
    except ValueError:
        raise DataError(f'{path} is not valid JSON') from None
    if not isinstance(manifest, dict) or manifest.get('format') != MANIFEST_FORMAT:
        raise DataError(f'{path} was written by another version of the study format')
    return manifest
