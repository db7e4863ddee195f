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

from octoroach_model.errors import BagError
from octoroach_model.limits import MAX_FOLDER_DEPTH
from octoroach_model.recordings.safe_yaml import load_yaml_file

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
    plain folder only bag directories and files ending in `suffixes` count. A folder is never
    entered twice (a symbolic link back up the tree), nor deeper than
    `limits.MAX_FOLDER_DEPTH`. The same file or bag named twice (directly, or inside a folder
    also named) is an error: its runs would count twice.
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
        inside = _search_folder(path, suffixes, set(), 0)
        if not inside:
            raise BagError(f'{path}: {_nothing_to_read(path, suffixes)}')
        found.extend(inside)
    if not found:
        raise BagError('no bag given')
    _refuse_twice(found)
    return found


def _nothing_to_read(folder: Path, suffixes: tuple[str, ...]) -> str:
    """Say why a folder gave no input: empty, or which files it holds instead."""
    wanted = ', '.join(suffixes)
    try:
        others = sorted({child.suffix or child.name for child in folder.iterdir()})
    except OSError as error:
        return f'cannot list it ({error.strerror or error})'
    if not others:
        return f'empty directory (no metadata.yaml, bag or {wanted} file)'
    listed = ', '.join(others[:5]) + (', ...' if len(others) > 5 else '')
    return (f'no input in this directory or below (no metadata.yaml, bag or {wanted} file; '
            f'it holds {listed})')


def _refuse_twice(found: list[Path]) -> None:
    """Raise BagError when two entries are the same file or bag directory."""
    seen: dict[tuple[int, int], Path] = {}
    for path in found:
        try:
            status = path.stat()
        except OSError:
            continue  # the reader says what is wrong with it
        key = (status.st_dev, status.st_ino)
        if key in seen:
            raise BagError(f'{path} is given twice (also as {seen[key]}); its runs would '
                           'count twice: give each input once')
        seen[key] = path


def _search_folder(folder: Path, suffixes: tuple[str, ...], visited: set[tuple[int, int]],
                   depth: int) -> list[Path]:
    try:
        status = folder.stat()
    except OSError:
        return []        # a dangling or looping link: nothing to read there
    key = (status.st_dev, status.st_ino)
    if key in visited or depth > MAX_FOLDER_DEPTH:
        return []
    visited.add(key)
    found: list[Path] = []
    try:
        children = sorted(folder.iterdir())
    except OSError:
        return []
    for child in children:
        if child.is_dir():
            found.extend([child] if is_bag_directory(child)
                         else _search_folder(child, suffixes, visited, depth + 1))
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


def _inside(directory: Path, name: str) -> bool:
    """Tell a relative_file_paths entry that stays inside `directory` (links resolved)."""
    if not name or Path(name).is_absolute():
        return False
    try:
        return (directory / name).resolve().is_relative_to(directory.resolve())
    except (OSError, RuntimeError, ValueError):
        return False


def _files_in_metadata(path: Path, notes: list[str]
                       ) -> tuple[str, list[Path], dict[str, str] | None] | None:
    """(storage, files, custom data) of metadata.yaml, or None when missing or useless."""
    metadata_path = path / METADATA_FILE
    if not metadata_path.is_file():
        return None
    try:
        info = load_yaml_file(metadata_path)['rosbag2_bagfile_information']
        storage = str(info.get('storage_identifier') or 'mcap')
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
    if storage not in ('mcap', 'sqlite3'):
        raise BagError(f'{path}: storage {storage!r} is not supported, only mcap and sqlite3')
    outside = [name for name in relative if not _inside(path, name)]
    if outside:
        raise BagError(f'{metadata_path}: relative_file_paths names a file outside the bag '
                       f'directory ({outside[0]!r}); only files inside it are read')
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
