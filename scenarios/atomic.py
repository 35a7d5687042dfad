"""Outputs written whole or not at all: each file is written under a temporary name in
its own directory (unique per process and call, hidden, with the final suffix so that
writers choosing a format by extension keep working) and renamed onto its final name
when complete (``os.replace``: atomic on one file system). A killed run leaves the old
file or none, never a partial one; an exception (a full disk, Ctrl-C) removes the
temporary file."""
from __future__ import annotations

import json
import math
import os
import uuid
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator


def temporary_name(path: Path) -> Path:
    """A unique hidden name beside path, with path's suffix: .NAME.PID.RANDOM.tmpSUFFIX."""
    return path.with_name(f".{path.stem}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp{path.suffix}")


@contextmanager
def atomic_path(path: str | Path, own_directory: bool = False) -> Iterator[Path]:
    """Yield a temporary path to write ``path``'s content to; on leaving the block it is
    renamed onto ``path``, or removed if the block raised. own_directory: the temporary
    file lives in a hidden directory of its own, removed with it, for writers that run
    in another process (ffmpeg may still create its file after an interruption: with
    its directory gone, it cannot)."""
    path = Path(path)
    if own_directory:
        import shutil
        folder = temporary_name(path).with_suffix("")
        folder.mkdir()
        try:
            yield folder / path.name
            os.replace(folder / path.name, path)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        return
    tmp = temporary_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text(path: str | Path, text: str) -> Path:
    """Write text (UTF-8) to path atomically; returns path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def strict_json_value(value: Any) -> Any:
    """value with every non-finite number (NaN, inf; Python or NumPy) as None (JSON
    null), NumPy scalars and arrays as Python numbers and lists, tuples as lists: what
    ``json.dumps(..., allow_nan=False)`` accepts (strict JSON has no NaN or Infinity)."""
    if isinstance(value, dict):
        return {k: strict_json_value(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict_json_value(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):   # NumPy
        return strict_json_value(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def json_text(value: Any, **options: Any) -> str:
    """Strict JSON of value (``strict_json_value``: non-finite numbers are null)."""
    return json.dumps(strict_json_value(value), allow_nan=False, **options)


def write_json(path: str | Path, value: Any) -> Path:
    """Write value as indented strict JSON to path atomically (NaN and inf as null,
    ``json_text``); returns path."""
    return write_text(path, json_text(value, indent=2))


def is_temporary(path: Path) -> bool:
    """Whether a file name is one of ``temporary_name``'s, or an earlier version's
    ``NAME.tmp.npz`` (a leftover of a killed run)."""
    name = path.name
    return (name.startswith(".") and ".tmp" in name) or name.endswith(".tmp.npz")


def save_figure(fig: Any, path: str | Path, **options: Any) -> Path:
    """``fig.savefig(path, **options)`` atomically (the format from path's suffix)."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **options)
    return Path(path)
