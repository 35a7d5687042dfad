"""What the PSINS checks (``ckf_000.py``, ``lckf_001.py``, ``static_002.py``,
``filters_004.py``) share: their options, finding GNU Octave and a PSINS tree, the stub
its ``glvf`` needs, the temporary workspace and the Octave run itself."""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

DEFAULT_GIT = "/work/.mirror/WangShanpeng+PSINS/repo"
HERE = Path(__file__).resolve().parent


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


def add_psins_options(ap) -> None:
    """The options every check takes: where PSINS is, the work directory, --keep."""
    ap.add_argument("--psins", default=None, help="PSINS work tree (with base/)")
    ap.add_argument("--work", default=None, help="directory for the .mat files")
    ap.add_argument("--keep", action="store_true",
                    help="keep the temporary directory (PSINS extract, stub, default work dir)")


@contextmanager
def psins_workspace(script: str, args, needed: tuple[str, ...]):
    """Octave, a PSINS tree holding needed, the work directory and the psinsenvi stub
    (SimpleNamespace octave, psins, work, shim), or None after one line saying what is
    missing. The temporary directory goes on exit unless --keep (a --work directory is
    outside it and stays)."""
    octave = find_octave()
    if octave is None:
        print(f"{script}: octave not found; skipped")
        yield None
        return
    tmp = Path(tempfile.mkdtemp(prefix=script.replace("_", "") + "_"))
    try:
        psins = find_psins(args.psins, tmp, needed)
        if psins is None:
            print(f"{script}: PSINS snapshot not found (--psins, $PSINS_DIR or $PSINS_GIT); "
                  "skipped")
            yield None
            return
        work = Path(args.work) if args.work else tmp / "work"
        work.mkdir(parents=True, exist_ok=True)
        yield SimpleNamespace(octave=octave, psins=psins, work=work, shim=psinsenvi_shim(tmp))
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)


def run_octave(script: str, ws, inputs: list[Path], outputs: list[Path]) -> bool:
    """Run ``<script>_run(listfile, psins, shim)`` (this directory's .m) on inputs, listed
    one a line in work/runs.txt; True if every file of outputs was written, else the end
    of Octave's output and one line saying how many are missing."""
    listfile = ws.work / "runs.txt"
    listfile.write_text("".join(f"{p}\n" for p in inputs))
    cmd = [ws.octave, "--no-gui", "--quiet", "--eval",
           f"addpath('{HERE}'); {script}_run('{listfile}', '{ws.psins}', '{ws.shim}')"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    missing = [p for p in outputs if not Path(p).is_file()]
    if missing:
        print(proc.stdout[-3000:], proc.stderr[-3000:], sep="\n")
        print(f"{script}: octave failed ({len(missing)} runs without output)")
    return not missing
