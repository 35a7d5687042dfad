"""The truth cache: a simulation's seed-independent part, kept on disk for other processes.

The part of an episode that MuJoCo computes (the carrier's truth and the ideal IMU
increments) often repeats: every seed of a car on a smooth road, or of a prescribed ship
without random phases, has the same one, and a seed run again (a campaign's parallel
workers, the env, a later campaign) has its own again. Each process keeps the recent ones
in memory (``scenarios.simulate``); this cache lets the other processes load them instead
of simulating them.

Entries live in ``$ALIGNGYM_TRUTH_CACHE`` (default ``$XDG_CACHE_HOME/aligngym/truth``,
else ``~/.cache/aligngym/truth``; ``off`` disables the cache), one .npz per entry, named
by a hash of what decides it: the simulation's inputs, the simulation code
(``simulation_code_sha256``) and the versions of MuJoCo and NumPy, so a changed
simulation never loads an old entry. An entry is written whole or not at all
(``atomic``); one that does not load is removed and simulated again; a cache that cannot
be written (a full disk, no permission) is reported once and the run goes on without it.
The directory is kept under ``TRUTH_CACHE_BYTES`` by removing the least recently used
entries.
"""
from __future__ import annotations

import hashlib
import os
import warnings
import zipfile
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

TRUTH_CACHE_ENV = "ALIGNGYM_TRUTH_CACHE"
"""Environment variable naming the cache's directory ("off": no cache)."""
TRUTH_CACHE_BYTES = 2 * 1024 ** 3
"""Most bytes the cache keeps (about 100 car runs of 600 s at 100 Hz)."""
_reported: set[str] = set()


def cache_directory() -> Path | None:
    """The cache's directory (not created), or None when ``ALIGNGYM_TRUTH_CACHE=off``."""
    chosen = os.environ.get(TRUTH_CACHE_ENV, "")
    if chosen.lower() == "off":
        return None
    if chosen:
        return Path(chosen)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "aligngym" / "truth"


SIMULATION_SOURCES = ("models", "sensors", "estimators", "scenarios/experiments",
                      "scenarios/campaign", "scenarios/simulate.py", "scenarios/config.py")
"""The package's code that prepares an episode: any change to it is a new bank."""


def simulation_code_sha256() -> str:
    """A hash of ``SIMULATION_SOURCES`` (the .py files, in name order)."""
    root = Path(__file__).resolve().parents[1]        # the package's source root
    digest = hashlib.sha256()
    for part in SIMULATION_SOURCES:
        path = root / part
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for f in files:
            digest.update(str(f.relative_to(root)).encode())
            digest.update(f.read_bytes())
    return digest.hexdigest()


@lru_cache(maxsize=1)
def _versions() -> str:
    import mujoco
    return f"{simulation_code_sha256()} mujoco {mujoco.__version__} numpy {np.__version__}"


def entry_name(kind: str, key: tuple) -> str:
    """The entry's file name: kind and a hash of key (its repr: dataclasses and floats
    print every digit) with the code and library versions."""
    digest = hashlib.sha256(f"{kind} {key!r} {_versions()}".encode()).hexdigest()
    return f"{kind}-{digest[:24]}.npz"


def cached_arrays(kind: str, key: tuple, compute: Callable[[], dict[str, np.ndarray]],
                  usable: Callable[[dict[str, np.ndarray]], bool] | None = None
                  ) -> dict[str, np.ndarray]:
    """The arrays compute() returns for key, loaded from the cache if it holds them, else
    computed and stored (kind names the simulation, e.g. "car-smooth-road"). usable: an
    entry it refuses (say, a run too short) is computed again and replaced."""
    folder = cache_directory()
    if folder is None or " at 0x" in repr(key):  # no cache, or a key that prints no value
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
    """The entry's arrays, or None if it is absent or damaged (then removed)."""
    if not path.exists():
        return None
    try:
        with np.load(path) as f:
            arrays = {name: f[name] for name in f.files}
        os.utime(path)                         # recently used: kept by the trimming
        return arrays
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError):
        path.unlink(missing_ok=True)
        return None


@contextmanager
def _entry_lock(folder: Path, path: Path) -> Iterator[bool]:
    """Hold the entry's lock file while it is computed, so that processes needing the
    same entry at once simulate it once (the others wait, then load it); yields whether
    the lock is held (False when the cache's directory cannot be written)."""
    import fcntl
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle = open(path.with_suffix(".lock"), "a")
    except OSError:
        yield False
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield True
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _store(folder: Path, path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write the entry atomically and trim the cache; on failure report it once."""
    from aligngym.scenarios.atomic import atomic_path
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            np.savez(tmp, **arrays)
        _trim(folder)
    except OSError as error:
        if str(folder) not in _reported:
            _reported.add(str(folder))
            warnings.warn(f"truth cache {folder} cannot be written ({error.strerror or error});"
                          f" simulating without it (set {TRUTH_CACHE_ENV}=off to silence)",
                          RuntimeWarning, stacklevel=3)


def _trim(folder: Path, limit: int = TRUTH_CACHE_BYTES) -> None:
    """Remove the least recently used entries until the cache holds at most limit bytes."""
    entries = []
    for path in folder.glob("*.npz"):
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
