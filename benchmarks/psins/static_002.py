"""Paper 002's static-base alignment against an independent one (GNU Octave, PSINS).

Question: do PSINS's own large-misalignment filters, on the same raw increments from the
same INS start, end as far from the static self-alignment floors as ours? This script

1. prepares episodes of ``paper002`` (the campaign's seeds, the paper's 58.5 deg start)
   and exports, per episode, the raw IMU increments of the fine alignment, the INS start
   C_b^p(0) (the truth turned by the start error, as our model starts), the position,
   and a P0/Q/R: the paper's (--priors paper: P0 45/45/60 deg, drift 0.1 deg/h,
   accelerometer bias 0.02 mg, densities 0.01 deg/h/sqrt(Hz) and 0.05 mg/sqrt(Hz),
   velocity 0.1 m/s) or the simulated sensors' own (--priors sensors: drift 0.01 deg/h,
   bias 50 ug, the IMU's noise densities, velocity 1 mm/s);
2. runs ours on the same episodes with the same priors (``ekf``, ``ukf``, ``sghkf-2``,
   ``sghkf-4``; ``scenarios.campaign.runs.run_filter``);
3. runs ``static_002_run.m`` in Octave: PSINS's ``alignvn_ekf`` (5 states: phi, dvE,
   dvN; its Jacob5 large-angle model; no bias states) and ``alignvn_stekf`` (12 states:
   phi, dv, eb, db) called as a library, one update per two IMU samples;
4. prints per episode and filter the final heading minus the episode's floor
   (-eps_E / (Omega cos L) + phi_N tan L, the biases rotated to n), the level minus its
   floors, and the filter's heading sigma.

Mapping: PSINS's attitude [pitch, roll, yaw] and ours follow the same convention
(``models.attitude``: C_b^n = Rz(yaw) Rx(pitch) Ry(roll), ENU, right-forward-up), so
its final attitude is compared with the truth by the same ``misalignment``. Its Rk =
wvn^2 / nts per 0.02 s step carries the same information per second as our one 1 s
measurement of sigma wvn. Not mapped: the models (PSINS's are its own), its 0.02 s steps
against our 1 s epochs, and alignvn_ekf holds no bias states (its heading settles on
the drift's floor by construction) and feeds back 91 % of the attitude each step; its
velocity P0 is fixed at 1 m/s (ours 0.1 m/s).

Usage:  python benchmarks/psins/static_002.py [--episodes 3] [--seed 0]
        [--priors paper|sensors] [--psins DIR] [--work DIR] [--keep]
Without octave or a PSINS snapshot the script says so in one line and exits 0.
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from psins_setup import add_psins_options, psins_workspace, run_octave

PSINS_FILES = ("base/align/alignvn_ekf.m", "base/align/alignvn_stekf.m",
               "base/base2/Jacob5.m")
OURS = ("ekf", "ukf", "sghkf-2", "sghkf-4")


def priors(exp, config, which: str):
    """(tuning for our model, the PSINS settings in SI) of the named priors."""
    from aligngym.models.units import deg_per_h, ug
    tuning = exp.tuning(config)
    if which == "sensors":
        gyro, accel = config.imu.gyro, config.imu.accel
        tuning = replace(tuning, gyro_bias_sigma=0.01 * deg_per_h, accel_bias_sigma=50 * ug,
                         gyro_psd=gyro.white_noise_density ** 2,
                         accel_psd=accel.white_noise_density ** 2,
                         measurement_sigma=1e-3)
    psins = {"phi0": np.asarray(tuning.euler_sigma),
             "eb": np.full(3, tuning.gyro_bias_sigma),
             "db": np.full(3, tuning.accel_bias_sigma),
             "web": np.full(3, np.sqrt(tuning.gyro_psd)),
             "wdb": np.full(3, np.sqrt(tuning.accel_psd)),
             "wvn": np.full(3, tuning.measurement_sigma)}
    return tuning, psins


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--priors", choices=("paper", "sensors"), default="paper")
    add_psins_options(ap)
    args = ap.parse_args(argv)

    with psins_workspace("static_002", args, PSINS_FILES) as ws:
        if ws is None:
            return 0
        from scipy.io import loadmat, savemat

        from aligngym.estimators.alignment import run_alignment
        from aligngym.estimators.euler_integrals import stack_integrals
        from aligngym.estimators.euler_kinematics import C_p_n
        from aligngym.estimators.euler_large import EulerLargeMisalignmentModel
        from aligngym.estimators.catalogue import make_filter
        from aligngym.estimators.metrics import misalignment, static_alignment_floor
        from aligngym.models.attitude import euler_to_dcm
        from aligngym.models.units import arcmin, deg
        from aligngym.scenarios.campaign import analyse_run, episode_seeds
        from aligngym.scenarios.campaign.episodes import simulate_screened
        from aligngym.scenarios.experiments import experiment

        t0 = time.time()
        exp = experiment("paper002")
        config = exp.scenario_config()
        tuning, settings = priors(exp, config, args.priors)
        seeds = episode_seeds(args.seed, args.episodes)
        episodes = [exp.prepare_episode(s) for s in seeds]
        starts = np.stack([e.start_error for e in episodes])
        C0 = np.swapaxes(C_p_n(starts), -1, -2) @ np.stack([e.C_b_n_true[0]
                                                             for e in episodes])
        n_fine = int(round(exp.fine_duration * config.imu_rate))
        paths = []
        for b, seed in enumerate(seeds):
            raw, _ = simulate_screened(config, seed)       # the increments prepared above
            path = ws.work / f"run_{b}.mat"
            savemat(path, {"dtheta": raw.dtheta[:n_fine], "dv": raw.dv[:n_fine],
                           "t": (np.arange(n_fine) + 1) * config.imu_interval,
                           "C0": C0[b], "pos": [episodes[b].lat, raw.truth.lon[0],
                                                episodes[b].h], **settings})
            paths.append(path)
        floors = np.stack([static_alignment_floor(e.C_s_n_true[-1], e.gyro_bias,
                                                  e.accel_bias, e.lat, e.h)
                           for e in episodes])
        print(f"paper002, {args.priors} priors: prepared and exported {len(seeds)} "
              f"episodes (seeds {seeds}), {time.time() - t0:.0f} s; work dir {ws.work}")

        rows = {}
        for name in OURS:
            model = EulerLargeMisalignmentModel(
                stack_integrals([e.integrals for e in episodes]), C0, tuning,
                feedback_below=exp.feedback_sigma_deg * deg)
            run = analyse_run(name, "x", run_alignment(make_filter(name), model),
                              episodes, exp)
            rows[f"ours {name}"] = (run.error_n[:, -1], run.result.sigma_n[:, -1, 2])
        print(f"our filters done, {time.time() - t0:.0f} s")

        outputs = [str(p).replace(".mat", "_out.mat") for p in paths]
        if not run_octave("static_002", ws, paths, outputs):
            return 1
        print(f"octave done, {time.time() - t0:.0f} s")
        for label, att_key, var_index in (("PSINS alignvn_ekf", "att_ekf", 7),
                                          ("PSINS alignvn_stekf", "att_stekf", 14)):
            finals, sigmas = [], []
            for b, out in enumerate(outputs):
                o = loadmat(out)
                att = o[att_key][-1, :3]
                C_est = euler_to_dcm(att)
                finals.append(misalignment(episodes[b].C_b_n_true[-1], C_est))
                key = "xp_ekf" if att_key == "att_ekf" else "xp_stekf"
                sigmas.append(np.sqrt(o[key][-1, var_index]))
            rows[label] = (np.stack(finals), np.array(sigmas))

        print("\n| filter | heading - floor per episode (arcmin) | RMS | level - floors, "
              "max (arcmin) | heading sigma (arcmin) |")
        print("|---|---|---|---|---|")
        for label, (final, sigma) in rows.items():
            d = (final - floors) / arcmin
            print(f"| {label} | " + ", ".join(f"{v:+.2f}" for v in d[:, 2])
                  + f" | {np.sqrt(np.mean(d[:, 2] ** 2)):.2f} | "
                  f"{np.abs(d[:, :2]).max():.2f} | {np.mean(sigma) / arcmin:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
