"""aligngym render: an episode of a scenario as a video (MP4) or a frame (PNG)."""
from __future__ import annotations

import argparse
import math

from aligngym.scenarios.commands.options import float_option, seed_option


def add_parser(sub: argparse._SubParsersAction) -> None:
    """The ``render`` command's options."""
    ren = sub.add_parser("render", help="render an episode of a scenario as a video (MP4): "
                         "the carrier, its IMU's close-up, and an estimator's errors")
    ren.add_argument("scenario", help="scenario name or .toml file")
    ren.add_argument("--start", type=float_option("--start", allow_zero=True), default=0.0,
                     metavar="S", help="time of the episode the video starts at, s (default: 0)")
    ren.add_argument("--duration", type=float_option("--duration"), default=30.0, metavar="S",
                     help="seconds of the episode to show (default: 30)")
    ren.add_argument("--seed", type=seed_option, default=0, metavar="N",
                     help="episode seed (>= 0; default: 0)")
    ren.add_argument("--estimator", metavar="NAME",
                     help="a filter whose attitude errors the overlay shows (scenarios with "
                          "an alignment pipeline)")
    ren.add_argument("--fps", type=float_option("--fps"), default=20.0, metavar="HZ",
                     help="frames per second of the episode's time (default: 20)")
    ren.add_argument("--size", default="480x640", metavar="HxW",
                     help="frame height x width, pixels (default: 480x640)")
    ren.add_argument("--out", required=True, metavar="FILE.mp4",
                     help="the video file (FILE.png: the frame at --start alone)")


def run(args: argparse.Namespace) -> int:
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
