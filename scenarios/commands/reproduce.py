"""aligngym reproduce: each paper's claims run on the testbed, with verdicts."""
from __future__ import annotations

import argparse

from aligngym.scenarios.commands.options import check_writable, integer_option, seed_option
from aligngym.scenarios.registry import experiment_names


def add_parser(sub: argparse._SubParsersAction) -> None:
    """The ``reproduce`` command's options."""
    rpr_help = ("run each paper's claims (from its text) on the testbed and print each "
                "beside what was measured, with a verdict: reproduced, or not and why")
    rpr = sub.add_parser("reproduce", help=rpr_help, description=rpr_help)
    rpr.add_argument("papers", metavar="PAPER", help="an experiment (" +
                     ", ".join(experiment_names()) + "), a comma-separated list, or all")
    rpr.add_argument("--episodes", type=integer_option("--episodes"), metavar="N",
                     help="episodes per campaign (default: each paper's own, "
                     "Experiment.reproduce; all of them take 1.5-2 min on 2 cores)")
    rpr.add_argument("--seed", type=seed_option, default=None, metavar="S",
                     help="campaign seed (default: each paper's own)")
    rpr.add_argument("--out", metavar="DIR", help="write DIR/claims.md (the page, with the "
                     "figures) and each campaign's outputs under DIR/PAPER/")
    rpr.add_argument("--workers", type=integer_option("--workers"), metavar="K",
                     help="cores to use: parallel processes of one thread "
                     "each (default: all cores)")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from aligngym.scenarios.campaign.plan import claims_plan
    from aligngym.scenarios.config import ConfigError
    from aligngym.scenarios.reproduce import reproduce

    names = experiment_names()
    papers = (list(names) if args.papers == "all"        # each once, in the order given
              else list(dict.fromkeys(p.strip() for p in args.papers.split(",") if p.strip())))
    unknown = [p for p in papers if p not in names]
    if unknown or not papers:
        raise ConfigError(f"reproduce: unknown paper {(unknown or [args.papers])[0]!r}; "
                          "valid: all, " + ", ".join(names))
    # every claim campaign planned and checked (the memory too) before --out is made
    plan = claims_plan(papers, args.episodes, args.seed)
    if args.out:
        check_writable(str(Path(args.out) / "claims.md"), "--out")
    _, text = reproduce(papers, episodes=args.episodes, seed=args.seed,
                        out_dir=Path(args.out) if args.out else None, workers=args.workers,
                        log=lambda line: print(line, flush=True), plan=plan)
    print(text)
    return 0
