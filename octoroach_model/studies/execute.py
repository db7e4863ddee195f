"""
Where tasks run: in this process one after another, or as tasks on Dask distributed.

Dask does the distribution, the retries and the recovery from lost workers: each task is a
`client.submit` of `replicate.run_task` with `retries=RETRIES`; a relative task is handed the
future of its replicate's null task, which Dask resolves before running it. A task whose worker
dies is rescheduled by Dask on another worker (up to `distributed.scheduler.allowed-failures`
times), so a lost worker costs a recomputation, not a row. Rows come back as they finish and
go to `on_row` at once.

Security (docs/studies.md, "Security"). A Dask scheduler runs whatever its clients submit on
its workers, and a client unpickles what the scheduler and workers send back: whoever reaches
the scheduler's port can run code as the workers' user, and a scheduler can run code in the
client. So the local cluster speaks TLS with a throw-away certificate authority made for it
(`Security.temporary()`: no other process, of this user or another, can connect) and serves
no HTTP at all (no dashboard, no /health or /metrics: `private_cluster`); a remote scheduler
is reached over `tls://` with the certificates named by `--tls-ca-file`, `--tls-cert`,
`--tls-key` (dask's `distributed.comm.tls` configuration).
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
import contextlib
import os
from typing import Any
import uuid

from octoroach_model.errors import OctoroachError, ParameterError
from octoroach_model.studies.design import Task
from octoroach_model.studies.replicate import run_task
from octoroach_model.studies.rows import StudyRow
from octoroach_model.studies.spec import StudySpec

RETRIES = 3
CONNECT_TIMEOUT_S = 10.0
OnRow = Callable[[StudyRow], None]


def default_workers() -> int:
    """Count one single-threaded worker process per core of this machine."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity')
               else os.cpu_count() or 1)


def scheduler_security(scheduler: str) -> Any:
    """
    Return the Security for a remote scheduler: dask's configuration (what --tls-* set).

    A `tls://` address without a CA file and a client certificate is refused before
    connecting, with the options that give them.
    """
    from distributed import Security

    security = Security()
    files = (getattr(security, 'tls_ca_file', None), getattr(security, 'tls_client_cert', None))
    if scheduler.startswith('tls://') and not all(files):
        raise ParameterError(f'the scheduler {scheduler} speaks TLS: give --tls-ca-file, '
                             '--tls-cert and --tls-key (docs/studies.md, "Security")')
    return security


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None,
                connect_timeout_s: float = CONNECT_TIMEOUT_S) -> Iterator[Any]:
    """
    Yield a distributed Client to `scheduler`, or to a new private local cluster.

    The local cluster (`private_cluster.private_local_cluster`) has `workers` processes with
    one thread each and is closed again on exit. An address that does not answer within
    `connect_timeout_s` is a ParameterError.
    """
    from distributed import Client

    if scheduler:
        security = scheduler_security(scheduler)
        try:
            client = Client(scheduler, timeout=f'{connect_timeout_s}s', security=security)
        except (OSError, TimeoutError, ValueError, TypeError) as error:
            raise ParameterError(f'cannot reach the Dask scheduler at {scheduler}: '
                                 f'{type(error).__name__}: {error}') from None
        try:
            check_workers(client)
            yield client
        finally:
            client.close()
        return
    count = workers or default_workers()
    try:
        from octoroach_model.studies.private_cluster import private_local_cluster

        cluster = private_local_cluster(count)
    except (OSError, RuntimeError, ImportError) as error:
        raise OctoroachError(f'cannot start a local Dask cluster of {count} workers: '
                             f'{error}') from None
    try:
        with Client(cluster, security=cluster.security) as client:
            yield client
    finally:
        cluster.close()


def check_where(client: Any | None, scheduler: str | None, workers: int | None) -> None:
    """Check that the choice of where to run is coherent (before any work starts)."""
    if client is not None and scheduler:
        raise ParameterError('give a Dask client or a scheduler address, not both')
    if (client is not None or scheduler) and workers is not None:
        raise ParameterError('with a Dask client or scheduler the cluster has its own workers; '
                             'leave --workers out')
    if workers is not None and workers < 0:
        raise ParameterError(f'workers must be 0 (in this process) or more, got {workers}')


def where_to_run(client: Any | None = None, scheduler: str | None = None,
                 workers: int | None = None, connect_timeout_s: float = CONNECT_TIMEOUT_S
                 ) -> contextlib.AbstractContextManager:
    """
    Return the context in which tasks run.

    That is a given client, a new one (to `scheduler`, or a LocalCluster of `workers`), or
    None (this process) for `workers=0`.
    """
    check_where(client, scheduler, workers)
    if client is not None:
        check_workers(client)
        return contextlib.nullcontext(client)
    if workers == 0 and not scheduler:
        return contextlib.nullcontext(None)
    return dask_client(scheduler, workers, connect_timeout_s)


def _package_version() -> str:
    import octoroach_model

    return octoroach_model.__version__


def check_workers(client: Any) -> None:
    """Check that every worker the scheduler has now runs this package at this version."""
    from octoroach_model import __version__

    try:
        versions = client.run(_package_version)
    except Exception as error:  # noqa: BLE001 - whatever a remote worker raises, say it
        raise ParameterError(f'the Dask workers cannot run octoroach_model '
                             f'({type(error).__name__}: {error}); install the package on '
                             f'them') from None
    other = {worker: version for worker, version in versions.items() if version != __version__}
    if other:
        worker, version = next(iter(other.items()))
        raise ParameterError(f'Dask worker {worker} has octoroach_model {version}, this is '
                             f'{__version__}: the same version must run everywhere')


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
