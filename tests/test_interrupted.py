"""An interrupted campaign: SIGKILL while episodes are being written, then --resume,
gives the uninterrupted run's results; a half-written file is never read as finished."""
import fcntl
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np

from aligngym.scenarios.campaign.manifest import LOCK_NAME
from aligngym.scenarios.cli import main
from aligngym.scenarios.regress import flatten

ARGS = ["bench", "paper002", "--episodes", "8", "--filters", "ekf", "--workers", "2",
        "--seed", "9", "--no-figures"]


def aligngym(*args: str) -> list[str]:
    return [sys.executable, "-c", "import sys; from aligngym.scenarios.cli import main; "
            "sys.exit(main(sys.argv[1:]))", *args]


def test_sigkill_then_resume_equals_an_uninterrupted_run(tmp_path):
    out = tmp_path / "killed"
    proc = subprocess.Popen(aligngym(*ARGS, "--out", str(out)), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    episodes = out / "episodes"

    def finished_files():
        return [p for p in episodes.glob("seed_*.npz") if not p.name.endswith(".tmp.npz")]

    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if len(finished_files()) >= 2:                       # mid-campaign
            break
        time.sleep(0.01)
    assert proc.poll() is None, "the campaign ended before it could be killed"
    os.killpg(proc.pid, signal.SIGKILL)                      # the workers too
    proc.wait()
    # The kernel ends the workers, which hold the campaign lock too, a moment later.
    with open(out / LOCK_NAME) as lock:
        deadline = time.monotonic() + 30
        while True:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                assert time.monotonic() < deadline, "the killed run's workers hold its lock"
                time.sleep(0.01)
        fcntl.flock(lock, fcntl.LOCK_UN)
    # A write cut short leaves a *.tmp.npz (renamed only when complete): every
    # seed_N.npz is a whole episode.
    finished = finished_files()
    assert 2 <= len(finished) < 8
    for path in finished:
        with np.load(path) as f:
            assert "seed" in f.files and np.all(np.isfinite(f["C_b_n_true"]))
    (episodes / "seed_99999.tmp.npz").write_bytes(b"half a file")   # as if killed mid-write
    # The resumed and the clean run in this process (the killed one is the subject).
    assert main([*ARGS, "--out", str(out), "--resume", "--json",
                 str(tmp_path / "resumed.json")]) == 0
    assert main([*ARGS, "--out", str(tmp_path / "clean"), "--json",
                 str(tmp_path / "clean.json")]) == 0
    # Every result equal (the summary without its timing entries).
    assert flatten(json.loads((tmp_path / "resumed.json").read_text())) == flatten(
        json.loads((tmp_path / "clean.json").read_text()))
