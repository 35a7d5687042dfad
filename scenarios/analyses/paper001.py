"""Paper 001's own analysis of a campaign: the navigation errors (ENU, m and m/s), the
schemes' accuracy while moving and turning, the GNSS outage and the outlier epochs; the
JSON summary and the paper-shaped tables (``scenarios.experiments.paper001`` declares
them)."""
from __future__ import annotations

import numpy as np

from aligngym.estimators.loose_gps import POSITION, heading_cw
from aligngym.estimators.model import wrap_angle
from aligngym.models.earth import C_n_e, geodetic_to_ecef
from aligngym.models.units import arcmin, deg
from aligngym.scenarios.campaign import CampaignResult, GnssEpisode
from aligngym.scenarios.campaign.results import STATUS_HEADER, status_columns
from aligngym.estimators.metrics import status_fractions


AXES_ENU = ("E", "N", "U")


def _enu_error(lat, lon, h, true_lat, true_lon, true_h) -> np.ndarray:
    """Estimated minus true position (..., 3) m along the true E, N, U."""
    d = geodetic_to_ecef(lat, lon, h) - geodetic_to_ecef(true_lat, true_lon, true_h)
    return np.einsum("...ji,...j->...i", C_n_e(true_lat, true_lon), d)


def navigation_errors(run, episodes: list[GnssEpisode]) -> tuple[np.ndarray, np.ndarray]:
    """Position (m) and velocity (m/s) errors (B, K+1, 3) E, N, U of a run's INS."""
    s = run.result.series
    K = run.result.t.size
    truth = lambda name: np.stack([getattr(e, name)[:K] for e in episodes])  # noqa: E731
    pos = _enu_error(s["lat"], s["lon"], s["h"], truth("true_lat"), truth("true_lon"),
                     truth("true_h"))
    return pos, s["v_n"] - truth("true_v_n")


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
