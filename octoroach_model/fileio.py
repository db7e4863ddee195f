"""
The one way the package writes a finished output: a temporary name beside it, then a rename.

Why: a reader, a re-run or a user sees the whole file (or folder) or nothing of it, never
half of one (a kill, Ctrl-C, a full disk); and no write follows a symbolic link planted at
the output or at the temporary name. Temporary files are created by `tempfile.mkstemp`
(O_CREAT | O_EXCL | O_NOFOLLOW, a random name, mode 0600) in the output's own folder, so the
rename stays on one file system and is atomic; a rename replaces a link itself, never its
target. An output that must not replace anything is published with `os.link`, which fails
when the name exists (whatever it is), so two writers cannot both win.

`check_writable` is what every program runs before long work: it creates (and removes) a
temporary file where the output will go.

A log of results that grows as work goes on (a resumable benchmark's JSON lines) is the one
output not written whole: `appended_lines` opens it for appending, never through a link, and
starts on a line of its own after a line an interruption cut short.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
import errno
import fcntl
import os
from pathlib import Path
import shutil
import stat
import tempfile
from typing import BinaryIO, TextIO, Union

from octoroach_model.errors import OutputError

__all__ = ['appended_lines', 'atomic_directory', 'atomic_file', 'check_writable', 'folder_lock',
           'is_empty_directory', 'user_path', 'write_bytes_atomic', 'write_text_atomic',
           'LOCK_NAME', 'PARTIAL_SUFFIX']

PathLike = Union[str, 'os.PathLike[str]']
PARTIAL_SUFFIX = '.partial'
FILE_MODE = 0o644      # what a plain open() gives under the usual umask 022
DIRECTORY_MODE = 0o755


def _temporary_name(target: Path) -> str:
    """Prefix of a hidden temporary name that says which output it will become."""
    return f'.{target.name}.'


def user_path(value: object, what: str) -> Path:
    """Return `value` as a Path, or ParameterError in one line: a name is text or a Path."""
    if isinstance(value, (str, os.PathLike)):
        return Path(value)
    from octoroach_model.errors import ParameterError
    from octoroach_model.settings import shown

    raise ParameterError(f'{what} must be a file or folder name (text or a pathlib.Path), got '
                         f'{shown(value)}')


def check_writable(path: PathLike, what: str) -> Path:
    """
    Check that a new file or folder can be created at `path`, before any long work.

    The nearest existing folder on the way must take a new file: one is created there and
    removed again (``/proc/x`` and read-only mounts fail here, at once). Raises OutputError.
    """
    target = Path(path)
    folder = target.absolute().parent
    while not folder.exists():
        if folder.is_symlink():
            raise OutputError(f'{what} {target}: {folder} is a dangling symbolic link')
        folder = folder.parent
    if not folder.is_dir():
        raise OutputError(f'{what} {target}: {folder} is not a directory')
    try:
        descriptor, probe = tempfile.mkstemp(dir=folder, prefix='.octoroach-probe-')
    except OSError as error:
        raise OutputError(f'{what} {target}: cannot write in {folder} '
                          f'({error.strerror or error})') from None
    os.close(descriptor)
    os.unlink(probe)
    return target


def _publish(temporary: Path, target: Path, replace: bool, what: str) -> None:
    """Give `temporary` the name `target`: replacing whatever is there, or only a free name."""
    if replace:
        if target.is_dir() and not target.is_symlink():
            raise OutputError(f'{what} {target} is a directory')
        os.replace(temporary, target)
        return
    try:
        os.link(temporary, target, follow_symlinks=False)
    except FileExistsError:
        raise OutputError(f'{what} {target} exists already; choose a new path') from None
    except OSError as error:
        if error.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
            raise
        # a file system without hard links: rename, after a last look
        if os.path.lexists(target):
            raise OutputError(f'{what} {target} exists already; choose a new path') from None
        os.rename(temporary, target)
        return
    os.unlink(temporary)


@contextmanager
def atomic_file(path: PathLike, *, replace: bool = False,
                what: str = 'output') -> Iterator[BinaryIO]:
    """
    Yield a binary stream whose content appears at `path` only when the block ends well.

    `replace`: an existing file (or link) at `path` is replaced (for outputs the program
    owns, such as a table it rewrites); else an existing name is an OutputError and nothing
    is written. On any exception (KeyboardInterrupt too) the temporary file is removed.
    """
    target = Path(path)
    folder = target.parent
    try:
        descriptor, name = tempfile.mkstemp(dir=folder, prefix=_temporary_name(target),
                                            suffix=PARTIAL_SUFFIX)
    except OSError as error:
        raise OutputError(f'{what} {target}: cannot write in {folder} '
                          f'({error.strerror or error})') from None
    temporary = Path(name)
    try:
        with os.fdopen(descriptor, 'wb') as stream:
            yield stream
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary, FILE_MODE)
        _publish(temporary, target, replace, what)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def write_bytes_atomic(path: PathLike, data: bytes, *, replace: bool = False,
                       what: str = 'output') -> Path:
    """Write `data` to `path` atomically (see `atomic_file`); return the path."""
    with atomic_file(path, replace=replace, what=what) as stream:
        stream.write(data)
    return Path(path)


def write_text_atomic(path: PathLike, text: str, *, replace: bool = False,
                      what: str = 'output') -> Path:
    """Write UTF-8 `text` to `path` atomically (see `atomic_file`); return the path."""
    return write_bytes_atomic(path, text.encode('utf-8'), replace=replace, what=what)


def is_empty_directory(path: Path) -> bool:
    """Tell a real (not linked) directory that holds nothing."""
    return path.is_dir() and not path.is_symlink() and not any(path.iterdir())


@contextmanager
def atomic_directory(path: PathLike, *, what: str = 'output') -> Iterator[Path]:
    """
    Yield a new temporary folder that becomes `path` when the block ends well.

    `path` must not exist, or be an empty directory (which the new one replaces); anything
    else is an OutputError, before the block runs. On any exception the temporary folder and
    what it holds are removed: `path` holds the whole output or is as it was.
    """
    target = Path(path)
    if os.path.lexists(target) and not is_empty_directory(target):
        raise OutputError(f'{what} {target} exists and is not an empty directory; '
                          'choose a new path')
    parent = target.absolute().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        temporary = Path(tempfile.mkdtemp(dir=parent, prefix=_temporary_name(target),
                                          suffix=PARTIAL_SUFFIX))
    except OSError as error:
        raise OutputError(f'{what} {target}: cannot write in {parent} '
                          f'({error.strerror or error})') from None
    try:
        yield temporary
        os.chmod(temporary, DIRECTORY_MODE)
        try:
            os.rename(temporary, target)     # replaces an empty directory, nothing else
        except OSError as error:
            if error.errno in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR):
                raise OutputError(f'{what} {target} was written meanwhile by another '
                                  'program; choose a new path') from None
            raise
    except BaseException:
        shutil.rmtree(temporary, ignore_errors=True)
        raise


@contextmanager
def appended_lines(path: PathLike, *, what: str = 'results file') -> Iterator[TextIO]:
    """
    Open `path` to append lines of text (created if absent, its folder too), never via a link.

    O_APPEND | O_NOFOLLOW: a symbolic link at `path` is an OutputError, not a write to its
    target; so is anything else but a regular file (a pipe, a device). A file whose last line
    an interruption cut short gets a line break first, so the next line is whole (a reader
    skips the cut one).
    """
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        descriptor = os.open(target, os.O_RDWR | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW
                             | os.O_CLOEXEC, FILE_MODE)
    except OSError as error:
        reason = ('it is a symbolic link' if error.errno == errno.ELOOP
                  else error.strerror or str(error))
        raise OutputError(f'{what} {target}: cannot append to it ({reason})') from None
    try:
        status = os.fstat(descriptor)
        if not stat.S_ISREG(status.st_mode):
            raise OutputError(f'{what} {target}: cannot append to it (not a regular file)')
        if status.st_size and os.pread(descriptor, 1, status.st_size - 1) != b'\n':
            os.write(descriptor, b'\n')
        stream = os.fdopen(descriptor, 'a', encoding='utf-8')
    except BaseException:
        os.close(descriptor)
        raise
    with stream:
        yield stream


LOCK_NAME = '.lock'


@contextmanager
def folder_lock(folder: PathLike, *, what: str = 'output folder') -> Iterator[Path]:
    """
    Hold the one-writer lock of `folder` (it must exist) for the block.

    An advisory `flock` on ``folder/.lock``: the operating system releases it when the
    process ends however it ends (a kill, a crash), so no stale lock is ever left to clear by
    hand; the file stays. A folder locked by another process is an OutputError naming it.
    """
    path = Path(folder) / LOCK_NAME
    try:
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC,
                             FILE_MODE)
    except OSError as error:
        raise OutputError(f'{what} {folder}: cannot create its lock file '
                          f'({error.strerror or error})') from None
    try:
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(descriptor, 32, 0).decode('ascii', 'replace').strip()
            who = f' (process {holder})' if holder.isdigit() else ''
            raise OutputError(f'{what} {folder} is being written by another run{who}; '
                              'wait for it to end') from None
        os.ftruncate(descriptor, 0)
        os.pwrite(descriptor, f'{os.getpid()}\n'.encode('ascii'), 0)
        yield path
    finally:
        os.close(descriptor)
