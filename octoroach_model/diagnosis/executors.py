"""
Where the diagnosis runs its side-by-side work: any concurrent.futures executor.

By default a local pool of worker processes: forked from this process when it runs a single
thread (quick, and a user's script needs no `if __name__ == '__main__'` guard), else started
by a fork server (safe inside a ROS node, whose threads a plain fork would copy mid-flight);
`workers=1` runs everything in this process; a caller may pass its own executor (a Dask client's
`get_executor()` sends the work to a cluster).

Every process runs its numpy with one BLAS thread (`one_blas_thread`): the diagnosis works on
small arrays, where a second BLAS thread only spins (measured: the same wall time for twice
the CPU), so the cores are better spent on whole tasks side by side.
"""
from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from contextlib import contextmanager
import multiprocessing
import threading


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


@contextmanager
def single_threaded() -> Iterator[None]:
    """One BLAS thread in this process for the block, as before afterwards."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        yield


@contextmanager
def executor_for(executor: Executor | None, workers: int) -> Iterator[Executor]:
    """`executor` itself (left running), or a pool of `workers` processes for the block."""
    if executor is not None:
        yield executor
        return
    if workers <= 1:
        yield InlineExecutor()
        return
    context: multiprocessing.context.BaseContext
    if threading.active_count() == 1:
        context = multiprocessing.get_context('fork')
    else:
        server = multiprocessing.get_context('forkserver')
        server.set_forkserver_preload(['octoroach_model.diagnosis.diagnose'])
        context = server
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                               initializer=one_blas_thread)
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
