"""
The tidy table of a study (one row per diagnosed data set) and its manifest.

`table.csv` is appended one row at a time, each row flushed to disk as it arrives, so a study
that is stopped keeps every row it finished; a row cut off by a kill (no line end) is dropped
when the table is read. When the study completes, the table is rewritten in the design's
canonical order. `study.json` (the manifest) holds the normalised spec and its hash, which
`--resume` compares before adding rows.

Cells: numbers as Python writes them (they read back bit for bit), booleans true/false, lists
of causes joined by ';', an empty cell for a missing value (NaN, None). `row_cells` and
`row_of` are the one conversion between a typed row (studies/rows.py) and its cells.
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
from octoroach_model.studies.rows import Outcome, Status, StudyRow, TermOutcome
from octoroach_model.studies.spec import ArmKind
from octoroach_model.studies.terms import column, TERMS

TABLE_NAME = 'table.csv'
MANIFEST_NAME = 'study.json'
MANIFEST_FORMAT = 1

# (column, type), in table order; docs/studies.md says what each holds. The first and the
# last are fields of StudyRow, _OUTCOME those of its Outcome, _PER_CAUSE those of each term's
# TermOutcome (columns `<field>_<term>`); a tuple is a list of causes
_ROW: tuple[tuple[str, type], ...] = (
    ('key', str), ('arm', str), ('kind', ArmKind), ('replicate', int), ('seed', int),
    ('runs', int), ('size', float), ('limit_multiple', float),
    ('leg_length_cm', float), ('hip_distance_cm', float),
    ('touchdown_1_deg', float), ('touchdown_2_deg', float), ('touchdown_3_deg', float),
    ('touchdown_4_deg', float), ('stride_frequency_hz', float), ('cycles', float),
    ('sample_rate_hz', float), ('spread_scale', float), ('sigma1_rad', float),
    ('sigma2_rad', float), ('duration_s', float), ('runs_cut', int), ('frames_dropped', int),
    ('true_causes', tuple),
)
_OUTCOME: tuple[tuple[str, type], ...] = (
    ('named', tuple), ('false_causes', tuple), ('all_true_named', bool), ('adequate', bool),
    ('unexplained', tuple), ('baseline_adequate', bool), ('undecided', tuple),
)
_PER_CAUSE: tuple[tuple[str, type], ...] = (
    ('true', float), ('named', bool), ('estimate', float), ('low', float), ('high', float),
    ('rel_error', float), ('limit', float), ('t', float), ('t_critical', float),
    ('t_scoring_se', float), ('first_t', float), ('clears_floor', bool),
    ('bound_power', float), ('test_power', float),
)
_TAIL: tuple[tuple[str, type], ...] = (('status', Status), ('note', str), ('elapsed_s', float))
COLUMNS: tuple[tuple[str, type], ...] = (
    _ROW + _OUTCOME + tuple((f'{prefix}_{column(term)}', kind) for term in TERMS
                            for prefix, kind in _PER_CAUSE) + _TAIL)
COLUMN_NAMES = tuple(name for name, _ in COLUMNS)
# columns that depend on the machine rather than the spec (left out when tables are compared)
TIMING_COLUMNS = ('elapsed_s',)


def format_cell(value: Any, kind: type) -> str:
    """Format one cell of a column of type `kind` as text (see the module docstring)."""
    if value is None:
        return ''
    if kind is bool:
        return 'true' if value else 'false'
    if kind is int:
        return str(int(value))
    if kind is float:
        number = float(value)
        return repr(number) if math.isfinite(number) else ''
    if kind is tuple:
        return ';'.join(str(item) for item in value)
    return ' '.join(str(value).split())       # one line, whatever the text held


def parse_cell(text: str, kind: type) -> Any:
    """Parse one cell written by `format_cell`."""
    if kind is str:
        return text
    if kind is tuple:
        return tuple(cause for cause in text.split(';') if cause)
    if text == '':
        return math.nan if kind is float else None
    if kind is bool:
        return text == 'true'
    return kind(text)


def row_cells(row: StudyRow) -> list[str]:
    """Return a row's cells in table order: the one conversion of a row to the table."""
    values = [getattr(row, name) for name, _ in _ROW]
    values += [getattr(row.outcome, name) for name, _ in _OUTCOME]
    values += [getattr(row.terms[term], prefix) for term in TERMS for prefix, _ in _PER_CAUSE]
    values += [getattr(row, name) for name, _ in _TAIL]
    return [format_cell(value, kind) for value, (_, kind) in zip(values, COLUMNS)]


def row_of(cells: Mapping[str, str]) -> StudyRow:
    """Return the row of a table's cells by column name (a column missing reads as empty)."""
    def parsed(columns: tuple[tuple[str, type], ...], suffix: str = '') -> dict[str, Any]:
        return {name: parse_cell(cells.get(name + suffix, ''), kind) for name, kind in columns}

    terms = {term: TermOutcome(**parsed(_PER_CAUSE, f'_{column(term)}')) for term in TERMS}
    return StudyRow(**parsed(_ROW), outcome=Outcome(**parsed(_OUTCOME)), terms=terms,
                    **parsed(_TAIL))


def one_line(text: str) -> str:
    """Return `text` as its table cell holds it: one line, single spaces."""
    return ' '.join(text.split())


def row_line(row: StudyRow) -> str:
    """Format a row as one CSV line (with its line end), columns in table order."""
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator='\n').writerow(row_cells(row))
    return buffer.getvalue()


def header_line() -> str:
    return ','.join(COLUMN_NAMES) + '\n'


def start_table(path: Path) -> None:
    """Start a new table with its header only (a name that exists is an OutputError)."""
    write_text_atomic(path, header_line(), what='study table')


def append_row(path: Path, row: StudyRow) -> None:
    """Add one row at the end, on disk before returning (flush and fsync); no link followed."""
    descriptor = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_NOFOLLOW | os.O_CLOEXEC)
    with os.fdopen(descriptor, 'a', encoding='utf-8') as stream:
        stream.write(row_line(row))
        stream.flush()
        os.fsync(stream.fileno())


def write_table(path: Path, rows: Iterable[StudyRow]) -> None:
    """Write the whole table at once, replacing the study's own file atomically."""
    with atomic_file(path, replace=True, what='study table') as stream:
        stream.write(header_line().encode('utf-8'))
        for row in rows:
            stream.write(row_line(row).encode('utf-8'))


def read_table(path: Path, earlier: bool = False) -> tuple[list[StudyRow], int]:
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
        rows.append(row_of(dict(zip(names, cells))))
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
