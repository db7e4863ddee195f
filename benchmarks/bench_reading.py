"""
Measure how fast a bag is read: poses a second, decoded in blocks against message by message.

Reads the reference bag (`bags/reference`, 500 runs, 125,500 TransformStamped poses and 500
run markers; or `--bag`) both ways in the same process: with the pose messages decoded in
blocks over whole MCAP chunks (`recordings.bagio.pose_blocks`, the default) and with every
message decoded by rosbags' CDR deserializer (`bag_streams.BLOCK_DECODING = False`, the path
before). Three stages, each from the bag on:

- pose streams: the bag's poses as every program gets them (`iter_pose_samples`: decoded,
  turned to the z-up world, headings, the clock chosen);
- read_runs: cut into runs and cleaned;
- load_measured: the runs on one time grid (what `validate` and `diagnose` read).

Times are CPU seconds of this process (`time.process_time`), the best of `--repeat`: wall time
is unreliable on a loaded machine. A tiny bag is read first both ways, so imports and the
deserializers rosbags compiles once per process are not counted. Both ways must give the same
pose streams, bit for bit (checked here; `test/test_recordings_blocks.py` checks it on every
test bag). `--before REF` also times the three stages with the package as it was at git
commit REF (its files exported by `git archive`, read in a child process), in the same run.

Run: ``.venv/bin/python benchmarks/bench_reading.py [--bag PATH] [--repeat 3] [--before REF]``
"""
from __future__ import annotations

import argparse
from collections.abc import Callable
import json
from pathlib import Path
import subprocess
import sys
import tempfile
import time
from typing import Any

import numpy as np
from revisions import commit_of, export

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import octoroach_model as om  # noqa: E402
from octoroach_model.recordings import (  # noqa: E402
    iter_pose_samples,
    load_measured,
    read_runs,
    write_paths_bag,
)
from octoroach_model.recordings.poses import bag_streams  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
REFERENCE = REPO / 'bags' / 'reference'
# The stages timed with an older release, in a child process whose path starts at its files
BEFORE = r"""
import json, sys, tempfile, time
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import octoroach_model as om
from octoroach_model.recordings import (iter_pose_samples, load_measured, read_runs,
                                        write_paths_bag)
bag, repeat = Path(sys.argv[2]), int(sys.argv[3])
with tempfile.TemporaryDirectory() as folder:
    write_paths_bag(Path(folder) / 'tiny', om.simulate(3, seed=1, cycles=2))
    list(iter_pose_samples(Path(folder) / 'tiny'))
times = []
for work in (lambda: list(iter_pose_samples(bag)), lambda: read_runs(bag),
             lambda: load_measured(bag)):
    best = float('inf')
    for _ in range(repeat):
        started = time.process_time()
        work()
        best = min(best, time.process_time() - started)
    times.append(best)
print(json.dumps({'file': om.__file__, 'times': times}))
"""


def _cpu_seconds(work: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    """Return the least CPU time of `repeat` calls of `work`, and its last result."""
    best, result = float('inf'), None
    for _ in range(repeat):
        started = time.process_time()
        result = work()
        best = min(best, time.process_time() - started)
    return best, result


def _both_ways(work: Callable[[], Any], repeat: int) -> tuple[tuple[float, Any], ...]:
    """Time `work` with pose messages decoded in blocks, then message by message."""
    timed = []
    for blocks in (True, False):
        bag_streams.BLOCK_DECODING = blocks
        try:
            timed.append(_cpu_seconds(work, repeat))
        finally:
            bag_streams.BLOCK_DECODING = True
    return tuple(timed)


def _same_streams(new: list, old: list) -> bool:
    """Whether two lists of PoseChunk hold the same values, bit for bit."""
    if len(new) != len(old):
        return False
    for a, b in zip(new, old):
        for name in a._fields:
            x, y = getattr(a, name), getattr(b, name)
            if isinstance(x, np.ndarray):
                if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
                    return False
            elif x != y and not (x != x and y != y):  # NaN read fractions are equal
                return False
    return True


def _release_before(commit: str, bag: Path, repeat: int) -> list[float]:
    """CPU seconds of the three stages with the package of git commit `commit`."""
    with tempfile.TemporaryDirectory() as scratch:
        folder = str(export(commit, Path(scratch) / 'release', ('octoroach_model', 'config')))
        ran = subprocess.run([sys.executable, '-c', BEFORE, folder, str(bag), str(repeat)],
                             cwd=folder, capture_output=True, text=True)
    if ran.returncode != 0:
        raise SystemExit(f'the release of {commit} did not read the bag: '
                         f'{(ran.stderr.strip().splitlines() or ["?"])[-1]}')
    found = json.loads(ran.stdout.strip().splitlines()[-1])
    assert found['file'].startswith(folder), found['file']  # that release's files, not ours
    return list(found['times'])


def main() -> int:
    """Run the benchmark and print one table."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--bag', type=Path, default=REFERENCE)
    parser.add_argument('--repeat', type=int, default=3)
    parser.add_argument('--before', metavar='REF',
                        help='also time the package as it was at this git commit')
    args = parser.parse_args()
    repeat = max(1, args.repeat)
    release = commit_of(args.before) if args.before else None    # before the long work
    with tempfile.TemporaryDirectory() as folder:
        tiny = Path(folder) / 'tiny'
        write_paths_bag(tiny, om.simulate(3, seed=1, cycles=2))
        _both_ways(lambda: list(iter_pose_samples(tiny)), 1)

    stages = {
        'pose streams (iter_pose_samples)': lambda: list(iter_pose_samples(args.bag)),
        'read_runs': lambda: read_runs(args.bag),
        'load_measured': lambda: load_measured(args.bag),
    }
    rows = []
    poses = 0
    for label, work in stages.items():
        (new_s, new), (old_s, old) = _both_ways(work, repeat)
        if label.startswith('pose streams'):
            poses = sum(len(chunk.x) for chunk in new)
            assert _same_streams(new, old), 'the two ways read different pose streams'
        rows.append((label, new_s, old_s))

    before = _release_before(release, args.bag.resolve(), repeat) if release else None
    print(f'{args.bag}: {poses:,} poses; CPU seconds of this process, best of {repeat}')
    header = '| stage | in blocks | poses/s | message by message | poses/s | speed-up |'
    print(header + (f' {args.before} | poses/s |' if before else ''))
    print('| --- ' * (8 if before else 6) + '|')
    for number, (label, new_s, old_s) in enumerate(rows):
        line = (f'| {label} | {new_s:.3f} s | {poses / new_s:,.0f} | {old_s:.3f} s | '
                f'{poses / old_s:,.0f} | {old_s / new_s:.1f}x |')
        if before:
            line += f' {before[number]:.3f} s | {poses / before[number]:,.0f} |'
        print(line)
    return 0


if __name__ == '__main__':
    sys.exit(main())
