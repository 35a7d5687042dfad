"""Benchmark: wall time of the whole test suite, in one process (-n 0, as before
pytest-xdist) and on every core (the default run: -n auto, a test file per worker).
On two cores the default run takes about 3 minutes (the suite's CPU: about 5.7 minutes,
which the one-process run takes in wall time, or more). Run: python
benchmarks/bench_suite.py"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(*options: str) -> float:
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           *options], cwd=ROOT, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    tail = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else done.stderr
    print(f"pytest {' '.join(options) or '(default)'}: {elapsed:.0f} s wall; {tail}")
    return elapsed


def main() -> None:
    single = run("-n", "0")
    default = run()
    print(f"speed-up {single / default:.2f}x")


if __name__ == "__main__":
    main()
