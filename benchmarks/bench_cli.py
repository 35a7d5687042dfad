"""Benchmark: start-up of the command line (help, version, an option error), each run as
a new process the way a user types it. Run: python benchmarks/bench_cli.py"""
from __future__ import annotations

import shutil
import subprocess
import time

COMMANDS = (["--help"], ["simulate", "--help"], ["--version"],
            ["simulate", "ship-sway-rotary", "--seed", "-1", "--out", "x.npz"],
            ["bench", "--help"])


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
