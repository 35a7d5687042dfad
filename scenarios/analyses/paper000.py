"""Paper 000's own analysis of a campaign: per run the errors against the static
reference after the stop and against the truth, the innovation test's flags, the
odometer scale and mounting estimates; the JSON summary, the paper-shaped tables and the
sensor-estimate plot (``scenarios.experiments.paper000`` declares them)."""
from __future__ import annotations

import numpy as np

from aligngym.estimators.metrics import euler_error, status_fractions
from aligngym.estimators.odometer_large import KD, MOUNT_PITCH
from aligngym.models.units import arcmin, deg
from aligngym.scenarios.atomic import save_figure
from aligngym.scenarios.campaign import CampaignResult
from aligngym.scenarios.campaign.results import STATUS_HEADER, status_columns


NIS_LIMIT = 16.27
"""Innovation test: chi-square with 3 degrees of freedom at 0.999."""


ANGLES = ("pitch", "roll", "heading")


def _stats(errors: np.ndarray) -> dict:
    """mean, std, RMS over episodes of (B, 3) errors in rad -> arcmin lists."""
    e = errors / arcmin
    return {"mean_arcmin": e.mean(0).tolist(), "std_arcmin": e.std(0).tolist(),
            "rms_arcmin": np.sqrt((e ** 2).mean(0)).tolist()}


def run_metrics(result: CampaignResult, run) -> dict:
    """One filter from one start: errors at the stop against the truth and the static
    reference ([pitch, roll, heading]), the odometer scale and mounting estimates'
    errors, the innovation test's flags (all, and within 1 epoch after a slip burst)."""
    episodes = result.episodes
    k = np.array([e.k_stop for e in episodes])
    b = np.arange(len(episodes))
    C_est = run.result.C_s_n[b, k]                                    # IMU frame
    vs_truth = euler_error(np.stack([e.C_s_n_true[i] for e, i in zip(episodes, k)]), C_est)
    vs_reference = euler_error(np.stack([e.C_reference for e in episodes]), C_est)
    series, x = run.result.series, run.result.x
    scale = series["scale"][b, k] * (1.0 + x[b, k, KD])
    true = np.array([e.odometer_scale_true for e in episodes])
    dkd_error = scale * (1.0 + true) - 1.0                            # relative
    K = run.result.t.size
    v_error = series["v_n"] - np.stack([e.true_v_n[:K] for e in episodes])
    t = episodes[0].t[:K]
    t_stop = t[np.minimum(k, K - 1)][:, None] - 5.0         # the stop command (k: 5 s after)
    moving = (t[None] >= t_stop - 60.0) & (t[None] < t_stop)          # the last 60 s driving
    out = {"vs_truth": _stats(vs_truth), "vs_reference": _stats(vs_reference),
           "velocity_error_rms_m_s": np.sqrt(np.nanmean(np.where(
               moving[..., None], v_error ** 2, np.nan), axis=(0, 1))).tolist(),
           **status_fractions(run.status),
           "dkd_error_ppm": float(np.sqrt(np.mean(dkd_error ** 2)) * 1e6),
           "heading_convergence_s": float(np.mean(run.heading_convergence))}
    if "mounting" in series and x.shape[-1] > MOUNT_PITCH:
        mount = series["mounting"][b, k] + x[b, k, MOUNT_PITCH:]
        truth = np.stack([e.mounting for e in episodes])
        out["mounting_error_deg"] = (np.sqrt(np.mean((mount - truth) ** 2, 0)) / deg).tolist()
    nis = run.result.nis
    flagged = nis > NIS_LIMIT
    out["flagged_epochs"] = float(np.mean(np.sum(flagged, axis=1)))
    if episodes[0].slips.size:
        t = episodes[0].t[: run.result.t.size]         # the run's epochs, s of the episode
        step = t[1] - t[0]
        hits = []
        for i, e in enumerate(episodes):
            for start, duration, _ in e.slips:
                # Flagged at the update that ends the burst's epoch, or the next one.
                window = (t[1:] > start) & (t[1:] <= start + duration + step + 1e-9)
                hits.append(bool(flagged[i, window].any()))
        out["slip_bursts_flagged"] = float(np.mean(hits))
    return out


def paper000_summary(result: CampaignResult) -> dict:
    """{"fine": {FILTER: {"vs_truth": {"mean_arcmin", "std_arcmin", "rms_arcmin"} (pitch,
    roll, heading at the stop), "vs_reference": {...}, "velocity_error_rms_m_s" (E, N, U,
    over the last 60 s of driving), the status fractions (``metrics.status_fractions``),
    "dkd_error_ppm", "heading_convergence_s", "mounting_error_deg" [pitch, heading],
    "flagged_epochs", "slip_bursts_flagged"}}} for the coarse start, and the same under
    "fine_large" for the large-heading start; "coarse": the coarse stage's Euler errors."""
    out = {"fine": {}, "fine_large": {}}
    for run in result.runs:
        key = "fine" if run.start == "coarse" else "fine_large"
        out[key][run.filter] = run_metrics(result, run)
    out["coarse"] = _stats(np.stack([e.coarse_error for e in result.episodes]))
    return out


def format_tables(result: CampaignResult) -> str:
    """The paper's table: per filter, the error at the stop against the reference and
    against the truth (mean and std over episodes, arcmin), and the odometer estimates."""
    summary = paper000_summary(result)
    coarse = summary["coarse"]
    lines = [f"Ring road, {len(result.seeds)} runs. Coarse (odometer-aided, in motion), "
             "Euler error E, N, U (arcmin): mean " + " ".join(
                 f"{v:8.2f}" for v in coarse["mean_arcmin"]) + ", std " + " ".join(
                 f"{v:8.2f}" for v in coarse["std_arcmin"])]
    for key, label in (("fine", "from the coarse alignment"),
                       ("fine_large", f"from a {result.experiment.large_heading_deg:g} deg "
                                      "heading error")):
        lines += ["", f"At the stop, {label}: pitch, roll, heading (arcmin) against the "
                  "static reference / the truth",
                  f"{'filter':8s}{'stat':6s}" + "".join(f"{'ref ' + a:>12s}" for a in ANGLES)
                  + "".join(f"{'true ' + a:>13s}" for a in ANGLES)
                  + f"{'dK_D ppm':>10s}{'mount deg':>14s}{'v mm/s':>8s}{'flagged':>9s}"
                  + STATUS_HEADER]
        for name, s in summary[key].items():
            for stat in ("mean", "std"):
                tail = ""
                if stat == "mean":
                    mount = s.get("mounting_error_deg")
                    mount = "-" if mount is None else "/".join(f"{v:.2f}" for v in mount)
                    v = 1000 * np.hypot(*s["velocity_error_rms_m_s"][:2])
                    tail = (f"{s['dkd_error_ppm']:10.0f}{mount:>14s}{v:8.1f}"
                            f"{s['flagged_epochs']:9.1f}" + status_columns(s))
                lines.append(f"{name if stat == 'mean' else '':8s}{stat:6s}"
                             + "".join(f"{v:12.2f}" for v in s["vs_reference"][f"{stat}_arcmin"])
                             + "".join(f"{v:13.2f}" for v in s["vs_truth"][f"{stat}_arcmin"])
                             + tail)
    return "\n".join(lines)


def plot_sensor_estimates(result: CampaignResult, out) -> list:
    """sensor_estimates.png: on the first episode, each filter's (coarse start) estimates
    of the odometer scale error (ppm), the mounting pitch and heading (deg) and the gyro
    drifts (deg/h) with their +-3 sigma bounds, against the truth (dashed black); each
    panel zoomed on the tightest filter's final band."""
    from aligngym.scenarios.figures import DPI, PNG_OPTIONS, pyplot
    plt = pyplot()
    from aligngym.models.units import deg_per_h

    runs = [r for r in result.runs if r.start == "coarse"]
    if not runs:
        return []
    e = result.episodes[0]
    fig, axes = plt.subplots(3, 2, figsize=(11, 9), sharex=True)
    panels = [("dK_D (ppm)", KD, 1e6, None), ("mounting pitch (deg)", MOUNT_PITCH, 1 / deg,
                                              e.mounting[0]),
              ("mounting heading (deg)", MOUNT_PITCH + 1, 1 / deg, e.mounting[1])] + [
        (f"gyro drift {axis} (deg/h)", 9 + i, 1 / deg_per_h, e.gyro_bias[i])
        for i, axis in enumerate("xyz")]
    true_scale = 1.0 / (1.0 + e.odometer_scale_true) - 1.0
    for ax, (label, i, unit, truth) in zip(axes.ravel(), panels):
        final_sigmas = []
        for j, run in enumerate(runs):
            r = run.result
            if r.x.shape[-1] <= i:
                continue
            t = r.t - r.t[0]
            s = r.series
            base = {KD: s["scale"][0] - 1.0, MOUNT_PITCH: s["mounting"][0, :, 0],
                    MOUNT_PITCH + 1: s["mounting"][0, :, 1]}.get(
                i, s["gyro_bias"][0, :, i - 9] if 9 <= i < 12 else 0.0)
            estimate = (base + r.x[0, :, i]) * unit
            sigma = 3 * np.sqrt(np.maximum(r.P[0, :, i, i], 0.0)) * unit
            ax.plot(t, estimate, color=f"C{j}", label=run.filter)
            ax.fill_between(t, estimate - sigma, estimate + sigma, color=f"C{j}", alpha=0.1)
            final_sigmas.append(sigma[-1])
        truth_value = (true_scale if i == KD else truth) * unit
        ax.axhline(truth_value, color="k", ls="--", lw=0.8)
        if final_sigmas:   # zoom on the best filter's band (a diverged one would hide it)
            span = max(10.0 * min(final_sigmas), 2.0 * abs(truth_value), 1e-9)
            ax.set_ylim(truth_value - span, truth_value + span)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time since the start of fine alignment (s)")
    fig.suptitle(f"Sensor-error estimates, seed {result.seeds[0]} (bands: +-3 sigma; "
                 "dashed: truth)")
    fig.tight_layout()
    path = out / "sensor_estimates.png"
    save_figure(fig, path, dpi=DPI, **PNG_OPTIONS)
    plt.close(fig)
    return [path]
