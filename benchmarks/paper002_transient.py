"""Paper 002: what sets the heading residual each filter keeps after the large-angle
transient (issue 42), on error-free sensors (every floor 0), 600 s, the paper's model.

On a static base the heading and the east drift are one observable combination,
c = eps_E + Omega cos L phi_U; the split between them comes from the priors alone. An
exact Bayesian estimator that sees c exactly keeps E[phi_U | c] = phi_U (1 - k), a
residual k phi_U with k = s_eps^2 / (s_eps^2 + (Omega cos L s_phi)^2) (s_eps: the drift
prior, s_phi: P0's heading sigma): the "linear-Gaussian residual" column. What a filter
keeps beyond it is its own Gaussian approximation of the transient. The cases vary the
rule's accuracy (sparse grids of levels 2-5, the tensor GH-3 with 3^10 points), the
actual start, P0's size (the sigma points spread over P0, not over the actual error) and
the drift prior.

Run: python benchmarks/paper002_transient.py [--episodes N] [--cases a,b]
Prints one table per case (final heading error, arcmin, per episode; the filter's
sigma): docs/paper002.md's "What is left" (its table gives one value where the two
episodes agree to 0.1', both otherwise).
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from aligngym.estimators.alignment import run_alignment
from aligngym.estimators.euler_integrals import stack_integrals
from aligngym.estimators.euler_kinematics import C_p_n
from aligngym.estimators.euler_large import PAPER002, EulerLargeMisalignmentModel
from aligngym.estimators.catalogue import make_filter
from aligngym.models.earth import OMEGA_IE
from aligngym.models.units import arcmin, deg, deg_per_h
from aligngym.scenarios.campaign import analyse_run, episode_seeds
from aligngym.scenarios.experiments import experiment
from aligngym.sensors.imu import ImuSpec

CASES = {
    # name: (actual heading start deg, P0 sigmas (level, heading) deg, drift prior deg/h,
    #        filters)
    "paper": (58.5, (45.0, 60.0), 0.1,
              ["ekf", "ukf", "sghkf-2", "sghkf-3", "sghkf-4", "sghkf-5", "ghkf-3"]),
    "small-start": (5.0, (45.0, 60.0), 0.1, ["ekf", "ukf", "sghkf-2", "sghkf-4"]),
    "small-start-matched-p0": (5.0, (1.0, 5.0), 0.1, ["ekf", "ukf", "sghkf-2", "sghkf-4"]),
    "tight-drift": (58.5, (45.0, 60.0), 0.03, ["ekf", "sghkf-2", "sghkf-4"]),
    "loose-drift": (58.5, (45.0, 60.0), 0.3, ["ekf", "sghkf-2", "sghkf-4"]),
}


def run_case(name: str, episodes: int) -> None:
    start_deg, (level_deg, heading_deg), drift, filters = CASES[name]
    exp = experiment("paper002", azimuth_error_deg=start_deg)
    config = replace(exp.scenario_config(), imu=ImuSpec())          # error-free
    eps = [exp.prepare_episode(s, config) for s in episode_seeds(5, episodes)]
    tuning = replace(PAPER002, euler_sigma=(level_deg * deg, level_deg * deg,
                                            heading_deg * deg),
                     gyro_bias_sigma=drift * deg_per_h)
    start = np.stack([e.start_error for e in eps])
    C0 = np.swapaxes(C_p_n(start), -1, -2) @ np.stack([e.C_b_n_true[0] for e in eps])
    lat = eps[0].lat
    k = tuning.gyro_bias_sigma ** 2 / (tuning.gyro_bias_sigma ** 2 + (
        OMEGA_IE * np.cos(lat) * tuning.euler_sigma[2]) ** 2)
    bayes = k * start[:, 2] / arcmin
    print(f"\n{name}: start {start_deg:g} deg heading (level drawn, 1 deg), P0 sigma "
          f"{level_deg:g}/{level_deg:g}/{heading_deg:g} deg, drift prior {drift:g} deg/h; "
          f"linear-Gaussian residual k phi_U = "
          + ", ".join(f"{b:+.3f}'" for b in bayes))
    print("| filter | points | final heading error per episode (arcmin) | RMS | sigma "
          "| s |")
    print("|---|---|---|---|---|---|")
    for filt in filters:
        model = EulerLargeMisalignmentModel(stack_integrals([e.integrals for e in eps]),
                                            C0, tuning, feedback_below=5 * deg)
        began = time.perf_counter()
        f = make_filter(filt)
        result = run_alignment(f, model)
        seconds = time.perf_counter() - began
        run = analyse_run(filt, "x", result, eps, exp)
        final = run.error_n[:, -1, 2] / arcmin
        points = f.rule.point_count(model.initial()[0].shape[-1])
        print(f"| {filt} | {points} | " + ", ".join(f"{v:+.2f}" for v in final)
              + f" | {np.sqrt(np.mean(final ** 2)):.2f} | "
              f"{np.mean(result.sigma_n[:, -1, 2]) / arcmin:.1f} | {seconds:.0f} |",
              flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--cases", default=",".join(CASES))
    args = parser.parse_args(argv)
    for name in args.cases.split(","):
        run_case(name, args.episodes)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
