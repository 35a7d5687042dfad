"""Benchmark: wall time of the whole test suite, in one process (-n 0, as before
pytest-xdist) and on every core (the default run: -n auto, a test file per worker).

The suite's budget is 3 minutes on two cores, set on the machine of 2026-12-04, where
commit ff10adb's suite took 2:41-3:05 (median 2:53, seven runs). A machine's speed
changes that number (the same commit took 3:42-4:01 on the 2-core machine of
2026-12-06), so ``--against COMMIT`` times that commit's suite on this machine too, just
after this one's (this one with the running interpreter; the reference in a fresh venv
of its own, as CI runs it): the ratio is the suite's cost against the reference,
whatever the machine. A suite that fails is reported, and no ratio is printed. (Inside a venv the reference fails its two wheel
tests at once, the defect issue 41 fixed, so it does some 12 s of work less than it would
elsewhere: the ratio is a little pessimistic.)

Run: python benchmarks/bench_suite.py [--against ff10adb] [--single]"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = "ff10adb"
"""The last commit measured within the budget on the machine it was set on (2:53)."""


def run(python: str | Path, tree: Path, *options: str, failures_expected: int = 0
        ) -> float | None:
    """Wall time (s) of the suite of tree run by python with pytest options, or None if
    more tests failed than failures_expected (or pytest could not run); prints it with
    pytest's last line."""
    start = time.perf_counter()
    done = subprocess.run([str(python), "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           *options], cwd=tree, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    tail = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else done.stderr
    print(f"{tree.name}: pytest {' '.join(options) or '(default)'}: {elapsed:.0f} s wall; "
          f"{tail}", flush=True)
    failed = re.search(r"(\d+) failed", tail)
    count = int(failed.group(1)) if failed else (0 if done.returncode == 0 else None)
    return elapsed if count is not None and count <= failures_expected else None


def reference_tree(commit: str, folder: Path) -> tuple[Path, Path]:
    """(work tree, python) of commit checked out under folder and installed with its test
    extras into a fresh venv (pip's cache makes this about a minute)."""
    tree = folder / f"reference-{commit}"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree),
                    commit], check=True, capture_output=True)
    env = folder / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(env)], check=True)
    python = env / "bin" / "python"
    subprocess.run([str(python), "-m", "pip", "install", "-q", "-e", ".[test]"], cwd=tree,
                   check=True)
    return tree, python


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--against", metavar="COMMIT", nargs="?", const=REFERENCE,
                        help=f"time COMMIT's suite too (default {REFERENCE})")
    parser.add_argument("--single", action="store_true",
                        help="also the suite in one process (-n 0)")
    args = parser.parse_args(argv)
    if args.single:
        single = run(sys.executable, ROOT, "-n", "0")
    default = run(sys.executable, ROOT)
    if args.single and single and default:
        print(f"speed-up on every core: {single / default:.2f}x")
    if args.against:
        with tempfile.TemporaryDirectory(prefix="aligngym-suite-") as folder:
            try:
                tree, python = reference_tree(args.against, Path(folder))
                # ff10adb's two wheel tests fail at once inside a venv (the docstring)
                reference = run(python, tree, failures_expected=2 * (args.against
                                                                      == REFERENCE))
            finally:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                                str(Path(folder) / f"reference-{args.against}")],
                               capture_output=True)
        if default and reference:
            print(f"this suite / {args.against}'s: {default / reference:.2f} "
                  f"(the budget: at most 1.04, {REFERENCE}'s 2:53 against 3:00)")
        else:
            print("no ratio: a suite failed (above)")


if __name__ == "__main__":
    main()
