"""
Memory and time of reading a 1,000,000-pose Vicon CSV export and C3D file.

Each input holds 4000 trials of 250 frames at 50 Hz with 1 s of untracked frames between them
(1,200,000 frames, 1,000,000 poses), written in a child process: the CSV as Vicon's export
lays it out (one rigid object, helical rotations in degrees, millimetres), the C3D with the
`c3d` package's Writer (ezc3d stops at 65535 frames) holding 4 markers of a rigid body. Each
format is then read in a fresh child process twice: the reader alone (chunks consumed and
dropped), then read and cut into runs by the run splitter, as `read_runs` does for bags. It
reports the peak RSS growth over the process's state before reading (`resource.getrusage`),
the size of the returned runs, and the time; with ``--tracemalloc`` also the peak of traced
allocations of the reader alone.

Run: ``.venv/bin/python benchmarks/bench_mocap_memory.py [--runs 4000 --samples 250]``
"""
from __future__ import annotations

import argparse
import csv
import multiprocessing
from pathlib import Path
import resource
import sys
import tempfile
import time
import tracemalloc
import warnings

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from octoroach_model.recordings.mocap.c3d_file import iter_c3d_pose_chunks  # noqa: E402
from octoroach_model.recordings.mocap.vicon_csv import iter_csv_pose_chunks  # noqa: E402
from octoroach_model.recordings.options import ReadOptions  # noqa: E402
from octoroach_model.recordings.runs.run_set import _StreamSplitter, RunSet  # noqa: E402

RATE_HZ = 50
PAUSE_FRAMES = 50  # 1 s untracked between trials
LAYOUT_MM = np.array([[70.0, 4, 30], [-40, 50, 25], [-45, -50, 35], [0, 10, 60]])
READERS = {'csv': iter_csv_pose_chunks, 'c3d': iter_c3d_pose_chunks}


def _peak_rss_mb() -> float:
    """Peak resident set size of this process so far (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _trial_poses(n_runs: int, n_samples: int, block: int):
    """Yield (first trial, tracked (F,), x, y, heading) per block, 1 s untracked after each."""
    t = np.arange(n_samples) / RATE_HZ
    rng = np.random.default_rng(0)
    for first in range(0, n_runs, block):
        count = min(block, n_runs - first)
        heading = np.pi / 2 + rng.normal(0, 0.2, (count, 1)) * t
        x = np.broadcast_to(0.01 * np.sin(t), heading.shape)
        y = np.broadcast_to(0.2 * t, heading.shape)
        pad = np.zeros((count, PAUSE_FRAMES))
        tracked = np.concatenate([np.ones_like(heading, bool), pad.astype(bool)], 1).ravel()
        yield first, tracked, *(np.concatenate([v, pad], 1).ravel() for v in (x, y, heading))


def write_csv(path: Path, n_runs: int, n_samples: int) -> None:
    """Write a Vicon Objects export, block by block (never holding all rows)."""
    frame = 1
    with path.open('w', newline='') as stream:
        writer = csv.writer(stream, lineterminator='\r\n')
        writer.writerows([['Objects'], [RATE_HZ], ['', '', 'Global Angle octoroach:octoroach'],
                          ['Frame', 'Sub Frame', 'RX', 'RY', 'RZ', 'TX', 'TY', 'TZ'],
                          ['', '', 'deg', 'deg', 'deg', 'mm', 'mm', 'mm']])
        for _, tracked, x, y, heading in _trial_poses(n_runs, n_samples, 100):
            rz = np.degrees(np.angle(np.exp(1j * heading)))
            for index in range(len(tracked)):
                if tracked[index]:
                    writer.writerow([frame, 0, '0', '0', f'{rz[index]:.6f}',
                                     f'{x[index] * 1e3:.4f}', f'{y[index] * 1e3:.4f}', '20'])
                else:
                    writer.writerow([frame, 0, '', '', '', '', '', ''])
                frame += 1


def write_c3d(path: Path, n_runs: int, n_samples: int) -> None:
    """Write one C3D file of 4 markers on the body, untracked frames as residual -1."""
    import c3d

    writer = c3d.Writer(point_rate=float(RATE_HZ), point_units='mm')
    writer.set_point_labels([f'octoroach:m{index}' for index in range(len(LAYOUT_MM))])
    frames = []
    empty = np.zeros((0, 0), np.float32)
    for _, tracked, x, y, heading in _trial_poses(n_runs, n_samples, 100):
        cos, sin = np.cos(heading), np.sin(heading)
        wx = x[:, None] * 1e3 + cos[:, None] * LAYOUT_MM[:, 0] - sin[:, None] * LAYOUT_MM[:, 1]
        wy = y[:, None] * 1e3 + sin[:, None] * LAYOUT_MM[:, 0] + cos[:, None] * LAYOUT_MM[:, 1]
        wz = np.broadcast_to(LAYOUT_MM[:, 2], wx.shape)
        points = np.zeros((len(tracked), len(LAYOUT_MM), 5), np.float32)
        points[..., 0], points[..., 1], points[..., 2] = wx, wy, wz
        points[~tracked, :, 3] = -1.0
        frames.extend((frame_points, empty) for frame_points in points)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        writer.add_frames(frames)
        del frames
        with path.open('wb') as handle:
            writer.write(handle)


def _writer(kind: str, path: Path, n_runs: int, n_samples: int,
            result: multiprocessing.Queue) -> None:
    started = time.perf_counter()
    (write_csv if kind == 'csv' else write_c3d)(path, n_runs, n_samples)
    result.put(time.perf_counter() - started)


def _read_runs(kind: str, path: Path) -> RunSet:
    """Read the file's runs, cut by the run splitter as read_runs feeds it bag chunks."""
    notes: list[str] = []
    splitters: dict[tuple[str, str], _StreamSplitter] = {}
    for chunk in READERS[kind](path, ReadOptions(), notes):
        key = (chunk.source, chunk.topic)
        if key not in splitters:
            splitters[key] = _StreamSplitter(chunk, False, 0.5)
        splitters[key].feed(chunk)
    return RunSet([run for s in splitters.values() for run in s.runs], notes)


def _measure(kind: str, path: Path, traced: bool, result: multiprocessing.Queue) -> None:
    """In a fresh process: the reader alone, then read + split (peaks only grow)."""
    warm_up = path.with_name(f'tiny.{kind}')
    (write_csv if kind == 'csv' else write_c3d)(warm_up, 2, 10)
    _read_runs(kind, warm_up)  # imports and first-use costs: not data-dependent
    figures = {'baseline_mb': _peak_rss_mb()}
    started = time.perf_counter()
    poses = sum(len(chunk.x) for chunk in READERS[kind](path, ReadOptions(), []))
    figures['reader_s'] = time.perf_counter() - started
    figures['reader_mb'] = _peak_rss_mb() - figures['baseline_mb']
    figures['poses'] = poses
    started = time.perf_counter()
    run_set = _read_runs(kind, path)
    figures['runs_s'] = time.perf_counter() - started
    figures['runs_mb'] = _peak_rss_mb() - figures['baseline_mb']
    figures['runs'] = len(run_set)
    figures['result_mb'] = sum(r.t.nbytes + r.poses.nbytes for r in run_set.runs) / 2**20
    del run_set
    if traced:
        tracemalloc.start()
        for _ in READERS[kind](path, ReadOptions(), []):
            pass
        figures['traced_mb'] = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    result.put(figures)


def _in_child(target, *args):
    queue: multiprocessing.Queue = multiprocessing.Queue()
    child = multiprocessing.get_context('fork').Process(target=target, args=(*args, queue))
    child.start()
    value = queue.get()
    child.join()
    return value


def main() -> int:
    """Write each input, measure its reading, print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--runs', type=int, default=4000)
    parser.add_argument('--samples', type=int, default=250)
    parser.add_argument('--formats', nargs='+', default=['csv', 'c3d'], choices=READERS)
    parser.add_argument('--tracemalloc', action='store_true',
                        help='read a third time under tracemalloc (slower)')
    args = parser.parse_args()

    rows = [('poses per input', f'{args.runs * args.samples:,} ({args.runs:,} trials x '
                                f'{args.samples} frames, 1 s untracked between)')]
    with tempfile.TemporaryDirectory() as folder:
        for kind in args.formats:
            path = Path(folder) / f'big.{kind}'
            write_s = _in_child(_writer, kind, path, args.runs, args.samples)
            size_mb = path.stat().st_size / 2**20
            figures = _in_child(_measure, kind, path, args.tracemalloc)
            n = figures['poses']
            rows += [
                (f'{kind}: file', f'{size_mb:.0f} MB, written in {write_s:.1f} s (child)'),
                (f'{kind}: reader alone', f'{figures["reader_s"]:.1f} s '
                                          f'({figures["reader_s"] / n * 1e6:.1f} us/pose), '
                                          f'{n:,} poses, peak RSS growth '
                                          f'{figures["reader_mb"]:.0f} MB'),
                (f'{kind}: read + split', f'{figures["runs_s"]:.1f} s, {figures["runs"]:,} '
                                          f'runs, peak RSS growth {figures["runs_mb"]:.0f} MB'
                                          f' (the runs themselves: '
                                          f'{figures["result_mb"]:.0f} MB)'),
            ]
            if args.tracemalloc:
                rows.append((f'{kind}: tracemalloc peak, reader alone',
                             f'{figures["traced_mb"]:.1f} MB'))
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f'{name:<{width}}  {value}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
