"""The truth cache: what MuJoCo computes of an episode, kept on disk for other processes.

The part of an episode that MuJoCo computes (the carrier's truth and the ideal IMU
increments) often repeats: every seed of a car on a smooth road, or of a prescribed ship
without random phases, has the same one, and a seed run again (a campaign's parallel
workers, the env, a later campaign) has its own again. Each process keeps the recent ones
in memory (``scenarios.simulate``); this cache lets the other processes load them instead
of simulating them.

Entries live in ``$ALIGNGYM_TRUTH_CACHE`` (default ``$XDG_CACHE_HOME/aligngym/truth``,
else ``~/.cache/aligngym/truth``; ``off`` disables the cache), one .npz per entry, named
by a hash of what decides it: the simulation's inputs, the simulation code
(``TRUTH_SOURCES``, hashed when the process loaded it: a filter's or an experiment's edit
keeps the entries) and the versions of MuJoCo, NumPy, SciPy and the machine's architecture
(and Numba's), so a changed simulation never loads an old entry (edit the code between
runs, not during one). An entry is written whole or not at all (``atomic``); one that does
not load is removed and simulated again; a cache that cannot be written (a full disk, no
permission) is reported once and the run goes on without it. The directory is kept under
``TRUTH_CACHE_BYTES`` by removing the least recently used entries. An entry is computed
under a lock file (``flock``) that its holder removes before letting go, so the cache
holds no lock file between runs.
"""
from __future__ import annotations

import hashlib
import os
import warnings
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

TRUTH_CACHE_ENV = "ALIGNGYM_TRUTH_CACHE"
"""Environment variable naming the cache's directory ("off": no cache)."""
TRUTH_CACHE_BYTES = 2 * 1024 ** 3
"""Most bytes the cache keeps (about 160 car runs of 600 s at 100 Hz, 12.6 MB each)."""
FREE_BYTES_KEPT = 5 * 1024 ** 3
"""The cache is not written where the disk would keep less than this free."""
_reported: set[str] = set()
"""Cache directories this process found unwritable (reported once, not tried again)."""


def cache_directory() -> Path | None:
    """The cache's directory (not created), or None when ``ALIGNGYM_TRUTH_CACHE=off``."""
    chosen = os.environ.get(TRUTH_CACHE_ENV, "")
    if chosen.lower() == "off":
        return None
    if chosen:
        return Path(chosen)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "aligngym" / "truth"


PACKAGE_ROOT = Path(__file__).resolve().parents[1]
"""The package's source root, which ``TRUTH_SOURCES`` and ``SIMULATION_SOURCES`` are in."""
TRUTH_SOURCES = ("models", "sensors", "scenarios/simulate.py", "scenarios/config.py",
                 "scenarios/config_keys.py", "scenarios/config_tables.py",
                 "scenarios/worlds.py", "scenarios/world_truth.py")
"""The package's code a simulation runs (``scenarios.simulate`` and every module it imports,
at any depth; a test): any change to it is new truth entries."""
SIMULATION_SOURCES = TRUTH_SOURCES + ("estimators", "scenarios/experiments",
                                      "scenarios/campaign")
"""The package's code that prepares an episode (the truth's, the sensors' errors, the
coarse alignment and the screen): any change to it is a new bank, and a campaign's
episodes are not resumed by other code (``simulation_versions``). A filter's or an
experiment's edit keeps the truth entries: they depend on ``TRUTH_SOURCES`` alone."""


def _sources_sha256(parts: tuple[str, ...]) -> str:
    """A hash of the package's .py files under parts (in name order)."""
    digest = hashlib.sha256()
    for part in parts:
        path = PACKAGE_ROOT / part
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for f in files:
            digest.update(str(f.relative_to(PACKAGE_ROOT)).encode())
            digest.update(f.read_bytes())
    return digest.hexdigest()


def in_truth_sources(path: str | Path | None) -> bool:
    """Whether the file at path is one of ``TRUTH_SOURCES`` (its edits change the
    entries' names)."""
    if path is None:
        return False
    path = Path(path).resolve()
    return any(path == PACKAGE_ROOT / part or (PACKAGE_ROOT / part) in path.parents
               for part in TRUTH_SOURCES)


def simulation_code_sha256() -> str:
    """A hash of ``SIMULATION_SOURCES`` (the .py files, in name order)."""
    return _sources_sha256(SIMULATION_SOURCES)


_CODE_SHA256: str | None = None
"""The hash of ``SIMULATION_SOURCES`` when the first simulation module was loaded
(``remember_code``): the code a process runs, even if the files change under it."""
_TRUTH_SHA256: str | None = None
"""The hash of ``TRUTH_SOURCES``, taken with it."""


def remember_code() -> None:
    """Hash the simulation code now (``scenarios.simulate`` calls it when imported, so
    forked workers inherit it): editing the files during a run cannot label old numbers
    with the new code's hash."""
    global _CODE_SHA256, _TRUTH_SHA256
    if _CODE_SHA256 is None or _TRUTH_SHA256 is None:
        code, truth = simulation_code_sha256(), _sources_sha256(TRUTH_SOURCES)
        _CODE_SHA256, _TRUTH_SHA256 = code, truth      # both or neither


def _library_versions() -> str:
    """MuJoCo's, NumPy's, SciPy's and Numba's versions (the attitude scan is compiled) and
    the machine's architecture."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    import mujoco
    import scipy
    try:
        numba = version("numba")
    except PackageNotFoundError:
        numba = "none"
    return (f"mujoco {mujoco.__version__} numpy {np.__version__} scipy {scipy.__version__} "
            f"numba {numba} {platform.machine()}")


def prepared_code_sha256() -> str:
    """The hash of ``SIMULATION_SOURCES`` this process runs (``remember_code``: taken when
    it loaded the simulation, not the files' now): the bank's key."""
    remember_code()
    return _CODE_SHA256


@lru_cache(maxsize=1)
def simulation_versions() -> str:
    """The preparation code's hash (``SIMULATION_SOURCES``) and the library versions that
    key a campaign's manifest."""
    remember_code()
    return f"{_CODE_SHA256} {_library_versions()}"


@lru_cache(maxsize=1)
def truth_versions() -> str:
    """The simulation code's hash (``TRUTH_SOURCES``) and the library versions that key
    the cache's entries."""
    remember_code()
    return f"{_TRUTH_SHA256} {_library_versions()}"


def entry_name(kind: str, key: tuple) -> str:
    """The entry's file name: kind and a hash of key (its repr: dataclasses, tuples and
    floats print every digit; ``cached_arrays`` does not cache a key holding an array)
    with the simulation code's and the libraries' versions (``truth_versions``)."""
    digest = hashlib.sha256(f"{kind} {key!r} {truth_versions()}".encode()).hexdigest()
    return f"{kind}-{digest[:24]}.npz"


def cached_arrays(kind: str, key: tuple, compute: Callable[[], dict[str, np.ndarray]],
                  usable: Callable[[dict[str, np.ndarray]], bool] | None = None
                  ) -> dict[str, np.ndarray]:
    """The arrays compute() returns for key, loaded from the cache if it holds them, else
    computed and stored (kind names the simulation, e.g. "car-smooth-road"). usable: an
    entry it refuses (say, a run too short) is computed again and replaced."""
    folder = cache_directory()
    text = repr(key)
    if folder is None or " at 0x" in text or "array(" in text:   # no value printed whole
        return compute()
    path = folder / entry_name(kind, key)

    def load():
        arrays = _load(path)
        return arrays if arrays is not None and (usable is None or usable(arrays)) else None
    arrays = load()
    if arrays is not None:
        return arrays
    with _entry_lock(folder, path) as locked:
        # Another process may have written it while this one waited for the lock.
        arrays = load() if locked else None
        if arrays is None:
            arrays = compute()
            _store(folder, path, arrays)
    return arrays


def _load(path: Path) -> dict[str, np.ndarray] | None:
    """The entry's arrays, or None if it is absent, unreadable, damaged or not a truth
    entry (``is_truth_entry``: a file of another kind in its place); a damaged or foreign
    one is removed where the cache can be written, so that it is computed and written
    again (a miss, never an error)."""
    try:
        with open(path, "rb") as handle:                # closed if damaged
            archive = np.load(handle)
            if not isinstance(archive, np.lib.npyio.NpzFile):
                raise ValueError("a single array, not an entry")
            with archive as f:
                arrays = {name: f[name] for name in f.files}
        if not is_truth_entry(arrays):
            raise ValueError("not a truth entry")
    except FileNotFoundError:
        return None
    except OSError:                      # unreadable (permissions, I/O): not its content
        return None
    except Exception:                    # its content is bad: whatever numpy or zipfile raise
        _remove(path)
        return None
    try:
        os.utime(path)                   # recently used: kept by the trimming
    except OSError:                      # another user's entry, a read-only cache
        pass
    return arrays


def is_truth_entry(arrays: dict[str, np.ndarray]) -> bool:
    """Whether loaded arrays can be an entry: at least one array, numbers only (an
    episode file, a campaign's time series or text arrays in its place are not)."""
    return bool(arrays) and all(a.dtype.kind in "biufc" for a in arrays.values())


def _remove(path: Path) -> None:
    """Remove a damaged entry or a lock file this process holds; one the cache cannot
    remove (another user's, a read-only cache) is left."""
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass


@contextmanager
def _entry_lock(folder: Path, path: Path) -> Iterator[bool]:
    """Hold the entry's lock file while it is computed, so that processes needing the
    same entry at once simulate it once (the others wait, then load it); yields whether
    the lock is held (False when the cache's directory cannot be written). No lock file
    is left: its holder removes it before letting go, and a process that waited on a
    removed one (its name now gone or another file's) lets go and locks the name anew."""
    try:
        import fcntl
        folder.mkdir(parents=True, exist_ok=True)
    except (ImportError, OSError):       # no flock here, or the directory is read-only
        yield False
        return
    lock = path.with_suffix(".lock")
    while True:
        try:
            handle = open(lock, "a")
        except OSError:                  # the directory is read-only
            yield False
            return
        try:
            fcntl.flock(handle, fcntl.LOCK_EX)
        except OSError:                  # a file system without locks (ENOLCK)
            handle.close()
            yield False
            return
        if _is_at(handle.fileno(), lock):
            break
        handle.close()                   # removed by its holder meanwhile: again
    try:
        yield True
    finally:
        _remove(lock)
        handle.close()                   # lets go of the lock


def _is_at(fd: int, path: Path) -> bool:
    """Whether the open file fd is the file now named path."""
    try:
        named = os.stat(path)
    except OSError:
        return False
    mine = os.fstat(fd)
    return (mine.st_ino, mine.st_dev) == (named.st_ino, named.st_dev)


def _remove_free_locks(folder: Path) -> None:
    """Remove the lock files no process holds (an earlier version left every one):
    each is locked without waiting, and removed while locked if it is still the file
    of that name; one held by another process is left to it."""
    try:
        import fcntl
    except ImportError:
        return
    for lock in folder.glob("*.lock"):
        try:
            fd = os.open(lock, os.O_RDONLY)          # never created here
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if _is_at(fd, lock):
                _remove(lock)
        except OSError:                  # held (being computed), or no locks here
            pass
        finally:
            os.close(fd)


def _store(folder: Path, path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write the entry atomically and trim the cache. A cache that cannot be written, or
    whose disk would keep less than ``FREE_BYTES_KEPT`` free, is reported once and not
    written again by this process."""
    import shutil

    from aligngym.scenarios.atomic import atomic_path
    if str(folder) in _reported:
        return
    try:
        folder.mkdir(parents=True, exist_ok=True)
        size = sum(a.nbytes for a in arrays.values())
        if shutil.disk_usage(folder).free - size < FREE_BYTES_KEPT:
            raise OSError(f"less than {FREE_BYTES_KEPT / 1e9:g} GB would stay free")
        with atomic_path(path) as tmp:
            np.savez(tmp, **arrays)
        _trim(folder)
    except OSError as error:
        _reported.add(str(folder))
        warnings.warn(f"truth cache {folder} cannot be written ({error.strerror or error});"
                      f" simulating without it (set {TRUTH_CACHE_ENV}=off to silence)",
                      RuntimeWarning, stacklevel=3)


def _trim(folder: Path, limit: int = TRUTH_CACHE_BYTES) -> None:
    """Remove the least recently used entries until the cache holds at most limit bytes."""
    from aligngym.scenarios.atomic import is_temporary
    entries = []
    for path in folder.glob("*.npz"):
        if is_temporary(path):                 # another process's entry being written
            continue
        try:
            stat = path.stat()
        except FileNotFoundError:              # removed by another process meanwhile
            continue
        entries.append((stat.st_mtime, stat.st_size, path))
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries):
        if total <= limit:
            break
        path.unlink(missing_ok=True)
        total -= size
    _remove_free_locks(folder)
