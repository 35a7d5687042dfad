"""aligngym report: one self-contained HTML page of a campaign directory."""
from __future__ import annotations

import argparse
import time


def add_parser(sub: argparse._SubParsersAction) -> None:
    """The ``report`` command's options."""
    rep_help = ("write DIR/report.html: one self-contained page of a campaign directory "
                "(settings, tables, results, figures)")
    rep = sub.add_parser("report", help=rep_help, description=rep_help)
    rep.add_argument("dir", metavar="DIR", help="a bench --out directory (or a directory of "
                     "them, as bench paper004 --swing all writes)")


def run(args: argparse.Namespace) -> int:
    from aligngym.scenarios.html_report import write_report

    start = time.perf_counter()
    path = write_report(args.dir)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB, "
          f"{time.perf_counter() - start:.2f} s)")
    return 0
