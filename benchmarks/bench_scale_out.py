"""
Scale-out of a study on a Dask cluster started as a user starts one.

The cluster is `dask scheduler` and `dask worker` processes on this machine. Runs
studies/scale.yaml (Table II's robot, 500 runs, a null and a persistent turning per replicate)
against a scheduler with one worker, then with two (one thread each, as `dask worker
--nthreads 1`), and prints the wall times and the speed-up. The cluster is the user's,
reached by its address (`study --scheduler tcp://127.0.0.1:PORT`): the study's client only
hands out the tasks. Needs the two cores to itself (minutes).

Run: .venv/bin/python benchmarks/bench_scale_out.py [--replicates 6]
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time
from typing import Iterator

REPO = Path(__file__).resolve().parents[1]
SPEC = REPO / 'studies' / 'scale.yaml'
DASK = Path(sys.executable).with_name('dask')
START_TIMEOUT_S = 60.0


def wait_for(condition, what: str) -> None:
    """Poll `condition` until it holds, or fail after START_TIMEOUT_S saying `what`."""
    deadline = time.monotonic() + START_TIMEOUT_S
    while not condition():
        if time.monotonic() > deadline:
            raise SystemExit(f'error: bench_scale_out: {what} did not start within '
                             f'{START_TIMEOUT_S:.0f} s')
        time.sleep(0.2)


@contextlib.contextmanager
def dask_cluster(workers: int, folder: Path) -> Iterator[str]:
    """Start `dask scheduler` and `workers` `dask worker` processes; yield the address."""
    environment = {**os.environ, 'OPENBLAS_NUM_THREADS': '1', 'OMP_NUM_THREADS': '1'}
    scheduler_file = folder / f'scheduler-{workers}.json'
    processes = [subprocess.Popen(
        [str(DASK), 'scheduler', '--host', '127.0.0.1', '--port', '0', '--no-dashboard',
         '--scheduler-file', str(scheduler_file)],
        env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        wait_for(scheduler_file.exists, 'the dask scheduler')
        address = json.loads(scheduler_file.read_text())['address']
        for _ in range(workers):
            processes.append(subprocess.Popen(
                [str(DASK), 'worker', address, '--nthreads', '1', '--nworkers', '1',
                 '--no-dashboard', '--memory-limit', '0'],
                env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address) as client:
            wait_for(lambda: len(client.scheduler_info()['workers']) == workers,
                     f'{workers} dask worker(s)')
        yield address
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                process.kill()


def spec_with(replicates: int, folder: Path) -> Path:
    """Return studies/scale.yaml with `replicates` replicates, written into `folder`."""
    import yaml

    spec = yaml.safe_load(SPEC.read_text())
    spec['replicates'] = replicates
    path = folder / 'scale.yaml'
    path.write_text(yaml.safe_dump(spec))
    return path


def measure(workers: int, spec: Path, folder: Path) -> tuple[int, float]:
    """Return (data sets, wall time [s]) of the study on a cluster of `workers` workers."""
    import octoroach_model as om

    with dask_cluster(workers, folder) as address:
        started = time.perf_counter()
        result = om.run_study(spec, folder / f'study-{workers}', scheduler=address,
                              plots=False)
        return result.rows, time.perf_counter() - started


def main() -> None:
    """Print the wall times with one and two workers and the speed-up."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--replicates', type=int, default=6,
                        help='replicates of studies/scale.yaml (2 data sets each)')
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        spec = spec_with(args.replicates, folder)
        walls = {}
        for workers in (1, 2):
            tasks, walls[workers] = measure(workers, spec, folder)
            print(f'{workers} dask worker(s): {tasks} data sets in {walls[workers]:.1f} s '
                  f'({walls[workers] / tasks:.1f} s each)', flush=True)
    print(f'\nspeed-up from 1 to 2 workers: {walls[1] / walls[2]:.2f}')


if __name__ == '__main__':
    main()
