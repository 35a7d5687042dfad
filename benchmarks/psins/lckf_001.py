"""Paper 001's classic loosely coupled KF against an independent one (GNU Octave, PSINS).

Question: does our ``lckf`` (``estimators.loose_gps``: an e-frame error state, our
strapdown) solve the figure-8 RTK GPS/INS problem as PSINS's classic 15-state KF does
with the same tuning? This script

1. prepares a few episodes of ``paper001`` (the campaign's seeds, its "coarse" start: the
   static analytic alignment over the first 60 s) and exports, per episode, everything
   the filter consumes: the raw IMU increments, the GPS antenna position and velocity
   fixes and their times, the lever arm, the INS start (attitude, velocity, position),
   P0, the white-noise densities (Q), the GPS sigmas (R) and the feedback rule
   (``<work>/run_<b>.mat``);
2. runs our ``lckf`` on the same episodes (``scenarios.campaign.runs.run_filter``);
3. runs ``lckf_001_run.m`` in Octave: a PSINS strapdown (``insinit``/``insupdate``) and
   PSINS's classic 15-state KF (``psinstypedef(156)``, ``kfinit``, ``kffk``/``etm``,
   ``kfhk``, ``kfupdate``, ``kffeedback``) called as a library, one time update per
   strapdown step, one measurement update per GPS fix, the antenna through ``inslever``;
4. prints, per episode, the attitude (E, N, U arcmin), position (cm) and velocity (mm/s)
   errors against the truth, ours against PSINS and their difference, and both filters'
   heading sigma and 15-state NEES (``experiment.nees``).

Mapping (``psins_map``): lckf's state is x = [dr^e, dv^e, phi^e, d, b] (ECEF position
and velocity errors, the misalignment resolved in e with C~ = (I - [phi x]) C, the
body-frame gyro drift and accelerometer bias); PSINS's is [phi^n, dv^n, dpos, eb, db]
(ENU; dpos = [dlat, dlon, dh]; its phi has the same sign: ``qdelphi`` corrects with
exp([phi x])). So phi^n = C_e^n phi^e, dv^n = C_e^n dv^e, dpos = Mpv C_e^n dr^e (Mpv:
ENU metres to lat, lon, h), eb = d, db = b; this drops the n frame's own turn by the
position error (|dr| / R ~ 1e-8 rad, ~1e-7 m/s) between phi^e and phi^n and dv^e and
dv^n. P0 goes through it forwards, PSINS's P back at every epoch for the NEES. Q: the
same isotropic densities (PSINS Qt = diag([web; wdb; 0])^2, Qk = Qt nts). R: the GPS
sigmas, horizontal in m over R_Mh and cos(lat) R_Nh for PSINS's lat and lon. The lever
arm: PSINS's ``inslever`` (posL = pos + Mpv C l, vnL = vn + C (w_eb x l)) and its rows
in H (phi, and eb for the velocity) that ``kfhk(156)`` leaves out, as lckf has them.
Feedback: all 15 states after every fix, the state reset to zero, P kept (both).
Not mapped, each side its own unless ``--as-lckf`` says otherwise: the body rate in the
antenna's lever-arm velocity (``rate``: ours the last two 0.01-s rates extrapolated to
the fix, PSINS's ins.web the last 0.02-s mean), the discretisation (``discretisation``:
ours one step an epoch from mid-epoch, I + F T + (F T)^2 / 2, the epoch's mean force and
a trapezoid Q; PSINS I + F nts and Qt nts every 0.02 s), gravity (``gravity``: ours
WGS-84 Somigliana, PSINS its series, 1.7e-6 m/s^2 apart at 30.5 deg; "lckf" fixes
PSINS's at ours at the start) and the strapdown algorithm (ours 100 Hz, PSINS 2-sample
steps; both on WGS-84 here, ``glvf``).

Found (seeds 0-2, 707 s): at the end the two agree to 0.012 cm, 0.037 mm/s and 0.012';
before, where the heading is weakly observable (still, heading sigma 200-600'; the first
~30 s of motion with 10 deg of heading error) the conventions above move them apart by
up to 50' of heading, 1.2 cm and 4.4 mm/s; with ``--as-lckf rate,discretisation,gravity``
they agree at every epoch to 0.14', 0.023 cm and 0.030 mm/s (the NEES to 0.04).

Usage:  python benchmarks/psins/lckf_001.py [--episodes 3] [--seed 0] [--psins DIR]
        [--work DIR] [--keep] [--fine-duration S] [--as-lckf rate,discretisation,gravity]
PSINS: --psins or $PSINS_DIR (a work tree with base/), else the bare snapshot $PSINS_GIT
(default /work/.mirror/WangShanpeng+PSINS/repo), whose base/ is extracted to a temp dir.
Without octave or a PSINS snapshot the script says so in one line and exits 0.
Runtime: about 3.5 min for 3 episodes of 707 s (preparation ~10 s an episode, Octave ~58
s an episode; ~45 s with --as-lckf discretisation); prefix it with `nice -n 10`.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from psins_setup import add_psins_options, psins_workspace, run_octave

PSINS_FILES = ("base/kf/kfupdate.m",)
"""What the check calls in PSINS (under its tree)."""
ARCMIN = np.pi / 180 / 60
TIMES = (0, 1, 2, 5, 10, 30, 60, 120, 200, 210, 215, 220, 240, 300, 400, 500, 600)
"""Epochs (s since the fine start, 60 s into the run) to print; the car starts at 210."""
START = "coarse"
AS_LCKF = ("rate", "discretisation", "gravity")
"""What ``--as-lckf`` can make PSINS's side do as lckf does (see the module docstring)."""


def psins_map(lat: np.ndarray, lon: np.ndarray, h: np.ndarray) -> np.ndarray:
    """T (..., 15, 15) with x_PSINS = T x_lckf at INS position (lat, lon rad; h m): lckf's
    [dr^e, dv^e, phi^e, d, b] to PSINS's [phi^n, dv^n, (dlat, dlon, dh), eb, db]."""
    from aligngym.models.earth import C_n_e, radii

    lat, lon, h = np.broadcast_arrays(*(np.asarray(a, float) for a in (lat, lon, h)))
    C_en = np.swapaxes(C_n_e(lat, lon), -1, -2)
    R_M, R_N = radii(lat)
    Mpv = np.zeros(lat.shape + (3, 3))          # ENU metres to (lat, lon, h)
    Mpv[..., 0, 1] = 1.0 / (R_M + h)
    Mpv[..., 1, 0] = 1.0 / ((R_N + h) * np.cos(lat))
    Mpv[..., 2, 2] = 1.0
    T = np.zeros(lat.shape + (15, 15))
    T[..., 0:3, 6:9] = C_en
    T[..., 3:6, 3:6] = C_en
    T[..., 6:9, 0:3] = Mpv @ C_en
    T[..., 9:15, 9:15] = np.eye(6)
    return T


def export_runs(exp, episodes, work: Path, as_lckf: set[str] = frozenset()
                ) -> list[tuple[int, Path]]:
    """One .mat per episode with what the filter consumes (PSINS's units and states);
    as_lckf: the ``AS_LCKF`` items the glue does lckf's way instead of PSINS's."""
    from scipy.io import savemat
    from aligngym.models import earth
    from aligngym.models.attitude import quat_to_dcm

    starts = exp.start_errors(episodes)
    model = exp.model(episodes, starts[START], "position-velocity")
    inp, tu = model.inputs, model.tuning
    _, P0 = model.initial()
    B, K, S = inp.dtheta.shape[:3]
    runs = []
    for b in range(B):
        T = psins_map(inp.lat0[b], inp.lon0[b], inp.h0[b])
        path = work / f"run_{b}.mat"
        savemat(path, {
            "K": K, "S": S, "T": model.step, "dt": inp.imu_dt, "t": inp.t,
            "dtheta": inp.dtheta[b].reshape(-1, 3), "dv": inp.dv[b].reshape(-1, 3),
            "gps_pos": np.stack([inp.gps_lat[b], inp.gps_lon[b], inp.gps_h[b]], -1),
            "gps_vn": inp.gps_v_n[b], "lever": inp.lever_arm_b[b],
            "C0": quat_to_dcm(inp.q_b_n0[b]), "v0": inp.v_n0[b],
            "pos0": np.array([inp.lat0[b], inp.lon0[b], inp.h0[b]]),
            "P0": T @ P0[b] @ T.T, "P0_lckf": P0[b],
            "gyro_noise": tu.gyro_noise_density, "accel_noise": tu.accel_noise_density,
            "gyro_bias_sigma": tu.gyro_bias_sigma, "accel_bias_sigma": tu.accel_bias_sigma,
            "gps_position_sigma_h": tu.gps_position_sigma_h,
            "gps_position_sigma_v": tu.gps_position_sigma_v,
            "gps_velocity_sigma": tu.gps_velocity_sigma,
            "fbstr": "avped", "T_fb": model.step,
            **{key: "lckf" if key in as_lckf else "psins" for key in AS_LCKF},
            "g_fix": earth.normal_gravity(inp.lat0[b], inp.h0[b]),
            "Re": earth.A, "flattening": earth.F, "wie": earth.OMEGA_IE})
        runs.append((b, path))
    return runs


def psins_result(path: Path, episodes, b: int, exp) -> SimpleNamespace:
    """One Octave run's errors against the truth with our metrics: attitude (K+1, 3) rad
    (misalignment), position (m) and velocity (m/s) E, N, U (``navigation_errors``),
    heading sigma (K+1,) rad, 15-state NEES (K+1,) with PSINS's P mapped to our states."""
    from scipy.io import loadmat
    from aligngym.estimators.metrics import misalignment
    from aligngym.scenarios.analyses.paper001 import navigation_errors

    o = loadmat(str(path).replace(".mat", "_out.mat"))
    pos, vn, C, P_n = o["pos"], o["vn"], o["C"], o["P"]
    K1 = C.shape[0]
    e = episodes[b]
    Ti = np.linalg.inv(psins_map(pos[:, 0], pos[:, 1], pos[:, 2]))
    P = Ti @ P_n @ np.swapaxes(Ti, -1, -2)
    x = np.einsum("kij,kj->ki", Ti, o["x"])
    att = misalignment(e.C_s_n_true[:K1], C)
    series = {"lat": pos[None, :, 0], "lon": pos[None, :, 1], "h": pos[None, :, 2],
              "v_n": vn[None], "C_b_n": C[None], "gyro_bias": o["eb"][None],
              "accel_bias": o["db"][None]}
    result = SimpleNamespace(t=e.t[:K1], x=x[None], P=P[None], series=series)
    p_err, v_err = navigation_errors(SimpleNamespace(result=result), [e])
    return SimpleNamespace(att=att, pos=p_err[0], vel=v_err[0],
                           sigma_u=np.sqrt(np.maximum(P_n[:, 2, 2], 0.0)),
                           nees=exp.nees(result, [e], att[None])[0],
                           updated=int(o["updated"].sum()))


def table(title: str, unit: str, scale: float, ks: list[int], ours: np.ndarray,
          theirs: np.ndarray) -> list[str]:
    """Rows of E, N, U (scaled by ``scale``): ours, PSINS, ours - PSINS, at epochs ks."""
    head = "".join(f"{a:>8s}" for a in "ENU")
    lines = [f"  {title} ({unit}):", f"  {'t s':>5s}  ours{head[4:]}   PSINS{head[5:]}"
             f"   diff{head[4:]}"]
    for k in ks:
        cells = [ours[k] * scale, theirs[k] * scale, (ours[k] - theirs[k]) * scale]
        lines.append(f"  {k:5d}" + "   ".join("".join(f"{v:8.3f}" for v in c)
                                              for c in cells))
    d = np.abs(ours - theirs) * scale
    lines.append("  max |diff| over all epochs: " + ", ".join(
        f"{a} {v:.4f}" for a, v in zip("ENU", d.max(0))) + f" {unit}")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    add_psins_options(ap)
    ap.add_argument("--fine-duration", type=float, default=None,
                    help="s of filtering after the coarse stage (default: to the run's end)")
    ap.add_argument("--as-lckf", default="", metavar="LIST",
                    help="comma-separated, PSINS's side done as lckf does it (diagnostics): "
                    "rate (the lever-arm body rate extrapolated to the fix), discretisation "
                    "(one time update an epoch), gravity (our normal gravity, fixed)")
    args = ap.parse_args(argv)
    as_lckf = {a for a in args.as_lckf.split(",") if a}
    if as_lckf - set(AS_LCKF):
        ap.error(f"--as-lckf: unknown {sorted(as_lckf - set(AS_LCKF))}; valid: "
                 + ", ".join(AS_LCKF))

    with psins_workspace("lckf_001", args, PSINS_FILES) as ws:
        if ws is None:
            return 0
        work = ws.work

        from aligngym.scenarios.campaign.episodes import episode_seeds
        from aligngym.scenarios.campaign.executors import prepare_all
        from aligngym.scenarios.campaign.runs import run_filter
        from aligngym.scenarios.experiments import experiment
        from aligngym.scenarios.analyses.paper001 import navigation_errors

        exp = experiment("paper001", fine_duration=args.fine_duration)
        t0 = time.time()
        seeds = episode_seeds(args.seed, args.episodes)
        episodes = prepare_all(exp, seeds, None, False, 1, False)
        runs = export_runs(exp, episodes, work, as_lckf)
        print(f"prepared and exported {len(episodes)} episodes (seeds {seeds}), "
              f"{time.time() - t0:.0f} s; work dir {work}")
        run = run_filter("lckf", START, exp.start_errors(episodes)[START], episodes, exp)
        pos, vel = navigation_errors(run, episodes)
        print(f"our lckf done, {time.time() - t0:.0f} s")

        inputs = [p for _, p in runs]
        if not run_octave("lckf_001", ws, inputs,
                          [str(p).replace(".mat", "_out.mat") for p in inputs]):
            return 1
        print(f"octave done, {time.time() - t0:.0f} s")

        summary = []
        for b, path in runs:
            mine = psins_result(path, episodes, b, exp)
            K1 = run.error_n.shape[1]
            ks = [k for k in TIMES if k < K1 - 1] + [K1 - 1]
            print(f"\n== episode {b} (seed {seeds[b]}), start {START!r} (coarse heading "
                  f"error {episodes[b].coarse_error[2] / ARCMIN:.1f}'), {K1 - 1} epochs, "
                  f"PSINS {mine.updated} fixes: ours lckf vs PSINS 15-state KF")
            print("\n".join(table("attitude error", "arcmin", 1 / ARCMIN, ks,
                                  run.error_n[b], mine.att)))
            print("\n".join(table("position error", "cm", 100.0, ks, pos[b], mine.pos)))
            print("\n".join(table("velocity error", "mm/s", 1000.0, ks, vel[b], mine.vel)))
            print("  heading sigma (arcmin) and 15-state NEES:")
            print(f"  {'t s':>5s} {'sigma ours':>11s} {'PSINS':>8s} {'NEES ours':>10s} "
                  f"{'PSINS':>8s}")
            for k in ks:
                print(f"  {k:5d} {run.result.sigma_n[b, k, 2] / ARCMIN:11.3f} "
                      f"{mine.sigma_u[k] / ARCMIN:8.3f} {run.nees[b, k]:10.2f} "
                      f"{mine.nees[k]:8.2f}")
            print(f"  mean NEES over epochs 1..end: ours {np.nanmean(run.nees[b, 1:]):.2f}, "
                  f"PSINS {np.nanmean(mine.nees[1:]):.2f} (15 dof); ours diverged="
                  f"{bool(run.diverged[b])}")
            moving = np.hypot(*episodes[b].true_v_n[:K1, :2].T) > 1.0   # as paper001
            diffs = [np.abs(a - p) * scale for a, p, scale in (
                (run.error_n[b], mine.att, 1 / ARCMIN), (pos[b], mine.pos, 100.0),
                (vel[b], mine.vel, 1000.0))]
            in_motion = [d[moving].max() if moving.any() else np.nan for d in diffs]
            summary.append((b, [d.max() for d in diffs], in_motion,
                            [d[-1].max() for d in diffs]))
        print("\nSUMMARY max |ours - PSINS| over the axes: attitude ('), position (cm), "
              "velocity (mm/s);\n  episode, over all epochs | in motion (true speed > 1 m/s) "
              "| at the end")
        for b, every, motion, end in summary:
            cell = lambda v: "".join(f"{x:9.4f}" for x in v)  # noqa: E731
            print(f"  {b:3d} {cell(every)}  |{cell(motion)}  |{cell(end)}")
        return 0


if __name__ == "__main__":
    sys.exit(main())
