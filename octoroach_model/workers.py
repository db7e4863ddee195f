"""
Where work runs: in this process, in local worker processes, or on a Dask cluster.

One choice for every command (`--workers N` / `--scheduler ADDRESS`, README "Workers"): N = 0
runs everything in this process; N > 0 starts N single-threaded workers; a scheduler address
(or a caller's Dask client) sends the work to a cluster, which has its own workers. Whatever
was chosen, the work is handed to a `concurrent.futures.Executor` (`InlineExecutor`, a
process pool, a Dask client's `get_executor()`), so the diagnosis never asks which it got;
a study's tasks use the Dask client itself where there is one (retries, keys,
`studies/execute.py`).

Local processes are forked from this process when it runs a single thread (quick, and a
user's script needs no `if __name__ == '__main__'` guard), else started by a fork server
(safe inside a ROS node, whose threads a plain fork would copy mid-flight). Every process
runs its numpy with one BLAS thread (`one_blas_thread`): the work is on small arrays, where a
second BLAS thread only spins (measured: the same wall time for twice the CPU), so the cores
are better spent on whole tasks side by side.

Security of the Dask side (docs/studies.md, "Security"): the local cluster speaks TLS with a
throw-away certificate authority and serves no HTTP (`private_cluster.py`); a remote
scheduler is reached over `tls://` with the certificates named by `--tls-ca-file`,
`--tls-cert`, `--tls-key`.
"""
from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor
import contextlib
import multiprocessing
import numbers
import os
import signal
import sys
import threading
from typing import Any

from octoroach_model.errors import OctoroachError, ParameterError
from octoroach_model.settings import shown

CONNECT_TIMEOUT_S = 10.0


class InlineExecutor(Executor):
    """
    An executor that runs each submitted call at once, in this process.

    For workers=1 and for work that is already one task of a larger pool.
    """

    def submit(self, fn, /, *args, **kwargs) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as error:  # noqa: BLE001 - handed to the caller via result()
            future.set_exception(error)
        return future


def one_blas_thread() -> None:
    """Limit this process's BLAS and OpenMP pools to one thread (a worker's initializer)."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


@contextlib.contextmanager
def single_threaded() -> Iterator[None]:
    """One BLAS thread in this process for the block, as before afterwards."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        yield


def default_workers() -> int:
    """Count one single-threaded worker process per core of this machine."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity')
               else os.cpu_count() or 1)


# Worker processes of a command leave Ctrl-C to the command's process: a terminal sends
# SIGINT to the whole process group, and a worker interrupted while it waits for work prints
# a traceback of its own. The command stops the pool on its KeyboardInterrupt.
_workers_ignore_sigint = False


def _ignore_sigint_in_worker() -> None:
    if _workers_ignore_sigint:
        signal.signal(signal.SIGINT, signal.SIG_IGN)


os.register_at_fork(after_in_child=_ignore_sigint_in_worker)


@contextlib.contextmanager
def process_pool(workers: int, *, command: bool = False) -> Iterator[Executor]:
    """
    Yield a pool of `workers` local processes, each with one BLAS thread, shut down after.

    A `command`'s pool is always forked and its processes ignore SIGINT (the command stops
    them); a library caller's is forked only from a single-threaded process (module
    docstring).
    """
    global _workers_ignore_sigint
    context: multiprocessing.context.BaseContext
    if command or threading.active_count() == 1:
        context = multiprocessing.get_context('fork')
    else:
        server = multiprocessing.get_context('forkserver')
        server.set_forkserver_preload(['octoroach_model.diagnosis.diagnose'])
        context = server
    _workers_ignore_sigint = command
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                               initializer=one_blas_thread)
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        _workers_ignore_sigint = False


def check_executor(executor: Any) -> None:
    """
    Refuse in one line what cannot take work: an executor is None or has a callable `submit`.

    concurrent.futures' executors and a Dask client's `get_executor()` have one; their kind is
    not asked (module docstring), so a caller's own executor is taken too; a class is not one.
    """
    if isinstance(executor, type):
        raise ParameterError('executor must be an executor, not the class '
                             f'{executor.__name__}: give one, {executor.__name__}(...)')
    if executor is not None and not callable(getattr(executor, 'submit', None)):
        raise ParameterError('executor must be None or have a submit method (one of '
                             'concurrent.futures, or client.get_executor() of a Dask client), '
                             f'got {shown(executor)}')


@contextlib.contextmanager
def executor_for(executor: Executor | None, workers: int) -> Iterator[Executor]:
    """`executor` itself (left running), else this process (`workers` <= 1) or a pool."""
    if executor is not None:
        yield executor
    elif workers <= 1:
        yield InlineExecutor()
    else:
        with process_pool(workers) as pool:
            yield pool


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
        from octoroach_model.private_cluster import private_local_cluster

        cluster = private_local_cluster(count)
    except (OSError, RuntimeError, ImportError) as error:
        raise OctoroachError(f'cannot start a local Dask cluster of {count} worker'
                             f'{"s" if count != 1 else ""}: '
                             f'{error}{main_guard_hint(error)}') from None
    try:
        with Client(cluster, security=cluster.security) as client:
            yield client
    finally:
        cluster.close()


def main_guard_hint(error: BaseException) -> str:
    """
    Return how a script starts Dask's workers safely, where a worker failed to start in one.

    Dask starts a local cluster's workers by spawning, and a spawned process imports the main
    script again: a script that calls run_study at its top level starts it once more in each
    worker, which then fails ("Nanny failed to start", after a traceback of Python's). A
    program run as a module (`python -m`) or interactively is not imported again.
    """
    main = sys.modules.get('__main__')
    if 'failed to start' not in str(error) or main is None \
            or getattr(main, '__spec__', None) is not None or not getattr(main, '__file__', None):
        return ''
    return ("; Dask's worker processes import the main script again, so a script makes its "
            "calls under `if __name__ == '__main__':`")


def check_where(client: Any | None, scheduler: str | None, workers: int | None) -> None:
    """Check that the choice of where to run is coherent (before any work starts)."""
    if client is not None and scheduler:
        raise ParameterError('give a Dask client or a scheduler address, not both')
    if (client is not None or scheduler) and workers is not None:
        raise ParameterError('with a Dask client or scheduler the cluster has its own workers; '
                             'leave --workers out')
    if workers is not None and (isinstance(workers, bool)
                                or not isinstance(workers, numbers.Integral) or workers < 0):
        raise ParameterError(f'workers must be a whole number, 0 (in this process) or more, '
                             f'got {shown(workers)}')


def where_to_run(client: Any | None = None, scheduler: str | None = None,
                 workers: int | None = None, connect_timeout_s: float = CONNECT_TIMEOUT_S
                 ) -> contextlib.AbstractContextManager:
    """
    Return the context in which a study's tasks run: a Dask client, or None (this process).

    That is a given client, a new one (to `scheduler`, or a private local cluster of
    `workers`), or None for `workers=0`.
    """
    check_where(client, scheduler, workers)
    if client is not None:
        check_workers(client)
        return contextlib.nullcontext(client)
    if workers == 0 and not scheduler:
        return contextlib.nullcontext(None)
    return dask_client(scheduler, workers, connect_timeout_s)


@contextlib.contextmanager
def executor_where(client: Any | None = None, scheduler: str | None = None,
                   workers: int | None = None, connect_timeout_s: float = CONNECT_TIMEOUT_S
                   ) -> Iterator[tuple[Executor, int]]:
    """
    Yield an executor for the choice and how many workers it has.

    A Dask client's (given, or connected to `scheduler`), else this process or a pool of
    `workers` local processes (default one per core).
    """
    if client is not None or scheduler:
        with where_to_run(client, scheduler, None, connect_timeout_s) as where:
            yield where.get_executor(), max(len(where.scheduler_info().get('workers', {})), 1)
        return
    count = default_workers() if workers is None else workers
    with executor_for(None, count) as executor:
        yield executor, count


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
