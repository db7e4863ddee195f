"""
Running a study's tasks: in this process one after another, or as tasks on Dask distributed.

Where they run is chosen by `workers.where_to_run` (the package's one choice of where work
runs); this module hands the tasks to it.

Dask does the distribution, the retries and the recovery from lost workers: each task is a
`client.submit` of `replicate.run_task` with `retries=RETRIES`; a relative task is handed the
future of its replicate's null task, which Dask resolves before running it. A task whose worker
dies is rescheduled by Dask on another worker (up to `distributed.scheduler.allowed-failures`
times), so a lost worker costs a recomputation, not a row. Rows come back as they finish and
go to `on_row` at once.

Security: `workers.py` and docs/studies.md, "Security".
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any
import uuid

from octoroach_model.errors import OctoroachError
from octoroach_model.studies.design import Task
from octoroach_model.studies.replicate import run_task
from octoroach_model.studies.rows import StudyRow
from octoroach_model.studies.spec import StudySpec

RETRIES = 3
OnRow = Callable[[StudyRow], None]


def run_tasks(tasks: Sequence[Task], spec: StudySpec, *, client: Any | None,
              done: Mapping[str, StudyRow], on_row: OnRow) -> None:
    """
    Run `tasks`, handing every new row to `on_row` (rows in `done` are not recomputed).

    `client` None runs them here, in order; otherwise they are Dask tasks on `client`.
    """
    if client is None:
        finished = dict(done)
        for task in tasks:
            null_row = finished.get(task.depends_on) if task.depends_on else None
            row = run_task(task, spec, null_row)
            finished[task.key] = row
            on_row(row)
        return
    _run_on_dask(tasks, spec, client, done, on_row)


def _run_on_dask(tasks: Sequence[Task], spec: StudySpec, client: Any,
                 done: Mapping[str, StudyRow], on_row: OnRow) -> None:
    from distributed import as_completed

    token = uuid.uuid4().hex[:8]
    futures: dict[str, Any] = {}
    for task in tasks:
        null: Any = None
        if task.depends_on:
            null = futures.get(task.depends_on, done.get(task.depends_on))
        futures[task.key] = client.submit(run_task, task, spec, null, retries=RETRIES,
                                          pure=False, key=f'octoroach-study-{token}-{task.key}')
    keys = {future.key: key for key, future in futures.items()}
    try:
        for future in as_completed(list(futures.values())):
            try:
                row = future.result()
            except Exception as error:  # noqa: BLE001 - the cluster gave up on this task
                raise OctoroachError(f'task {keys[future.key]} failed on the Dask cluster '
                                     f'after {RETRIES} retries: {type(error).__name__}: '
                                     f'{error}') from None
            on_row(row)
    finally:
        client.cancel(list(futures.values()))
