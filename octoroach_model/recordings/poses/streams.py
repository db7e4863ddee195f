"""
Each pose stream as it passes from a reader to its consumer: clock, axes, density, progress.

`watch_streams` sits between every reader and every consumer (the run splitter, `convert`),
so what it decides holds alike for `validate`, `diagnose`, `convert` and the validator node:

- **Clock.** A bag's pose carries two clocks: its header stamp (often the camera's capture
  time) and its log time (when the recorder received it). Drivers stamp either; frames
  captured 4 ms apart may arrive 100 us apart. The first `CLOCK_WINDOW` samples of a stream
  are held while both clocks are measured: the typical interval P (the larger of the two
  median intervals, so a burst of arrivals cannot pass for the frame period) and each clock's
  jitter, the median distance of its intervals from P. The header stamps are used unless the
  log times' jitter is less than 1 / STEADIER_FACTOR of theirs. The notes say which clock the
  poses carry, its interval and jitter (and the other's).
- **Up.** The extent of the motion along each z-up axis is tracked (of the running median over
  EXTENT_WINDOW samples, so a damaged frame is no motion); when the vertical one is
  comparable to the horizontal one (at least VERTICAL_RATIO of it, and more than
  MIN_VERTICAL_M), one note says the up axis looks wrong and which axis of the input is the
  flattest, the one that fits (`UP_AXIS_NOTE` marks it; the programs print it).
- **Density.** A stream without run markers is cut into runs at pauses longer than gap_s; one
  whose median interval exceeds SPARSE_FRACTION of gap_s cannot form runs (a 2 Hz pose every
  0.5 s is a pause each time) and is refused with its rate.

`ReadProgress` reports how far the reading of all inputs has got, from each chunk's
`read_fraction`, to a progress callback (the programs' progress lines).
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from enum import Enum
import os
from pathlib import Path

import numpy as np

from octoroach_model.errors import DataError
from octoroach_model.recordings.conventions.axes import input_axis_of
from octoroach_model.recordings.conventions.chunks import PoseChunk
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.settings import Progress


CLOCK_WINDOW = 2000  # samples of a stream held while its clock is chosen
MAX_INTERVALS = 1 << 17  # intervals kept per clock for the notes (1 MiB each)
STEADIER_FACTOR = 2.0  # log times replace header stamps only when this much steadier
VERTICAL_RATIO = 0.5  # vertical extent at least this share of the horizontal: up looks wrong
MIN_VERTICAL_M = 0.1  # ... and more than this (a robot's own bobbing never is)
SPARSE_FRACTION = 0.5  # median interval above this share of gap_s: too sparse to form runs
EXTENT_QUANTILE = 0.5  # percent cut at each end of a chunk's extent (a stray value is no motion)
EXTENT_WINDOW = 5  # extents are of the running median over this many samples (as runs.reachable)
UP_AXIS_NOTE = 'the up axis looks wrong'


class Clock(Enum):
    """The time a stream's samples carry."""

    HEADER = 'header stamps'
    LOG = 'log (receive) times'
    FRAMES = "the file's own times"


@dataclass
class _Intervals:
    """Positive intervals of one clock (at most MAX_INTERVALS), and its last stamp."""

    kept: list[np.ndarray] = field(default_factory=list)
    count: int = 0
    last: int | None = None

    def add(self, stamps: np.ndarray) -> None:
        if not len(stamps):
            return
        joined = stamps if self.last is None else np.concatenate([[self.last], stamps])
        self.last = int(stamps[-1])
        steps = np.diff(joined)
        steps = steps[steps > 0]
        room = MAX_INTERVALS - self.count
        if room > 0 and len(steps):
            self.kept.append(steps[:room])
            self.count += min(room, len(steps))

    def values(self) -> np.ndarray:
        return np.concatenate(self.kept) if self.kept else np.zeros(0, dtype=np.int64)


# A sorting network of five values (Knuth): after these compare-exchanges they are in order
_FIVE = ((0, 1), (3, 4), (2, 4), (2, 3), (0, 3), (0, 2), (1, 4), (1, 3), (1, 2))


def median_of_five(windows: np.ndarray) -> np.ndarray:
    """
    Return the median along the last axis of `windows`, exactly as np.median gives it.

    For windows of five finite floats (the running medians of `streams` and `runs`) a sorting
    network picks the middle value, about 15 times faster than np.median's partition of every
    window; anything else goes to np.median.
    """
    if windows.shape[-1] != 5 or windows.dtype.kind != 'f' or np.isnan(windows).any():
        return np.median(windows, axis=-1)
    values = [windows[..., index] for index in range(5)]
    for low, high in _FIVE:
        values[low], values[high] = (np.minimum(values[low], values[high]),
                                     np.maximum(values[low], values[high]))
    return values[2]


def median_interval_ns(intervals: np.ndarray) -> float:
    """
    Return the median of int64 intervals, as np.median gives it, taken over float64.

    numpy partitions int64 values that are nearly all equal (a steady clock) slowly: 15 ms
    for a stream of 125,000 intervals, 2 ms as float64. The value is the same: rounding to
    float64 keeps the order, and np.median averages the middle pair in float64 either way.
    """
    return float(np.median(np.asarray(intervals, dtype=np.float64)))


def typical_interval_ns(*clocks: np.ndarray) -> float:
    """Return P: the largest of the clocks' median intervals (NaN when none has any)."""
    medians = [median_interval_ns(values) for values in clocks if len(values)]
    return max(medians) if medians else float('nan')


def jitter_ns(intervals: np.ndarray, period_ns: float) -> float:
    """Return the median distance of `intervals` from the typical interval `period_ns`."""
    if not len(intervals) or not np.isfinite(period_ns):
        return float('nan')
    return float(np.median(np.abs(intervals - period_ns)))


@dataclass
class _Watch:
    """What is known of one stream so far."""

    label: str
    kind: Clock  # FRAMES for files; HEADER until decided for bags
    held: list[PoseChunk] = field(default_factory=list)
    held_samples: int = 0
    decided: Clock | None = None
    stamps: _Intervals = field(default_factory=_Intervals)
    logs: _Intervals = field(default_factory=_Intervals)
    differ: bool = False  # the two clocks differ somewhere
    low: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))
    high: np.ndarray = field(default_factory=lambda: np.full(3, -np.inf))
    samples: int = 0

    def measure(self, chunk: PoseChunk) -> None:
        """Take the chunk's clocks and extent into account (before any clock is applied)."""
        self.samples += len(chunk.stamp_ns)
        self.stamps.add(chunk.stamp_ns)
        self.logs.add(chunk.log_time_ns)
        if len(chunk.stamp_ns) and not self.differ:
            self.differ = bool(np.any(chunk.stamp_ns != chunk.log_time_ns))
        if chunk.z is None or not len(chunk.x):
            return
        points = np.column_stack([chunk.x, chunk.y, chunk.z])
        points = points[np.isfinite(points).all(axis=1)]
        if len(points) >= EXTENT_WINDOW:    # one or two damaged frames cannot move a median
            windows = np.lib.stride_tricks.sliding_window_view(points, EXTENT_WINDOW, axis=0)
            points = median_of_five(windows)
        if not len(points):
            return
        if len(points) >= 200:
            low, high = np.percentile(points, [EXTENT_QUANTILE, 100 - EXTENT_QUANTILE], axis=0)
        else:
            low, high = points.min(axis=0), points.max(axis=0)
        self.low = np.minimum(self.low, low)
        self.high = np.maximum(self.high, high)

    def choose_clock(self) -> Clock:
        """Decide the clock from what was measured so far (the held window)."""
        if self.kind is Clock.FRAMES or not self.differ:
            return self.kind
        stamps, logs = self.stamps.values(), self.logs.values()
        period = typical_interval_ns(stamps, logs)
        stamp_jitter, log_jitter = jitter_ns(stamps, period), jitter_ns(logs, period)
        if np.isfinite(log_jitter) and (not np.isfinite(stamp_jitter)
                                        or log_jitter * STEADIER_FACTOR < stamp_jitter):
            return Clock.LOG
        return Clock.HEADER

    def clock_note(self) -> str:
        """Say which clock the poses carry, its interval and jitter (and the other's)."""
        stamps, logs = self.stamps.values(), self.logs.values()
        chosen = self.decided or self.kind
        period = typical_interval_ns(stamps, logs) if self.differ \
            else typical_interval_ns(stamps)
        if not np.isfinite(period) or period <= 0:
            return f'{self.label}: clock: {chosen.value} (too few samples to measure it)'

        def said(intervals: np.ndarray) -> str:
            median = median_interval_ns(intervals) if len(intervals) else float('nan')
            return (f'median interval {median / 1e6:.4g} ms, jitter '
                    f'{jitter_ns(intervals, period) / 1e6:.3g} ms')

        rate = 1e9 / period
        if chosen is Clock.FRAMES or not self.differ:
            what = chosen.value if chosen is not Clock.HEADER else \
                'header stamps (equal to the log times)'
            return (f'{self.label}: clock: {what}, {rate:.4g} Hz ({said(stamps)}), over '
                    f'{self.samples} poses')
        used, other = (stamps, logs) if chosen is Clock.HEADER else (logs, stamps)
        other_clock = Clock.LOG if chosen is Clock.HEADER else Clock.HEADER
        return (f'{self.label}: clock: {chosen.value} used, the steadier: {rate:.4g} Hz '
                f'({said(used)}); {other_clock.value}: {said(other)}; over {self.samples} '
                'poses')

    def vertical_note(self, options: ReadOptions) -> str | None:
        """Say that the up axis looks wrong, and which input axis fits, when it does."""
        if not np.isfinite(self.low).all():
            return None
        spans = self.high - self.low
        horizontal = float(max(spans[0], spans[1]))
        vertical = float(spans[2])
        flattest = int(np.argmin(spans))
        if vertical < MIN_VERTICAL_M or vertical < VERTICAL_RATIO * horizontal or flattest == 2:
            return None
        fits = input_axis_of(flattest, options.up_axis)
        return (f'{self.label}: {UP_AXIS_NOTE}: the poses span {vertical:.3g} m vertically '
                f'against {horizontal:.3g} m horizontally with --up-axis {options.up_axis}; '
                f"the motion is flattest along the input's {fits} axis: --up-axis {fits} "
                f'(or -{fits} if it points down) fits')

    def sparse_error(self, gap_s: float) -> DataError | None:
        """Refuse a stream without markers whose samples are too far apart to form runs."""
        intervals = self.logs.values() if self.decided is Clock.LOG else self.stamps.values()
        if len(intervals) < 2:
            return None
        median_s = median_interval_ns(intervals) / 1e9
        if median_s <= SPARSE_FRACTION * gap_s:
            return None
        return DataError(
            f'{self.label}: poses at {1 / median_s:.3g} Hz (a median interval of '
            f'{median_s:.3g} s) are too sparse to form runs: without run markers a pause '
            f'longer than --gap-s {gap_s:g} s ends a run; choose a denser stream (--topic) '
            f'or a --gap-s above {median_s / SPARSE_FRACTION:.3g} s')


def _apply(chunk: PoseChunk, clock: Clock) -> PoseChunk:
    return chunk._replace(stamp_ns=chunk.log_time_ns) if clock is Clock.LOG else chunk


def watch_streams(chunks: Iterable[PoseChunk], options: ReadOptions, notes: list[str], *,
                  from_files: bool, gap_s: float | None = None) -> Iterator[PoseChunk]:
    """
    Pass the chunks of one source on, each stream on the clock chosen for it (module doc).

    `from_files`: the source's samples carry frame times (no log times of their own).
    With `gap_s`, a stream without run markers too sparse to form runs raises DataError.
    The notes get each stream's clock, and a line when the up axis looks wrong.
    """
    watches: dict[tuple[str, str], _Watch] = {}
    for chunk in chunks:
        key = (chunk.source, chunk.topic)
        watch = watches.get(key)
        if watch is None:
            watch = watches[key] = _Watch(f'{chunk.source} {chunk.topic}',
                                          Clock.FRAMES if from_files else Clock.HEADER)
        watch.measure(chunk)
        if watch.decided is None:
            watch.held.append(chunk)
            watch.held_samples += len(chunk.stamp_ns)
            if watch.held_samples < CLOCK_WINDOW and not chunk.is_last:
                continue
            watch.decided = watch.choose_clock()
            if gap_s is not None and not chunk.marker_topic:
                error = watch.sparse_error(gap_s)
                if error is not None:
                    raise error
            held, watch.held = watch.held, []
            for waiting in held:
                yield _apply(waiting, watch.decided)
        else:
            yield _apply(chunk, watch.decided)
        if chunk.is_last and watch.samples:
            notes.append(watch.clock_note())
            vertical = watch.vertical_note(options)
            if vertical:
                notes.append(vertical)


def input_size(path: Path) -> int:
    """Return the bytes of an input (a bag directory: its files), at least 1."""
    try:
        if path.is_dir():
            return max(1, sum(entry.stat().st_size for entry in path.iterdir()
                              if entry.is_file()))
        return max(1, os.path.getsize(path))
    except OSError:
        return 1


class ReadProgress:
    """Report the share of all inputs read so far, by size, from the chunks' read_fraction."""

    def __init__(self, report: Progress | None, paths: list[Path]) -> None:
        """Weigh each input by its size; `report` None: say nothing."""
        self.report = report
        self.sizes = [input_size(path) for path in paths]
        self.total = float(sum(self.sizes)) or 1.0
        self.poses = 0

    def follow(self, index: int, path: Path, chunks: Iterable[PoseChunk]) -> Iterator[PoseChunk]:
        """Pass on the chunks of input `index`, reporting as they come."""
        before = float(sum(self.sizes[:index]))
        for chunk in chunks:
            self.poses += len(chunk.stamp_ns)
            if self.report is not None:
                within = chunk.read_fraction if np.isfinite(chunk.read_fraction) else 0.0
                if chunk.is_last:
                    within = 1.0
                done = (before + min(max(within, 0.0), 1.0) * self.sizes[index]) / self.total
                self.report(min(done, 1.0), f'reading {path.name} ({index + 1} of '
                                            f'{len(self.sizes)}): {self.poses} poses')
            yield chunk
