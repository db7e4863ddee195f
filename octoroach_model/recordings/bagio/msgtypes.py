"""
Message types: ROS 2 Jazzy's standard types, plus those a bag defines for itself.

Every bag that follows rosbag2 carries the full definition of each message type it holds (MCAP
schemas, sqlite3's message_definitions table, ROS 1 connection headers). Types this package
does not know (a lab's own pose message) are registered from that definition with rosbags'
typesys, so they decode like the standard ones; known types keep Jazzy's definition.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any, TYPE_CHECKING

from rosbags.typesys import (
    get_types_from_idl,
    get_types_from_msg,
    get_typestore,
    Stores,
    TypesysError,
)

from octoroach_model.settings import unknown_name

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

_IDL_SEPARATOR = '=' * 80 + '\n'
# Definition encodings: of msg texts, of IDL texts
_MSG_ENCODINGS = ('ros2msg', 'ros1msg', 'msg')
_IDL_ENCODINGS = ('ros2idl', 'idl')


@dataclass(frozen=True)
class TypeDefinition:
    """What a bag stores about a message type: definition text, its encoding, RIHS01 hash."""

    msgtype: str
    encoding: str  # 'ros2msg' or 'ros2idl' (MCAP schema encoding)
    text: str
    type_hash: str  # 'RIHS01_...'


@lru_cache(maxsize=1)
def jazzy_types() -> Typestore:
    """ROS 2 Jazzy's standard message types (shared; never register into it)."""
    return get_typestore(Stores.ROS2_JAZZY)


@lru_cache(maxsize=256)
def standard_definition(msgtype: str) -> TypeDefinition | None:
    """Describe a standard Jazzy type as a bag stores it; None for an unknown type."""
    store = jazzy_types()
    if msgtype not in store.fielddefs:
        return None
    text, _ = store.generate_msgdef(msgtype, ros_version=2)
    return TypeDefinition(msgtype, 'ros2msg', text, store.hash_rihs01(msgtype))


def parse_definition(msgtype: str, encoding: str, text: str) -> dict:
    """Parse a definition text (msg or IDL) into rosbags types; TypesysError if unreadable."""
    if encoding in _MSG_ENCODINGS:
        return get_types_from_msg(text, msgtype)
    if encoding in _IDL_ENCODINGS:
        types: dict = {}
        sections = text.split(_IDL_SEPARATOR)[1:] if text.startswith(
            f'{_IDL_SEPARATOR}IDL: ') else [f'IDL: \n{text}']
        for section in sections:
            types.update(get_types_from_idl(section.split('\n', 1)[1]))
        return types
    raise TypesysError('unknown definition encoding, '
                       f'{unknown_name(encoding, _MSG_ENCODINGS + _IDL_ENCODINGS)}')


class BagTypes:
    """The types of one bag: Jazzy's, plus the bag's own definitions of types Jazzy lacks."""

    def __init__(self, store: Typestore | None = None) -> None:
        """
        Start from `store`, or from Jazzy's shared store until the bag defines a type.

        The shared store keeps the deserializers it compiled (about 10 ms a type), so bag after
        bag of standard types decodes without compiling them again.
        """
        self.store = store if store is not None else jazzy_types()
        self._own = store is not None  # whether types may be registered into `store`
        self.unreadable: dict[str, str] = {}  # message type -> why its definition failed

    def knows(self, msgtype: str) -> bool:
        """Whether messages of `msgtype` can be decoded."""
        return msgtype in self.store.fielddefs

    def add_definition(self, msgtype: str, encoding: str, text: str) -> bool:
        """
        Register `msgtype` (and the types it uses) from a bag's definition if unknown.

        Returns whether the type can be decoded afterwards; why not is kept in `unreadable`.
        """
        if self.knows(msgtype):
            return True
        if not text:
            self.unreadable[msgtype] = 'the bag has no definition of it'
            return False
        try:
            types = parse_definition(msgtype, encoding, text)
            if not self._own:
                self.store, self._own = get_typestore(Stores.ROS2_JAZZY), True
            self.store.register({name: fields for name, fields in types.items()
                                 if name not in self.store.fielddefs})
        except (TypesysError, ValueError, KeyError, IndexError):
            # rosbags' message quotes the definition: the text of the file, never shown
            self.unreadable[msgtype] = 'its definition in the bag is not valid msg or IDL text'
            return False
        return self.knows(msgtype)

    def deserialize_cdr(self, data: bytes | memoryview, msgtype: str) -> Any:
        """Decode a CDR message into a rosbags message object."""
        return self.store.deserialize_cdr(data, msgtype)
