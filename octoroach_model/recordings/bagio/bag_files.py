"""
The files of a bag, and which storage they use.

A rosbag2 directory's storage files are those metadata.yaml lists, else the .mcap files found;
a bare .mcap or .db3 file is its own bag.

A recorder that died leaves a directory of .mcap files without metadata.yaml; they are read
directly, and `repair` makes the bag complete. A metadata.yaml that names a file outside its
directory, a storage other than mcap and sqlite3, or file-compressed storage is refused.
"""
from __future__ import annotations

from enum import StrEnum
import os
from pathlib import Path
from typing import NamedTuple, Union

from octoroach_model.errors import BagError
from octoroach_model.safe_yaml import load_yaml_file
from octoroach_model.settings import unknown_name

PathLike = Union[str, 'os.PathLike[str]']

ROS2_SUFFIXES = ('.mcap', '.db3')
ROS1_SUFFIX = '.bag'
METADATA_FILE = 'metadata.yaml'


class Storage(StrEnum):
    """How a bag stores its messages; the value is rosbag2's storage identifier."""

    MCAP = 'mcap'
    SQLITE3 = 'sqlite3'
    ROS1 = 'ros1'  # a ROS 1 .bag file (rosbag format 2.0)


class BagFiles(NamedTuple):
    """The storage files of one rosbag2 source, in recording order, and what was odd."""

    name: str
    storage: Storage  # MCAP or SQLITE3
    files: tuple[Path, ...]
    notes: tuple[str, ...]
    directory: Path | None  # the bag directory; None for a bare .mcap file
    custom_data: dict[str, str] | None = None  # metadata.yaml's custom_data


def is_bag_directory(path: Path) -> bool:
    """Tell a rosbag2 directory: metadata.yaml, or storage files named after it."""
    if (path / METADATA_FILE).is_file():
        return True
    files = [p for p in path.iterdir() if p.is_file() and p.suffix in ROS2_SUFFIXES]
    return bool(files) and all(p.name.startswith(path.name) for p in files)


def bag_files(source: PathLike) -> BagFiles:
    """List the storage files of a rosbag2 bag directory (or file), metadata.yaml first."""
    path = Path(source)
    if not path.exists():
        raise BagError(f'{path}: no such file or directory')
    if path.is_file():
        storage = Storage.SQLITE3 if path.suffix == '.db3' else Storage.MCAP
        return BagFiles(str(path), storage, (path,), (), None)
    notes: list[str] = []
    listed = _files_in_metadata(path, notes)
    if listed is not None:
        return BagFiles(str(path), listed[0], tuple(listed[1]), tuple(notes), path, listed[2])
    found = sorted(p for p in path.glob('*.mcap') if p.is_file())
    if not found:
        if any(path.glob('*.db3')):
            raise BagError(f'{path}: sqlite3 bag without metadata.yaml; recreate it with '
                           '`ros2 bag reindex` first')
        raise BagError(f'{path}: empty directory (no metadata.yaml and no .mcap file)')
    if not (path / METADATA_FILE).exists():
        notes.append(f'{path}: no metadata.yaml (recorder not closed?); read '
                     f'{len(found)} .mcap file(s) directly; `repair` makes the bag complete')
    return BagFiles(str(path), Storage.MCAP, tuple(found), tuple(notes), path)


def _inside(directory: Path, name: str) -> bool:
    """Tell a relative_file_paths entry that stays inside `directory` (links resolved)."""
    if not name or Path(name).is_absolute():
        return False
    try:
        return (directory / name).resolve().is_relative_to(directory.resolve())
    except (OSError, RuntimeError, ValueError):
        return False


def _files_in_metadata(path: Path, notes: list[str]
                       ) -> tuple[Storage, list[Path], dict[str, str] | None] | None:
    """(storage, files, custom data) of metadata.yaml, or None when missing or useless."""
    metadata_path = path / METADATA_FILE
    if not metadata_path.is_file():
        return None
    try:
        info = load_yaml_file(metadata_path)['rosbag2_bagfile_information']
        identifier = str(info.get('storage_identifier') or Storage.MCAP)
        relative = [str(name) for name in info.get('relative_file_paths') or []]
        custom = info.get('custom_data')
        custom = {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) \
            else None
    except BagError as exc:
        notes.append(f'{exc}; read the .mcap files directly')
        return None
    except (KeyError, TypeError, AttributeError) as exc:
        notes.append(f'{metadata_path}: unreadable ({type(exc).__name__}); '
                     'read the .mcap files directly')
        return None
    if identifier not in (Storage.MCAP, Storage.SQLITE3):
        raise BagError(f'{path}: storage_identifier, '
                       f'{unknown_name(identifier, (Storage.MCAP, Storage.SQLITE3))}, is not '
                       'supported, only mcap and sqlite3')
    storage = Storage(identifier)
    outside = [number for number, name in enumerate(relative, 1) if not _inside(path, name)]
    if outside:
        raise BagError(f'{metadata_path}: entry {outside[0]} of {len(relative)} of '
                       'relative_file_paths names a file outside the bag directory; only files '
                       'inside it are read')
    files = [path / name for name in relative]
    present = [p for p in files if p.is_file()]
    if len(present) < len(files):      # by entry: a name in metadata.yaml is not quoted
        missing = [number for number, p in enumerate(files, 1) if not p.is_file()]
        more = f' and {len(missing) - 5} more' if len(missing) > 5 else ''
        notes.append(f'{path}: files listed in metadata.yaml are missing: '
                     f'entr{"ies" if len(missing) > 1 else "y"} '
                     f'{", ".join(map(str, missing[:5]))}{more} of {len(files)} of '
                     'relative_file_paths')
    compressed = [number for number, p in enumerate(files, 1)
                  if p.is_file() and p.suffix not in ROS2_SUFFIXES]
    if compressed:
        raise BagError(f'{path}: file-compressed bags are not supported (entry {compressed[0]} '
                       f'of {len(files)} of relative_file_paths); decompress them with '
                       '`ros2 bag convert` first')
    if not present:
        return None if storage is Storage.MCAP else (storage, [], custom)
    return storage, present, custom
