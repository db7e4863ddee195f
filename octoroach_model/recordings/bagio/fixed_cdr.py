"""
Pose messages decoded over whole runs of MCAP records with numpy, where their layout is fixed.

A message type made of fixed-size fields and strings (TransformStamped, PoseStamped, Odometry,
a lab's own type of that shape) has the same CDR byte layout in every message of a channel
whose strings (the frame ids) do not change. `FixedLayout.of` finds that layout from the
type's definition and one message of the channel (its template): where the stamp, position
and orientation are, and which bytes are structure (the encapsulation kind, and each string
with its length). `FixedLayout.decode` reads a run of such messages as numpy views of the
chunk, after checking that each one's structural bytes equal the template's: a message whose
strings differ is left to rosbags' deserializer, message by message.

Nothing here decides alone: a layout is made only when rosbags decodes its template to the
same stamp and pose, bit for bit, and the reader checks every chunk's decoded messages on a
sample against rosbags again (`reader`); a mismatch refuses the layout. Bytes are only read.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
from rosbags.interfaces import Nodetype

from octoroach_model.recordings.bagio.pose_messages import PoseLayout

# An MCAP message record: opcode (1), record length (8), channel id (2), sequence (4), log
# time (8), publish time (8), then the message's bytes
LOG_TIME_AT = 15
DATA_AT = 31
# The CDR encapsulation: representation id (2 bytes, 00 01 is little-endian CDR), options (2)
ENCAPSULATION = 4
LITTLE_ENDIAN_CDR = b'\x00\x01'
# Bytes of each primitive that decodes from any bytes; numpy's code for the ones read here
_SIZES = {'bool': 1, 'byte': 1, 'char': 1, 'int8': 1, 'uint8': 1, 'int16': 2, 'uint16': 2,
          'int32': 4, 'uint32': 4, 'int64': 8, 'uint64': 8, 'float32': 4, 'float64': 8}
_CODES = {'int32': '<i4', 'uint32': '<u4', 'float32': '<f4', 'float64': '<f8'}
# Nesting deeper than this is not a pose message (rosbags' definitions cannot loop anyway)
_MAX_DEPTH = 16
# The fields of a decoded pose, in the order of pose_messages.Sample after the stamp
POSE_FIELDS = ('x', 'y', 'z', 'qx', 'qy', 'qz', 'qw')


class Unfixed(Exception):
    """A type or message whose layout is not fixed (a sequence, an odd primitive, bad bytes)."""


class _Walk:
    """Offsets of every primitive and the spans of every string, walking a template."""

    def __init__(self, fielddefs: Mapping[str, Any], payload: bytes) -> None:
        self.fielddefs = fielddefs
        self.payload = payload  # the message's bytes after the encapsulation
        self.position = 0
        self.fields: dict[str, tuple[int, str]] = {}  # path -> (offset, primitive type)
        self.strings: list[tuple[int, int]] = []  # (start, end) of length and text

    def align(self, size: int) -> None:
        self.position = (self.position + size - 1) & -size

    def message(self, msgtype: str, prefix: str, depth: int) -> None:
        entry = self.fielddefs.get(msgtype)
        if entry is None or depth > _MAX_DEPTH:
            raise Unfixed(msgtype)
        for name, desc in entry[1]:
            self.field(desc, prefix + name, depth)

    def field(self, desc: Any, path: str, depth: int) -> None:
        kind, detail = desc
        if kind == Nodetype.NAME:
            self.message(detail, path + '.', depth + 1)
        elif kind == Nodetype.BASE and detail[0] == 'string':
            self.string()
        elif kind == Nodetype.BASE:
            self.primitive(detail[0], path)
        elif kind == Nodetype.ARRAY and detail[0][0] == Nodetype.BASE \
                and detail[0][1][0] in _SIZES:
            size = _SIZES[detail[0][1][0]]
            self.align(size)
            self.position += size * int(detail[1])
        elif kind == Nodetype.ARRAY and detail[0][0] == Nodetype.NAME:
            for index in range(int(detail[1])):
                self.message(detail[0][1], f'{path}[{index}].', depth + 1)
        else:
            raise Unfixed(path)  # sequences, arrays of strings: their size varies

    def primitive(self, typename: str, path: str) -> None:
        size = _SIZES.get(typename)
        if size is None:
            raise Unfixed(typename)
        self.align(size)
        self.fields[path] = (self.position, typename)
        self.position += size

    def string(self) -> None:
        self.align(4)
        start = self.position
        if start + 4 > len(self.payload):
            raise Unfixed('string')
        length = int.from_bytes(self.payload[start:start + 4], 'little')
        end = start + 4 + length
        if length < 1 or end > len(self.payload) or self.payload[end - 1] != 0:
            raise Unfixed('string')
        self.strings.append((start, end))
        self.position = end


class PoseArrays(NamedTuple):
    """A run of decoded pose messages: header stamps (0: none), log times, poses."""

    stamp_ns: np.ndarray  # (k,) int64
    log_time_ns: np.ndarray  # (k,) int64
    values: np.ndarray  # (k, 7) float64: x, y, z, qx, qy, qz, qw


class FixedLayout:
    """
    Where a pose type keeps its stamp and pose in the messages of one channel and size.

    Made by `of` from a template message; `decode` reads runs of MCAP message records of
    exactly `record_size` bytes. See the module docstring.
    """

    def __init__(self, record_size: int, dtype: np.dtype, has_stamp: bool,
                 structure: list[tuple[int, bytes]]) -> None:
        """Keep a record layout made by `of`."""
        self.record_size = record_size
        self.dtype = dtype
        self.has_stamp = has_stamp
        self.structure = structure  # (offset in the record, bytes every record must have)
        # the structural spans as opaque fields, compared whole, and the template's values
        self._spans = np.dtype({'names': [f's{i}' for i in range(len(structure))],
                                'formats': [f'V{len(expected)}' for _, expected in structure],
                                'offsets': [offset for offset, _ in structure],
                                'itemsize': record_size})
        self._expected = [np.frombuffer(expected, dtype=f'V{len(expected)}')[0]
                          for _, expected in structure]

    @classmethod
    def of(cls, layout: PoseLayout, fielddefs: Mapping[str, Any],
           data: bytes) -> FixedLayout:
        """Find the layout of `layout.msgtype` from one message's bytes; Unfixed if none."""
        if data[:2] != LITTLE_ENDIAN_CDR:
            raise Unfixed('not little-endian CDR')
        walk = _Walk(fielddefs, data[ENCAPSULATION:])
        walk.message(layout.msgtype, '', 0)
        end = ENCAPSULATION + walk.position
        if not end <= len(data) <= end + 3:  # rosbags allows three bytes of padding
            raise Unfixed('size')
        wanted = [(f'{layout.position}.{axis}', name)
                  for axis, name in zip('xyz', POSE_FIELDS[:3])]
        wanted += [(f'{layout.orientation}.{axis}', name)
                   for axis, name in zip('xyzw', POSE_FIELDS[3:])]
        if layout.stamp:
            wanted += [(f'{layout.stamp}.sec', 'sec'), (f'{layout.stamp}.nanosec', 'nanosec')]
        names, formats, offsets = ['log_time'], ['<u8'], [LOG_TIME_AT]
        for path, name in wanted:
            offset, typename = walk.fields.get(path, (-1, ''))
            expected = {'sec': ('int32',), 'nanosec': ('uint32',)}.get(
                name, ('float64',) if name.startswith('q') else ('float64', 'float32'))
            if typename not in expected:
                raise Unfixed(path)
            names.append(name)
            formats.append(_CODES[typename])
            offsets.append(DATA_AT + ENCAPSULATION + offset)
        record_size = DATA_AT + len(data)
        dtype = np.dtype({'names': names, 'formats': formats, 'offsets': offsets,
                          'itemsize': record_size})
        structure = [(DATA_AT, LITTLE_ENDIAN_CDR)]
        structure += [(DATA_AT + ENCAPSULATION + start,
                       data[ENCAPSULATION + start:ENCAPSULATION + end])
                      for start, end in walk.strings]
        return cls(record_size, dtype, bool(layout.stamp), structure)

    def records(self, chunk: bytes, runs: list[tuple[int, int]]) -> np.ndarray:
        """Copy runs of records of a chunk, each (first byte, records), into one (k,) array."""
        record = np.dtype((np.void, self.record_size))
        return np.concatenate([np.ndarray((count,), record, buffer=chunk, offset=start)
                               for start, count in runs])

    def matching(self, records: np.ndarray) -> np.ndarray:
        """(k,) bool: the records whose structural bytes are the template's."""
        spans = records.view(self._spans)
        same = spans['s0'] == self._expected[0]
        for index in range(1, len(self._expected)):
            same &= spans[f's{index}'] == self._expected[index]
        return same

    def log_times_fit(self, records: np.ndarray) -> bool:
        """Whether every log time fits int64, as the message-by-message path needs."""
        return bool((records.view(self.dtype)['log_time'] < np.uint64(1 << 63)).all())

    def decode(self, records: np.ndarray) -> PoseArrays:
        """Read stamps, log times and poses of (k,) records (their structure checked)."""
        fields = records.view(self.dtype)
        values = np.empty((len(fields), len(POSE_FIELDS)), dtype=np.float64)
        for column, name in enumerate(POSE_FIELDS):
            values[:, column] = fields[name]
        if self.has_stamp:
            stamp = (fields['sec'].astype(np.int64) * 1_000_000_000
                     + fields['nanosec'].astype(np.int64))
        else:
            stamp = np.zeros(len(fields), dtype=np.int64)
        return PoseArrays(stamp, fields['log_time'].astype(np.int64), values)
