"""The ``aligngym`` command line.

Imports stay inside the commands: help, version and option errors answer without
loading MuJoCo, SciPy or the estimators.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import fields
from typing import NoReturn, Sequence

from aligngym.scenarios.registry import SCENARIO_PAPER, experiment_names, scenario_names


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump) and exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


class _Version(argparse.Action):
    """--version: the installed package's version (read only when asked)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="print the version and exit"):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        from importlib.metadata import PackageNotFoundError, version
        try:
            text = version("aligngym")
        except PackageNotFoundError:
            text = "unknown (not installed)"
        print(f"aligngym {text}")
        parser.exit(0)


def _float_option(field: str, allow_zero: bool = False):
    """Parser of a finite number > 0 (>= 0 with allow_zero) for the option ``field``."""
    return _number_option(field, 0.0, strict=not allow_zero)


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seed must be an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"--seed must be an integer >= 0, got {value}")
    return value


def _bench_epilog(experiment: type | None) -> str:
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


def _number_option(flag: str, minimum: float | None, strict: bool = False):
    """Parser of a finite number >= minimum (> with strict; any finite number without a
    minimum) for the option ``flag``."""
    bound = ("finite" if minimum is None else f"{'>' if strict else '>='} {minimum:g}")

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{flag} must be a number, got {text!r}") from None
        below = minimum is not None and (value <= minimum if strict else value < minimum)
        if not math.isfinite(value) or below:
            raise argparse.ArgumentTypeError(f"{flag} must be {bound}, got {text}")
        return value
    return parse


def _add_setting_options(bench: argparse.ArgumentParser, experiment: type) -> None:
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


def build_parser(bench_details: bool = False, experiment: type | None = None
                 ) -> argparse.ArgumentParser:
    """The parser; bench_details: list the filters in ``bench --help`` (imports them);
    experiment: the Experiment class bench names, whose declared settings become options
    (imported only when bench names one)."""
    parser = _Parser(prog="aligngym", description="SINS initial-alignment scenario testbed")
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", parser_class=_Parser, metavar="COMMAND")

    sim = sub.add_parser("simulate", help="simulate one episode and write its data (.npz)")
    sim.add_argument("scenario", help="scenario name (" + ", ".join(scenario_names())
                     + ") or a .toml file")
    sim.add_argument("--duration", type=_float_option("--duration"), metavar="S",
                     help="run length, s (default: the scenario's)")
    sim.add_argument("--seed", type=_seed, default=0, metavar="N",
                     help="episode seed (>= 0; default: 0)")
    sim.add_argument("--ideal", action="store_true", help="error-free sensors")
    sim.add_argument("--imu-rate", type=_float_option("--imu-rate"), metavar="HZ",
                     help="IMU output rate, Hz (default: the scenario's)")
    sim.add_argument("--out", required=True, metavar="FILE.npz",
                     help="output file (arrays and units: README, Data files)")

    fid = sub.add_parser("fidelity", help="check the truth: strapdown from the true state on "
                         "ideal sensors must track it")
    fid.add_argument("scenario", help="scenario name or .toml file")
    fid.add_argument("--duration", type=_float_option("--duration"), metavar="S",
                     help="run length, s (default: the scenario's)")
    fid.add_argument("--seed", type=_seed, default=0, metavar="N",
                     help="episode seed (>= 0; default: 0)")
    fid.add_argument("--imu-rate", type=_float_option("--imu-rate"), metavar="HZ",
                     help="IMU output rate, Hz (default: the scenario's)")
    bench = sub.add_parser("bench", help="run an experiment's Monte Carlo comparison",
                           epilog=_bench_epilog(experiment) if bench_details else None,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    defaults = {} if experiment is None else {f.name: f.default for f in fields(experiment)}
    bench.add_argument("paper", choices=list(experiment_names()), metavar="EXPERIMENT",
                       help="the experiment: " + ", ".join(experiment_names())
                       + "; 'bench EXPERIMENT --help' lists its settings")
    bench.add_argument("--episodes", type=_positive_int("--episodes"), metavar="N",
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
    bench.add_argument("--seed", type=_seed, default=0, metavar="S",
                       help="campaign seed (default: 0)")
    bench.add_argument("--filters", help="comma-separated filter names (default: the "
                       "experiment's" + ("" if "default_filters" not in defaults else
                                         ", " + ",".join(defaults["default_filters"])) + ")")
    if experiment is not None:
        _add_setting_options(bench, experiment)
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
    bench.add_argument("--workers", type=_positive_int("--workers"), metavar="K",
                       help="parallel processes, or CPUs of a local Ray instance "
                       "(default: all cores)")
    bench.add_argument("--executor", choices=["local", "ray"], default="local",
                       help="where episodes are prepared: local processes, or Ray tasks "
                       "(pip install -e '.[ray]'; default: local)")
    bench.add_argument("--address", metavar="ADDR",
                       help="with --executor ray: the cluster to join ('auto', "
                       "'ray://HOST:10001'; default: start a local instance)")
    rep_help = ("write DIR/report.html: one self-contained page of a campaign directory "
                "(settings, tables, results, figures)")
    ren = sub.add_parser("render", help="render an episode of a scenario as a video (MP4): "
                         "the carrier, its IMU's close-up, and an estimator's errors")
    ren.add_argument("scenario", help="scenario name or .toml file")
    ren.add_argument("--start", type=_float_option("--start", allow_zero=True), default=0.0,
                     metavar="S", help="time of the episode the video starts at, s (default: 0)")
    ren.add_argument("--duration", type=_float_option("--duration"), default=30.0, metavar="S",
                     help="seconds of the episode to show (default: 30)")
    ren.add_argument("--seed", type=_seed, default=0, metavar="N",
                     help="episode seed (>= 0; default: 0)")
    ren.add_argument("--estimator", metavar="NAME",
                     help="a filter whose attitude errors the overlay shows (scenarios with "
                          "an alignment pipeline)")
    ren.add_argument("--fps", type=_float_option("--fps"), default=20.0, metavar="HZ",
                     help="frames per second of the episode's time (default: 20)")
    ren.add_argument("--size", default="480x640", metavar="HxW",
                     help="frame height x width, pixels (default: 480x640)")
    ren.add_argument("--out", required=True, metavar="FILE.mp4",
                     help="the video file (FILE.png: the frame at --start alone)")

    rep = sub.add_parser("report", help=rep_help, description=rep_help)
    rep.add_argument("dir", metavar="DIR", help="a bench --out directory (or a directory of "
                     "them, as bench paper004 --swing all writes)")
    rpr_help = ("run each paper's claims (from its text) on the testbed and print each "
                "beside what was measured, with a verdict: reproduced, or not and why")
    rpr = sub.add_parser("reproduce", help=rpr_help, description=rpr_help)
    rpr.add_argument("papers", metavar="PAPER", help="an experiment (" +
                     ", ".join(experiment_names()) + "), a comma-separated list, or all")
    rpr.add_argument("--episodes", type=_positive_int("--episodes"), metavar="N",
                     help="episodes per campaign (default: each paper's own, "
                     "Experiment.reproduce; all of them take about 14 min on 2 cores)")
    rpr.add_argument("--seed", type=_seed, default=None, metavar="S",
                     help="campaign seed (default: each paper's own)")
    rpr.add_argument("--out", metavar="DIR", help="write DIR/claims.md (the page, with the "
                     "figures) and each campaign's outputs under DIR/PAPER/")
    rpr.add_argument("--workers", type=_positive_int("--workers"), metavar="K",
                     help="parallel processes (default: all cores)")
    bank_help = ("simulate a split's episodes of a scenario once into an episode bank, which "
                 "the env's reset loads (gym.make(..., bank=DIR, split=SPLIT))")
    bnk = sub.add_parser("bank", help=bank_help, description=bank_help)
    bnk.add_argument("scenario", metavar="SCENARIO", help="scenario name (" + ", ".join(
        scenario_names()) + ") or a .toml file that names an experiment")
    bnk.add_argument("--out", required=True, metavar="DIR", help="the bank directory")
    bnk.add_argument("--split", choices=["train", "validation", "test"], default="train",
                     help="the seed split (train [0, 1.6e9), validation [1.6e9, 1.8e9), "
                     "test [1.8e9, 2^31 - 1); default: train)")
    bnk.add_argument("--episodes", type=_positive_int("--episodes"), default=100,
                     metavar="N", help="episodes: the split's seeds FIRST .. FIRST + N - 1 "
                     "(default: 100)")
    bnk.add_argument("--first", type=_positive_int("--first", minimum=0), default=0,
                     metavar="K",
                     help="the first episode of the split (default: 0)")
    bnk.add_argument("--episode-length", type=_float_option("--episode-length"),
                     default=600.0, metavar="S", help="the env's episode_length, s "
                     "(default: 600)")
    bnk.add_argument("--epoch-length", type=_float_option("--epoch-length"), default=1.0,
                     metavar="S", help="the env's epoch_length, s (default: 1)")
    bnk.add_argument("--set", action="append", metavar="NAME=VALUE",
                     help="a setting of the scenario's experiment, as the env's settings "
                     "(e.g. coarse_duration=60); repeatable")
    bnk.add_argument("--workers", type=_positive_int("--workers"), metavar="K",
                     help="parallel processes, or CPUs of a local Ray instance "
                     "(default: all cores)")
    bnk.add_argument("--executor", choices=["local", "ray"], default="local",
                     help="local processes or Ray tasks (default: local)")
    bnk.add_argument("--address", metavar="ADDR", help="with --executor ray: the cluster")
    reg = sub.add_parser("regress", help="run each paper's small fixed-seed campaign against "
                         "its stored baseline; exit 1 when a metric moved beyond tolerance")
    reg.add_argument("--papers", default=None,
                     help="comma-separated experiments (default: every one with a "
                     "regression campaign: " + ",".join(experiment_names()) + ")")
    reg.add_argument("--update", action="store_true",
                     help="store this run's metrics as the new baselines (default: compare)")
    reg.add_argument("--baselines", metavar="DIR",
                     help="baseline directory (default: the baselines shipped with the package)")
    reg.add_argument("--workers", type=_positive_int("--workers"), metavar="K",
                     help="parallel processes (default: all cores)")
    return parser


def _positive_int(field: str, minimum: int = 1):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{field} must be an integer >= {minimum}, "
                                              f"got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{field} must be an integer >= {minimum}, "
                                              f"got {value}")
        return value
    return parse


def _setting_value(text: str):
    """A setting's value as written on the command line: a TOML value (number,
    true/false, "string", [list] -> tuple), else the plain string; "none" is None."""
    import tomllib

    if text.strip().lower() == "none":
        return None
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text
    return tuple(value) if isinstance(value, list) else value


def _settings_of(cls: type, args: argparse.Namespace) -> dict:
    """The experiment settings bench's options and --set NAME=VALUE give, each checked to be
    a setting (a dataclass field) of the experiment class; values read by
    ``_setting_value`` (their types and ranges are checked when the experiment is made,
    ``campaign.experiment.validate_settings``). Records in args.setting_labels how each was
    written (--NAME, --set NAME), for the error that names it."""
    from aligngym.scenarios.config import ConfigError
    known = {f.name: f for f in fields(cls)}
    labels = getattr(args, "setting_labels", {})
    out = {}
    for f in cls.flagged_settings():
        given = getattr(args, f.name, None)
        if given is not None:
            out[f.name] = given if f.metadata["choices"] else _setting_value(given)
            labels[f.name] = "--" + f.name.replace("_", "-")
    for item in args.set or ():
        name, sep, text = item.partition("=")
        name = name.strip().replace("-", "_")
        if not sep or name not in known:
            raise ConfigError(f"--set {item!r}: need NAME=VALUE with NAME a setting of "
                              f"{args.paper}: " + ", ".join(sorted(known)))
        out[name] = _setting_value(text)
        labels[name] = f"--set {name}"
    args.setting_labels = labels
    return out


def _check_writable(path_text: str, option: str) -> None:
    """Before any work: the output file can be written (its directory exists or can be
    made, and is writable; an existing file is writable)."""
    import os
    from pathlib import Path

    from aligngym.scenarios.config import ConfigError

    path = Path(path_text)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"{option} {path}: cannot create {path.parent} "
                          f"({exc.strerror})") from None
    if path.is_dir() or not os.access(path if path.exists() else path.parent, os.W_OK):
        raise ConfigError(f"{option} {path}: cannot write this file")


def _cmd_bench(args: argparse.Namespace) -> int:
    from pathlib import Path

    from aligngym.scenarios.campaign import run_campaign
    from aligngym.scenarios.campaign.engine import check_campaign_memory
    from aligngym.scenarios.config import ConfigError
    from aligngym.scenarios.experiments import experiment, experiment_class
    from aligngym.scenarios.report import format_tables, write_outputs

    if args.resume and not args.out:
        raise ConfigError("--resume needs --out DIR (where the finished episodes are)")
    cls = experiment_class(args.paper)
    settings = {} if args.scenario is None else {"scenario": args.scenario}
    settings.update(_settings_of(cls, args))
    sweep = next((f for f in cls.flagged_settings()
                  if f.metadata["sweep"] and settings.get(f.name) == "all"), None)
    levels = [None] if sweep is None else list(sweep.metadata["choices"])  # one campaign each
    episodes = args.episodes or cls.default_episodes
    experiments = []        # every campaign's settings checked before anything is written
    for level in levels:
        exp = experiment(args.paper, args.setup,
                         **(settings if level is None else {**settings, sweep.name: level}))
        filters = (list(exp.default_filters) if args.filters is None
                   else [f.strip() for f in args.filters.split(",") if f.strip()])
        if not filters:
            raise ConfigError("--filters is empty; give at least one filter name")
        exp.check(exp.scenario_config())
        exp.check_filters(filters)
        check_campaign_memory(exp, episodes, filters)   # before --out is created
        experiments.append((level, exp, filters))
    if args.json:
        _check_writable(args.json, "--json")
    summaries, elapsed = [], 0.0
    for level, exp, filters in experiments:
        out = args.out if level is None or args.out is None else str(Path(args.out) / level)
        start = time.perf_counter()
        with _holding(out):            # the campaign and its outputs: one writer
            result = run_campaign(exp, episodes=episodes, seed=args.seed, filters=filters,
                                  out_dir=out, resume=args.resume, workers=args.workers,
                                  executor=args.executor, address=args.address,
                                  force=args.force)
            elapsed += time.perf_counter() - start
            print(format_tables(result))
            written = write_outputs(result, out, args.json if level is None else None,
                                    command=args.command_line, figures=not args.no_figures,
                                    processes=args.workers)
        for path in written:
            print(f"wrote {path}")
        summaries.append(result.summary())
    if sweep is not None and args.json:
        from aligngym.scenarios.atomic import write_json
        write_json(args.json, cls.merge_sweep(sweep.name, summaries))
        print(f"wrote {args.json}")
    print(f"{episodes} episodes x {len(filters)} filters x {len(exp.starts)} start(s)"
          + (f" x {len(levels)} {sweep.name} values" if sweep is not None else "")
          + f" in {elapsed:.1f} s")
    return 0


def _holding(out: str | None):
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


def _interrupted(args: argparse.Namespace) -> str:
    """The one line for Ctrl-C: what was kept and how to continue."""
    from pathlib import Path

    if args.command != "bench":
        return "aligngym: interrupted; no output was written (an existing one is unchanged)"
    if not args.out:
        return "aligngym: interrupted; nothing was kept (bench without --out keeps no episodes)"
    kept = len(list(Path(args.out).glob("**/episodes/seed_*.npz")))
    again = [w for w in args.command_line if w not in ("--resume", "--force")] + ["--resume"]
    return (f"aligngym: interrupted; {kept} finished episode(s) kept in {args.out}; "
            f"continue with: {' '.join(again)}")


def _option_labels(args: argparse.Namespace) -> dict[str, str]:
    """The scenario fields --duration and --imu-rate override, by option (errors name
    what the user wrote)."""
    return {field: option for field, option in (("duration", "--duration"),
                                                 ("imu_rate", "--imu-rate"))
            if getattr(args, field) is not None}


def _cmd_simulate(args: argparse.Namespace) -> int:
    from aligngym.models.attitude import quat_to_euler
    from aligngym.models.units import deg
    from aligngym.scenarios.config import load_scenario
    from aligngym.scenarios.simulate import simulate

    config = load_scenario(args.scenario).with_options(args.duration, args.imu_rate,
                                                       labels=_option_labels(args))
    start = time.perf_counter()
    episode = simulate(config, seed=args.seed, ideal=args.ideal)
    path = episode.save(args.out)
    elapsed = time.perf_counter() - start
    euler = quat_to_euler(episode.truth.q_b_n)
    print(f"{config.name}: {config.duration:g} s, IMU {config.imu_rate:g} Hz "
          f"({episode.dtheta.shape[0]} samples, {'ideal' if args.ideal else config.imu_preset}),"
          f" seed {args.seed}, {elapsed:.2f} s wall")
    print("  hull pitch/roll/yaw range: "
          + ", ".join(f"[{lo:.1f}, {hi:.1f}] deg" for lo, hi in
                      zip(euler.min(0) / deg, euler.max(0) / deg)))
    print(f"  wrote {path}")
    return 0


def _cmd_fidelity(args: argparse.Namespace) -> int:
    from aligngym.models.units import arcsec
    from aligngym.scenarios.config import load_scenario
    from aligngym.scenarios.fidelity import fidelity_errors

    config = load_scenario(args.scenario).with_options(args.duration, args.imu_rate,
                                                       labels=_option_labels(args))
    err = fidelity_errors(config, seed=args.seed)
    print(f"{config.name}: strapdown vs truth over {config.duration:g} s at "
          f"{config.imu_rate:g} Hz, ideal sensors")
    print(f"  attitude {err['attitude_rad'] / arcsec:.4f} arcsec   velocity "
          f"{err['velocity_m_s'] * 1e3:.4f} mm/s   position {err['position_m']:.4f} m   "
          f"(limits 1 arcsec, 5 mm/s, 1 m)")
    ok = err["attitude_rad"] < arcsec and err["velocity_m_s"] < 5e-3 and err["position_m"] < 1.0
    print("  PASS" if ok else "  FAIL")
    return 0 if ok else 1


def _cmd_render(args: argparse.Namespace) -> int:
    from aligngym.scenarios.config import ConfigError, load_scenario
    from aligngym.scenarios.render import check_size
    from aligngym.scenarios.video import render_video

    try:
        size = tuple(int(v) for v in args.size.lower().split("x"))
    except ValueError:
        size = ()
    if len(size) != 2:
        raise ConfigError(f"--size must be HxW in pixels, e.g. 480x640, got {args.size!r}")
    check_size(size)
    if args.estimator:
        from aligngym.estimators.catalogue import UnknownFilter, filter_entry
        try:
            filter_entry(args.estimator)
        except UnknownFilter as exc:
            raise ConfigError(f"--estimator: {exc}") from None
    scenario = load_scenario(args.scenario)
    # A PNG needs the run up to --start only; the run is a whole number of IMU intervals.
    end = args.start + (0.0 if args.out.lower().endswith(".png") else args.duration)
    end = max(math.ceil(end * scenario.imu_rate - 1e-9), 2) / scenario.imu_rate
    try:
        config = scenario.with_options(duration=end)
    except ConfigError as exc:
        raise ConfigError(f"render to {end:g} s: {exc}") from None
    try:
        done = render_video(config, args.out, seed=args.seed, estimator=args.estimator,
                            fps=args.fps, size=size, start=args.start)
    except OSError as exc:
        raise ConfigError(f"--out {args.out}: {exc.strerror or exc}") from None
    print(f"wrote {done['path']}: {done['frames']} frames, {done['seconds']:.1f} s "
          f"({done['seconds_per_frame'] * 1e3:.0f} ms per frame)")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from aligngym.scenarios.html_report import write_report

    start = time.perf_counter()
    path = write_report(args.dir)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB, "
          f"{time.perf_counter() - start:.2f} s)")
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from pathlib import Path

    from aligngym.scenarios.config import ConfigError
    from aligngym.scenarios.reproduce import reproduce

    names = experiment_names()
    papers = (list(names) if args.papers == "all"
              else [p.strip() for p in args.papers.split(",") if p.strip()])
    unknown = [p for p in papers if p not in names]
    if unknown or not papers:
        raise ConfigError(f"reproduce: unknown paper {(unknown or [args.papers])[0]!r}; "
                          "valid: all, " + ", ".join(names))
    if args.episodes is not None:        # every claim campaign held, before --out is made
        from aligngym.scenarios.campaign.engine import check_campaign_memory
        from aligngym.scenarios.experiments import experiment, experiment_class
        for paper in papers:
            for claim in experiment_class(paper).claims:
                exp = experiment(paper, claim.setup, **claim.settings)
                check_campaign_memory(exp, args.episodes,
                                      list(claim.filters) or list(exp.default_filters))
    if args.out:
        _check_writable(str(Path(args.out) / "claims.md"), "--out")
    _, text = reproduce(papers, episodes=args.episodes, seed=args.seed,
                        out_dir=Path(args.out) if args.out else None, workers=args.workers,
                        log=lambda line: print(line, flush=True))
    print(text)
    return 0


def _cmd_bank(args: argparse.Namespace) -> int:
    import os

    from aligngym.scenarios.bank import EpisodeBank, check_split, split_seeds
    from aligngym.scenarios.campaign.engine import check_seed_memory
    from aligngym.scenarios.config import load_scenario
    from aligngym.scenarios.experiments import env_experiment, experiment_class

    config = load_scenario(args.scenario)
    args.paper = config.experiment or "the scenario's experiment"
    args.setting_labels = {"fine_duration": "--episode-length", "filter_step": "--epoch-length"}
    settings = _settings_of(experiment_class(config.experiment), args) if (
        config.experiment and args.set) else {}
    lo, hi = check_split(args.split)
    if args.first + args.episodes <= hi - lo:     # a seed list the machine can hold
        check_seed_memory(args.episodes)
    seeds = split_seeds(args.split, args.episodes, args.first)
    experiment = env_experiment(args.scenario, args.episode_length, args.epoch_length,
                                settings, config=config)
    bank = EpisodeBank(args.out, experiment)
    start = time.perf_counter()
    simulated = bank.build(seeds, workers=args.workers or os.cpu_count() or 1,
                           executor=args.executor, address=args.address)
    print(f"{bank.directory}: {len(seeds)} {args.split} episodes (seeds {seeds[0]} .. "
          f"{seeds[-1]}), {simulated} simulated, {len(seeds) - simulated} already there; "
          f"{time.perf_counter() - start:.1f} s")
    return 0


def _cmd_regress(args: argparse.Namespace) -> int:
    from aligngym.scenarios.regress import BASELINE_DIR, campaigns, regress

    papers = (list(campaigns()) if args.papers is None
              else [p.strip() for p in args.papers.split(",") if p.strip()])
    passed, report = regress(papers, update=args.update,
                             directory=args.baselines or BASELINE_DIR, workers=args.workers)
    print(report)
    return 0 if passed else 1


def _bench_experiment(argv: list[str]) -> type | None:
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


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(bench_details="bench" in argv and ("-h" in argv or "--help" in argv),
                          experiment=_bench_experiment(argv))
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        hint = (f" ('aligngym bench {args.paper} --help' lists its settings; any other is "
                "--set NAME=VALUE)" if args.command == "bench" else "")
        parser.error(f"unrecognized arguments: {' '.join(unknown)}{hint}")
    args.command_line = ["aligngym", *argv]
    if args.command is None:      # a usage error: the usage, and status 2
        parser.print_help()
        return 2
    from aligngym.scenarios.config import ConfigError, SettingError
    from aligngym.scenarios.interrupts import remember_interrupts

    commands = {"simulate": _cmd_simulate, "bench": _cmd_bench, "regress": _cmd_regress,
                "reproduce": _cmd_reproduce, "bank": _cmd_bank, "report": _cmd_report,
                "render": _cmd_render, "fidelity": _cmd_fidelity}
    try:
        with remember_interrupts():
            return commands[args.command](args)
    except ConfigError as exc:
        if isinstance(exc, SettingError):    # a setting: named as the user wrote it
            labels = getattr(args, "setting_labels", {})
            exc = exc.as_written(lambda name: labels.get(name, name))
        print(f"aligngym: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(_interrupted(args), file=sys.stderr)
        return 130
    except OSError as exc:         # a full disk, a file removed under us: path and cause
        where = exc.filename or "an output"
        print(f"aligngym: error: {where}: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
