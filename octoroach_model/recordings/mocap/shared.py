"""
What the motion-capture file readers share: units, subject names, markers, pose chunks.

The Vicon CSV reader (`vicon_csv`), the C3D reader (`c3d_file`), the Qualisys TSV
reader (`qualisys`) and the trajectory tables (`tables`) turn frames of a capture into
`PoseChunk` streams. This module holds the facts they have in common:

- units: lengths in mm, cm or m and angles in deg or rad, converted to SI;
- labels: Vicon names a marker or segment ``Subject:Name``; a subject is chosen with
  `ReadOptions.subject` (or is the only one in the file);
- stamps: frame f of a file at rate r is stamped (f - first frame) / r seconds, so every file
  starts at 0 s and a missing frame leaves a gap of its own length;
- `MarkerBody`: the markers of one rigid body, its reference layout and axes, and the pose
  per frame by `rigid.fit_rigid` in the z-up world (`axes`). A body whose markers do not move
  as one rigid body (the fit's typical residual above MAX_TYPICAL_RESIDUAL_M, a few mm: a
  whole walking subject, a loose marker) is refused, naming the markers that keep their
  distances best, unless `ReadOptions.accept_loose_fit`;
- lines: `text_lines` reads a text export line by line, each at most `limits.MAX_CSV_LINE`.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
import math
from pathlib import Path
from typing import Any

import numpy as np

from octoroach_model.errors import BagError
from octoroach_model.limits import MAX_BODY_MARKERS, MAX_CSV_LINE
from octoroach_model.recordings.conventions.axes import (
    axes_words,
    headings_from_rotations,
    to_z_up,
)
from octoroach_model.recordings.conventions.chunks import PoseChunk
from octoroach_model.recordings.mocap.rigid import (
    fit_rigid,
    layout_from_frames,
    layout_spans_a_plane,
    MIN_MARKERS,
)
from octoroach_model.recordings.options import ReadOptions
from octoroach_model.settings import listed_names, unknown_name

# Unit words as motion-capture exports write them, and their value in SI units.
LENGTH_UNITS = {'mm': 1e-3, 'millimeters': 1e-3, 'millimetres': 1e-3, 'cm': 1e-2, 'm': 1.0,
                'meters': 1.0, 'metres': 1.0}
ANGLE_UNITS = {'deg': math.pi / 180.0, 'degrees': math.pi / 180.0, 'rad': 1.0,
               'radians': 1.0}
# Frames in which every body marker was seen, averaged into the reference layout.
LAYOUT_FRAMES = 10
# A rigid body's markers fit its layout within the capture's noise (a good Vicon or Qualisys
# fit: well under 2 mm). A typical (median) rms residual above this is not one rigid body.
MAX_TYPICAL_RESIDUAL_M = 0.005
# Frames per block whose marker distances feed the search for the markers that fit best
RIGIDITY_FRAMES = 20
# A marker coordinate beyond this (or not finite) is no position a capture volume holds: the
# marker counts as not seen, so no arithmetic on it overflows.
MAX_COORDINATE_M = 1e4
_EMPTY_INT = np.zeros(0, dtype=np.int64)


@dataclass(frozen=True)
class PoseInput:
    """What a file reader is made for: the file, how to find the pose in it, where notes go."""

    path: Path
    options: ReadOptions
    notes: list[str]


def text_lines(stream: Any, where: str, what: str) -> Iterator[str]:
    """Yield the lines of a text stream, refusing one longer than `limits.MAX_CSV_LINE`."""
    number = 0
    while True:
        line = stream.readline(MAX_CSV_LINE + 1)
        if not line:
            return
        number += 1
        if len(line) > MAX_CSV_LINE:
            raise BagError(f'{where}: line {number} is longer than {MAX_CSV_LINE} characters; '
                           f'not {what}')
        yield line


def stream_fraction(stream: Any, size: int) -> float:
    """Return how much of a file an open text stream has read (its buffer's position)."""
    try:
        return min(1.0, stream.buffer.tell() / max(1, size))
    except (AttributeError, OSError, ValueError):
        return math.nan


def unit_scale(unit: str, table: dict[str, float], what: str, where: str) -> float:
    """Return the SI value of `unit` in `table` (LENGTH_UNITS or ANGLE_UNITS), or raise."""
    word = unit.strip().lower()
    if word in table:
        return table[word]
    known = ', '.join(sorted({name for name in table if len(name) <= 3}))
    raise BagError(f'{where}: unknown {what} unit, {unknown_name(word, sorted(table))}; '
                   f'expected {known}')


def split_label(label: str) -> tuple[str, str]:
    """Split a ``Subject:Name`` label into ('Subject', 'Name'); ('', label) if no subject."""
    subject, colon, name = label.strip().partition(':')
    return (subject.strip(), name.strip()) if colon else ('', subject.strip())


def is_marker_label(label: str) -> bool:
    """Tell a marker label from an empty one or an unlabelled trajectory (``*12``)."""
    text = label.strip()
    return bool(text) and not text.startswith('*')


def axis_words(options: ReadOptions) -> str:
    """Say the axes and the heading convention in the words of the notes."""
    return axes_words(options.up_axis, options.forward_axis)


def length_words(unit: str) -> str:
    """Say how positions in `unit` were converted, in the words of the notes."""
    return 'positions in m' if unit.strip().lower() in ('m', 'meters', 'metres') \
        else f'positions in {unit.strip()} converted to m'


def stamps_ns(frames: np.ndarray, first_frame: int, rate_hz: float) -> np.ndarray:
    """Return int64 ns stamps of frame numbers: (frame - first_frame) / rate_hz."""
    offsets = np.asarray(frames, dtype=np.float64) - float(first_frame)
    return np.round(offsets * (1e9 / rate_hz)).astype(np.int64)


def check_rate(rate_hz: float, where: str) -> float:
    """Return the frame rate as a positive finite float, else raise BagError."""
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise BagError(f'{where}: frame rate must be a positive number of Hz, got {rate_hz:g}')
    return float(rate_hz)


def pose_chunk(source: str, topic: str, first_sequence: int, stamp_ns: np.ndarray,
               x: np.ndarray, y: np.ndarray, heading: np.ndarray, *, is_last: bool = False,
               truncated: bool = False, z: np.ndarray | None = None,
               read_fraction: float = math.nan) -> PoseChunk:
    """Make a PoseChunk of one stream without run markers; log time = stamp."""
    count = len(stamp_ns)
    sequence = np.arange(first_sequence, first_sequence + count, dtype=np.int64)
    return PoseChunk(source, topic, '', sequence, stamp_ns, stamp_ns.copy(),
                     np.asarray(x, dtype=float), np.asarray(y, dtype=float),
                     np.asarray(heading, dtype=float), _EMPTY_INT, _EMPTY_INT.copy(),
                     _EMPTY_INT.copy(), is_last, truncated,
                     None if z is None else np.asarray(z, dtype=float), read_fraction)


def last_chunk(source: str, topic: str, sequence: int, *,
               truncated: bool = False) -> PoseChunk:
    """Make the empty chunk that ends a stream."""
    empty = np.zeros(0)
    return pose_chunk(source, topic, sequence, np.zeros(0, dtype=np.int64), empty, empty,
                      empty, is_last=True, truncated=truncated, z=empty, read_fraction=1.0)


def _listed(names: Iterable[str], limit: int = 12) -> str:
    return listed_names(names, limit)       # names from the file: those that look like names


def choose_subject(where: str, subjects: Sequence[str], wanted: str | None,
                   what: str = 'subject') -> str:
    """Return the subject to read: `wanted` if present, else the only one (or BagError)."""
    unique = list(dict.fromkeys(subjects))
    if wanted is not None:
        if wanted in unique:
            return wanted
        raise BagError(f'{where}: no {what} {wanted!r}; it has {_listed(unique) or "none"}')
    named = [subject for subject in unique if subject]
    if len(unique) == 1:
        return unique[0]
    if not named:
        raise BagError(f'{where}: no {what} found')
    raise BagError(f'{where}: several {what}s ({_listed(named)}); pass --subject NAME')


def select_body_markers(where: str, labels: Sequence[str], options: ReadOptions,
                        default_subject: str = '', named: Sequence[str] = ()) -> list[int]:
    """
    Return the indexes into `labels` of the body's markers, checked to be at least 3.

    Markers named by `named` (a given layout) or `options.markers` are found by full label
    or by marker name within the subject; otherwise the body is every marker of the subject
    (`options.subject`, or the only subject; unprefixed labels belong to `default_subject`).
    """
    candidates = [index for index, label in enumerate(labels) if is_marker_label(label)]
    if not candidates:
        raise BagError(f'{where}: no labelled markers in the file')
    if not default_subject and not any(split_label(labels[i])[0] for i in candidates):
        default_subject = options.subject or ''  # labels without subjects: take the name given
    owner = {}
    for index in candidates:
        subject, name = split_label(labels[index])
        owner[index] = (subject or default_subject, name)
    wanted = list(named or options.markers)
    if wanted:
        subjects = [owner[index][0] for index in candidates]
        in_scope = candidates
        if options.subject is not None:
            choose_subject(where, subjects, options.subject)
            in_scope = [i for i in candidates if owner[i][0] == options.subject]
        chosen = [_find_marker(where, labels, in_scope, owner, name) for name in wanted]
        if len(set(chosen)) < len(chosen):
            raise BagError(f'{where}: a marker is named twice in {_listed(wanted)}')
    else:
        subject = choose_subject(where, [owner[index][0] for index in candidates],
                                 options.subject)
        chosen = [index for index in candidates if owner[index][0] == subject]
    if len(chosen) < MIN_MARKERS:
        on_body = _listed(labels[index].strip() for index in chosen) or 'none'
        available = _listed(labels[index].strip() for index in candidates)
        raise BagError(f'{where}: {len(chosen)} marker(s) on the body ({on_body}); a rigid '
                       f'fit needs at least {MIN_MARKERS}: pass --subject NAME or --markers '
                       f'A,B,C naming 3 or more of {available}')
    if len(chosen) > MAX_BODY_MARKERS:
        raise BagError(f'{where}: {len(chosen)} markers on the body, more than the '
                       f'{MAX_BODY_MARKERS} a rigid body may have here; pass --markers A,B,C')
    return chosen


def _find_marker(where: str, labels: Sequence[str], scope: list[int],
                 owner: dict[int, tuple[str, str]], name: str) -> int:
    """
    Find a marker named `name`: its full label, or Subject:Marker, or the bare marker name.

    ``SI02:LASI`` finds the label ``SI02:LASI``, or ``LASI`` of subject SI02 (a file whose
    labels carry no prefix, its subject named in SUBJECTS:NAMES or by --subject), or a lone
    unprefixed ``LASI``; a bare ``LASI`` finds the marker LASI of any one subject.
    """
    exact = [index for index in scope if labels[index].strip() == name.strip()]
    if len(exact) == 1:
        return exact[0]
    subject, marker = split_label(name)
    if subject:
        owned = [index for index in scope if owner[index] == (subject, marker)]
        if len(owned) == 1:
            return owned[0]
        unowned = [index for index in scope if owner[index] == ('', marker)]
        if not owned and len(unowned) == 1:
            return unowned[0]
    by_name = [index for index in scope if owner[index][1] == marker]
    if len(by_name) == 1 and not subject:
        return by_name[0]
    if by_name and not subject:
        found = _listed(labels[index].strip() for index in by_name)
        raise BagError(f'{where}: marker {name!r} is ambiguous ({found}); pass --subject NAME '
                       'or name it as Subject:Marker')
    available = _listed(labels[index].strip() for index in scope)
    raise BagError(f'{where}: no marker {name!r}; it has {available}')


@dataclass
class FitSummary:
    """Counts over a marker stream, for the notes."""

    frames: int = 0
    dropped: int = 0
    partial: int = 0
    residuals_m: list[float] = field(default_factory=list)
    worst_m: float = 0.0

    @property
    def typical_m(self) -> float:
        """Return the typical rms residual: the median of the blocks' medians (NaN: none)."""
        return float(np.median(self.residuals_m)) if self.residuals_m else math.nan

    def add(self, seen: np.ndarray, valid: np.ndarray, rms_m: np.ndarray) -> None:
        """Count one block of frames: markers seen (F, M), valid fits, rms residuals."""
        self.frames += len(valid)
        self.dropped += int((~valid).sum())
        self.partial += int((valid & ~seen.all(axis=1)).sum())
        if valid.any():
            good = rms_m[valid]
            self.residuals_m.append(float(np.median(good)))
            self.worst_m = max(self.worst_m, float(good.max()))

    def notes(self, where: str, names: str) -> list[str]:
        """Say in plain words what was dropped, partly seen, and how well the fit fits."""
        notes = []
        if self.dropped:
            notes.append(f'{where}: {self.dropped} of {self.frames} frame(s) with fewer than '
                         f'{MIN_MARKERS} of the body markers ({names}) seen (or seen on one '
                         'line) dropped')
        if self.partial:
            notes.append(f'{where}: {self.partial} frame(s) fitted on the markers that were '
                         'seen (some body markers missing)')
        if self.residuals_m:
            notes.append(f'{where}: rigid fit rms residual {self.typical_m * 1e3:.3g} mm '
                         f'typical, {self.worst_m * 1e3:.3g} mm worst')
        return notes


@dataclass
class Rigidity:
    """
    How well each pair of markers keeps its distance, from a sample of the frames.

    Per pair: the count, sum and sum of squares of their distance over up to RIGIDITY_FRAMES
    frames per block in which both were seen. Markers on one rigid body keep their
    distances (spread ~ the capture's noise); markers on different segments do not.
    """

    count: np.ndarray
    total: np.ndarray
    squares: np.ndarray

    @classmethod
    def of(cls, markers: int) -> Rigidity:
        """Start the statistics of `markers` markers."""
        shape = (markers, markers)
        return cls(np.zeros(shape), np.zeros(shape), np.zeros(shape))

    def add(self, markers_m: np.ndarray) -> None:
        """Take up to RIGIDITY_FRAMES evenly spaced frames of (F, M, 3) positions."""
        if not len(markers_m):
            return
        pick = np.unique(np.linspace(0, len(markers_m) - 1, RIGIDITY_FRAMES).astype(int))
        frames = markers_m[pick]
        distance = np.linalg.norm(frames[:, :, None, :] - frames[:, None, :, :], axis=-1)
        seen = np.isfinite(distance)
        values = np.where(seen, distance, 0.0)
        self.count += seen.sum(axis=0)
        self.total += values.sum(axis=0)
        self.squares += (values * values).sum(axis=0)

    def spread_m(self) -> np.ndarray:
        """(M, M) standard deviation of each pair's distance (inf where seen under 3 times)."""
        with np.errstate(invalid='ignore', divide='ignore'):
            mean = self.total / self.count
            variance = self.squares / self.count - mean * mean
        spread = np.sqrt(np.clip(variance, 0.0, None))
        return np.where(self.count >= 3, spread, np.inf)

    def best_group(self, seeds: int = 64) -> tuple[list[int], float]:
        """
        Return the largest group of markers that keep their distances, and its spread [m].

        Grown greedily from each of the `seeds` steadiest pairs: the marker whose largest
        spread to the group is smallest joins while that spread is within
        MAX_TYPICAL_RESIDUAL_M.
        """
        spread = self.spread_m()
        count = len(spread)
        if count < 2:
            return [], math.inf
        np.fill_diagonal(spread, np.inf)
        rows, columns = np.triu_indices(count, 1)
        best: tuple[list[int], float] = ([], math.inf)
        for pair in np.argsort(spread[rows, columns], kind='stable')[:seeds]:
            first, second = int(rows[pair]), int(columns[pair])
            if not spread[first, second] <= MAX_TYPICAL_RESIDUAL_M:
                break
            group = [first, second]
            worst = np.maximum(spread[first], spread[second])
            worst[group] = np.inf
            while True:
                pick = int(np.argmin(worst))
                if not worst[pick] <= MAX_TYPICAL_RESIDUAL_M:
                    break
                group.append(pick)
                worst = np.maximum(worst, spread[pick])
                worst[group] = np.inf
            inside = spread[np.ix_(group, group)]
            within = float(inside[np.isfinite(inside)].max())
            if (len(group), -within) > (len(best[0]), -best[1]):
                best = (sorted(group), within)
        return best


class MarkerBody:
    """
    The markers of one rigid body and its reference layout: poses from marker frames.

    `layout_m` (M, 3) is in metres in the body frame, one row per marker in `names` order;
    None until `set_layout_from_frames` has seen enough complete frames.
    """

    def __init__(self, where: str, names: Sequence[str], options: ReadOptions,
                 layout_m: np.ndarray | None = None) -> None:
        """Name the body's markers; `layout_m` (metres, body frame) if it is known."""
        self.where = where
        self.names = tuple(names)
        self.options = options
        self.layout_m: np.ndarray | None = None
        self.layout_origin = ''
        self.summary = FitSummary()
        self.rigidity = Rigidity.of(len(self.names))
        if layout_m is not None:
            self._set_layout(np.asarray(layout_m, dtype=float), 'the given layout')

    def _set_layout(self, layout_m: np.ndarray, origin: str) -> None:
        if layout_m.shape != (len(self.names), 3) or not layout_spans_a_plane(layout_m):
            raise BagError(f'{self.where}: the layout of {_listed(self.names)} does not span '
                           f'a plane (needs {MIN_MARKERS} markers not on one line)')
        self.layout_m = layout_m
        self.layout_origin = origin

    def set_layout_from_frames(self, complete_frames_m: np.ndarray, first_frame: int) -> None:
        """Set the layout from (K, M, 3) frames with every marker seen (layout_from_frames)."""
        if len(complete_frames_m) == 0:
            raise BagError(f'{self.where}: no frame shows all of {_listed(self.names)} at '
                           'once, so their layout is unknown; pass --markers naming markers '
                           'seen together')
        layout = layout_from_frames(to_z_up(complete_frames_m, self.options.up_axis))
        self._set_layout(layout, f'the layout of the first {len(complete_frames_m)} complete '
                                 f'frame(s) from frame {first_frame} (body axes = world axes '
                                 "there, z up, origin at the markers' centroid)")

    def poses(self, markers_m: np.ndarray) -> tuple[np.ndarray, ...]:
        """
        Return x, y, z [m], heading [rad] and validity of (F, M, 3) frames in metres.

        Positions are in the z-up world. Raises BagError once the fit shows that the markers
        are not one rigid body (`check_rigid`).
        """
        if self.layout_m is None:
            raise RuntimeError('MarkerBody.poses needs the layout first')
        markers_m = to_z_up(markers_m, self.options.up_axis)
        markers_m = seen_markers(markers_m)
        fit = fit_rigid(self.layout_m, markers_m)
        self.summary.add(np.isfinite(markers_m).all(axis=2), fit.valid, fit.rms_residual)
        self.rigidity.add(markers_m)
        self.check_rigid()
        heading = headings_from_rotations(fit.rotation, 'z', self.options.forward_axis)
        return (fit.translation[:, 0], fit.translation[:, 1], fit.translation[:, 2], heading,
                fit.valid)

    def check_rigid(self) -> None:
        """Refuse a body whose fit's typical residual exceeds MAX_TYPICAL_RESIDUAL_M."""
        typical = self.summary.typical_m
        if self.options.accept_loose_fit or not typical > MAX_TYPICAL_RESIDUAL_M:
            return
        group, within = self.rigidity.best_group()
        if len(group) >= MIN_MARKERS:
            best = (f'the markers that keep their distances best are '
                    f'{_listed(self.names[index] for index in group)} (within '
                    f'{within * 1e3:.2g} mm): pass them with --markers')
        else:
            best = (f'no {MIN_MARKERS} of them keep their distances within '
                    f'{MAX_TYPICAL_RESIDUAL_M * 1e3:g} mm: pass --markers naming the markers '
                    'of one rigid body')
        raise BagError(f'{self.where}: the {len(self.names)} body markers do not move as one '
                       f"rigid body: the rigid fit's typical residual is {typical * 1e3:.3g} "
                       f'mm, above the {MAX_TYPICAL_RESIDUAL_M * 1e3:g} mm a rigid body allows; '
                       f'{best}, or --accept-loose-fit to use this fit anyway')


def seen_markers(frames_m: np.ndarray) -> np.ndarray:
    """Return (F, M, 3) frames with every marker whose position is not plausible set to NaN."""
    plausible = (np.abs(frames_m) <= MAX_COORDINATE_M).all(axis=-1, keepdims=True)
    return np.where(plausible, frames_m, np.nan)


def complete_frames(frames_m: np.ndarray) -> np.ndarray:
    """Return the frames of (F, M, 3) in which every marker was seen."""
    frames_m = seen_markers(frames_m)
    return frames_m[np.isfinite(frames_m).all(axis=(1, 2))]


def first_complete_frames(blocks: Iterable[tuple[np.ndarray, np.ndarray]],
                          n_markers: int) -> tuple[np.ndarray, int]:
    """
    Return up to LAYOUT_FRAMES frames in which every marker was seen, and the first one's number.

    `blocks` yields (frame numbers (F,), markers (F, M, 3) in metres) in file order, as each
    marker reader reads its file; reading stops once enough frames are found. The number is
    the first complete frame's even when earlier blocks had none (it names where the layout
    comes from in the reader's note).
    """
    found: list[np.ndarray] = []
    count, first_frame = 0, 0
    for frames, markers_m in blocks:
        seen = seen_markers(markers_m)
        complete = np.isfinite(seen).all(axis=(1, 2))
        if complete.any() and not count:
            first_frame = int(np.asarray(frames)[complete][0])
        found.append(seen[complete])
        count += int(complete.sum())
        if count >= LAYOUT_FRAMES:
            break
    frames_m = np.concatenate(found)[:LAYOUT_FRAMES] if found else np.zeros((0, n_markers, 3))
    return frames_m, first_frame
