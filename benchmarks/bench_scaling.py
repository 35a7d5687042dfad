"""Benchmark: how a campaign scales with its worker processes. For each paper, the
command-line ``bench PAPER --episodes N --no-figures`` (the whole process: start-up,
preparation, filters, analysis, writing) at 1, 2, 4 ... workers up to this machine's
cores, and at workers beyond them (2x the cores and 16), each in a fresh output
directory with the truth cache warm (a first, uncounted run fills it). Prints a
Markdown table of the median wall time of ``--repeat`` runs, the speed-up over one
worker and the efficiency (speed-up / min(workers, cores)); above the papers, the
machine's own ceiling: a fixed amount of work split, as a campaign splits its own, over
that many processes but no more than the cores (beyond them, the cores' cell again), each
needing nothing from the others (a pure-Python loop; NumPy passes over 8 MB arrays, which
share the memory bandwidth and the last-level cache), timed inside each process without
its start-up (a campaign forks its workers), the counts interleaved. A paper's speed-up
is read against these: on a shared or virtual machine, two processes seldom get twice
one's throughput.

Run: python benchmarks/bench_scaling.py [--papers paper000,...] [--episodes 32]
     [--repeat 1] [--ceiling-repeat 5]
(all five papers at 32 episodes: about 25 min on 2 cores.)
"""
from __future__ import annotations

import argparse
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from aligngym.scenarios.campaign.executors import usable_cores

PAPERS = ("paper000", "paper001", "paper002", "paper003", "paper004")


def worker_counts(cores: int) -> list[int]:
    """1, 2, 4 ... up to the cores, then 2x the cores and 16 (beyond the cores)."""
    counts, w = [], 1
    while w < cores:
        counts.append(w)
        w *= 2
    counts.append(cores)
    return sorted(set(counts + [2 * cores, max(16, 2 * cores)]))


def bench_seconds(paper: str, episodes: int, workers: int) -> float:
    """Wall seconds of one ``bench`` command in a fresh output directory."""
    out = tempfile.mkdtemp(prefix="aligngym-scaling-")
    try:
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "aligngym.scenarios.cli", "bench", paper,
                        "--episodes", str(episodes), "--workers", str(workers),
                        "--no-figures", "--out", out],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        return time.perf_counter() - start
    finally:
        shutil.rmtree(out, ignore_errors=True)


CEILING_JOBS = {
    "pure-Python loop": ("", "s = 0\nfor i in range({n} * 4_000_000 // {k}): s += i * i % 7"),
    "NumPy, 8 MB arrays": ("import numpy as np\na = np.random.default_rng(0).random(1_000_000)",
                           "for _ in range({n} * 120 // {k}): b = np.sqrt(a * a + 1.0)"),
}
"""The ceiling's jobs: (set-up, work), the work {n} units split into {k} processes."""

TIMED = """import time
{setup}
start = time.perf_counter()
{work}
print(time.perf_counter() - start)"""
"""A ceiling process: its set-up (imports, arrays) outside the time it prints."""


def ceiling_seconds(job: str, processes: int, units: int = 5) -> float:
    """Seconds of ``units`` of a ``CEILING_JOBS`` job split over ``processes`` processes
    started at once: the longest of their work alone (an interpreter's start and its
    imports left out: a campaign forks its workers)."""
    setup, work = CEILING_JOBS[job]
    code = TIMED.format(setup=setup, work=work.format(n=units, k=processes))
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
             for _ in range(processes)]
    outputs = [p.communicate()[0] for p in procs]        # every one waited for
    if any(p.returncode for p in procs):
        raise RuntimeError(f"the ceiling job {job!r} failed")
    return max(float(out) for out in outputs)


def ceiling_times(job: str, counts: list[int], cores: int, repeat: int) -> dict[int, float]:
    """Median seconds of a ceiling job per worker count, the counts interleaved in each
    round (the machine drifts); beyond the cores the cores' time (a campaign runs no more
    processes than the cores)."""
    runs: dict[int, list[float]] = {w: [] for w in counts if w <= cores}
    for _ in range(repeat):
        for w in runs:
            runs[w].append(ceiling_seconds(job, w))
    return {w: statistics.median(runs[min(w, cores)]) for w in counts}


def row(label: str, times: dict[int, float], cores: int) -> str:
    """A table row: each count's wall time, speed-up over one and efficiency."""
    cells = []
    for w, seconds in times.items():
        speedup = times[1] / seconds
        cells.append(f"{seconds:.1f} s, {speedup:.2f}x, {100 * speedup / min(w, cores):.0f} %")
    return f"| {label} | " + " | ".join(cells) + " |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--papers", default=",".join(PAPERS))
    parser.add_argument("--episodes", type=int, default=32)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--ceiling-repeat", type=int, default=5,
                        help="runs of each ceiling job per count (median)")
    args = parser.parse_args()
    cores = usable_cores()
    counts = worker_counts(cores)
    print(f"{platform.processor() or platform.machine()}, {cores} cores, "
          f"{args.episodes} episodes, median of {args.repeat}")
    print()
    print("| paper | " + " | ".join(f"{w} worker{'s' if w > 1 else ''}" for w in counts)
          + " |")
    print("|---|" + "---|" * len(counts))
    for job in CEILING_JOBS:
        times = ceiling_times(job, counts, cores, args.ceiling_repeat)
        print(row(f"ceiling: {job}", times, cores), flush=True)
    for paper in args.papers.split(","):
        bench_seconds(paper, args.episodes, cores)          # fills the truth cache
        times = {w: statistics.median(bench_seconds(paper, args.episodes, w)
                                      for _ in range(args.repeat)) for w in counts}
        print(row(paper, times, cores), flush=True)


if __name__ == "__main__":
    main()
