"""Large arrays between a campaign's processes through shared memory (``shared_arrays``).

A worker's results went back through the pool's pipe: pickled into one buffer, written
through the pipe, read into another and unpickled into a third, each a fresh allocation
faulted in page by page (paper 001, 32 episodes, two workers: 246 000 page faults and
1.4 s of system time against 77 000 and 0.4 s in one process). Within ``shared_arrays`` an
array of at least ``SHARED_ARRAY_BYTES`` is written once into a file in ``SHARED_DIR``
(memory, not disk) and the receiver reads it in one call: the same values, dtype, shape
and order, one copy instead of three. Where the file cannot be written (no such
directory, too little room: a container's /dev/shm is often 64 MB) the array goes
through the pipe as before.
"""
from __future__ import annotations

import glob
import os
import tempfile
from contextlib import contextmanager
from typing import Callable, Iterator

import numpy as np

SHARED_DIR = "/dev/shm"
"""Where the arrays' files are written: a memory file system (Linux)."""
SHARED_ARRAY_BYTES = 1 << 20
"""Arrays this large or larger travel as shared files; smaller ones through the pipe."""
ROOM_FACTOR = 2.0
"""An array is written only where the directory has this many times its size free."""

_OWNER: int | None = None
"""The pid of the process that opened ``shared_arrays`` (its files carry it), inherited by
the workers it forks; None outside the block."""


PREFIX = "aligngym-"
"""The files' names: PREFIX, the owner's pid, "-", a unique tail."""


def _prefix(owner: int) -> str:
    return f"{PREFIX}{owner}-"


def _remove(pattern: str, keep: Callable[[str], bool] = lambda path: False) -> None:
    """Remove the files of SHARED_DIR that match pattern (glob), except those kept;
    one already gone or not removable is left."""
    for path in glob.glob(os.path.join(SHARED_DIR, pattern)):
        if not keep(path):
            try:
                os.unlink(path)
            except OSError:
                pass


def _reduce(array: np.ndarray):
    """How multiprocessing pickles an array within ``shared_arrays``: a shared file for a
    large one of numbers or records (C or Fortran order kept), the array's own reduction
    otherwise."""
    if (_OWNER is None or array.nbytes < SHARED_ARRAY_BYTES or array.dtype.hasobject
            or array.dtype.kind in "mM" or type(array) is not np.ndarray):
        return array.__reduce__()
    fortran = array.flags.f_contiguous and not array.flags.c_contiguous
    path = _write(array.T if fortran else np.ascontiguousarray(array))
    if path is None:
        return array.__reduce__()
    return _rebuild, (path, array.dtype, array.shape, fortran)


def _write(array: np.ndarray) -> str | None:
    """The bytes of a C-contiguous array in a new file of SHARED_DIR, its path; None
    (nothing left behind) where there is not the room or the file cannot be written."""
    try:
        room = os.statvfs(SHARED_DIR)
        if room.f_bavail * room.f_frsize < ROOM_FACTOR * array.nbytes:
            return None
        fd, path = tempfile.mkstemp(prefix=_prefix(_OWNER), dir=SHARED_DIR)
    except OSError:
        return None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(memoryview(array).cast("B"))
    except (OSError, ValueError, TypeError, BufferError):
        os.unlink(path)
        return None
    return path


RECEIVED = 0
"""Arrays this process has received as shared files (for the tests)."""


def _rebuild(path: str, dtype: np.dtype, shape: tuple[int, ...],
             fortran: bool = False) -> np.ndarray:
    """The array a shared file holds, read in one call (no descriptor is kept: a mapping
    would hold one per array, hundreds in a campaign), the file removed."""
    global RECEIVED
    with open(path, "rb") as f:
        flat = np.fromfile(f, dtype=dtype, count=int(np.prod(shape, dtype=np.int64)))
    os.unlink(path)
    RECEIVED += 1
    return flat.reshape(shape, order="F" if fortran else "C")


def remove_orphans() -> None:
    """Remove the shared files of blocks whose process is gone (killed before its block's
    end could remove what no process had read)."""
    _remove(PREFIX + "*-*", keep=_owner_alive)


def _owner_alive(path: str) -> bool:
    """Whether the process a file's name carries may still exist (or cannot be told)."""
    try:
        os.kill(int(os.path.basename(path)[len(PREFIX):].split("-")[0]), 0)
    except ProcessLookupError:
        return False
    except (ValueError, OSError):
        pass
    return True


@contextmanager
def shared_arrays() -> Iterator[None]:
    """Within the block, the pools this process starts (and their workers, which must be
    forked inside it) send large arrays as shared files (see the module docstring). At
    the end, any file of this block that no process read (a task cancelled, a worker
    killed) is removed. Nested blocks are the outer one."""
    global _OWNER
    from multiprocessing.reduction import ForkingPickler

    if _OWNER is not None:
        yield
        return
    remove_orphans()
    _OWNER = os.getpid()
    ForkingPickler.register(np.ndarray, _reduce)
    try:
        yield
    finally:
        ForkingPickler._extra_reducers.pop(np.ndarray, None)
        _remove(_prefix(_OWNER) + "*")
        _OWNER = None
