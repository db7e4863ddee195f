"""
What a data set file (.npz) claims, checked before numpy allocates it.

An .npz is a zip of .npy arrays whose headers state their shape and type; `np.load` then
allocates what the header states, and the reader widens it to float64. A 1 MB archive of
compressed int8 zeros can so become 10 GB. `check_arrays` reads only the headers and refuses
an array whose float64 size passes `limits.MAX_DATASET_BYTES` or `MAX_DATASET_EXPANSION`
times the file's size, and an info text over `MAX_DATASET_INFO_BYTES`.
"""
from __future__ import annotations

from collections.abc import Sequence
import math
from pathlib import Path
from typing import IO
import zipfile

import numpy as np

from octoroach_model.errors import DataError
from octoroach_model.limits import (
    MAX_DATASET_BYTES,
    MAX_DATASET_EXPANSION,
    MAX_DATASET_INFO_BYTES,
    MIB,
    size_words,
)

__all__ = ['check_arrays']


def check_arrays(source: Path, numbers: Sequence[str], texts: Sequence[str]) -> None:
    """Raise DataError when an array of `source` would take more memory than allowed."""
    try:
        file_size = source.stat().st_size
        with zipfile.ZipFile(source) as archive:
            members = set(archive.namelist())
            for name in (*numbers, *texts):
                if f'{name}.npy' not in members:
                    continue  # load_dataset says what is missing
                with archive.open(f'{name}.npy') as stream:
                    shape, dtype = _header(stream)
                _check(source, name, shape, dtype, file_size, name in texts)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError,
            NotImplementedError, RuntimeError):
        raise DataError(f'{source}: not a multisample data set (.npz): an unreadable '
                        'archive or array header') from None


def _header(stream: IO[bytes]) -> tuple[tuple[int, ...], np.dtype]:
    """Shape and dtype from an .npy header (numpy's public header readers)."""
    version = np.lib.format.read_magic(stream)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(stream)
    elif version == (2, 0):
        shape, _, dtype = np.lib.format.read_array_header_2_0(stream)
    else:
        raise ValueError(f'unsupported .npy version {version}')
    return tuple(int(n) for n in shape), np.dtype(dtype)


def _check(source: Path, name: str, shape: tuple[int, ...], dtype: np.dtype, file_size: int,
           text: bool) -> None:
    if dtype.hasobject:
        raise DataError(f'{source}: array {name} holds Python objects; a data set holds '
                        'numbers only')
    count = math.prod(shape)
    if text:
        size, limit = count * dtype.itemsize, MAX_DATASET_INFO_BYTES
        if size > limit:
            raise DataError(f'{source}: {name} takes {size_words(size)}, above the limit of '
                            f'{size_words(limit)}')
        return
    if dtype.kind not in 'biuf':
        raise DataError(f'{source}: array {name} is of type {dtype}, not numbers')
    size = count * max(8, dtype.itemsize)          # as the float64 the reader makes of it
    limit = min(MAX_DATASET_BYTES, MAX_DATASET_EXPANSION * file_size + MIB)
    if size > limit:
        raise DataError(f'{source}: array {name} {shape} takes {size_words(size)} as float64, '
                        f'above the limit of {size_words(limit)} for a file of '
                        f'{size_words(file_size)} (docs/bags.md, "Limits")')
