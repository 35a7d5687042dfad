"""aligngym bench: an experiment's Monte Carlo campaign (every sweep value of a setting in
turn), its tables printed and its outputs written."""
from __future__ import annotations

import argparse
import time
from dataclasses import fields

from aligngym.scenarios.commands.options import (EXECUTOR_CHOICES, check_writable,
                                                 integer_option, seed_option, settings_of)
from aligngym.scenarios.registry import (SCENARIO_PAPER, experiment_names, scenario_names)


def add_parser(sub: argparse._SubParsersAction, bench_details: bool = False,
               experiment: type | None = None) -> None:
    """The ``bench`` command's options; bench_details: list the filters in its help
    (imports them); experiment: the Experiment class it names, whose declared settings
    become options of their own."""
    bench = sub.add_parser("bench", help="run an experiment's Monte Carlo comparison",
                           epilog=bench_epilog(experiment) if bench_details else None,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    defaults = {} if experiment is None else {f.name: f.default for f in fields(experiment)}
    bench.add_argument("paper", choices=list(experiment_names()), metavar="EXPERIMENT",
                       help="the experiment: " + ", ".join(experiment_names())
                       + "; 'bench EXPERIMENT --help' lists its settings")
    bench.add_argument("--episodes", type=integer_option("--episodes"), metavar="N",
                       help="Monte Carlo episodes (default: the experiment's"
                       + ("" if experiment is None else f", {experiment.default_episodes}")
                       + ")")
    bench.add_argument("--setup", default="default", metavar="NAME",
                       help="a named setup of the experiment (settings it declares, e.g. "
                       "paper003's 'paper': the paper's own setup; "
                       + ("" if experiment is None else "here: " + ", ".join(
                           ["default", *experiment.setups]) + "; ") + "default: default)")
    bench.add_argument("--set", action="append", metavar="NAME=VALUE",
                       help="any setting of the experiment (a field of its Experiment "
                       "class, e.g. fine_duration=300); repeatable")
    bench.add_argument("--scenario", metavar="NAME|FILE.toml",
                       help="scenario to run the experiment on: a shipped name or a .toml "
                       "whose world the experiment runs on; a .toml may carry a [filter] "
                       "table (default: the experiment's"
                       + (f", {defaults['scenario']}" if defaults.get("scenario") else "")
                       + ")")
    bench.add_argument("--seed", type=seed_option, default=0, metavar="S",
                       help="campaign seed (default: 0)")
    bench.add_argument("--filters", help="comma-separated filter names (default: the "
                       "experiment's" + ("" if "default_filters" not in defaults else
                                         ", " + ",".join(defaults["default_filters"])) + ")")
    if experiment is not None:
        add_setting_options(bench, experiment)
    bench.add_argument("--out", metavar="DIR", help="directory for results.csv, coarse.csv, "
                       "timeseries.npz, tables.txt, summary.json, settings.json, the figures "
                       "and the per-episode files; 'aligngym report DIR' makes a page of it "
                       "(default: none)")
    bench.add_argument("--json", metavar="FILE",
                       help="write the summary as JSON (default: none)")
    bench.add_argument("--no-figures", action="store_true",
                       help="with --out: leave out the PNG figures (the numbers and the "
                       "report page without them; default: draw them)")
    bench.add_argument("--resume", action="store_true",
                       help="reuse the episodes already finished in --out")
    bench.add_argument("--force", action="store_true",
                       help="replace the campaign an existing --out holds (default: refuse)")
    bench.add_argument("--workers", type=integer_option("--workers"), metavar="K",
                       help="cores to use: parallel processes of one thread each (1: this "
                       "process, one thread), or CPUs of a local Ray instance "
                       "(default: all cores)")
    bench.add_argument("--executor", choices=EXECUTOR_CHOICES, default="local",
                       help="where episodes are prepared: local processes, or Ray tasks "
                       "(pip install -e '.[ray]'; default: local)")
    bench.add_argument("--address", metavar="ADDR",
                       help="with --executor ray: the cluster to join ('auto', "
                       "'ray://HOST:10001'; default: start a local instance)")


def bench_epilog(experiment: type | None) -> str:
    """What ``bench --help`` lists besides the options: the experiments, the filters and
    the scenarios with a pipeline; with an experiment, its other settings (--set)."""
    from aligngym.estimators.catalogue import filter_names
    from aligngym.scenarios.experiments import setup_for
    lines = ["experiments: " + ", ".join(experiment_names()), "filters: " + ", ".join(filter_names()),
             "scenarios with a pipeline: "
             + ", ".join(f"{s} ({p})" for s, p in sorted(SCENARIO_PAPER.items()))
             + "".join(f", {s} ({named[0]} --setup {named[1]})" for s in scenario_names()
                       if s not in SCENARIO_PAPER and (named := setup_for(s)))]
    if experiment is not None:
        flagged = {f.name for f in experiment.flagged_settings()}
        lines.append("--set NAME=VALUE settings (default): " + ", ".join(
            f"{f.name} ({f.default!r})" for f in fields(experiment)
            if f.name not in flagged | {"scenario", "default_filters"}))
        lines.append("(their meaning and units: the docstring of "
                     f"{experiment.__module__}.{experiment.__name__})")
    return "\n".join(lines)


def add_setting_options(bench: argparse.ArgumentParser, experiment: type) -> None:
    """The experiment's declared settings (``campaign.setting``) as bench options of their
    own: --NAME with the declared choices (and "all" for a sweep) or a number."""
    group = bench.add_argument_group(f"settings of {experiment.__name__}")
    for f in experiment.flagged_settings():
        meta, flag = f.metadata, "--" + f.name.replace("_", "-")
        kwargs: dict = {"dest": f.name, "default": None}
        if meta["choices"]:
            kwargs["choices"] = list(meta["choices"]) + (["all"] if meta["sweep"] else [])
        else:      # read as --set reads its VALUE; checked with the experiment's settings
            kwargs["metavar"] = meta["unit"].upper() or "VALUE"
        default = f.default if f.default not in ("", None) else "none"
        tail = (", or all in turn" if meta["sweep"] else "") + f"; default: {default}"
        group.add_argument(flag, help=meta["doc"] + (f", {meta['unit']}" if meta["unit"] else "")
                           + tail, **kwargs)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from aligngym.scenarios.campaign.plan import bench_plan
    from aligngym.scenarios.config import ConfigError
    from aligngym.scenarios.experiments import experiment_class
    from aligngym.scenarios.report import format_tables, write_outputs

    if args.resume and not args.out:
        raise ConfigError("--resume needs --out DIR (where the finished episodes are)")
    cls = experiment_class(args.paper)
    settings = {} if args.scenario is None else {"scenario": args.scenario}
    settings.update(settings_of(cls, args))
    filters = (None if args.filters is None
               else [f.strip() for f in args.filters.split(",") if f.strip()])
    # every campaign checked before anything is written (--out is not created yet)
    plan = bench_plan(args.paper, args.setup, settings, args.episodes, args.seed, filters)
    if args.json:
        check_writable(args.json, "--json")
    summaries, elapsed = [], 0.0
    for spec in plan.specs:
        if not args.no_figures:        # matplotlib imported while the campaign's workers run
            from aligngym.scenarios.campaign.executors import while_waiting
            from aligngym.scenarios.figures import load_drawing
            while_waiting(load_drawing)
        out = (args.out if plan.sweep is None or args.out is None
               else str(Path(args.out) / spec.label))
        start = time.perf_counter()
        with holding(out):            # the campaign and its outputs: one writer
            result = spec.run(out_dir=out, resume=args.resume, workers=args.workers,
                              executor=args.executor, address=args.address,
                              force=args.force)
            elapsed += time.perf_counter() - start
            print(format_tables(result))
            written = write_outputs(result, out, args.json if plan.sweep is None else None,
                                    command=args.command_line, figures=not args.no_figures,
                                    processes=args.workers)
        for path in written:
            print(f"wrote {path}")
        summaries.append(result.summary())
    if plan.sweep is not None and args.json:
        from aligngym.scenarios.atomic import write_json
        write_json(args.json, cls.merge_sweep(plan.sweep, summaries))
        print(f"wrote {args.json}")
    last = plan.specs[-1]
    print(f"{last.episodes} episodes x {len(last.filters)} filters x "
          f"{len(last.experiment.starts)} start(s)"
          + (f" x {len(plan.specs)} {plan.sweep} values" if plan.sweep is not None else "")
          + f" in {elapsed:.1f} s")
    return 0


def holding(out: str | None):
    """The campaign directory's lock (``campaign.manifest.campaign_lock``), or nothing
    without --out."""
    import contextlib
    from pathlib import Path

    if out is None:
        return contextlib.nullcontext()
    from aligngym.scenarios.campaign.engine import claim_directory
    from aligngym.scenarios.campaign.manifest import campaign_lock
    claim_directory(Path(out))
    return campaign_lock(Path(out))


def named_experiment(argv: list[str]) -> type | None:
    """The Experiment class a bench command names (its first word that is an experiment
    name), imported for its settings' options; None for other commands or none named."""
    if not argv or argv[0] != "bench":
        return None
    names = set(experiment_names())
    name = next((word for word in argv[1:] if word in names), None)
    if name is None:
        return None
    from aligngym.scenarios.experiments import experiment_class
    return experiment_class(name)
