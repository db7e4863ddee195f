"""
Measure memory and time of reading large pose inputs: do `read_runs` and `convert` stay bounded.

For each bag kind (the package's MCAP bag, TFMessage on /tf in MCAP, Odometry in MCAP,
TransformStamped in a rosbag2 sqlite3 bag, a ROS 1 bag), a child process writes an input of
1,000,000 poses (4000 runs of 250 samples) with an independent writer (rosbags' writers; the
package's own for its MCAP bag), and another child converts it to the standard bag with
`convert_to_bag`, reporting the peak RSS growth over its state after converting a tiny input
of the same kind (imports and type stores are a fixed cost, not data) and the time. Then
`read_runs` reads the package's MCAP bag here, as before: its peak RSS growth and time, and
how much of it is the returned runs themselves.

Run: ``.venv/bin/python benchmarks/bench_bag_memory.py [--runs 4000 --samples 250]
[--kinds mcap,tf,odometry,sqlite3,ros1] [--tracemalloc]``
"""
from __future__ import annotations

import argparse
import math
import multiprocessing
from pathlib import Path
import resource
import sys
import tempfile
import time
import tracemalloc

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from octoroach_model.recordings import PoseBagWriter, read_runs  # noqa: E402

START_NS = 1_700_000_000 * 10**9
KINDS = ('mcap', 'tf', 'odometry', 'sqlite3', 'ros1')
LABELS = {
    'mcap': 'ROS 2 MCAP, TransformStamped (this package)',
    'tf': 'ROS 2 MCAP, TFMessage on /tf (rosbags)',
    'odometry': 'ROS 2 MCAP, Odometry (rosbags)',
    'sqlite3': 'ROS 2 sqlite3, TransformStamped (rosbags)',
    'ros1': 'ROS 1 .bag, TransformStamped (rosbags)',
}


def _peak_rss_mb() -> float:
    """Peak resident set size of this process so far (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _runs(n_runs: int, n_samples: int):
    """(run, stamps ns, poses (n_samples, 3)) of every run, made block by block."""
    t = np.arange(n_samples) / 50.0
    period_ns = int(round(t[-1] * 1e9)) + 1_000_000_000
    offsets_ns = np.round(t * 1e9).astype(np.int64)
    rng = np.random.default_rng(0)
    block = 500
    for first in range(0, n_runs, block):
        count = min(block, n_runs - first)
        heading = np.pi / 2 + rng.normal(0, 0.2, (count, 1)) * t
        x = np.broadcast_to(0.01 * np.sin(t), heading.shape)
        y = np.broadcast_to(0.2 * t, heading.shape)
        poses = np.stack([x, y, heading], axis=-1)
        for offset in range(count):
            run = first + offset
            yield run, START_NS + run * period_ns + offsets_ns, poses[offset]


def _write_standard(bag: Path, n_runs: int, n_samples: int) -> None:
    with PoseBagWriter(bag) as writer:
        for run, stamps, poses in _runs(n_runs, n_samples):
            writer.write_marker(run, int(stamps[0]))
            writer.write_poses(stamps, poses)


def _write_rosbags(kind: str, bag: Path, n_runs: int, n_samples: int) -> Path:
    """Write an input with rosbags' own writers, message by message."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import get_typestore, Stores

    if kind == 'ros1':
        bag = bag.with_suffix('.bag')
        store = get_typestore(Stores.ROS1_NOETIC)
        writer = Writer1(bag)
        serialize = store.serialize_ros1
    else:
        store = get_typestore(Stores.ROS2_JAZZY)
        storage = StoragePlugin.SQLITE3 if kind == 'sqlite3' else StoragePlugin.MCAP
        writer = Writer2(bag, version=9, storage_plugin=storage)
        serialize = store.serialize_cdr
    types = store.types
    seq = {'seq': 0} if kind == 'ros1' else {}
    msgtypes = {'tf': 'tf2_msgs/msg/TFMessage', 'odometry': 'nav_msgs/msg/Odometry'}
    msgtype = msgtypes.get(kind, 'geometry_msgs/msg/TransformStamped')
    topic = {'tf': '/tf', 'odometry': '/odom'}.get(kind, '/vicon/octoroach/octoroach')
    stamp = types['builtin_interfaces/msg/Time'](sec=0, nanosec=0)
    header = types['std_msgs/msg/Header'](stamp=stamp, frame_id='vicon/world', **seq)
    vector = types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)
    rotation = types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)
    transform = types['geometry_msgs/msg/TransformStamped'](
        header=header, child_frame_id='vicon/octoroach/octoroach',
        transform=types['geometry_msgs/msg/Transform'](translation=vector, rotation=rotation))
    if kind == 'tf':
        message = types[msgtype](transforms=[transform])
    elif kind == 'odometry':
        covariance = np.zeros(36)
        point = types['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0)
        zero = types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)
        message = types[msgtype](
            header=header, child_frame_id='base_link',
            pose=types['geometry_msgs/msg/PoseWithCovariance'](
                pose=types['geometry_msgs/msg/Pose'](position=point, orientation=rotation),
                covariance=covariance),
            twist=types['geometry_msgs/msg/TwistWithCovariance'](
                twist=types['geometry_msgs/msg/Twist'](linear=zero, angular=zero),
                covariance=covariance))
        vector = point
    else:
        message = transform
    marker = types['std_msgs/msg/UInt32'](data=0)
    with writer:
        poses_at = writer.add_connection(topic, msgtype, typestore=store)
        markers_at = writer.add_connection('/octoroach/run_start', 'std_msgs/msg/UInt32',
                                           typestore=store)
        for run, stamps, poses in _runs(n_runs, n_samples):
            marker.data = run
            writer.write(markers_at, int(stamps[0]), serialize(marker, 'std_msgs/msg/UInt32'))
            for stamp_ns, (x, y, heading) in zip(stamps.tolist(), poses.tolist()):
                stamp.sec, stamp.nanosec = divmod(stamp_ns, 10**9)
                vector.x, vector.y = x, y
                rotation.z, rotation.w = math.sin(heading / 2), math.cos(heading / 2)
                writer.write(poses_at, stamp_ns, serialize(message, msgtype))
    return bag


def _write(kind: str, bag: Path, n_runs: int, n_samples: int,
           result: multiprocessing.Queue) -> None:
    """Child process: write one input, send back (path, seconds)."""
    started = time.perf_counter()
    if kind == 'mcap':
        _write_standard(bag, n_runs, n_samples)
        path = bag
    else:
        path = _write_rosbags(kind, bag, n_runs, n_samples)
    result.put((str(path), time.perf_counter() - started))


def _convert(source: str, tiny: str, folder: str, result: multiprocessing.Queue) -> None:
    """Child process: convert `tiny` (warm-up), then `source`; send (seconds, RSS growth)."""
    from octoroach_model.recordings.standard_bag.from_inputs import convert_to_bag

    convert_to_bag([tiny], Path(folder) / 'tiny_out')
    baseline = _peak_rss_mb()
    started = time.perf_counter()
    report = convert_to_bag([source], Path(folder) / 'big_out')
    seconds = time.perf_counter() - started
    result.put((seconds, _peak_rss_mb() - baseline, report.samples))


def _in_child(target, *args):
    queue: multiprocessing.Queue = multiprocessing.Queue()
    child = multiprocessing.get_context('fork').Process(target=target, args=(*args, queue))
    child.start()
    value = queue.get()
    child.join()
    return value


def _size_mb(path: Path) -> float:
    if path.is_dir():
        return sum(p.stat().st_size for p in path.iterdir()) / 2**20
    return path.stat().st_size / 2**20


def main() -> int:
    """Run the benchmark and print one table."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--runs', type=int, default=4000)
    parser.add_argument('--samples', type=int, default=250)
    parser.add_argument('--kinds', default=','.join(KINDS),
                        help=f'comma-separated subset of {",".join(KINDS)}')
    parser.add_argument('--tracemalloc', action='store_true',
                        help='read the MCAP bag a second time under tracemalloc (slower)')
    args = parser.parse_args()
    kinds = [kind for kind in args.kinds.split(',') if kind]
    unknown = sorted(set(kinds) - set(KINDS))
    if unknown:
        parser.error(f'unknown kinds {unknown}')
    n_poses = args.runs * args.samples
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        for kind in kinds:
            big, write_s = _in_child(_write, kind, root / f'{kind}_big', args.runs,
                                     args.samples)
            tiny, _ = _in_child(_write, kind, root / f'{kind}_tiny', 2, 10)
            work = root / f'{kind}_work'
            work.mkdir()
            convert_s, growth_mb, samples = _in_child(_convert, big, tiny, str(work))
            rows.append((LABELS[kind], _size_mb(Path(big)), write_s, convert_s, growth_mb,
                         samples))
        read = None
        if 'mcap' in kinds:
            bag = root / 'mcap_big'
            read_runs(root / 'mcap_tiny')  # first use loads the typestore: not data
            baseline_mb = _peak_rss_mb()
            started = time.perf_counter()
            run_set = read_runs(bag)
            read_s = time.perf_counter() - started
            growth = _peak_rss_mb() - baseline_mb
            result_mb = sum(run.t.nbytes + run.poses.nbytes for run in run_set.runs) / 2**20
            traced_mb = float('nan')
            if args.tracemalloc:
                del run_set
                tracemalloc.start()
                read_runs(bag)
                traced_mb = tracemalloc.get_traced_memory()[1] / 2**20
                tracemalloc.stop()
            read = (read_s, growth, result_mb, traced_mb)

    print(f'inputs of {n_poses:,} poses ({args.runs:,} runs x {args.samples} samples)')
    header = ('input', 'size', 'write', 'convert', 'peak RSS growth')
    print(f'| {" | ".join(header)} |')
    print('| --- | --- | --- | --- | --- |')
    for label, size_mb, write_s, convert_s, growth_mb, samples in rows:
        assert samples == n_poses, (label, samples)
        print(f'| {label} | {size_mb:.0f} MB | {write_s:.1f} s | {convert_s:.1f} s '
              f'({convert_s / n_poses * 1e6:.1f} us/pose) | {growth_mb:.0f} MB |')
    if read is not None:
        read_s, growth, result_mb, traced_mb = read
        print(f'read_runs of the MCAP bag: {read_s:.1f} s ({read_s / n_poses * 1e6:.1f} '
              f'us/pose), peak RSS growth {growth:.0f} MB, of which the returned runs '
              f'{result_mb:.0f} MB')
        if args.tracemalloc:
            print(f'tracemalloc peak of read_runs: {traced_mb:.0f} MB')
    return 0


if __name__ == '__main__':
    sys.exit(main())
