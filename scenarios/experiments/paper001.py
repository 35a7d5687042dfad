"""Paper 001 end to end: a van on the figure-8 with an RTK GPS and a 1 deg/h IMU, still
for 270 s, then at 60 km/h; the loosely coupled GPS/INS (``estimators.loose_gps``) with
the classic KF (``lckf``, position and velocity), Yang's robust adaptive KF with the GPS
heading (``rakf``) and the selective-weight adaptive KF with the GPS heading (``swakf``).

Each episode: the analytic coarse alignment over the first ``coarse_duration`` s of the
stationary phase (level from the accelerometers, heading from the earth rate: with this
gyro's drift and random walk, a few degrees of heading error), the INS started there
from the GPS fix, then one closed-loop filter epoch per GPS fix to the end of the run.
The paper's table: the std of the (filtered INS - GPS) position and velocity differences
per axis in motion and each scheme's improvement over the classic one; beyond it, the
errors against the truth (position, velocity, attitude), the heading against the GPS
heading in the turns, GPS outages (``outage``) and outliers (scenario [gps] outliers).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from aligngym.estimators.inertial_frame import static_coarse_alignment, velocity_aided_alignment
from aligngym.estimators.loose_gps import (ACCEL, GYRO, LAYOUT, PHI, POSITION, VELOCITY,
                                  GpsInsInputs, LooselyCoupledModel, LooseTuning, heading_cw,
                                  ins_start_at_fix)
from aligngym.estimators.metrics import misalignment, status_fractions
from aligngym.estimators.model import stack_episodes, wrap_angle
from aligngym.models.attitude import quat_to_dcm, rotvec_to_dcm
from aligngym.models.earth import C_n_e, geodetic_to_ecef
from aligngym.models.units import arcmin, deg
from aligngym.scenarios.campaign import (CampaignResult, Experiment, GnssEpisode, TruthMap,
                                         setting, simulate_screened)
from aligngym.scenarios.campaign.requirements import SensorTable, StepOnFixes, StrapdownImu
from aligngym.scenarios.campaign.results import STATUS_HEADER, status_columns
from aligngym.scenarios.campaign.claims import Claim
from aligngym.scenarios.config import ConfigError, ScenarioConfig, SettingError
from aligngym.scenarios.campaign.settings import MAX_RUN, POSITIVE, bounded
from aligngym.sensors.imu import ImuTuning

START = "coarse"
SCHEMES = ("lckf", "rakf", "swakf")
COARSE = ("static", "moving")
HEADING_POINTS = ("antenna", "rear-axle")
AXES_ENU = ("E", "N", "U")
PAPER_SETUP = {"setup": "paper", "scenario": "figure8-gps-paper"}
"""``--setup paper``: the paper's own reason for its classic KF's trouble (001 sec. 3: the
INS's actual accuracy departs from its calibration in complex motion, the filter keeps the
calibrated values), made concrete as uncalibrated gyro misalignment (300") and scale
factor (300 ppm) that the 15-state model does not hold and no filter believes."""


@dataclass
class Paper001Episode(GnssEpisode):
    """One figure-8 episode from the end of the coarse alignment (``GnssEpisode``;
    C_s_b = I). gps_heading_sigma at the boundaries (NaN where the receiver gives no
    heading); true_lat, true_lon (rad), true_h (m), true_v_n (m/s) of the IMU at the
    boundaries; lever_arm_b (3,) m IMU to antenna; coarse_error (3,) rad misalignment E,
    N, U of the coarse alignment."""

    gps_heading_sigma: np.ndarray
    true_lat: np.ndarray
    true_lon: np.ndarray
    true_h: np.ndarray
    true_v_n: np.ndarray
    lever_arm_b: np.ndarray
    coarse_error: np.ndarray


def prepare_episode(experiment: Paper001Experiment, seed: int,
                    config: ScenarioConfig | None = None) -> Paper001Episode:
    """Simulate the run, align coarsely (still or moving), cut the data into the filter's
    epochs."""
    config = config or experiment.scenario_config()
    episode, flags = simulate_screened(config, seed)
    truth, dt = episode.truth, config.imu_interval
    gps = episode.measurements["gps"]
    motion = config.motion
    lever_arm_b = np.subtract(motion.gps_antenna_b, motion.imu_offset_b)
    start, end = experiment.coarse_window(config)
    n_start, n_coarse = int(round(start / dt)), int(round(end / dt))
    C_b_n_true = quat_to_dcm(truth.q_b_n)
    if experiment.coarse == "static":
        f_b = episode.dv[:n_coarse].sum(0) / (n_coarse * dt)
        omega_b = episode.dtheta[:n_coarse].sum(0) / (n_coarse * dt)
        C_coarse = static_coarse_alignment(f_b, omega_b, float(truth.lat[n_coarse]))
    else:
        fixes = np.flatnonzero((gps.t >= start - 1e-9) & (gps.t <= end + 1e-9)
                               & gps.valid)
        C_coarse, _ = velocity_aided_alignment(
            episode.dtheta[n_start:n_coarse], episode.dv[n_start:n_coarse], dt,
            (gps.t[fixes] - start) / dt, gps.lat[fixes], gps.h[fixes],
            gps.v_n[fixes], lever_arm_b)
    per_epoch = int(round(experiment.filter_step / dt))
    epochs = (truth.t.size - 1 - n_coarse) // per_epoch
    idx = n_coarse + per_epoch * np.arange(epochs + 1)
    t = truth.t[idx]
    dtheta = episode.dtheta[n_coarse: idx[-1]].reshape(epochs, per_epoch, 3)
    dv = episode.dv[n_coarse: idx[-1]].reshape(epochs, per_epoch, 3)
    g = np.rint((t - gps.t[0]) * config.gps.rate).astype(int)
    if np.any(np.abs(gps.t[g] - t) > 1e-6):
        raise ConfigError("paper001: the filter epochs must fall on GPS fixes (latency 0)")
    heading_sigma = np.where(gps.heading_valid[g], gps.heading_sigma[g], np.nan)
    return Paper001Episode(
        **flags,
        seed=seed, t=t, imu_dt=dt, dtheta=dtheta, dv=dv, gps_lat=gps.lat[g],
        gps_lon=gps.lon[g], gps_h=gps.h[g], gps_v_n=gps.v_n[g],
        gps_heading_sigma=heading_sigma, true_lat=truth.lat[idx], true_lon=truth.lon[idx],
        true_h=truth.h[idx], true_v_n=truth.v_n[idx],
        lever_arm_b=lever_arm_b, coarse_error=misalignment(C_b_n_true[n_coarse], C_coarse),
        C_s_n_true=quat_to_dcm(truth.q_s_n[idx]), C_b_n_true=C_b_n_true[idx],
        C_s_b=np.broadcast_to(np.eye(3), (idx.size, 3, 3)).copy(),
        gyro_bias=episode.imu_realization.gyro.bias,
        accel_bias=episode.imu_realization.accel.bias,
        lat=float(truth.lat[0]), h=float(truth.h[0]))


def model_inputs(episodes: list[Paper001Episode], start_error: np.ndarray) -> GpsInsInputs:
    """The model's inputs for a batch; each INS starts at the first epoch from the true
    attitude turned by its start error (phi E, N, U, rad: C = exp(-[phi x]) C_true),
    from the GPS fix less the lever arm, and at the GPS velocity less the lever arm's
    (C_b^n (w_nb x l), w_nb the gyros' rate at the first fix, ``ins_start_at_fix``)."""
    inputs = []
    for e, phi in zip(episodes, start_error):
        C_b_n0 = rotvec_to_dcm(-phi) @ e.C_s_n_true[0]
        inputs.append(GpsInsInputs(
            **e.gnss_inputs(), gps_heading_sigma=e.gps_heading_sigma[None],
            lever_arm_b=e.lever_arm_b[None],
            **ins_start_at_fix(C_b_n0, e.gps_lat[0], e.gps_lon[0], e.gps_h[0], e.gps_v_n[0],
                               e.lever_arm_b, e.dtheta[0], e.imu_dt)))
    return stack_episodes(inputs, shared=("t", "imu_dt"))


# --- metrics -------------------------------------------------------------------------------
def _enu_error(lat, lon, h, true_lat, true_lon, true_h) -> np.ndarray:
    """Estimated minus true position (..., 3) m along the true E, N, U."""
    d = geodetic_to_ecef(lat, lon, h) - geodetic_to_ecef(true_lat, true_lon, true_h)
    return np.einsum("...ji,...j->...i", C_n_e(true_lat, true_lon), d)


def navigation_errors(run, episodes: list[Paper001Episode]) -> tuple[np.ndarray, np.ndarray]:
    """Position (m) and velocity (m/s) errors (B, K+1, 3) E, N, U of a run's INS."""
    s = run.result.series
    K = run.result.t.size
    truth = lambda name: np.stack([getattr(e, name)[:K] for e in episodes])  # noqa: E731
    pos = _enu_error(s["lat"], s["lon"], s["h"], truth("true_lat"), truth("true_lon"),
                     truth("true_h"))
    return pos, s["v_n"] - truth("true_v_n")


def state_errors(result, episodes: list[Paper001Episode], error_n: np.ndarray) -> np.ndarray:
    """Filter estimate minus truth (B, K+1, 15) in the state's e frame: INS position and
    velocity errors, misalignment, estimated minus drawn biases."""
    s, K = result.series, result.t.size
    truth = lambda name: np.stack([getattr(e, name)[:K] for e in episodes])  # noqa: E731
    C_ne = C_n_e(s["lat"], s["lon"])
    dr = geodetic_to_ecef(s["lat"], s["lon"], s["h"]) - geodetic_to_ecef(
        truth("true_lat"), truth("true_lon"), truth("true_h"))
    dv = np.einsum("bkij,bkj->bki", C_ne, s["v_n"] - truth("true_v_n"))
    # C_true = exp([phi^n x]) C_est: the filter's phi (C~ = (I - [phi x]) C) in e.
    phi = np.einsum("bkij,bkj->bki", C_ne, error_n)
    x = result.x
    return np.concatenate([
        x[..., POSITION] - dr, x[..., VELOCITY] - dv, x[..., PHI] - phi,
        s["gyro_bias"] + x[..., GYRO] - np.stack([e.gyro_bias for e in episodes])[:, None],
        s["accel_bias"] + x[..., ACCEL] - np.stack([e.accel_bias for e in episodes])[:, None],
    ], -1)


def _motion(episodes, K: int, speed: float = 1.0) -> np.ndarray:
    """(B, K+1) epochs in motion (true horizontal speed above ``speed`` m/s)."""
    v = np.stack([e.true_v_n[:K] for e in episodes])
    return np.hypot(v[..., 0], v[..., 1]) > speed


def _turning(episodes, K: int, rate: float) -> np.ndarray:
    """(B, K+1) epochs whose true heading changes faster than rate (rad/s)."""
    psi = np.stack([heading_cw(e.C_b_n_true[:K]) for e in episodes])
    t = episodes[0].t[:K]
    d = np.abs(np.gradient(np.unwrap(psi, axis=1), t, axis=1))
    return d > rate


def _finite_mean(values: np.ndarray, axis=None) -> np.ndarray:
    """Mean of the finite values along axis; NaN where there are none (an episode that
    never moves in a short run: no motion metrics), without numpy's empty-slice
    warning."""
    finite = np.isfinite(values)
    count = finite.sum(axis=axis)
    total = np.where(finite, values, 0.0).sum(axis=axis)
    return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _masked_rms(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """RMS over the masked epochs per episode, then RMS over episodes; values (B, K, ...);
    NaN where no epoch is masked."""
    m = mask.reshape(mask.shape + (1,) * (values.ndim - mask.ndim))
    sq = np.where(m & np.isfinite(values), values ** 2, np.nan)
    return np.sqrt(_finite_mean(_finite_mean(sq, axis=1), axis=0))


def scheme_metrics(result: CampaignResult, run) -> dict:
    """One scheme's metrics in motion (see ``paper001_summary``)."""
    exp, episodes = result.experiment, result.episodes
    K = run.result.t.size
    moving = _motion(episodes, K)
    diff = run.result.series["gps_difference"]
    sel = np.where(moving[..., None] & np.isfinite(diff), diff, np.nan)
    spread = (sel - _finite_mean(sel, axis=1)[:, None]) ** 2
    std = np.sqrt(_finite_mean(_finite_mean(spread, axis=1), axis=0))  # per episode, RMS'd
    pos, vel = navigation_errors(run, episodes)
    turning = _turning(episodes, K, exp.turn_rate_deg_s * deg) & moving
    gps_heading = np.stack([np.arctan2(e.gps_v_n[:K, 0], e.gps_v_n[:K, 1]) for e in episodes])
    ins_heading = heading_cw(run.result.series["C_b_n"])
    heading_diff = wrap_angle(ins_heading - gps_heading)
    return {
        "pos_std_m": std[:3].tolist(), "vel_std_m_s": std[3:].tolist(),
        "pos_error_rms_m": _masked_rms(pos, moving).tolist(),
        "vel_error_rms_m_s": _masked_rms(vel, moving).tolist(),
        "heading_rms_deg": float(_masked_rms(run.euler_error[..., 2], moving) / deg),
        "attitude_rms_arcmin": (_masked_rms(run.euler_error, moving) / arcmin).tolist(),
        "heading_gps_difference_turns_deg": float(_masked_rms(heading_diff, turning) / deg),
        "heading_gps_difference_straight_deg": float(
            _masked_rms(heading_diff, moving & ~turning) / deg),
        "nees_mean": float(_finite_mean(np.where(moving, run.nees, np.nan)[:, 1:])),
        **status_fractions(run.status)}


def outage_metrics(result: CampaignResult, run) -> dict | None:
    """At the last epoch of the experiment's GPS outage (the epochs without a fix): the
    horizontal position error (m), the filter's own 3-sigma horizontal bound (m) and
    their ratio (means over episodes); after it, the re-convergence time
    (s): from the first fix to the start of the first 10-s window whose RMS horizontal
    position and velocity errors are within twice their RMS over the 60 s before the
    outage (mean over episodes; inf if none is)."""
    exp = result.experiment
    if exp.outage <= 0.0:
        return None
    start, end = exp.outage_window(exp.scenario_config())
    t = result.episodes[0].t[: run.result.t.size]
    pos, vel = navigation_errors(run, result.episodes)
    horizontal = np.hypot(pos[..., 0], pos[..., 1])
    speed_error = np.hypot(vel[..., 0], vel[..., 1])
    inside = (t >= start) & (t < end)
    before = (t >= start - 60.0) & (t < start)
    k_end = int(np.flatnonzero(inside)[-1])
    worst = horizontal[:, k_end]
    lat = run.result.series["lat"][:, k_end]
    lon = run.result.series["lon"][:, k_end]
    C_en = np.swapaxes(C_n_e(lat, lon), -1, -2)
    P_n = C_en @ run.result.P[:, k_end, POSITION, POSITION] @ np.swapaxes(C_en, -1, -2)
    bound = 3.0 * np.sqrt(P_n[:, 0, 0] + P_n[:, 1, 1])
    window = 10
    rms_before = lambda e: np.sqrt(np.mean(e[:, before] ** 2, axis=1))  # noqa: E731
    running = lambda e: np.sqrt(np.convolve(e ** 2, np.ones(window) / window,  # noqa: E731
                                            mode="valid"))
    level, speed_level = 2.0 * rms_before(horizontal), 2.0 * rms_before(speed_error)
    k_after = int(np.flatnonzero(t >= end)[0])
    recovered = []
    for b in range(horizontal.shape[0]):
        back = np.flatnonzero((running(horizontal[b, k_after:]) <= level[b])
                              & (running(speed_error[b, k_after:]) <= speed_level[b]))
        recovered.append(float(t[k_after + back[0]] - end) if back.size else np.inf)
    return {"window_s": [start, end], "horizontal_error_m": float(worst.mean()),
            "horizontal_3sigma_m": float(bound.mean()),
            "error_over_3sigma": float(np.mean(worst / bound)),
            "reconvergence_s": float(np.mean(recovered))}


def outlier_metrics(result: CampaignResult, run) -> list[dict]:
    """Per scenario outlier: the horizontal position error (m) of the INS after the
    faulty fix and before it (mean over episodes), and the scheme's smallest weight on a
    position component at that fix (1: taken at face value)."""
    config = result.experiment.scenario_config()
    t = result.episodes[0].t[: run.result.t.size]
    pos, _ = navigation_errors(run, result.episodes)
    horizontal = np.hypot(pos[..., 0], pos[..., 1])
    out = []
    for when, *offset in config.gps.outliers:
        k = int(np.argmin(np.abs(t - when)))
        if not 0 < k < t.size:
            continue
        factors = run.result.factors[:, k - 1]
        weights = _position_weights(run.filter, factors)
        out.append({"time_s": when, "offset_m": offset,
                    "horizontal_error_before_m": float(horizontal[:, k - 1].mean()),
                    "horizontal_error_after_m": float(horizontal[:, k].mean()),
                    "position_weight": weights})
    return out


def _position_weights(name: str, factors: np.ndarray) -> float | None:
    """Smallest observation weight on the position rows at one epoch (mean over
    episodes); None for filters without observation weights."""
    if name == "rakf":
        return float(factors[:, 1:4].min(1).mean())
    if name == "swakf":
        m = factors.shape[-1] // 2
        return float(factors[:, m: m + 3].min(1).mean())
    return None


def paper001_summary(result: CampaignResult) -> dict:
    """{"schemes": {FILTER: {pos_std_m [3], vel_std_m_s [3] (E, N, U; std of the filtered
    INS - GPS differences in motion, per episode then RMS over episodes), improvement_pct
    {pos, vel} over lckf, pos_error_rms_m, vel_error_rms_m_s [3] against the truth,
    heading_rms_deg, attitude_rms_arcmin [pitch, roll, heading], heading_gps_difference
    _turns_deg / _straight_deg (INS heading - GPS heading), nees_mean (in motion),
    the status fractions (``metrics.status_fractions``), outage {...}, outliers [...]}}}."""
    schemes = {run.filter: scheme_metrics(result, run) for run in result.runs}
    classic = schemes.get("lckf")
    for run in result.runs:
        s = schemes[run.filter]
        if classic is not None:
            s["improvement_pct"] = {
                key: [100.0 * (c - v) / c for c, v in zip(classic[field], s[field])]
                for key, field in (("pos", "pos_std_m"), ("vel", "vel_std_m_s"))}
        outage = outage_metrics(result, run)
        if outage is not None:
            s["outage"] = outage
        outliers = outlier_metrics(result, run)
        if outliers:
            s["outliers"] = outliers
    return {"schemes": schemes}


def format_tables(result: CampaignResult) -> str:
    """Table 1's shape (std of the INS - GPS differences, improvement over the classic
    scheme), then the errors against the truth and the heading in turns."""
    summary = paper001_summary(result)["schemes"]
    n = len(result.seeds)
    lines = [f"Figure-8 GPS/INS, {n} runs, in motion: std of the filtered INS - GPS "
             "differences (position cm, velocity mm/s; E N U) and improvement over lckf (%)",
             f"{'scheme':8s}" + "".join(f"{'pos ' + a:>9s}" for a in AXES_ENU)
             + "".join(f"{'vel ' + a:>9s}" for a in AXES_ENU) + f"{'impr pos %':>22s}"]
    for name, s in summary.items():
        impr = s.get("improvement_pct", {}).get("pos", [np.nan] * 3)
        lines.append(f"{name:8s}" + "".join(f"{100 * v:9.2f}" for v in s["pos_std_m"])
                     + "".join(f"{1000 * v:9.2f}" for v in s["vel_std_m_s"])
                     + "".join(f"{v:8.1f}" for v in impr[:2]) + f"{impr[2]:6.1f}")
    lines += ["", "Against the truth, in motion (RMS): position cm, velocity mm/s, attitude "
              "arcmin; heading - GPS heading (deg) in turns / straights",
              f"{'scheme':8s}{'pos E':>8s}{'pos N':>8s}{'pos U':>8s}{'vel E':>8s}{'vel N':>8s}"
              f"{'vel U':>8s}{'pitch':>8s}{'roll':>8s}{'head':>8s}{'turns':>8s}{'straight':>9s}"
              f"{'NEES':>7s}" + STATUS_HEADER]
    for name, s in summary.items():
        lines.append(f"{name:8s}" + "".join(f"{100 * v:8.2f}" for v in s["pos_error_rms_m"])
                     + "".join(f"{1000 * v:8.2f}" for v in s["vel_error_rms_m_s"])
                     + "".join(f"{v:8.2f}" for v in s["attitude_rms_arcmin"])
                     + f"{s['heading_gps_difference_turns_deg']:8.3f}"
                     + f"{s['heading_gps_difference_straight_deg']:9.3f}"
                     + f"{s['nees_mean']:7.1f}" + status_columns(s))
    if any("outage" in s for s in summary.values()):
        lines += ["", "GPS outage, at its last epoch: horizontal error (m), the filter's "
                  "3-sigma (m); re-convergence after it (s)"]
        for name, s in summary.items():
            o = s["outage"]
            lines.append(f"{name:8s}{o['horizontal_error_m']:10.3f}"
                         f"{o['horizontal_3sigma_m']:10.3f}{o['reconvergence_s']:10.1f}")
    if any("outliers" in s for s in summary.values()):
        lines += ["", "GPS outliers: horizontal error before / after the fix (m), position "
                  "weight"]
        for name, s in summary.items():
            for o in s.get("outliers", []):
                w = "-" if o["position_weight"] is None else f"{o['position_weight']:.3g}"
                lines.append(f"{name:8s}t={o['time_s']:7.1f} s{o['horizontal_error_before_m']:9.3f}"
                             f"{o['horizontal_error_after_m']:9.3f}  {w}")
    return "\n".join(lines)


@dataclass(frozen=True)
class Paper001Experiment(Experiment):
    """Settings (SPEC 4.3; assumed values marked). Times in s, speeds in m/s.

    coarse: "static", the analytic coarse alignment over [0, coarse_duration] (in the
    stationary phase), or "moving", the GPS-velocity-aided alignment in motion
    (ALGORITHMS 1.2, lever arm compensated) over [coarse_start, coarse_start +
    coarse_duration] (coarse_start None: when the car starts to move); coarse_duration:
    60 s *assumed*; fine_duration: the filter's run after the coarse stage (None: to the
    end of the scenario); filter_step: filter epoch = GPS fix interval;
    attitude_sigma_deg: the filter's P0 misalignment E, N, U (*assumed*: level 0.1 deg,
    heading 10 deg, above the coarse stage's few degrees); accel_noise_density: the
    filter's accelerometer white noise, m/s/sqrt(s) (the paper prints none; *assumed*
    1e-4, a floor when the IMU spec has less); heading_min_speed: the GPS heading is used
    above this horizontal speed (001: ~10 m/s for 0.1 deg; 5 *assumed*); motion_speed: the
    adaptive filters act above this INS speed (classic KF while static); outage: length
    of a GPS outage in the middle of the motion phase (0: none); outage_start: its start
    (None: centred in the motion phase); turn_rate_deg_s: epochs turning faster than this
    count as "turns" in the heading table; heading_point: the body point whose velocity
    direction the GPS heading is taken to be: "antenna" (001: the antenna's own track,
    off the body heading by the kinematic sideslip, about (antenna - rear axle) / turn
    radius) or "rear-axle" (the GPS velocity moved to the rear axle's centre with the
    INS's rate and attitude, where the velocity is along the body if the rear tyres do
    not slip); heading_threshold_arcmin: heading convergence threshold; setup: "default"
    or "paper" (``PAPER_SETUP``).
    """

    scenario: str = "figure8-gps"
    coarse: str = setting("static", "the coarse alignment: static analytic in the first 60 "
                          "s, or GPS-velocity-aided over the first 60 s of motion (the "
                          "filter then starts in motion)", choices=("static", "moving"))
    coarse_start: float | None = bounded(None, "s", low=0.0, high=MAX_RUN)
    coarse_duration: float = bounded(60.0, "s", low=0.0, high=MAX_RUN, low_open=True)
    fine_duration: float | None = bounded(None, "s", low=0.0, high=MAX_RUN, low_open=True)
    filter_step: float = bounded(1.0, "s", **POSITIVE)
    attitude_sigma_deg: tuple[float, float, float] = bounded((0.1, 0.1, 10.0), "deg",
                                                             **POSITIVE)
    accel_noise_density: float = bounded(1e-4, "m/s/sqrt(s)", low=0.0)
    heading_min_speed: float = bounded(5.0, "m/s", low=0.0)
    motion_speed: float = bounded(0.5, "m/s", low=0.0)
    outage: float = setting(0.0, "a GPS outage of this length in the middle of the motion "
                            "phase (0: none)", unit="s", low=0.0, high=MAX_RUN)
    outage_start: float | None = bounded(None, "s", low=0.0, high=MAX_RUN)
    turn_rate_deg_s: float = bounded(3.0, "deg/s", low=0.0)
    heading_point: str = setting("antenna", "the body point whose velocity gives the GPS "
                                 "heading: the antenna (the paper) or the rear axle (no "
                                 "kinematic sideslip)", choices=("antenna", "rear-axle"))
    heading_sigma: str = setting("eq4", "the GPS heading's sigma: 001 eq. 4's alone, or "
                                 "with the kinematic sideslip of the heading point (its "
                                 "distance ahead of the rear axle x yaw rate / speed)",
                                 choices=("eq4", "sideslip"))
    rms_window: float = bounded(60.0, "s", **POSITIVE)
    heading_threshold_arcmin: float = bounded(30.0, "arcmin", **POSITIVE)
    setup: str = "default"
    default_filters: tuple[str, ...] = SCHEMES

    paper = "001"
    regress = {"episodes": 2, "seed": 11, "filters": ["lckf", "rakf", "swakf"],
               "experiment": {"fine_duration": 300.0}}
    reproduce = {"episodes": 20, "seed": 0}
    claims = (
        Claim("The GPS heading constraint and the adaptive filters shrink the INS - GPS "
              "position differences against the classic KF by more than 70 %",
              "001 sec. 5, abstract",
              {"swakf E %": "schemes/swakf/improvement_pct/pos/0",
               "swakf N %": "schemes/swakf/improvement_pct/pos/1",
               "rakf E %": "schemes/rakf/improvement_pct/pos/0",
               "rakf N %": "schemes/rakf/improvement_pct/pos/1"},
              lambda n: min(n.values()) > 70.0,
              "our classic KF's INS - GPS difference is already centimetres with RTK fixes "
              "(PSINS's 15-state KF ends within 0.012 cm of lckf: benchmarks/psins/"
              "lckf_001.py), so a 70 % cut has no room "
              "(docs/paper001.md)"),
        Claim("The GPS heading constraint and the adaptive filters shrink the INS - GPS "
              "position differences against the classic KF by more than 70 %",
              "001 sec. 5, abstract",
              {"swakf E %": "schemes/swakf/improvement_pct/pos/0",
               "swakf N %": "schemes/swakf/improvement_pct/pos/1",
               "rakf E %": "schemes/rakf/improvement_pct/pos/0",
               "rakf N %": "schemes/rakf/improvement_pct/pos/1"},
              lambda n: min(n.values()) > 70.0,
              "close to the line: 20 episodes (seed 0) gave 77.7 / 76.5 % (rakf) and 71.8 / "
              "70.2 % (swakf); the cut grows with the unmodelled misalignment (60\": 40 %, "
              "150\": 68 %, docs/paper001.md)", setup="paper"),
        Claim("The heading constraint makes the attitude estimate more accurate than the "
              "classic KF's", "001 abstract, sec. 5",
              {"lckf heading RMS deg": "schemes/lckf/heading_rms_deg",
               "rakf deg": "schemes/rakf/heading_rms_deg",
               "swakf deg": "schemes/swakf/heading_rms_deg"},
              lambda n: max(n["rakf deg"], n["swakf deg"]) < n["lckf heading RMS deg"],
              "the antenna-track heading ignores the sideslip: rakf and swakf end 13-21' off "
              "with sigma 1.5-2.5' (NEES 86-141), issue 27 item 3"),
        Claim("The selective-weight adaptive KF is better than the robust adaptive KF",
              "001 sec. 4-5",
              {"swakf heading RMS deg": "schemes/swakf/heading_rms_deg",
               "rakf deg": "schemes/rakf/heading_rms_deg"},
              lambda n: n["swakf heading RMS deg"] < n["rakf deg"],
              "both carry the same heading-measurement bias (the sideslip); the selective "
              "weights do not remove a bias"),
    )
    setups = {"paper": PAPER_SETUP}
    worlds = ("car",)
    requires = (SensorTable("gps"), StrapdownImu(), StepOnFixes("GPS"))
    model_variants = ("position-velocity",)
    state_count = 15
    observation_features = frozenset({"conditionally-linear", "directions"})
    filter_settings = Experiment.filter_settings | {"accel_noise_density", "attitude_sigma_deg"}
    starts = (START,)

    episode_class = Paper001Episode
    preparation = staticmethod(prepare_episode)
    truth_map = TruthMap(LAYOUT, ("position", "velocity", "misalignment", "gyro_bias",
                                  "accel_bias"), state_errors)
    summarise = staticmethod(paper001_summary)
    tabulate = staticmethod(format_tables)

    @property
    def duration(self) -> float:
        if self.fine_duration is None:
            return self.scenario_file().duration
        return self.coarse_window(self.scenario_file())[1] + self.fine_duration

    def coarse_window(self, config: ScenarioConfig) -> tuple[float, float]:
        """(start, end) s of the coarse alignment; the filter starts at its end."""
        start = 0.0
        if self.coarse == "moving":
            start = (config.motion.start_time if self.coarse_start is None
                     else self.coarse_start)
        return start, start + self.coarse_duration

    def scenario_config(self) -> ScenarioConfig:
        """The scenario with this experiment's duration and its GPS outage, checked."""
        config = super().scenario_config()
        self.check(config)
        if self.outage > 0.0:
            start = self.outage_window(config)[0]
            gps = replace(config.gps, outages=config.gps.outages
                          + ((start, start + self.outage),))
            config = replace(config, gps=gps)
        return config

    def outage_window(self, config: ScenarioConfig) -> tuple[float, float]:
        """(start, end) s of the experiment's GPS outage."""
        start = self.outage_start
        if start is None:
            moving = config.motion.start_time
            start = 0.5 * (moving + config.duration) - 0.5 * self.outage
        return start, start + self.outage

    def check(self, config: ScenarioConfig) -> None:
        super().check(config)
        if self.coarse not in COARSE:
            raise ConfigError(f"coarse = {self.coarse!r}; valid: " + ", ".join(COARSE))
        if self.coarse == "static" and not 0.0 < self.coarse_duration <= \
                config.motion.start_time:
            raise SettingError("coarse_duration", self.coarse_duration,
                               f"= {self.coarse_duration:g} s must be in "
                               f"(0, {config.motion.start_time:g}] s (the stationary phase)")
        if self.coarse == "moving":
            start, end = self.coarse_window(config)
            if not (self.coarse_duration >= 3.0 / config.gps.rate
                    and config.motion.start_time <= start and end < config.duration):
                raise ConfigError(f"the moving coarse alignment's window [{start:g}, "
                                  f"{end:g}] s must lie in the motion phase "
                                  f"[{config.motion.start_time:g}, {config.duration:g}) s "
                                  "and hold >= 3 GPS fixes")
        if self.fine_duration is not None and not self.fine_duration >= self.filter_step:
            raise ConfigError(f"fine_duration = {self.fine_duration:g} s must be >= "
                              f"filter_step = {self.filter_step:g} s")
        if not (np.isfinite(self.heading_min_speed) and self.heading_min_speed >= 0.0):
            raise ConfigError(f"heading_min_speed = {self.heading_min_speed:g} m/s must be "
                              ">= 0")
        if self.heading_point not in HEADING_POINTS:
            raise ConfigError(f"--heading-point {self.heading_point!r}; valid: "
                              + ", ".join(HEADING_POINTS))
        if self.heading_sigma not in ("eq4", "sideslip"):
            raise ConfigError(f"--heading-sigma {self.heading_sigma!r}; valid: eq4, sideslip")
        if not (np.isfinite(self.outage) and self.outage >= 0.0):
            raise ConfigError(f"--outage {self.outage:g} s must be >= 0")
        if self.outage > 0.0:
            start, end = self.outage_window(config)
            first = self.coarse_window(config)[1]
            if not (first < start and end < config.duration):
                raise SettingError("outage", self.outage, f"{self.outage:g} s: the window "
                                   f"[{start:g}, {end:g}] s must lie inside the filter's run "
                                   f"({first:g}, {config.duration:g}) s")

    def tuning(self, config: ScenarioConfig, heading: bool = True) -> LooseTuning:
        imu = ImuTuning.from_spec(config.imu)
        gps = config.gps
        motion = config.motion
        offset = (np.zeros(3) if self.heading_point == "antenna" else
                  np.subtract(motion.car_params().rear_axle_b, motion.gps_antenna_b))
        return LooseTuning(
            position_sigma=max(gps.position_sigma_h, gps.position_sigma_v, 0.01),
            velocity_sigma=max(gps.velocity_sigma, 0.01),
            attitude_sigma=tuple(a * deg for a in self.attitude_sigma_deg),
            gyro_bias_sigma=imu.gyro_bias_sigma, accel_bias_sigma=max(imu.accel_bias_sigma,
                                                                      1e-6),
            gyro_noise_density=imu.gyro_noise_density,
            accel_noise_density=max(imu.accel_noise_density, self.accel_noise_density),
            gps_position_sigma_h=gps.position_sigma_h, gps_position_sigma_v=gps.position_sigma_v,
            gps_velocity_sigma=gps.velocity_sigma, use_heading=heading,
            heading_min_speed=self.heading_min_speed, motion_speed=self.motion_speed,
            heading_offset_b=tuple(float(v) for v in offset),
            heading_sideslip_arm=(0.0 if self.heading_sigma == "eq4" else float(
                np.subtract(motion.gps_antenna_b, motion.car_params().rear_axle_b)[1]
                + offset[1])))

    def start_errors(self, episodes):
        return {START: np.stack([e.coarse_error for e in episodes])}

    def model(self, episodes, start_error, variant=""):
        if variant not in ("", "position-velocity"):
            raise ValueError(f"paper001 has no model variant {variant!r}")
        start_error = np.broadcast_to(np.asarray(start_error, float), (len(episodes), 3))
        config = self.scenario_config()
        tuning = self.tuning(config, heading=variant == "")
        return LooselyCoupledModel(model_inputs(episodes, start_error), tuning)


EXPERIMENT = Paper001Experiment
"""This module's experiment (``scenarios.experiments``)."""
