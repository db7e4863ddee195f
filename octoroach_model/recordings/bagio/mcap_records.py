"""
The records of an MCAP file in file order, read by mcap's own record parsers.

`file_records` frames the file's data section as mcap's `StreamReader` does (magic, then
opcode, length and content, a record's padding skipped) and lets mcap's record classes parse
each record the reader uses. Index records are skipped unparsed: the reader never uses them,
and `StreamReader` parses every entry of every message index in Python, about 0.08 s of the
0.09 s it takes to walk the reference bag's 126,000 messages.

`chunk_segments` walks one decompressed chunk: schema and channel records parsed by mcap,
message records grouped into runs of consecutive records of one channel and one size, found
with numpy. A chunk it is not sure of (a record that overruns the chunk, a message shorter
than its header, a schema or channel whose content does not fill its record exactly) gives
None, and the reader reads that chunk with mcap's `breakup_chunk`, which decides as before.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from io import BytesIO
import os
import struct
from typing import Any, BinaryIO, NamedTuple, Union

from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile, RecordLengthLimitExceeded
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
from mcap.stream_reader import read_magic
import numpy as np

# The records the reader uses, each with mcap's parser of its content
_PARSERS: dict[int, Callable[[ReadDataStream, int], Any]] = {
    Opcode.CHUNK: lambda stream, length: Chunk.read(stream),
    Opcode.CHANNEL: lambda stream, length: Channel.read(stream),
    Opcode.SCHEMA: lambda stream, length: Schema.read(stream),
    Opcode.METADATA: lambda stream, length: Metadata.read(stream),
    Opcode.MESSAGE: Message.read,
    Opcode.DATA_END: lambda stream, length: DataEnd.read(stream),
    Opcode.FOOTER: lambda stream, length: Footer.read(stream),
}
_HEAD = struct.Struct('<BQ')  # opcode, record length
HEAD_BYTES = _HEAD.size
# opcode, length and channel id: equal in two message records means same channel and size
_SHAPE_BYTES = HEAD_BYTES + 2
MESSAGE_HEAD_BYTES = 22  # channel id, sequence, log time, publish time
_FIRST_WINDOW = 16  # records compared at once when a run starts, growing fourfold


def file_records(stream: BinaryIO, size: int) -> Iterator[Any]:
    """
    Schemas, channels, metadata, messages, chunks, data end and footer of an MCAP file.

    `stream` is the file opened for reading, `size` its size in bytes. Raises as
    `StreamReader` does: InvalidMagic, EndOfFile at a cut, and RecordLengthLimitExceeded for a
    record longer than the file.
    """
    data = ReadDataStream(stream)
    read_magic(data)
    while True:
        opcode = data.read1()
        length = data.read8()
        if length > size:
            raise RecordLengthLimitExceeded(opcode, length, size)
        parse = _PARSERS.get(opcode)
        if parse is None:
            stream.seek(length, os.SEEK_CUR)
            if stream.tell() > size:
                raise EndOfFile()
            continue
        before = data.count
        record = parse(data, length)
        padding = length - (data.count - before)
        if padding > 0:
            data.read(padding)
        yield record


class MessageRun(NamedTuple):
    """Consecutive message records of one channel, each `size` bytes, in a chunk."""

    channel_id: int
    start: int  # byte of the first record in the chunk's data
    size: int  # bytes of one record: opcode, length and content
    records: int

    def message(self, chunk: bytes, index: int) -> Message:
        """Parse record `index` of the run with mcap's Message parser."""
        at = self.start + index * self.size
        stream = ReadDataStream(BytesIO(chunk[at + HEAD_BYTES:at + self.size]))
        return Message.read(stream, self.size - HEAD_BYTES)


Segment = Union[MessageRun, Schema, Channel]


def chunk_segments(chunk: bytes) -> list[Segment] | None:
    """List the records of a decompressed chunk in order; None when unsure (module doc)."""
    segments: list[Segment] = []
    end_of_chunk = len(chunk)
    at = 0
    longest = 0  # the longest run so far: the next one is likely as long
    while at < end_of_chunk:
        if at + HEAD_BYTES > end_of_chunk:
            return None
        opcode, length = _HEAD.unpack_from(chunk, at)
        end = at + HEAD_BYTES + length
        if end > end_of_chunk:
            return None
        if opcode == Opcode.MESSAGE:
            if length < MESSAGE_HEAD_BYTES:
                return None
            size = end - at
            count = _run_length(chunk, at, size, longest)
            longest = max(longest, count)
            channel_id = int.from_bytes(chunk[at + HEAD_BYTES:at + _SHAPE_BYTES], 'little')
            segments.append(MessageRun(channel_id, at, size, count))
            at += count * size
            continue
        if opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            stream = ReadDataStream(BytesIO(chunk[at + HEAD_BYTES:end]))
            try:
                record = (Schema if opcode == Opcode.SCHEMA else Channel).read(stream)
            except Exception:  # noqa: BLE001 - breakup_chunk decides what a bad record does
                return None
            if stream.count != length:
                return None
            segments.append(record)
        at = end  # other records inside a chunk are skipped, as breakup_chunk does
    return segments


def _run_length(chunk: bytes, start: int, size: int, hint: int) -> int:
    """
    Count the records from `start` on with the opcode, length and channel of the first.

    Compared with numpy over growing windows, the first `hint` long: one comparison finds
    the end of a run as long as the previous one.
    """
    available = (len(chunk) - start) // size
    shape = chunk[start:start + _SHAPE_BYTES]
    if available < 2 or chunk[start + size:start + size + _SHAPE_BYTES] != shape:
        return 1
    heads = np.ndarray((available, _SHAPE_BYTES), np.uint8, buffer=chunk, offset=start,
                       strides=(size, 1))
    first = np.frombuffer(shape, np.uint8)
    done, window = 2, max(_FIRST_WINDOW, hint)
    while done < available:
        upto = min(available, done + window)
        same = (heads[done:upto] == first).all(axis=1)
        if not same.all():
            return done + int(np.argmin(same))
        done, window = upto, window * 4
    return available
