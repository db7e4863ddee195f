"""
Multisample data sets: runs already on a common grid, in one portable file.

Why a file of its own: splitting and resampling bags is the slow, note-producing step; a data
set keeps its result (and the notes) so validation can be rerun without the bags.

Format (version 1): one numpy ``.npz`` archive, readable with ``np.load(path)`` and no pickle:

- ``t``: float64 (T,), seconds from each run's first sample, strictly increasing;
- ``poses``: float64 (n, T, 3), x [m], y [m], heading [rad] unwrapped along time;
- ``info_json``: a 0-d unicode array holding a JSON object with at least ``format``
  (``"octoroach_model.dataset"``), ``format_version`` (1), ``rate_hz``, ``sources`` and
  ``notes``, plus the rest of `Paths.info` (values JSON cannot hold are stored as text).
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Union
import zipfile

import numpy as np

from octoroach_model.errors import DataError, OutputError
from octoroach_model.fileio import atomic_file, user_path
from octoroach_model.jsonio import jsonable
from octoroach_model.paths import check_paths, Paths
from octoroach_model.recordings.runs.npz_check import check_arrays
from octoroach_model.settings import flag

FORMAT_NAME = 'octoroach_model.dataset'
FORMAT_VERSION = 1
DATASET_SUFFIX = '.npz'

PathLike = Union[str, 'os.PathLike[str]']


def save_dataset(path: PathLike, paths: Paths, *, replace: bool = False) -> Path:
    """
    Write `paths` as a data set file (format in the module docstring); returns its path.

    Written to a temporary file first and then renamed (`fileio.atomic_file`), so a crash
    never leaves half a file; an existing file is replaced only with `replace` (else
    OutputError), and no symbolic link is followed.
    """
    target = user_path(path, 'the data set file')
    check_paths(paths)
    replace = flag('replace', replace)
    info = jsonable(dict(paths.info))
    info.update({
        'format': FORMAT_NAME,
        'format_version': FORMAT_VERSION,
        'rate_hz': float(paths.rate_hz),
        'n_paths': int(paths.n_paths),
    })
    info.setdefault('sources', [])
    info.setdefault('notes', [])
    try:
        with atomic_file(target, replace=replace, what='data set') as stream:
            np.savez(stream, t=np.asarray(paths.t, dtype=float),
                     poses=np.asarray(paths.poses, dtype=float),
                     info_json=np.array(json.dumps(info, allow_nan=False)))
    except OSError as exc:
        raise OutputError(f'{target}: cannot write the data set: {exc.strerror or exc}') from None
    return target


def is_dataset_file(path: PathLike) -> bool:
    """Tell whether a file looks like a data set (an .npz / zip archive)."""
    candidate = Path(path)
    if not candidate.is_file():
        return False
    if candidate.suffix == DATASET_SUFFIX:
        return True
    with candidate.open('rb') as stream:
        return stream.read(4) == b'PK\x03\x04'


def load_dataset(path: PathLike) -> Paths:
    """Read a data set file; a file of any other kind raises DataError saying why."""
    source = user_path(path, 'the data set file')
    if not source.is_file():
        raise DataError(f'{source}: no such data set file')
    check_arrays(source, ('t', 'poses'), ('info_json',))   # sizes before allocating
    try:
        with np.load(source, allow_pickle=False) as archive:
            missing = sorted({'t', 'poses', 'info_json'} - set(archive.files))
            if missing:
                raise DataError(f'{source}: not a multisample data set (missing '
                                f'{", ".join(missing)})')
            times = np.asarray(archive['t'], dtype=float)
            poses = np.asarray(archive['poses'], dtype=float)
            info_text = str(archive['info_json'])
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise DataError(f'{source}: not a multisample data set (.npz): '
                        f'{type(exc).__name__}') from None
    try:
        info = json.loads(info_text)
    except json.JSONDecodeError:
        raise DataError(f'{source}: info_json is not valid JSON') from None
    if not isinstance(info, dict) or info.get('format') != FORMAT_NAME:
        raise DataError(f'{source}: not a multisample data set (format is not {FORMAT_NAME})')
    if int(info.get('format_version', 0)) > FORMAT_VERSION:
        raise DataError(f'{source}: data set format version {info["format_version"]} is newer '
                        f'than this package reads ({FORMAT_VERSION})')
    if times.ndim != 1 or poses.ndim != 3 or poses.shape[1:] != (len(times), 3):
        raise DataError(f'{source}: t {times.shape} and poses {poses.shape} do not match '
                        '(expected (T,) and (n, T, 3))')
    if len(times) > 1 and not np.all(np.diff(times) > 0):
        raise DataError(f'{source}: times are not strictly increasing')
    info['dataset'] = str(source)
    return Paths(times, poses, info)
