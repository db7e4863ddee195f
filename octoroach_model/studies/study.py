"""
`run_study`: a spec's every data set diagnosed, the table, the summary and the plots.

Everything that can be checked is checked before the first task: the spec (on loading, and
its size before its tasks are built), the output directory, the scheduler (reached, workers
able to run this package). One study folder has one writer: a run holds `fileio.folder_lock`
on it from the first row read to the last file written (released by the OS however the run
ends), so a second `--resume` on the same folder is refused instead of appending rows too. Rows are
appended to DIR/table.csv as they arrive; on completion the table is rewritten in canonical
order, and DIR/summary.json and the plots are written. `resume=True` keeps the rows already
in DIR (after checking that DIR's spec hash is this spec's) and computes only the others.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
import contextlib
from dataclasses import dataclass
import os
from pathlib import Path
import time
from typing import Any

from octoroach_model.errors import DataError, OutputError, ParameterError
from octoroach_model.fileio import (check_writable, folder_lock, LOCK_NAME, user_path,
                                    write_text_atomic)
from octoroach_model.jsonio import dumps
from octoroach_model.limits import MAX_STUDY_TASKS
from octoroach_model.settings import check_callable, flag
from octoroach_model.studies.design import build_tasks
from octoroach_model.studies.execute import run_tasks
from octoroach_model.studies.plots import write_plots
from octoroach_model.studies.rows import StudyRow
from octoroach_model.studies.spec import load_spec, parse_spec, StudySpec
from octoroach_model.studies.summary import summarize
from octoroach_model.studies.summary_records import StudySummary
from octoroach_model.studies.table import (
    append_row, MANIFEST_NAME, read_manifest, read_table, start_table, TABLE_NAME, write_manifest,
    write_table)
from octoroach_model.workers import check_where, CONNECT_TIMEOUT_S, where_to_run

SUMMARY_NAME = 'summary.json'
# progress(rows done, rows in the study, the row that just arrived or None at the start)
StudyProgress = Callable[[int, int, 'StudyRow | None'], None]


@dataclass(frozen=True)
class StudyResult:
    """Where a finished study wrote its results, and its summary."""

    directory: Path
    table: Path
    summary_path: Path
    plots: tuple[Path, ...]
    rows: int
    computed: int                 # rows computed by this call (the rest were resumed)
    summary: StudySummary


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
    check_callable('progress', progress, 'rows done, rows in the study, row or None')
    resume, plots = flag('resume', resume), flag('plots', plots)
    spec = as_spec(spec)
    out = user_path(out, 'the study folder')
    check_where(client, scheduler, workers)
    check_size(spec)
    tasks = build_tasks(spec)
    if resume:
        with folder_lock(_study_folder(out), what='study folder'):
            return _run(spec, tasks, out, client, scheduler, workers, resume, progress, plots,
                        connect_timeout_s)
    _rows_done(out, spec, resume)        # checks before connecting: nothing written yet
    return _run(spec, tasks, out, client, scheduler, workers, resume, progress, plots,
                connect_timeout_s)


def check_size(spec: StudySpec) -> None:
    """Refuse a study of more than `limits.MAX_STUDY_TASKS` data sets, before building them."""
    count = spec.replicates * len(spec.run_cells) * len(spec.arms)
    if count > MAX_STUDY_TASKS:
        raise ParameterError(f'the spec asks for {count} data sets ({spec.replicates} '
                             f'replicates x {len(spec.run_cells)} run counts x '
                             f'{len(spec.arms)} arms), more than the {MAX_STUDY_TASKS} one '
                             'study may hold; split it into several studies')


def _study_folder(out: Path) -> Path:
    if not out.is_dir() or out.is_symlink():
        raise ParameterError(f'--resume: {out} is not a study directory')
    return out


def _run(spec: StudySpec, tasks: list[Any], out: Path, client: Any | None,
         scheduler: str | None, workers: int | None, resume: bool,
         progress: StudyProgress | None, plots: bool, connect_timeout_s: float
         ) -> StudyResult:
    """Run the study's pending tasks and write its results; see `run_study`."""
    done = _rows_done(out, spec, resume) if resume else {}
    pending = [task for task in tasks if task.key not in done]
    table = out / TABLE_NAME
    say = progress or (lambda finished, total, row: None)
    computed: dict[str, StudyRow] = {}

    def arrived(row: StudyRow) -> None:
        append_row(table, row)
        computed[row.key] = row
        say(len(done) + len(computed), len(tasks), row)

    # connect (or start the local cluster) before the directory is written: a scheduler that
    # does not answer leaves nothing behind
    context = where_to_run(client, scheduler, workers, connect_timeout_s) if pending \
        else contextlib.nullcontext(None)
    with context as where, contextlib.ExitStack() as held:
        if not resume:                  # a new folder: made and locked, checked again
            _make_folder(out)
            held.enter_context(folder_lock(out, what='study folder'))
            _rows_done(out, spec, resume)
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
        write_text_atomic(summary_path, dumps(summary, indent=2) + '\n', replace=True,
                          what='study summary')
        written = tuple(write_plots(summary, out)) if plots else ()
    return StudyResult(out, table, summary_path, written, len(rows), len(computed), summary)


def _rows_done(out: Path, spec: StudySpec, resume: bool) -> dict[str, StudyRow]:
    """
    Check `out` without writing anything; return the rows it holds already.

    Without `resume` it must be new or empty; with `resume`, a directory of this same spec.
    """
    if not resume:
        if os.path.lexists(out) and not out.is_dir() or out.is_symlink():
            raise OutputError(f'--out {out} exists and is not a directory')
        if out.is_dir() and any(child.name != LOCK_NAME for child in out.iterdir()):
            hint = ' (a study: add --resume to complete it)' \
                if (out / MANIFEST_NAME).exists() else ''
            raise OutputError(f'--out {out} is a directory that is not empty{hint}')
        check_writable(out / MANIFEST_NAME, '--out')
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
    if len({row.key for row in rows}) != len(rows):
        raise DataError(f'{table} holds a row twice; it was not written by one study')
    return {row.key: row for row in rows}


def _write_directory(out: Path, spec: StudySpec, n_tasks: int,
                     done: dict[str, StudyRow]) -> None:
    """
    Write a new directory's manifest and table header, or rewrite a resumed table.

    A resumed table is rewritten with the rows kept, without a line a kill cut off, so that
    new rows start on a line of their own.
    """
    table = out / TABLE_NAME
    if (out / MANIFEST_NAME).exists():
        write_table(table, done.values())
        return
    write_manifest(out, spec.to_json(), spec.spec_hash, n_tasks)
    start_table(table)


def _make_folder(out: Path) -> None:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputError(f'--out {out}: cannot create it ({error.strerror})') from None
