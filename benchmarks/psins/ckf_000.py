"""Paper 000's CKF (or EKF) against an independent implementation (GNU Octave, PSINS).

Question: our ``ckf`` diverges from paper 000's "large" start (30 deg heading error, P0
heading sigma 30 deg). Method, or defect? This script

1. prepares a few episodes of ``paper000`` (the campaign's seeds) and exports, per episode
   and start, everything the fine alignment consumes: the raw IMU and odometer increments,
   the INS start (attitude, velocity, position), the lever arm and mounting, P0, Q, R and
   the feedback threshold (``<work>/run_<start>_<b>.mat``);
2. runs our ``ckf`` (and ``rdghkf`` as a reference) on the same episodes
   (``scenarios.campaign.runs.run_filter``);
3. runs ``ckf_000_run.m`` in Octave: a PSINS strapdown (``insinit``/``insupdate``), the
   model of ``odo000_fx.m``/``odo000_hx.m`` (written from ALGORITHMS 4.1-4.7, exact in the
   Euler angles, RK4 in time) and PSINS's cubature filter ``ckf``/``ckfCT`` called as a
   library (``--filter ekf``: PSINS's ``ekf`` on the same maps, their Jacobians by
   central differences, ``odo000_jcb.m``), with the same closed-loop feedback rule;
4. prints the heading error, its sigma and the NEES over time, ours against PSINS, per
   episode and start, and the first epoch's measurement moments from the cubature rule
   against a Monte Carlo reference.

Usage:  python benchmarks/psins/ckf_000.py [--filter ckf|ekf] [--episodes 3] [--seed 0]
        [--psins DIR] [--work DIR] [--keep]
PSINS: --psins or $PSINS_DIR (a work tree with base/), else the bare snapshot $PSINS_GIT
(default /work/.mirror/WangShanpeng+PSINS/repo), whose base/ is extracted to a temp dir.
Without octave or a PSINS snapshot the script says so in one line and exits 0.
Runtime: about 10 min for 3 episodes (Octave: ~95 s per episode and start, of which
~20 s is the first epoch's Monte Carlo check; ``--filter ekf`` about 130 s, no
Monte Carlo); prefix it with `nice -n 10`.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from psins_setup import add_psins_options, psins_workspace, run_octave

PSINS_FILES = ("base/kf/ckf.m", "base/kf/ckfCT.m", "base/kf/ekf.m", "base/kf/ekfJcb.m")
"""What the check calls in PSINS (under its tree)."""
ARCMIN = np.pi / 180 / 60
TIMES = (0, 1, 2, 5, 10, 30, 60, 120, 300)


def export_runs(exp, episodes, work: Path, name: str = "ckf"
                ) -> list[tuple[str, int, Path]]:
    """One .mat per (start, episode) with what the filter ``name`` consumes."""
    from scipy.io import savemat
    from aligngym.models.attitude import quat_to_dcm

    runs = []
    starts = exp.start_errors(episodes)
    for start in exp.starts:
        model = exp.model(episodes, starts[start])
        inp, tu = model.inputs, model.tuning
        x0, P0 = model.initial()
        n = model.n
        q = np.zeros(n)
        q[0:3] = tu.gyro_noise_density ** 2
        q[3:6] = tu.accel_noise_density ** 2
        B, K, S = inp.dtheta.shape[:3]
        for b in range(B):
            path = work / f"run_{start}_{b}.mat"
            savemat(path, {
                "n": n, "K": K, "S": S, "T": model.T, "dt": inp.imu_dt,
                "dtheta": inp.dtheta[b].reshape(-1, 3), "dv": inp.dv[b].reshape(-1, 3),
                "distance": inp.distance[b].reshape(-1, 1),
                "Cmb": inp.C_m_b[b], "lever": inp.lever_arm_b[b],
                "C0": quat_to_dcm(inp.q_b_n0[b]), "v0": inp.v_n0[b],
                "pos0": np.array([inp.lat0[b], inp.lon0[b], inp.h0[b]]),
                "P0": P0[b], "x0": x0[b], "qdiag": q,
                "R": np.eye(3) * tu.measurement_sigma ** 2,
                "feedback_below": model.feedback_below,
                "start_error": np.broadcast_to(starts[start], (B, 3))[b],
                "filter": name, "check": int(name == "ckf")})
            runs.append((start, b, path))
    return runs


def psins_result(path: Path, episodes, b: int, exp):
    """Errors (K+1, 3) rad, sigma (K+1, 3) rad, NEES (K+1,) of one Octave run, with our
    metrics (misalignment, experiment.nees)."""
    from scipy.io import loadmat
    from aligngym.estimators.metrics import misalignment

    o = loadmat(str(path).replace(".mat", "_out.mat"))
    C, x, P = o["C"], o["x"], o["P"]
    K1 = C.shape[0]
    e = episodes[b]
    err = misalignment(e.C_s_n_true[:K1], C)
    sigma = np.sqrt(np.maximum(np.diagonal(P[:, :3, :3], axis1=-2, axis2=-1), 0.0))
    result = SimpleNamespace(t=e.t[:K1], x=x[None], C_s_n=C[None], P=P[None],
                             series={"gyro_bias": o["eb"][None], "accel_bias": o["db"][None]})
    nees = exp.nees(result, [e], err[None])[0]
    return SimpleNamespace(err=err, sigma=sigma, nees=nees, out=o,
                           diverged=int(o["diverged"].item()),
                           diverged_k=int(o["diverged_k"].item()))


def first_epoch_table(o) -> list[str]:
    """The first epoch's measurement moments: cubature (ckfCT) vs Monte Carlo."""
    f = o["first"][0, 0]
    g = lambda name: np.asarray(f[name], float)  # noqa: E731
    dS = g("dS").ravel()
    u = dS / np.linalg.norm(dS)               # along-track unit vector (n')
    c = np.array([u[1], -u[0], 0.0])           # cross-track (right of track), horizontal
    lines = []
    for label, key in (("cubature", "cub"), ("Monte Carlo", "mc")):
        z, Pzz, Pxz, dx = g("z_" + key).ravel(), g("Pzz_" + key), g("Pxz_" + key), g("dx_" + key).ravel()
        lines.append(
            f"    {label:11s} z^ along {z @ u:8.3f} m, cross {z @ c:8.3f} m; "
            f"sd(z) along {np.sqrt(u @ Pzz @ u):6.3f}, cross {np.sqrt(c @ Pzz @ c):6.3f} m; "
            f"cov(phi_U, z_cross) {Pxz[2] @ c:8.4f} rad m; "
            f"heading update {np.degrees(dx[2]):8.2f} deg")
    z = g("z").ravel()
    lines.append(f"    measured    z  along {z @ u:8.3f} m, cross {z @ c:8.3f} m "
                 f"(|dS| = {np.linalg.norm(dS):.2f} m)")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--filter", choices=("ckf", "ekf"), default="ckf")
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    add_psins_options(ap)
    args = ap.parse_args(argv)

    with psins_workspace("ckf_000", args, PSINS_FILES) as ws:
        if ws is None:
            return 0
        work = ws.work

        from aligngym.scenarios.campaign.episodes import episode_seeds
        from aligngym.scenarios.campaign.executors import prepare_all
        from aligngym.scenarios.campaign.runs import run_filter
        from aligngym.scenarios.experiments import experiment

        exp = experiment("paper000")
        t0 = time.time()
        seeds = episode_seeds(args.seed, args.episodes)
        episodes = prepare_all(exp, seeds, None, False, 1, False)
        name = args.filter
        runs = export_runs(exp, episodes, work, name)
        print(f"prepared and exported {len(episodes)} episodes (seeds {seeds}), "
              f"{time.time() - t0:.0f} s; work dir {work}")
        starts = exp.start_errors(episodes)
        ours = {}
        for filt in (name, "rdghkf"):
            for start in exp.starts:
                ours[filt, start] = run_filter(filt, start, starts[start], episodes, exp)
        print(f"our filters done, {time.time() - t0:.0f} s")

        inputs = [p for _, _, p in runs]
        if not run_octave("ckf_000", ws, inputs,
                          [str(p).replace(".mat", "_out.mat") for p in inputs]):
            return 1
        print(f"octave done, {time.time() - t0:.0f} s")

        summary = []
        for start, b, path in runs:
            mine = psins_result(path, episodes, b, exp)
            run, ref = ours[name, start], ours["rdghkf", start]
            K1 = run.error_n.shape[1]
            ks = [k for k in TIMES if k < K1] + [K1 - 1]
            print(f"\n== start {start!r}, episode {b} (seed {seeds[b]}): heading error / "
                  "sigma (arcmin), 9-state NEES")
            print(f"  {'t s':>5s} {'ours ' + name:>22s} {'PSINS ' + name:>22s} "
                  f"{'ours rdghkf':>22s}")
            for k in ks:
                cell = lambda e, s, v: f"{e / ARCMIN:9.2f}/{s / ARCMIN:7.2f} {v:6.0f}"  # noqa: E731
                print(f"  {k:5d} "
                      f"{cell(run.error_n[b, k, 2], run.result.sigma_n[b, k, 2], run.nees[b, k])}"
                      f" {cell(mine.err[k, 2], mine.sigma[k, 2], mine.nees[k])}"
                      f" {cell(ref.error_n[b, k, 2], ref.result.sigma_n[b, k, 2], ref.nees[b, k])}")
            d_end = (run.error_n[b, -1, 2] - mine.err[-1, 2]) / ARCMIN
            print(f"  end: ours {run.error_n[b, -1, 2] / ARCMIN:.2f}', PSINS "
                  f"{mine.err[-1, 2] / ARCMIN:.2f}' (difference {d_end:.2f}'); mean NEES "
                  f"ours {np.nanmean(run.nees[b, 1:]):.0f}, PSINS {np.nanmean(mine.nees[1:]):.0f} "
                  f"(9 dof); ours diverged={bool(run.diverged[b])} ({run.reason[b] or '-'}), "
                  f"PSINS numerically diverged={bool(mine.diverged)}")
            if "first" in mine.out:
                print("  first epoch, measurement moments and implied heading update "
                      "(PSINS model):")
                print("\n".join(first_epoch_table(mine.out)))
            summary.append((start, b, run.error_n[b, -1, 2] / ARCMIN, mine.err[-1, 2] / ARCMIN,
                            run.error_n[b, 30, 2] / ARCMIN, mine.err[30, 2] / ARCMIN))
        print("\nSUMMARY heading error (arcmin): start, episode, ours@end, PSINS@end, "
              "ours@30s, PSINS@30s")
        for s in summary:
            print(f"  {s[0]:7s} {s[1]}  {s[2]:9.2f} {s[3]:9.2f}   {s[4]:9.2f} {s[5]:9.2f}")
        control = [abs(s[2] - s[3]) for s in summary if s[0] == "coarse"]
        print(f"control (coarse start): max |ours - PSINS| at the end = {max(control):.2f}'"
              + ("  OK (< 1')" if max(control) < 1.0 else "  NOT within 1'"))
        return 0


if __name__ == "__main__":
    sys.exit(main())
