"""
QoS profiles as rosbag2 (Jazzy) stores them, and the profile a replay offers.

A bag keeps, per topic, the QoS profiles its publishers offered when it was recorded: in
metadata.yaml (``offered_qos_profiles``: a list of mappings, metadata version 9) and in each
MCAP channel's metadata (the same list as YAML text). Jazzy writes policies by name
(``keep_last``, ``reliable``, ...) and an infinite duration as RMW_DURATION_INFINITE, i.e.
``{sec: 9223372036, nsec: 854775807}``. Older bags wrote policies as numbers (version 8 and
before) and Foxy-era "infinite" values such as ``{sec: 2147483647, nsec: 4294967295}``; both are
read and normalised here, as rosbag2 does.

Plain data only (no rclpy): the nodes turn a `QosProfile` into an rclpy one. Policies are
enums whose values are rosbag2's names, so that YAML and JSON carry the names as before.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from enum import StrEnum
from typing import Any

import yaml

from octoroach_model.errors import BagError

INFINITE_NS = 2**63 - 1  # RMW_DURATION_INFINITE
# "Infinite" as Foxy's Fast DDS and Connext reported it; rosbag2 reads both as infinite.
# (Cyclone's Foxy value equals RMW_DURATION_INFINITE already.)
_FOXY_INFINITE = {(2**31 - 1, 2**32 - 1), (2**31 - 1, 2**31 - 1)}


class History(StrEnum):
    """Which samples a publisher keeps for late readers (rosbag2's names)."""

    SYSTEM_DEFAULT = 'system_default'
    KEEP_LAST = 'keep_last'
    KEEP_ALL = 'keep_all'
    UNKNOWN = 'unknown'


class Reliability(StrEnum):
    """Whether every sample is delivered (rosbag2's names)."""

    SYSTEM_DEFAULT = 'system_default'
    RELIABLE = 'reliable'
    BEST_EFFORT = 'best_effort'
    UNKNOWN = 'unknown'
    BEST_AVAILABLE = 'best_available'


class Durability(StrEnum):
    """Whether late subscribers get samples published before they joined (rosbag2's names)."""

    SYSTEM_DEFAULT = 'system_default'
    TRANSIENT_LOCAL = 'transient_local'
    VOLATILE = 'volatile'
    UNKNOWN = 'unknown'
    BEST_AVAILABLE = 'best_available'


class Liveliness(StrEnum):
    """How a publisher shows it is alive (rosbag2's names)."""

    SYSTEM_DEFAULT = 'system_default'
    AUTOMATIC = 'automatic'
    MANUAL_BY_TOPIC = 'manual_by_topic'
    UNKNOWN = 'unknown'
    BEST_AVAILABLE = 'best_available'


# rmw's numbering (rclpy's enums share it) -> the policies rosbag2 names since version 9
HISTORY = {0: History.SYSTEM_DEFAULT, 1: History.KEEP_LAST, 2: History.KEEP_ALL,
           3: History.UNKNOWN}
RELIABILITY = {0: Reliability.SYSTEM_DEFAULT, 1: Reliability.RELIABLE,
               2: Reliability.BEST_EFFORT, 3: Reliability.UNKNOWN,
               4: Reliability.BEST_AVAILABLE}
DURABILITY = {0: Durability.SYSTEM_DEFAULT, 1: Durability.TRANSIENT_LOCAL,
              2: Durability.VOLATILE, 3: Durability.UNKNOWN, 4: Durability.BEST_AVAILABLE}
LIVELINESS = {0: Liveliness.SYSTEM_DEFAULT, 1: Liveliness.AUTOMATIC,
              3: Liveliness.MANUAL_BY_TOPIC, 4: Liveliness.UNKNOWN,
              5: Liveliness.BEST_AVAILABLE}
_POLICIES: dict[str, tuple[type[StrEnum], dict[int, Any]]] = {
    'history': (History, HISTORY), 'reliability': (Reliability, RELIABILITY),
    'durability': (Durability, DURABILITY), 'liveliness': (Liveliness, LIVELINESS)}
_DURATIONS = ('deadline', 'lifespan', 'liveliness_lease_duration')


@dataclass(frozen=True)
class QosProfile:
    """One offered QoS profile; policies as enums (or their names), durations in ns."""

    history: History = History.KEEP_LAST
    depth: int = 10
    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    deadline_ns: int = INFINITE_NS
    lifespan_ns: int = INFINITE_NS
    liveliness: Liveliness = Liveliness.AUTOMATIC
    liveliness_lease_duration_ns: int = INFINITE_NS
    avoid_ros_namespace_conventions: bool = False

    def __post_init__(self) -> None:
        """Turn policies given by name into their enums (ValueError for an unknown name)."""
        for key, (kind, _) in _POLICIES.items():
            object.__setattr__(self, key, kind(getattr(self, key)))

    def to_rosbag2(self) -> dict[str, Any]:
        """Give the mapping rosbag2 Jazzy writes (metadata version 9), keys in its order."""
        def span(nanoseconds: int) -> dict[str, int]:
            sec, nsec = divmod(int(nanoseconds), 10**9)
            return {'sec': sec, 'nsec': nsec}

        return {
            'history': self.history.value,
            'depth': int(self.depth),
            'reliability': self.reliability.value,
            'durability': self.durability.value,
            'deadline': span(self.deadline_ns),
            'lifespan': span(self.lifespan_ns),
            'liveliness': self.liveliness.value,
            'liveliness_lease_duration': span(self.liveliness_lease_duration_ns),
            'avoid_ros_namespace_conventions': bool(self.avoid_ros_namespace_conventions),
        }

    @classmethod
    def from_rosbag2(cls, entry: Mapping[str, Any]) -> QosProfile:
        """Read a profile from metadata.yaml or channel metadata, of any metadata version."""
        try:
            values: dict[str, Any] = {}
            for key, (kind, numbers) in _POLICIES.items():
                value = entry[key]
                name = numbers.get(value, 'unknown') if isinstance(value, int) \
                    else str(value).lower()
                values[key] = kind(name) if name in kind.__members__.values() \
                    else kind('unknown')
            for key in _DURATIONS:
                sec, nsec = int(entry[key]['sec']), int(entry[key]['nsec'])
                infinite = (sec, nsec) in _FOXY_INFINITE or sec * 10**9 + nsec >= INFINITE_NS
                values[f'{key}_ns'] = INFINITE_NS if infinite else sec * 10**9 + nsec
            return cls(depth=int(entry['depth']),
                       avoid_ros_namespace_conventions=bool(
                           entry.get('avoid_ros_namespace_conventions', False)),
                       **values)
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            raise BagError(f'unreadable QoS profile ({type(error).__name__}: {error})') from None

    @property
    def keeps_last(self) -> bool:
        """Tell whether the depth means something (history keep_last and depth > 0)."""
        return self.history is History.KEEP_LAST and self.depth > 0


def dump_profiles(profiles: Iterable[QosProfile]) -> str:
    """YAML text of a list of profiles, as rosbag2 puts it in MCAP channel metadata."""
    entries = [profile.to_rosbag2() for profile in profiles]
    if not entries:
        return ''
    return yaml.safe_dump(entries, sort_keys=False, default_flow_style=False)


def load_profiles(value: str | Sequence[Mapping[str, Any]] | None) -> tuple[QosProfile, ...]:
    """Profiles from YAML text (channel metadata, old metadata.yaml) or a parsed list."""
    if not value:
        return ()
    entries: Any = value  # YAML text parses to anything: checked below
    if isinstance(value, str):
        from octoroach_model.safe_yaml import load_yaml_text

        entries = load_yaml_text(value, 'offered_qos_profiles')
        if not entries:
            return ()
    if not isinstance(entries, Sequence):
        raise BagError('offered_qos_profiles is not a list')
    return tuple(QosProfile.from_rosbag2(entry) for entry in entries)


@dataclass(frozen=True)
class QosOverride:
    """What a user forces on a replay; None / 0 keeps what the bag recorded."""

    reliability: Reliability | None = None
    durability: Durability | None = None
    depth: int = 0

    @classmethod
    def of_names(cls, reliability: str, durability: str, depth: int) -> QosOverride:
        """Read an override from a node's parameters: policy names, '' for as recorded."""
        return cls(Reliability(reliability) if reliability else None,
                   Durability(durability) if durability else None, depth)


def replay_profile(offered: Sequence[QosProfile], override: QosOverride = QosOverride(),
                   fallback_depth: int = 1000) -> tuple[QosProfile, str]:
    """
    Choose the profile to publish a recorded topic with, and say when it is not as recorded.

    As ``ros2 bag play`` does: the recorded offer when every publisher offered the same
    reliability, durability and liveliness; otherwise the most widely matched choice
    (best_effort only if some publisher offered it, volatile unless all were transient_local).
    The depth is the recorded one where the recording knows it (DDS discovery does not carry
    depth, so live recordings usually store ``history: unknown, depth: 0``), else
    `fallback_depth`. Deadline, lifespan and liveliness are left at the defaults (they do not
    change which subscribers match a publisher that leaves them unset).
    """
    note = ''
    if not offered:
        chosen = QosProfile(history=History.KEEP_LAST, depth=fallback_depth)
        note = 'no recorded QoS: reliable, volatile'
    else:
        reliabilities = {profile.reliability for profile in offered}
        durabilities = {profile.durability for profile in offered}
        reliability = Reliability.BEST_EFFORT if Reliability.BEST_EFFORT in reliabilities \
            else Reliability.RELIABLE
        durability = Durability.TRANSIENT_LOCAL \
            if durabilities == {Durability.TRANSIENT_LOCAL} else Durability.VOLATILE
        if len(reliabilities) > 1 or len(durabilities) > 1:
            note = (f'publishers offered {"/".join(sorted(reliabilities))} and '
                    f'{"/".join(sorted(durabilities))}: {reliability}, {durability}')
        depths = [profile.depth for profile in offered if profile.keeps_last]
        depth = max(depths) if depths else fallback_depth
        chosen = QosProfile(history=History.KEEP_LAST, depth=depth, reliability=reliability,
                            durability=durability)
    if override.reliability is not None:
        chosen = replace(chosen, reliability=override.reliability)
    if override.durability is not None:
        chosen = replace(chosen, durability=override.durability)
    if override.depth:
        chosen = replace(chosen, depth=int(override.depth))
    return chosen, note
