"""Benchmark: how a campaign scales with its worker processes. For each paper, the
command-line ``bench PAPER --episodes N --no-figures`` (the whole process: start-up,
preparation, filters, analysis, writing) at 1, 2, 4 ... workers up to this machine's
cores, and at workers beyond them (2x the cores and 16), each in a fresh output
directory with the truth cache warm (a first, uncounted run fills it). Prints a
Markdown table of the median wall time of ``--repeat`` runs, the speed-up over one
worker and the efficiency (speed-up / min(workers, cores)).

Run: python benchmarks/bench_scaling.py [--papers paper000,...] [--episodes 32]
     [--repeat 1]
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--papers", default=",".join(PAPERS))
    parser.add_argument("--episodes", type=int, default=32)
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    cores = usable_cores()
    counts = worker_counts(cores)
    print(f"{platform.processor() or platform.machine()}, {cores} cores, "
          f"{args.episodes} episodes, median of {args.repeat}")
    print()
    print("| paper | " + " | ".join(f"{w} worker{'s' if w > 1 else ''}" for w in counts)
          + " |")
    print("|---|" + "---|" * len(counts))
    for paper in args.papers.split(","):
        bench_seconds(paper, args.episodes, cores)          # fills the truth cache
        times = {w: statistics.median(bench_seconds(paper, args.episodes, w)
                                      for _ in range(args.repeat)) for w in counts}
        cells = []
        for w in counts:
            speedup = times[1] / times[w]
            cells.append(f"{times[w]:.1f} s, {speedup:.2f}x, "
                         f"{100 * speedup / min(w, cores):.0f} %")
        print(f"| {paper} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
