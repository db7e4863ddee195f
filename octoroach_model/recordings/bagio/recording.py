"""
The recorder's bag: raw messages in reception order, in a crash-safe `BagWriter`.

Arrival order is what splits runs (a run marker cuts its stream where it was received), but
an executor may hand over two topics' messages out of order when it falls behind. Messages
are therefore held for a short window and written sorted by their middleware reception time
(also their log time). The bag is flushed every `flush_period_s`, so a recorder killed with
SIGKILL leaves a bag that `BagReader` reads, and `repair` completes, up to about one flush
period before the kill.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from octoroach_model.recordings.bagio.bag_files import PathLike
from octoroach_model.recordings.bagio.msgtypes import standard_definition
from octoroach_model.recordings.bagio.qos import QosProfile
from octoroach_model.recordings.bagio.writer import BagWriter

REORDER_WINDOW_S = 0.2


@dataclass(order=True)
class _Pending:
    received_ns: int
    serial: int
    channel: int = field(compare=False)
    data: bytes = field(compare=False)


class Recording:
    """A bag being recorded live; see the module docstring."""

    def __init__(self, path: PathLike, *, flush_period_s: float = 1.0) -> None:
        self._bag = BagWriter(path, flush_period_s=flush_period_s).create()
        self.path = self._bag.path
        self._pending: list[_Pending] = []
        self._serial = 0
        self._topics: list[str] = []
        self.per_topic: dict[str, int] = {}
        self.written = 0
        self.closed = False

    @property
    def flush_period_s(self) -> float:
        """How often the bag is flushed while messages come in."""
        return float(self._bag.flush_period_s or 0.0)

    @flush_period_s.setter
    def flush_period_s(self, value: float) -> None:
        self._bag.flush_period_s = float(value)

    @staticmethod
    def knows(msgtype: str) -> bool:
        """Whether the bag can describe `msgtype` (Jazzy definition and hash)."""
        return standard_definition(msgtype) is not None

    def add_topic(self, topic: str, msgtype: str, offered_qos: Sequence[QosProfile] = (),
                  type_hash: str = '') -> int:
        """Add a channel for `topic` with its publishers' QoS profiles; return its id."""
        channel = self._bag.add_topic(topic, msgtype, offered_qos=offered_qos,
                                      type_hash=type_hash or None)
        while len(self._topics) <= channel:
            self._topics.append('')
        self._topics[channel] = topic
        self.per_topic.setdefault(topic, 0)
        return channel

    def push(self, channel: int, received_ns: int, data: bytes) -> None:
        """Queue one message; `drain` writes it in reception order."""
        self._serial += 1
        self._pending.append(_Pending(int(received_ns), self._serial, channel, bytes(data)))

    def drain(self, older_than_ns: int | None = None) -> int:
        """Write queued messages received before `older_than_ns` (None: all), oldest first."""
        if not self._pending:
            return 0
        self._pending.sort()
        cut = len(self._pending)
        if older_than_ns is not None:
            cut = next((i for i, item in enumerate(self._pending)
                        if item.received_ns >= older_than_ns), len(self._pending))
        for item in self._pending[:cut]:
            self._bag.write(item.channel, item.received_ns, item.data)
            self.per_topic[self._topics[item.channel]] += 1
        self.written += cut
        del self._pending[:cut]
        return cut

    def flush_if_due(self) -> None:
        """Flush if the last flush is a period old (the recorder's timer calls this)."""
        self._bag.flush_if_due()

    def flush(self) -> None:
        """Write what is due and flush now (before an export reads the bag)."""
        self._bag.flush()

    def close(self) -> None:
        """Write everything queued, the MCAP summary and metadata.yaml."""
        if self.closed:
            return
        self.drain()
        self._bag.close()
        self.closed = True
