"""
A chunk's pose messages decoded in blocks, each chunk checked against rosbags on a sample.

`BlockSplitter.split` turns one decompressed, checksum-checked MCAP chunk into what the
reader passes on, in file order: `PoseBlock`s (runs of messages of a pose topic decoded at once
by their fixed layout, `fixed_cdr`) and mcap `Message`s (everything else, decoded later by
rosbags one by one). Schemas and channels inside the chunk are taken as they come.

Every chunk is checked: of each layout's messages decoded in it, the first, the last and
`SAMPLE_RANDOM` others drawn at random are parsed again by mcap and decoded by rosbags, and
their log time, stamp and pose must equal the block's bit for bit. A mismatch refuses that
layout for the rest of the file, and the chunk is read again message by message with mcap's
`breakup_chunk`, as is a chunk whose records the walk is unsure of (`mcap_records`). A
topic's first messages of each record size make its layout (`FixedLayout.of`), and only when
rosbags decodes that template to the same values; a type with a sequence, or a message that
rosbags cannot decode, keeps the message-by-message path.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
import random
from typing import Any, NamedTuple

from mcap.records import Channel, Chunk, Message, Schema
from mcap.stream_reader import breakup_chunk
import numpy as np

from octoroach_model.recordings.bagio.fixed_cdr import DATA_AT, FixedLayout, PoseArrays, Unfixed
from octoroach_model.recordings.bagio.mcap_records import chunk_segments, MessageRun
from octoroach_model.recordings.bagio.pose_messages import pose_getter, PoseLayout, Sample

# Messages checked against rosbags in each chunk, per layout: first, last and this many more
SAMPLE_RANDOM = 3
# Templates tried for one channel and size before it keeps the message-by-message path
MAX_TEMPLATES = 8


class PoseBlock(NamedTuple):
    """Consecutive messages of one pose topic, decoded at once (see PoseArrays)."""

    topic: str
    channel: int  # index into BagReader.channels
    stamp_ns: np.ndarray  # (k,) int64 header stamps, 0 where the message has none
    log_time_ns: np.ndarray  # (k,) int64
    values: np.ndarray  # (k, 7) float64: x, y, z, qx, qy, qz, qw

    def __len__(self) -> int:
        """Return the number of messages."""
        return len(self.log_time_ns)


class WantedChannel(NamedTuple):
    """A channel of the file that the reader passes on."""

    channel: int  # index into BagReader.channels
    topic: str
    msgtype: str


class _Refused(Exception):
    """A sampled message decoded differently: the chunk is read message by message."""


@dataclass
class _Layout:
    """The runs of one channel and record size in a chunk, decoded at once by its layout."""

    layout: FixedLayout
    channel: WantedChannel
    getter: Callable[[Any], Sample]
    runs: list[MessageRun] = field(default_factory=list)
    arrays: PoseArrays | None = None
    records: np.ndarray | None = None  # (k,) the runs' records, copied out of the chunk
    matching: np.ndarray | None = None  # (k,) bool: structure as the template's


@dataclass
class BlockSplitter:
    """
    Split chunks of one MCAP file into pose blocks and messages (module docstring).

    `wanted` maps a channel id to the channel passed on (filled as channel records come, by
    `take`); `layouts` the topics decoded in blocks; `decode(data, msgtype)` is rosbags'
    deserializer; `fielddefs()` the type definitions it uses.
    """

    wanted: Mapping[int, WantedChannel]
    layouts: Mapping[str, PoseLayout]
    take: Callable[[Any], None]
    decode: Callable[[bytes, str], Any]
    fielddefs: Callable[[], Mapping[str, Any]]
    seed: int = 0
    # (channel, record size) -> its layout, None where it keeps the message-by-message path
    layouts_made: dict[tuple[WantedChannel, int], FixedLayout | None] = field(
        default_factory=dict)
    tries: dict[tuple[WantedChannel, int], int] = field(default_factory=dict)

    def split(self, chunk: Chunk) -> tuple[list[Any], int]:
        """Return the items of a chunk in file order, and how many messages it holds."""
        segments = chunk_segments(chunk.data)
        if segments is not None:
            try:
                return self._blocks(chunk.data, segments)
            except _Refused:
                pass
        records = breakup_chunk(chunk, validate_crc=False)  # the reader checked its CRC
        return records, sum(isinstance(record, Message) for record in records)

    def _blocks(self, data: bytes, segments: list[Any]) -> tuple[list[Any], int]:
        """Decode the chunk's pose runs by layout, then lay the items out in file order."""
        order: list[tuple[MessageRun, _Layout | None]] = []
        found: dict[tuple[WantedChannel, int], _Layout] = {}
        messages = 0
        for segment in segments:
            if isinstance(segment, (Schema, Channel)):
                self.take(segment)
                continue
            messages += segment.records
            channel = self.wanted.get(segment.channel_id)
            if channel is None:
                continue
            layout = self._layout(data, segment, channel)
            if layout is None:
                order.append((segment, None))
                continue
            key = (channel, segment.size)
            if key not in found:
                found[key] = _Layout(layout, channel, pose_getter(self.layouts[channel.topic]))
            found[key].runs.append(segment)
            order.append((segment, found[key]))
        for key, decoded in found.items():
            records = decoded.layout.records(data, [(run.start, run.records)
                                                    for run in decoded.runs])
            if not decoded.layout.log_times_fit(records):
                raise _Refused  # a log time past int64: as the message-by-message path reads
            decoded.records = records
            decoded.matching = decoded.layout.matching(records)
            decoded.arrays = decoded.layout.decode(records)
            if not self._sample_agrees(decoded):
                self.layouts_made[key] = None
                raise _Refused
        return self._items(data, order), messages

    def _items(self, data: bytes, order: list[tuple[MessageRun, _Layout | None]]) -> list[Any]:
        """Blocks of the runs' messages whose structure is the template's; the rest as messages."""
        items: list[Any] = []
        taken: dict[int, int] = {}  # id of a layout -> records of it laid out so far
        for run, decoded in order:
            if decoded is None:
                items.extend(run.message(data, i) for i in range(run.records))
                continue
            assert decoded.arrays is not None and decoded.matching is not None
            first = taken.get(id(decoded), 0)
            taken[id(decoded)] = first + run.records
            same = decoded.matching[first:first + run.records]
            if same.all():
                items.append(self._block(decoded, first, first + run.records))
                continue
            edges = np.flatnonzero(np.diff(np.concatenate([[False], same, [False]])
                                           .astype(np.int8)))
            done = 0
            for start, stop in zip(edges[::2].tolist(), edges[1::2].tolist()):
                items.extend(run.message(data, i) for i in range(done, start))
                items.append(self._block(decoded, first + start, first + stop))
                done = stop
            items.extend(run.message(data, i) for i in range(done, run.records))
        return items

    @staticmethod
    def _block(decoded: _Layout, start: int, stop: int) -> PoseBlock:
        arrays = decoded.arrays
        assert arrays is not None
        return PoseBlock(decoded.channel.topic, decoded.channel.channel,
                         arrays.stamp_ns[start:stop], arrays.log_time_ns[start:stop],
                         arrays.values[start:stop])

    def _layout(self, data: bytes, run: MessageRun,
                channel: WantedChannel) -> FixedLayout | None:
        """Return the layout of the run's channel and size, made from its first message if new."""
        pose = self.layouts.get(channel.topic)
        if pose is None:
            return None
        key = (channel, run.size)
        if key in self.layouts_made:
            return self.layouts_made[key]
        self.tries[key] = self.tries.get(key, 0) + 1
        if self.tries[key] > MAX_TEMPLATES:
            self.layouts_made[key] = None
            return None
        template = data[run.start + DATA_AT:run.start + run.size]
        try:
            expected = pose_getter(pose)(self.decode(template, channel.msgtype))
        except Exception:  # noqa: BLE001 - an undecodable template: the next run tries again
            return None
        try:
            layout: FixedLayout | None = FixedLayout.of(pose, self.fielddefs(), template)
        except Unfixed:
            layout = None
        if layout is not None and not _same(layout.decode(layout.records(
                data, [(run.start, 1)])), 0, expected):
            layout = None
        self.layouts_made[key] = layout
        return layout

    def _sample_agrees(self, decoded: _Layout) -> bool:
        """Check the first, last and a few random decoded messages against mcap and rosbags."""
        arrays, records, same = decoded.arrays, decoded.records, decoded.matching
        assert arrays is not None and records is not None and same is not None
        checked = np.flatnonzero(same)
        if not len(checked):
            return True
        rng = random.Random(self.seed * 1_000_003 + len(records))
        picks = {0, len(checked) - 1, *(rng.randrange(len(checked))
                                        for _ in range(SAMPLE_RANDOM))}
        size = decoded.layout.record_size
        for pick in sorted(picks):
            index = int(checked[pick])
            raw = records[index].tobytes()
            try:
                message = MessageRun(0, 0, size, 1).message(raw, 0)
                expected = decoded.getter(self.decode(message.data, decoded.channel.msgtype))
            except Exception:  # noqa: BLE001 - the layout said it decodes: a mismatch
                return False
            if message.log_time != int(arrays.log_time_ns[index]) \
                    or not _same(arrays, index, expected):
                return False
        return True


def _same(arrays: PoseArrays, index: int, expected: Sample) -> bool:
    """Whether decoded message `index` has the stamp and pose rosbags gave, bit for bit."""
    if int(arrays.stamp_ns[index]) != expected[0]:
        return False
    want = np.array(expected[1:], dtype=np.float64)
    return bool((arrays.values[index].view(np.int64) == want.view(np.int64)).all())
