"""
ROS 1 bags (format 2.0), streamed chunk by chunk with rosbags' own record readers.

rosbags' `Reader.open()` loads the index entry of every message before the first one is read
(some 180 bytes each: memory that grows with the bag). This reader opens the bag with
the same rosbags pieces (`Reader.read_connection`, `read_chunk_info`, `read_chunk`,
`Header.read`), keeps only the connections and the list of chunks from the index, and reads
the chunks in file order: one decompressed chunk is in memory at a time, and messages come in
the order ``rosbag record`` received them, as the MCAP reader gives them. Those methods are
rosbags' record parsers; `test/test_recordings_formats.py` reads ROS 1 bags written by
rosbags' writer through them, so an upgrade that changes them fails a test.
"""
from __future__ import annotations

from collections.abc import Collection, Iterator
from io import BytesIO
import os
from pathlib import Path
import re
from typing import Any

from octoroach_model.errors import BagError
from octoroach_model.limits import MAX_ROS1_CHUNK_BYTES, size_words
from octoroach_model.settings import unknown_name


class Ros1Bag:
    """One indexed ROS 1 bag: its connections, message counts and messages in file order."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.connections: list[Any] = []  # rosbags Connection records
        self.counts: dict[int, int] = {}  # connection id -> messages
        self.progress: tuple[float, float] = (0.0, 1.0)  # chunks read, chunks
        self._chunk_positions: list[int] = []
        self._reader: Any = None

    def __enter__(self) -> Ros1Bag:
        """Read the bag header and the index (connections, chunk list); not the messages."""
        from rosbags.rosbag1.reader import Header, Reader, ReaderError, RecordType

        reader = Reader(self.path)
        try:
            reader.bio = self.path.open('rb')
        except OSError as exc:
            raise BagError(f'{self.path}: cannot read: {exc.strerror or exc}') from None
        self._reader = reader
        try:
            magic = reader.bio.readline().decode(errors='replace')
            if not re.match(r'#ROSBAG V2\.0\n', magic):
                what = 'an empty file' if not magic else 'no "#ROSBAG V2.0" line at its start'
                raise BagError(f'{self.path}: not a ROS 1 bag of format 2.0 ({what})')
            header = Header.read(reader.bio, RecordType.BAGHEADER)
            index_pos = header.get_uint64('index_pos')
            if index_pos == 0:
                raise BagError(f'{self.path}: the bag has no index (rosbag record did not '
                               'finish); `rosbag reindex` repairs it')
            connection_count = header.get_uint32('conn_count')
            chunk_count = header.get_uint32('chunk_count')
            reader.bio.seek(index_pos)
            self.connections = [reader.read_connection() for _ in range(connection_count)]
            infos = [reader.read_chunk_info() for _ in range(chunk_count)]
        except (ReaderError, ValueError, KeyError, OSError) as error:
            self.__exit__()
            raise BagError(f'{self.path}: unreadable ROS 1 bag ({error})') from None
        except BaseException:
            self.__exit__()
            raise
        for info in infos:
            for connection_id, count in info.connection_counts.items():
                self.counts[connection_id] = self.counts.get(connection_id, 0) + count
        self._chunk_positions = sorted(info.pos for info in infos)
        return self

    def __exit__(self, *exc_info: object) -> None:
        """Close the file."""
        if self._reader is not None and self._reader.bio is not None:
            self._reader.bio.close()
            self._reader.bio = None

    def messages(self, connection_ids: Collection[int]) -> Iterator[tuple[Any, int, bytes]]:
        """Yield (connection, receive time ns, ROS 1 bytes) chunk by chunk in file order."""
        from rosbags.rosbag1.reader import (
            Header,
            read_bytes,
            read_uint32,
            ReaderError,
            RecordType,
        )

        wanted = set(connection_ids)
        by_id = {connection.id: connection for connection in self.connections}
        reader = self._reader
        try:
            total = float(len(self._chunk_positions)) or 1.0
            for number, position in enumerate(self._chunk_positions):
                self.progress = (float(number), total)
                reader.bio.seek(position)
                header = Header.read(reader.bio, RecordType.CHUNK)
                reader.bio.seek(position)
                chunk = reader.read_chunk()
                reader.bio.seek(chunk.datapos)
                data = _decompress(header.get_string('compression'),
                                   read_bytes(reader.bio, chunk.datasize),
                                   header.get_uint32('size'), self.path, position)
                records = BytesIO(data)
                while records.tell() < len(data):
                    header = Header.read(records)
                    size = read_uint32(records)
                    if header.get_uint8('op') != RecordType.MSGDATA:
                        records.seek(size, os.SEEK_CUR)
                        continue
                    connection_id = header.get_uint32('conn')
                    if connection_id not in wanted:
                        records.seek(size, os.SEEK_CUR)
                        continue
                    yield (by_id[connection_id], header.get_time('time'),
                           read_bytes(records, size))
        except (ReaderError, ValueError, KeyError, OSError, EOFError, RuntimeError) as error:
            raise BagError(f'{self.path}: unreadable ROS 1 chunk ({error})') from None


def _decompress(compression: str, data: bytes, claimed: int, path: Path,
                position: int) -> bytes:
    """
    Decompress one chunk, never past `limits.MAX_ROS1_CHUNK_BYTES` or its own stated size.

    rosbags' decompressors expand whatever the data hold; a small bz2 chunk can hold a
    gigabyte of zeros. The chunk header's `size` is checked first, then the data are
    decompressed by a bounded decompressor.
    """
    if claimed > MAX_ROS1_CHUNK_BYTES:
        raise BagError(f'{path}: the chunk at byte {position} claims {size_words(claimed)} '
                       f'decompressed, above the limit of {size_words(MAX_ROS1_CHUNK_BYTES)}')
    if compression == 'none':
        out = data
    elif compression == 'bz2':
        import bz2

        out = bz2.BZ2Decompressor().decompress(data, max_length=claimed + 1)
    elif compression == 'lz4':
        import lz4.frame

        out = lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=claimed + 1)
    else:
        raise BagError(f'{path}: the chunk at byte {position} names an unknown compression, '
                       f'{unknown_name(compression, ("none", "bz2", "lz4"))}; '
                       'supported: none, bz2, lz4')
    if len(out) != claimed:
        raise BagError(f'{path}: the chunk at byte {position} does not decompress to the '
                       'size it states')
    return out
