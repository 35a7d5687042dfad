"""Paper 004's STEKF, UKF (kappa = 3 - n) and EKF against an independent implementation
(GNU Octave, PSINS toolbox).

Question: do our ``stekf``, ``ukf-3n`` and ``ekf`` (paper 004's filters on the
rotation-vector GNSS model, ``estimators.rotation_vector``) align as an independent
strapdown and filter library does on the same data? This script

1. prepares a few episodes of ``paper004`` (the campaign's seeds, its start: "large"
   unless --set says otherwise) and exports, per episode, everything the fine alignment
   consumes: the raw IMU increments, the INS start (attitude, velocity, position), the
   GNSS fixes, the lever arm and the indexer's rate at every epoch boundary (IMU frame),
   P0, Q, R, the epoch length and the ellipsoid (``<work>/run_<b>.mat``);
2. runs our ``stekf``, ``ukf-3n`` and ``ekf`` on the same episodes
   (``scenarios.campaign.runs.run_filter``);
3. runs ``filters_004_run.m`` in Octave: a PSINS strapdown (``insinit``/``insupdate``)
   and, called as a library, PSINS's STEKF (``kfupdate`` with ``etmST`` per INS step),
   its EKF (``kfupdate`` with its standard 15-state ``etm``) and its UKF (``ukf``/
   ``ukfUT``, alpha 1, beta 2, kappa = 3 - n) on the classic large-angle model of
   ``gnss_004_fx.m``/``gnss_004_hx.m`` (written from ALGORITHMS (6.1), (6.2), (6.5));
   the measurement (antenna velocity and position, lever arm turning with the indexer)
   and the closed-loop feedback of every epoch with our reset rule P <- G P G^T (G from
   PSINS's ``rv2J``/``rv2m``); plus ``stekf-native``, PSINS's STEKF with P kept at the
   reset (as in its demo ``test_SINS_GPS_156_STEKF``);
4. prints, per episode and filter, the heading error, its sigma (arcmin) and the 9-state
   NEES at a few scenario times, ours against PSINS, then per filter the RMS heading over
   paper 004's accuracy window (600-2000 s), the mean NEES over it and |ours - PSINS|.

Usage:  python benchmarks/psins/filters_004.py [--episodes 2] [--seed 0] [--set KEY=VALUE]
        [--psins DIR] [--work DIR] [--keep]
PSINS: --psins or $PSINS_DIR (a work tree with base/), else the bare snapshot $PSINS_GIT
(default /work/.mirror/WangShanpeng+PSINS/repo), whose base/ is extracted to a temp dir.
Without octave or a PSINS snapshot the script says so in one line and exits 0.
Runtime: about 15 min per episode, 30 min for the default two (preparation and our
three filters ~30 s per episode; Octave ~15 min per episode: STEKF 3, UKF 6, EKF 3,
native STEKF 4.5 min); prefix it with `nice -n 19`.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from psins_setup import add_psins_options, psins_workspace, run_octave

PSINS_FILES = ("base/kf/ukf.m", "base/base2/etmST.m")
"""What the check calls in PSINS (under its tree)."""
ARCMIN = np.pi / 180 / 60
TIMES = (60.0, 120.0, 300.0, 600.0, 1000.0, 1500.0, 2000.0)
"""Scenario times (s) of the per-episode table (the fine stage starts at 60 s)."""
OURS = ("stekf", "ukf-3n", "ekf")
PSINS_FILTERS = ("stekf", "ukf-3n", "ekf", "stekf-native")
"""PSINS runs; each but stekf-native has its counterpart of the same name in OURS."""


def export_runs(exp, episodes, start_error: np.ndarray, work: Path) -> list[Path]:
    """One .mat per episode with what the fine alignment consumes (SI, ENU, IMU frame):
    increments (K*S, 3) rad and m/s, INS start C0 = C_s^n, v0 m/s, pos0 (lat, lon rad,
    h m), GNSS fixes at the K+1 boundaries, lever (K+1, 3) m IMU to antenna and omega_bs
    (K+1, 3) rad/s the indexer's rate, P0, the white-noise densities qdiag (Q = diag(qdiag)
    T), R, T s, and the ellipsoid (WGS-84 a, f, earth rate) for PSINS's glvf."""
    from scipy.io import savemat
    from aligngym.estimators.rotation_vector_dynamics import DP, DV, EPS, NABLA, PHI
    from aligngym.models import earth
    from aligngym.models.attitude import quat_to_dcm

    model = exp.model(episodes, start_error)
    if model.feedback_below is not None:
        raise SystemExit("filters_004: the model's feedback is not every epoch; the Octave "
                         "side implements only that rule")
    inp, tu = model.inputs, model.tuning
    _, P0 = model.initial()
    q = np.zeros(15)
    q[PHI], q[DV] = tu.gyro_noise_density ** 2, tu.accel_noise_density ** 2
    q[EPS], q[NABLA] = tu.gyro_bias_walk ** 2, tu.accel_bias_walk ** 2
    q[DP] = 0.0
    R = np.diag([tu.gnss_velocity_sigma ** 2] * 3 + [tu.gnss_position_sigma_h ** 2] * 2
                + [tu.gnss_position_sigma_v ** 2])
    B, K, S = inp.dtheta.shape[:3]
    paths = []
    for b in range(B):
        path = work / f"run_{b}.mat"
        savemat(path, {
            "K": K, "S": S, "T": model.T, "dt": inp.imu_dt,
            "dtheta": inp.dtheta[b].reshape(-1, 3), "dv": inp.dv[b].reshape(-1, 3),
            "C0": quat_to_dcm(inp.q_b_n0[b]), "v0": inp.v_n0[b],
            "pos0": np.array([inp.lat0[b], inp.lon0[b], inp.h0[b]]),
            "gps_lat": inp.gps_lat[b], "gps_lon": inp.gps_lon[b], "gps_h": inp.gps_h[b],
            "gps_v": inp.gps_v_n[b], "lever": inp.lever_arm_b[b],
            "omega_bs": inp.omega_bs_s[b], "P0": P0[b], "qdiag": q, "R": R,
            "Re": earth.A, "flattening": earth.F, "wie": earth.OMEGA_IE,
            "filters": ",".join(PSINS_FILTERS)})
        paths.append(path)
    return paths


def psins_result(path: Path, name: str, episode, exp) -> SimpleNamespace:
    """Heading error (K+1,) rad, its sigma (K+1,) rad and the 9-state NEES (K+1,) of one
    Octave run, with our metrics (misalignment, experiment.nees)."""
    from scipy.io import loadmat
    from aligngym.estimators.metrics import misalignment

    o = loadmat(str(path).replace(".mat", f"_{name}_out.mat"))
    C, x, P = o["C"], o["x"], o["P"]
    K1 = C.shape[0]
    err = misalignment(episode.C_s_n_true[:K1], C)
    result = SimpleNamespace(t=episode.t[:K1], x=x[None], C_s_n=C[None], P=P[None],
                             series={"gyro_bias": o["eb"][None], "accel_bias": o["db"][None]})
    return SimpleNamespace(heading=err[:, 2], sigma=np.sqrt(np.maximum(P[:, 2, 2], 0.0)),
                           nees=exp.nees(result, [episode], err[None])[0],
                           diverged=int(o["diverged"].item()),
                           diverged_k=int(o["diverged_k"].item()))


def window_stats(heading: np.ndarray, nees: np.ndarray, window: np.ndarray
                 ) -> tuple[float, float]:
    """RMS heading error (arcmin) and mean NEES over the accuracy window."""
    return (float(np.sqrt(np.mean(heading[window] ** 2)) / ARCMIN),
            float(np.nanmean(nees[window])))


def parse_settings(items: list[str]) -> dict:
    """--set KEY=VALUE pairs as experiment settings (numbers where they parse)."""
    out = {}
    for item in items:
        key, _, value = item.partition("=")
        try:
            out[key] = float(value)
        except ValueError:
            out[key] = value
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a paper004 setting (e.g. swing=severe, fine_duration=600)")
    add_psins_options(ap)
    args = ap.parse_args(argv)

    with psins_workspace("filters_004", args, PSINS_FILES) as ws:
        if ws is None:
            return 0
        work = ws.work

        from aligngym.scenarios.campaign.episodes import episode_seeds
        from aligngym.scenarios.campaign.executors import prepare_all
        from aligngym.scenarios.campaign.runs import run_filter
        from aligngym.scenarios.experiments import experiment

        exp = experiment("paper004", **parse_settings(args.set))
        t0 = time.time()
        seeds = episode_seeds(args.seed, args.episodes)
        episodes = prepare_all(exp, seeds, None, False, 1, False)
        (start, start_error), = exp.start_errors(episodes).items()
        paths = export_runs(exp, episodes, start_error, work)
        print(f"paper004 swing {exp.swing}, start {start!r}, case {exp.case}: prepared and "
              f"exported {len(episodes)} episodes (seeds {seeds}), {time.time() - t0:.0f} s;"
              f" work dir {work}")
        ours = {name: run_filter(name, start, start_error, episodes, exp) for name in OURS}
        print(f"our filters done, {time.time() - t0:.0f} s")

        outputs = [str(p).replace(".mat", f"_{n}_out.mat") for p in paths
                   for n in PSINS_FILTERS]
        if not run_octave("filters_004", ws, paths, outputs):
            return 1
        print(f"octave done, {time.time() - t0:.0f} s")

        fine_start = episodes[0].fine_start
        t = ours[OURS[0]].result.t
        window = exp.accuracy_window(t - t[0], fine_start)
        end = t[-1] - t[0] + fine_start
        ks = sorted({int(np.argmin(np.abs(t - t[0] + fine_start - s)))
                     for s in (*[s for s in TIMES if s < end], end)})
        summary: dict[str, list] = {name: [] for name in PSINS_FILTERS}
        for b, path in enumerate(paths):
            mine = {n: psins_result(path, n, episodes[b], exp) for n in PSINS_FILTERS}
            print(f"\n== episode {b} (seed {seeds[b]}, start error E/N/U "
                  + "/".join(f"{v:.2f}" for v in np.degrees(start_error[b]))
                  + " deg): heading error/sigma (arcmin) and NEES(9), ours | PSINS")
            print(f"  {'t s':>5s}" + "".join(f"  {n:>33s}" for n in OURS)
                  + f"  {'PSINS stekf-native':>18s}")
            for k in ks:
                cell = lambda h, s, v: f"{h / ARCMIN:7.1f}/{s / ARCMIN:5.1f} {v:4.0f}"  # noqa: E731
                row = f"  {t[k] + fine_start:5.0f}"
                for n in OURS:
                    r = ours[n]
                    row += (f"  {cell(r.error_n[b, k, 2], r.result.sigma_n[b, k, 2], r.nees[b, k])}"
                            f" |{cell(mine[n].heading[k], mine[n].sigma[k], mine[n].nees[k])}")
                m = mine["stekf-native"]
                row += f"  {cell(m.heading[k], m.sigma[k], m.nees[k])}"
                print(row)
            for n in PSINS_FILTERS:
                m = mine[n]
                rms_p, nees_p = window_stats(m.heading, m.nees, window)
                line = f"  {n:12s} PSINS: RMS heading {rms_p:6.2f}', NEES {nees_p:5.1f}"
                entry = [b, rms_p, nees_p, m.heading[-1] / ARCMIN]
                if n in ours:
                    r = ours[n]
                    rms_o, nees_o = window_stats(r.error_n[b, :, 2], r.nees[b], window)
                    diff = np.abs(r.error_n[b, :, 2] - m.heading)[window] / ARCMIN
                    line = (f"  {n:12s} ours: RMS heading {rms_o:6.2f}', NEES {nees_o:5.1f}; "
                            f"PSINS: {rms_p:6.2f}', {nees_p:5.1f}; |ours - PSINS| over the "
                            f"window: max {diff.max():5.2f}', RMS "
                            f"{np.sqrt(np.mean(diff ** 2)):5.2f}', end "
                            f"{diff[-1]:5.2f}'")
                    entry += [rms_o, nees_o, r.error_n[b, -1, 2] / ARCMIN, diff.max(),
                              bool(r.result.diverged[b]), int(r.result.repairs[b])]
                print(line + (f"; PSINS diverged at epoch {m.diverged_k}" if m.diverged
                              else ""))
                summary[n].append(entry)
        w0 = exp.accuracy_start(float(end))
        print(f"\nSUMMARY over [{w0:g}, {end:g}] s: per filter and "
              "episode, RMS heading error (arcmin) and mean NEES(9), ours vs PSINS; "
              "final heading error ours vs PSINS; max |ours - PSINS| in the window")
        for n in OURS:
            for e in summary[n]:
                print(f"  {n:7s} ep {e[0]}  RMS {e[4]:6.2f}' vs {e[1]:6.2f}'  NEES {e[5]:5.1f}"
                      f" vs {e[2]:5.1f}  final {e[6]:7.2f}' vs {e[3]:7.2f}'  max diff "
                      f"{e[7]:5.2f}'" + (f"  (ours: {e[9]} covariance repairs)" if e[9] else "")
                      + ("  OURS DIVERGED" if e[8] else ""))
            rms = lambda i: np.sqrt(np.mean([e[i] ** 2 for e in summary[n]]))  # noqa: E731
            mean = lambda i: np.mean([e[i] for e in summary[n]])  # noqa: E731
            print(f"  {n:7s} all   RMS {rms(4):6.2f}' vs {rms(1):6.2f}'  NEES {mean(5):5.1f}"
                  f" vs {mean(2):5.1f}  max diff {max(e[7] for e in summary[n]):5.2f}'")
        native = summary["stekf-native"]
        print(f"  PSINS stekf-native (P kept at the reset): RMS "
              f"{np.sqrt(np.mean([e[1] ** 2 for e in native])):6.2f}', NEES "
              f"{np.mean([e[2] for e in native]):5.1f}")
        return 0


if __name__ == "__main__":
    sys.exit(main())
