"""Memory and time of reading a large pose bag: does `read_runs` stay bounded?

Writes a bag of 1,000,000 poses (4000 runs of 250 samples) to a temporary directory in a child
process, then reads and splits it with `read_runs` here and reports the peak RSS growth (from
`resource.getrusage`, so the writer's memory is not counted) and the time. With ``--tracemalloc``
a second read reports the peak of traced Python/numpy allocations as well.

Run: ``.venv/bin/python benchmarks/bench_bag_memory.py [--runs 4000 --samples 250]``
"""
from __future__ import annotations

import argparse
import multiprocessing
import resource
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from octoroach_model.recordings import PoseBagWriter, read_runs  # noqa: E402


def _peak_rss_mb() -> float:
    """Peak resident set size of this process so far (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _write(bag: Path, n_runs: int, n_samples: int, result: multiprocessing.Queue) -> None:
    """Writes the bag run block by run block, so the writer never holds all poses either."""
    t = np.arange(n_samples) / 50.0
    started = time.perf_counter()
    block = 500
    period_ns = int(round(t[-1] * 1e9)) + 1_000_000_000
    offsets_ns = np.round(t * 1e9).astype(np.int64)
    rng = np.random.default_rng(0)
    with PoseBagWriter(bag) as writer:
        for first in range(0, n_runs, block):
            count = min(block, n_runs - first)
            heading = np.pi / 2 + rng.normal(0, 0.2, (count, 1)) * t
            x = np.broadcast_to(0.01 * np.sin(t), heading.shape)
            y = np.broadcast_to(0.2 * t, heading.shape)
            poses = np.stack([x, y, heading], axis=-1)
            for offset in range(count):
                stamps = 1_700_000_000 * 10**9 + (first + offset) * period_ns + offsets_ns
                writer.write_marker(first + offset, int(stamps[0]))
                writer.write_poses(stamps, poses[offset])
    result.put(time.perf_counter() - started)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=4000)
    parser.add_argument('--samples', type=int, default=250)
    parser.add_argument('--tracemalloc', action='store_true',
                        help='read a second time under tracemalloc (slower)')
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as folder:
        bag = Path(folder) / 'big'
        queue: multiprocessing.Queue = multiprocessing.Queue()
        child = multiprocessing.get_context('fork').Process(
            target=_write, args=(bag, args.runs, args.samples, queue))
        child.start()
        write_s = queue.get()
        child.join()
        bag_mb = sum(p.stat().st_size for p in bag.iterdir()) / 2**20

        cold_mb = _peak_rss_mb()
        warm_up = Path(folder) / 'tiny'
        _write(warm_up, 2, 10, queue)  # first use loads the typestore: not data-dependent
        read_runs(warm_up)
        queue.get()
        baseline_mb = _peak_rss_mb()
        started = time.perf_counter()
        run_set = read_runs(bag)
        read_s = time.perf_counter() - started
        rss_growth_mb = _peak_rss_mb() - baseline_mb
        started = time.perf_counter()
        paths = run_set.to_paths()
        resample_s = time.perf_counter() - started
        n_poses = sum(len(run.t) for run in run_set.runs)
        result_mb = sum(run.t.nbytes + run.poses.nbytes for run in run_set.runs) / 2**20

        traced_mb = float('nan')
        if args.tracemalloc:
            del run_set, paths
            tracemalloc.start()
            read_runs(bag)
            traced_mb = tracemalloc.get_traced_memory()[1] / 2**20
            tracemalloc.stop()

    rows = [
        ('poses read', f'{n_poses:,}'),
        ('runs', f'{args.runs:,} x {args.samples} samples'),
        ('bag size', f'{bag_mb:.1f} MB'),
        ('write (child process)', f'{write_s:.1f} s ({write_s / n_poses * 1e6:.1f} us/pose)'),
        ('read_runs (read + split)', f'{read_s:.1f} s ({read_s / n_poses * 1e6:.1f} us/pose)'),
        ('to_paths (resample)', f'{resample_s:.2f} s'),
        ('fixed cost of first use', f'{baseline_mb - cold_mb:.0f} MB (typestore, imports)'),
        ('peak RSS growth of read_runs', f'{rss_growth_mb:.0f} MB'),
        ('  of which the returned runs', f'{result_mb:.0f} MB'),
    ]
    if args.tracemalloc:
        rows.append(('tracemalloc peak of read_runs', f'{traced_mb:.0f} MB'))
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f'{name:<{width}}  {value}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
