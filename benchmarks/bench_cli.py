"""Benchmark: start-up of the command line (help, version, option and scenario errors,
each experiment's own option errors, which import that experiment), each run as a new
process the way a user types it (target: every error within 0.3 s). Run: python
benchmarks/bench_cli.py"""
from __future__ import annotations

import shutil
import subprocess
import time

COMMANDS = (["--help"], ["simulate", "--help"], ["--version"],
            ["simulate", "ship-sway-rotary", "--seed", "-1", "--out", "x.npz"],
            ["bench", "--help"], ["bench", "paper004", "--help"],
            ["simulate", "no-such-scenario", "--out", "x.npz"],
            ["simulate", "missing.toml", "--out", "x.npz"],
            ["bench", "paper000", "--disturbance", "mud"],
            ["bench", "paper001", "--outage", "-3"],
            ["bench", "paper002", "--filters", "nosuch"],
            ["bench", "paper002", "--scenario", "missing.toml"],
            ["bench", "paper003", "--swing", "mild"],
            ["bench", "paper004", "--swing", "wild"],
            ["regress", "--papers", "paper9"],
            ["render", "no-such", "--out", "x.mp4"])


def main() -> None:
    exe = shutil.which("aligngym")
    if exe is None:
        raise SystemExit("aligngym is not installed (pip install -e .)")
    for args in COMMANDS:
        times = []
        for _ in range(5):
            start = time.perf_counter()
            subprocess.run([exe, *args], capture_output=True)
            times.append(time.perf_counter() - start)
        print(f"aligngym {' '.join(args):55s} {min(times):6.3f} s (best of 5)")


if __name__ == "__main__":
    main()
