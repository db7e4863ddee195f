"""
Inputs by name: which files a source is, and what kind of input each one is.

A source is a rosbag2 bag directory (metadata.yaml plus .mcap or .db3 files, or only the .mcap
files when the recorder died), a bare .mcap file, a ROS 1 .bag file, a motion-capture export
(Vicon .csv, .c3d, Qualisys .tsv), a trajectory table (TUM .txt, EuRoC/ASL .csv, a CSV with a
header naming its time and pose columns), a multisample data set (.npz), or a folder holding
any of them (searched recursively; a bag directory counts as one source).

What a file is (`input_kind`) is told by its suffix where the suffix is a format's own (.mcap,
.db3, .bag, .c3d, .npz), else by its first bytes: the MCAP or ROS 1 magic, a C3D header, a
Qualisys TSV header, a Vicon CSV section name, a trajectory table's header or rows. A file that
is none of them is refused with one line listing what the package reads (`READ_FORMATS`).
"""
from __future__ import annotations

from collections.abc import Iterable
from enum import Enum
import os
from pathlib import Path
import re
from typing import Union

from octoroach_model.errors import BagError, ParameterError
from octoroach_model.fileio import user_path
from octoroach_model.limits import MAX_FOLDER_DEPTH
from octoroach_model.recordings.bagio.bag_files import (
    is_bag_directory,
    METADATA_FILE,
    PathLike,
    ROS1_SUFFIX,
    ROS2_SUFFIXES,
)
from octoroach_model.recordings.mocap.tables import detect_table
from octoroach_model.settings import shown

Sources = Union[PathLike, Iterable[PathLike]]

MOCAP_SUFFIXES = ('.csv', '.c3d', '.tsv')
# text files that are read in a folder only when their content is a format read here
TEXT_SUFFIXES = ('.txt',)
POSE_INPUT_SUFFIXES = (*ROS2_SUFFIXES, ROS1_SUFFIX, *MOCAP_SUFFIXES, *TEXT_SUFFIXES)
DATASET_SUFFIX = '.npz'
MEASURED_SUFFIXES = (*POSE_INPUT_SUFFIXES, DATASET_SUFFIX)
# What the package reads, for the error an unknown file gets (docs/formats.md has the table)
READ_FORMATS = (
    'rosbag2 bags (MCAP or sqlite3 folders, .mcap files)', 'ROS 1 .bag files',
    'Vicon CSV exports', 'C3D files', 'Qualisys TSV exports (3D or 6DOF)',
    'TUM trajectories (timestamp tx ty tz qx qy qz qw)', 'EuRoC/ASL CSV',
    'CSV with a header naming time and pose columns', '.npz data sets')
SNIFF_BYTES = 64 * 1024  # the first bytes a file is told by
_MAGIC = {b'\x89MCAP0\r\n': 'bag', b'#ROSBAG V2.0': 'bag', b'PK\x03\x04': 'dataset'}
VICON_SECTIONS = ('Objects', 'Segments', 'Trajectories', 'Devices', 'Joints',
                  'Model Outputs', 'Events')
_QUALISYS_KEYS = ('FILE_VERSION', 'NO_OF_FRAMES')


class InputKind(Enum):
    """What kind of input a file or folder is, and so which reader reads it."""

    BAG = 'rosbag2 or ROS 1 bag'
    VICON_CSV = 'Vicon CSV export'
    C3D = 'C3D file'
    QUALISYS_TSV = 'Qualisys TSV export'
    TABLE = 'trajectory table'
    DATASET = 'multisample data set'
    UNKNOWN = 'none of the formats read here'


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
    elif not isinstance(sources, Iterable):
        raise ParameterError('the inputs must be a file or folder name, or a list of them, got '
                             f'{shown(sources)}')
    found: list[Path] = []
    for source in sources:
        path = user_path(source, 'an input')
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
    wanted = ', '.join(suffixes).replace('.txt', '.txt trajectory')
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
        elif child.suffix in TEXT_SUFFIXES and child.suffix in suffixes:
            if input_kind(child) is not InputKind.UNKNOWN:    # a README.txt is no input
                found.append(child)
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


def input_kind(path: Path) -> InputKind:
    """Tell what a source is, by its format's own suffix, else by its first bytes."""
    suffix = path.suffix.lower()
    if path.is_dir() or suffix in (*ROS2_SUFFIXES, ROS1_SUFFIX):
        return InputKind.BAG
    if suffix == '.c3d':
        return InputKind.C3D
    if suffix == DATASET_SUFFIX:
        return InputKind.DATASET
    try:
        with path.open('rb') as stream:
            head = stream.read(SNIFF_BYTES)
    except OSError:
        return InputKind.BAG  # the bag reader says why it cannot be read
    for magic, kind in _MAGIC.items():
        if head.startswith(magic):
            return InputKind.BAG if kind == 'bag' else InputKind.DATASET
    if _looks_like_c3d(head):
        return InputKind.C3D
    if not head or b'\0' in head:
        return InputKind.UNKNOWN
    return text_kind(head.decode('utf-8-sig', errors='replace'), cut=len(head) == SNIFF_BYTES)


def _looks_like_c3d(head: bytes) -> bool:
    """Tell a C3D header: parameter block pointer, then the key 0x50, in a 512-byte block."""
    return len(head) >= 512 and head[1] == 0x50 and 1 < head[0] < 128


def text_kind(text: str, cut: bool = False) -> InputKind:
    """Tell a text export by its first lines; `cut`: the last line may be incomplete."""
    lines = text.splitlines()
    if cut and lines:
        lines = lines[:-1]
    lines = [line for line in lines[:400] if line.strip()]
    if not lines:
        return InputKind.UNKNOWN
    first = lines[0].strip()
    if first.split('\t')[0].strip() in _QUALISYS_KEYS:
        return InputKind.QUALISYS_TSV
    cells = [cell.strip() for cell in re.split('[,;\t]', first)]
    if cells[0] in VICON_SECTIONS and not any(cells[1:]):
        return InputKind.VICON_CSV
    if detect_table(lines) is not None:
        return InputKind.TABLE
    return InputKind.UNKNOWN


def unknown_input_message(path: Path) -> str:
    """Say in one line that a file is none of the formats read, and list them."""
    try:
        size = path.stat().st_size
    except OSError:
        size = -1
    what = 'an empty file' if size == 0 else 'its first bytes fit none of its formats'
    return f'{path}: not a file this package reads ({what}); it reads ' + \
        '; '.join(READ_FORMATS) + ' (docs/formats.md)'
