"""
`run_study`: a spec's every data set diagnosed, the table, the summary and the plots.

Everything that can be checked is checked before the first task: the spec (on loading), the
output directory, the scheduler (reached, workers able to run this package). Rows are
appended to DIR/table.csv as they arrive; on completion the table is rewritten in canonical
order, and DIR/summary.json and the plots are written. `resume=True` keeps the rows already
in DIR (after checking that DIR's spec hash is this spec's) and computes only the others.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
import contextlib
from dataclasses import dataclass
from pathlib import Path
import time
from typing import Any

from octoroach_model.errors import DataError, ParameterError
from octoroach_model.jsonio import dumps
from octoroach_model.studies.design import build_tasks
from octoroach_model.studies.execute import check_where, CONNECT_TIMEOUT_S, run_tasks, where_to_run
from octoroach_model.studies.plots import write_plots
from octoroach_model.studies.spec import load_spec, parse_spec, StudySpec
from octoroach_model.studies.summary import summarize
from octoroach_model.studies.table import (
    append_row, MANIFEST_NAME, read_manifest, read_table, start_table, TABLE_NAME, write_manifest,
    write_table)

SUMMARY_NAME = 'summary.json'
# progress(rows done, rows in the study, the row that just arrived or None at the start)
StudyProgress = Callable[[int, int, 'dict[str, Any] | None'], None]


@dataclass(frozen=True)
class StudyResult:
    """Where a finished study wrote its results, and its summary."""

    directory: Path
    table: Path
    summary_path: Path
    plots: tuple[Path, ...]
    rows: int
    computed: int                 # rows computed by this call (the rest were resumed)
    summary: dict


def as_spec(spec: StudySpec | str | Path | Mapping[str, Any]) -> StudySpec:
    """Return a StudySpec from a spec, a spec file's path or a spec file's mapping."""
    if isinstance(spec, StudySpec):
        return spec
    if isinstance(spec, Mapping):
        return parse_spec(spec)
    return load_spec(spec)


def run_study(spec: StudySpec | str | Path | Mapping[str, Any], out: str | Path, *,
              client: Any | None = None, scheduler: str | None = None,
              workers: int | None = None, resume: bool = False,
              progress: StudyProgress | None = None, plots: bool = True,
              connect_timeout_s: float = CONNECT_TIMEOUT_S) -> StudyResult:
    """
    Run the study `spec` into directory `out`.

    Where tasks run: `client` (a distributed.Client) if given; else the Dask scheduler at
    `scheduler`; else a new LocalCluster of `workers` single-threaded processes (default one
    per core); `workers=0` runs every task in this process, one after another.
    """
    spec = as_spec(spec)
    out = Path(out)
    check_where(client, scheduler, workers)
    tasks = build_tasks(spec)
    done = _rows_done(out, spec, resume)
    pending = [task for task in tasks if task.key not in done]
    table = out / TABLE_NAME
    say = progress or (lambda finished, total, row: None)
    computed: dict[str, dict[str, Any]] = {}

    def arrived(row: dict[str, Any]) -> None:
        append_row(table, row)
        computed[row['key']] = row
        say(len(done) + len(computed), len(tasks), row)

    # connect (or start the local cluster) before the directory is written: a scheduler that
    # does not answer leaves nothing behind
    context = where_to_run(client, scheduler, workers, connect_timeout_s) if pending \
        else contextlib.nullcontext(None)
    with context as where:
        _write_directory(out, spec, len(tasks), done)
        started = time.perf_counter()
        if pending:
            say(len(done), len(tasks), None)
            run_tasks(pending, spec, client=where, done=done, on_row=arrived)
        wall_time_s = time.perf_counter() - started
    rows = [{**done, **computed}[task.key] for task in tasks]
    write_table(table, rows)
    summary = summarize(spec, rows, wall_time_s if not done else None)
    summary_path = out / SUMMARY_NAME
    summary_path.write_text(dumps(summary, indent=2) + '\n')
    written = tuple(write_plots(summary, out)) if plots else ()
    return StudyResult(out, table, summary_path, written, len(rows), len(computed), summary)


def _rows_done(out: Path, spec: StudySpec, resume: bool) -> dict[str, dict[str, Any]]:
    """
    Check `out` without writing anything; return the rows it holds already.

    Without `resume` it must be new or empty; with `resume`, a directory of this same spec.
    """
    if not resume:
        if out.exists() and not out.is_dir():
            raise ParameterError(f'--out {out} exists and is not a directory')
        if out.is_dir() and any(out.iterdir()):
            hint = ' (a study: add --resume to complete it)' \
                if (out / MANIFEST_NAME).exists() else ''
            raise ParameterError(f'--out {out} is a directory that is not empty{hint}')
        return {}
    if not out.is_dir():
        raise ParameterError(f'--resume: {out} is not a study directory')
    manifest = read_manifest(out)
    if manifest.get('spec_hash') != spec.spec_hash:
        raise ParameterError(f'--resume: {out} holds a study of another spec (hash '
                             f'{manifest.get("spec_hash")}, this spec {spec.spec_hash})')
    table = out / TABLE_NAME
    if not table.exists():
        return {}
    rows, _ = read_table(table)
    if len({row['key'] for row in rows}) != len(rows):
        raise DataError(f'{table} holds a row twice; it was not written by one study')
    return {row['key']: row for row in rows}


def _write_directory(out: Path, spec: StudySpec, n_tasks: int,
                     done: dict[str, dict[str, Any]]) -> None:
    """
    Write a new directory's manifest and table header, or rewrite a resumed table.

    A resumed table is rewritten with the rows kept, without a line a kill cut off, so that
    new rows start on a line of their own.
    """
    table = out / TABLE_NAME
    if (out / MANIFEST_NAME).exists():
        write_table(table, done.values())
        return
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ParameterError(f'--out {out}: cannot create it ({error.strerror})') from None
    write_manifest(out, spec.to_json(), spec.spec_hash, n_tasks)
    start_table(table)
