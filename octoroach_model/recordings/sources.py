"""
Inputs by name: which files a source is, and what kind of input each one is.

A source is a rosbag2 bag directory (metadata.yaml plus .mcap or .db3 files, or only the .mcap
files when the recorder died), a bare .mcap file, a ROS 1 .bag file, a motion-capture export
(.csv, .c3d), a multisample data set (.npz), or a folder holding any of them (searched
recursively; a bag directory counts as one source).
"""
from __future__ import annotations

from collections.abc import Iterable
import os
from pathlib import Path
from typing import NamedTuple, Union

import yaml

from octoroach_model.errors import BagError

PathLike = Union[str, 'os.PathLike[str]']
Sources = Union[PathLike, Iterable[PathLike]]

ROS2_SUFFIXES = ('.mcap', '.db3')
ROS1_SUFFIX = '.bag'
MOCAP_SUFFIXES = ('.csv', '.c3d')
POSE_INPUT_SUFFIXES = (*ROS2_SUFFIXES, ROS1_SUFFIX, *MOCAP_SUFFIXES)
DATASET_SUFFIX = '.npz'
MEASURED_SUFFIXES = (*POSE_INPUT_SUFFIXES, DATASET_SUFFIX)
METADATA_FILE = 'metadata.yaml'


class BagFiles(NamedTuple):
    """The storage files of one rosbag2 source, in recording order, and what was odd."""

    name: str
    storage: str  # 'mcap' or 'sqlite3'
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


def expand_sources(sources: Sources, *,
                   suffixes: tuple[str, ...] = POSE_INPUT_SUFFIXES) -> list[Path]:
    """
    Bag directories and files named by `sources`; a folder expands to what it holds.

    Files and bag directories are taken as given (their content is checked when read); inside a
    plain folder only bag directories and files ending in `suffixes` count.
    """
    if isinstance(sources, (str, os.PathLike)):
        sources = [sources]
    found: list[Path] = []
    for source in sources:
        path = Path(source)
        if not path.exists():
            raise BagError(f'{path}: no such file or directory')
        if path.is_file() or is_bag_directory(path):
            found.append(path)
            continue
        inside = _search_folder(path, suffixes)
        if not inside:
            wanted = ', '.join(suffixes)
            raise BagError(f'{path}: empty directory (no metadata.yaml, bag or {wanted} file)')
        found.extend(inside)
    if not found:
        raise BagError('no bag given')
    return found


def _search_folder(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    found: list[Path] = []
    for child in sorted(folder.iterdir()):
        if child.is_dir():
            found.extend([child] if is_bag_directory(child) else _search_folder(child, suffixes))
        elif child.suffix in suffixes:
            found.append(child)
    return found


def source_files(sources: Sources, *,
                 suffixes: tuple[str, ...] = MEASURED_SUFFIXES) -> list[Path]:
    """
    List every file whose change changes what `sources` read as.

    That is a bag directory's storage files and metadata.yaml, and the other inputs themselves.
    Watch these (size, modification time) to notice a bag that a recorder is still writing:
    the directory's own time stamp does not change when a file inside it grows.
    """
    files: list[Path] = []
    for path in expand_sources(sources, suffixes=suffixes):
        if path.is_dir():
            files.extend(sorted(p for p in path.iterdir() if p.is_file() and (
                p.suffix in ROS2_SUFFIXES or p.name == METADATA_FILE)))
        else:
            files.append(path)
    return files


def input_kind(path: Path) -> str:
    """'rosbag2' (directory or .mcap/.db3 file), 'ros1', 'csv', 'c3d' or 'dataset'."""
    if path.is_dir() or path.suffix in ROS2_SUFFIXES:
        return 'rosbag2'
    if path.suffix == ROS1_SUFFIX:
        return 'ros1'
    if path.suffix in MOCAP_SUFFIXES:
        return path.suffix[1:]
    if path.suffix == DATASET_SUFFIX:
        return 'dataset'
    return 'rosbag2'  # unknown suffix: read as MCAP, which says what is wrong


def bag_files(source: PathLike) -> BagFiles:
    """List the storage files of a rosbag2 bag directory (or file), metadata.yaml first."""
    path = Path(source)
    if not path.exists():
        raise BagError(f'{path}: no such file or directory')
    if path.is_file():
        storage = 'sqlite3' if path.suffix == '.db3' else 'mcap'
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
    return BagFiles(str(path), 'mcap', tuple(found), tuple(notes), path)


def _files_in_metadata(path: Path, notes: list[str]
                       ) -> tuple[str, list[Path], dict[str, str] | None] | None:
    """(storage, files, custom data) of metadata.yaml, or None when missing or useless."""
    metadata_path = path / METADATA_FILE
    if not metadata_path.is_file():
        return None
    try:
        info = yaml.safe_load(metadata_path.read_text())['rosbag2_bagfile_information']
        storage = str(info.get('storage_identifier') or 'mcap')
        relative = [str(name) for name in info.get('relative_file_paths') or []]
        custom = info.get('custom_data')
        custom = {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) \
            else None
    except (yaml.YAMLError, KeyError, TypeError, AttributeError, UnicodeDecodeError) as exc:
        notes.append(f'{metadata_path}: unreadable ({type(exc).__name__}); '
                     'read the .mcap files directly')
        return None
    if storage not in ('mcap', 'sqlite3'):
        raise BagError(f'{path}: storage {storage!r} is not supported, only mcap and sqlite3')
    files = [path / name for name in relative]
    present = [p for p in files if p.is_file()]
    if len(present) < len(files):
        missing = ', '.join(p.name for p in files if not p.is_file())
        notes.append(f'{path}: files listed in metadata.yaml are missing: {missing}')
    compressed = [p.name for p in present if p.suffix not in ROS2_SUFFIXES]
    if compressed:
        raise BagError(f'{path}: file-compressed bags are not supported ({compressed[0]}); '
                       'decompress them with `ros2 bag convert` first')
    if not present:
        return None if storage == 'mcap' else (storage, [], custom)
    return storage, present, custom
