"""aligngym regress: each paper's small fixed-seed campaign against its stored baseline."""
from __future__ import annotations

import argparse

from aligngym.scenarios.commands.options import integer_option
from aligngym.scenarios.registry import experiment_names


def add_parser(sub: argparse._SubParsersAction) -> None:
    """The ``regress`` command's options."""
    reg = sub.add_parser("regress", help="run each paper's small fixed-seed campaign against "
                         "its stored baseline; exit 1 when a metric moved beyond tolerance")
    reg.add_argument("--papers", default=None,
                     help="comma-separated experiments (default: every one with a "
                     "regression campaign: " + ",".join(experiment_names()) + ")")
    reg.add_argument("--update", action="store_true",
                     help="store this run's metrics as the new baselines (default: compare)")
    reg.add_argument("--baselines", metavar="DIR",
                     help="baseline directory (default: the baselines shipped with the package)")
    reg.add_argument("--workers", type=integer_option("--workers"), metavar="K",
                     help="cores to use: parallel processes of one thread "
                     "each (default: all cores)")


def run(args: argparse.Namespace) -> int:
    from aligngym.scenarios.regress import BASELINE_DIR, campaigns, regress

    papers = (list(campaigns()) if args.papers is None
              else [p.strip() for p in args.papers.split(",") if p.strip()])
    passed, report = regress(papers, update=args.update,
                             directory=args.baselines or BASELINE_DIR, workers=args.workers)
    print(report)
    return 0 if passed else 1
