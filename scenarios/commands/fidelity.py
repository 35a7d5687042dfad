"""aligngym fidelity: the truth checked, a strapdown from the true state on ideal sensors
against it (the limits of SPEC's fidelity requirement)."""
from __future__ import annotations

import argparse

from aligngym.scenarios.commands.options import float_option, option_labels, seed_option


def add_parser(sub: argparse._SubParsersAction) -> None:
    """The ``fidelity`` command's options."""
    fid = sub.add_parser("fidelity", help="check the truth: strapdown from the true state on "
                         "ideal sensors must track it")
    fid.add_argument("scenario", help="scenario name or .toml file")
    fid.add_argument("--duration", type=float_option("--duration"), metavar="S",
                     help="run length, s (default: the scenario's)")
    fid.add_argument("--seed", type=seed_option, default=0, metavar="N",
                     help="episode seed (>= 0; default: 0)")
    fid.add_argument("--imu-rate", type=float_option("--imu-rate"), metavar="HZ",
                     help="IMU output rate, Hz (default: the scenario's)")


def run(args: argparse.Namespace) -> int:
    from aligngym.models.units import arcsec
    from aligngym.scenarios.config import load_scenario
    from aligngym.scenarios.fidelity import fidelity_errors

    config = load_scenario(args.scenario).with_options(args.duration, args.imu_rate,
                                                       labels=option_labels(args))
    err = fidelity_errors(config, seed=args.seed)
    print(f"{config.name}: strapdown vs truth over {config.duration:g} s at "
          f"{config.imu_rate:g} Hz, ideal sensors")
    print(f"  attitude {err['attitude_rad'] / arcsec:.4f} arcsec   velocity "
          f"{err['velocity_m_s'] * 1e3:.4f} mm/s   position {err['position_m']:.4f} m   "
          f"(limits 1 arcsec, 5 mm/s, 1 m)")
    ok = err["attitude_rad"] < arcsec and err["velocity_m_s"] < 5e-3 and err["position_m"] < 1.0
    print("  PASS" if ok else "  FAIL")
    return 0 if ok else 1
