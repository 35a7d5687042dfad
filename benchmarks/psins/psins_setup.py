"""What the PSINS checks (``ckf_000.py``, ``lckf_001.py``, ``filters_004.py``) share: finding
GNU Octave and a PSINS tree, and the stub its ``glvf`` needs."""
from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

DEFAULT_GIT = "/work/.mirror/WangShanpeng+PSINS/repo"


def find_octave() -> str | None:
    """The Octave executable, or None."""
    return shutil.which("octave") or shutil.which("octave-cli")


def find_psins(arg: str | None, tmp: Path, needed: tuple[str, ...]) -> Path | None:
    """A PSINS work tree holding every file of needed (paths under it), or None: arg or
    $PSINS_DIR, else base/ extracted into tmp from the bare snapshot $PSINS_GIT
    (default DEFAULT_GIT)."""
    tree = arg or os.environ.get("PSINS_DIR")
    if tree:
        return Path(tree) if all((Path(tree) / p).is_file() for p in needed) else None
    git_dir = os.environ.get("PSINS_GIT", DEFAULT_GIT)
    if not (Path(git_dir).is_dir() and shutil.which("git")):
        return None
    out = tmp / "psins"
    out.mkdir(exist_ok=True)
    # base/ only: the snapshot lacks some large data blobs elsewhere in the tree.
    archive = subprocess.run(["git", f"--git-dir={git_dir}", "archive", "HEAD", "base"],
                             capture_output=True)
    if archive.returncode != 0:
        return None
    subprocess.run(["tar", "-x", "-C", str(out)], input=archive.stdout, check=True)
    return out if all((out / p).is_file() for p in needed) else None


def psinsenvi_shim(tmp: Path) -> Path:
    """A directory holding a stub psinsenvi.m: PSINS's glvf calls it, and its installer,
    not its tree, generates it."""
    shim = tmp / "shim"
    shim.mkdir(exist_ok=True)
    (shim / "psinsenvi.m").write_text(
        "function [rpath, dpath, mytestflag] = psinsenvi()\n"
        "rpath = ''; dpath = ''; mytestflag = 0;\nend\n")
    return shim
