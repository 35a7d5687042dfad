"""Paper 004's own analysis of a campaign: per run the hull's attitude error over the
accuracy window and the heading convergence; the JSON summary, a swing sweep's levels
merged, the paper-shaped tables and the consistency plot
(``scenarios.experiments.paper004`` declares them)."""
from __future__ import annotations

import numpy as np

from aligngym.estimators.metrics import convergence_time, status_fractions
from aligngym.models.units import deg
from aligngym.scenarios.atomic import save_figure
from aligngym.scenarios.campaign import CampaignResult, Experiment, GnssEpisode
from aligngym.scenarios.campaign.results import STATUS_HEADER, status_columns


HEADING_LIMIT = 1.0 * deg


def run_metrics(run, episodes: list[GnssEpisode], experiment: Experiment) -> dict:
    """One filter's numbers over the episodes: RMS of the hull's pitch, roll, heading
    error over the accuracy window ([rms_start, end], s of scenario time; deg; per
    episode, then RMS over the episodes that did not diverge numerically), heading
    convergence (s of scenario time: first time after which |heading error| <= 1 deg, the
    run's end if never; median and 90th percentile), the status fractions
    (``metrics.status_fractions``), the fraction whose final heading error is beyond 1
    deg or that diverged numerically, NEES (9 states; mean over the same window, then
    over episodes: results.csv's nees_mean per episode), the fraction of epochs whose
    heading error lies inside the filter's own 3 sigma, and the filter's compute time an
    episode-epoch (ms, results.csv's: its batch's share, summed over the
    ms_per_epoch_chunks chunks the batch ran in; before 2026-12-07 the whole batch's)."""
    r = run.result
    t = r.t - r.t[0] + episodes[0].fine_start          # scenario time of the epochs
    window = experiment.accuracy_window(r.t - r.t[0], episodes[0].fine_start)
    ok = ~r.diverged
    err = run.euler_error[:, window]
    rms = np.sqrt(np.mean(err ** 2, axis=1))                      # (B, 3)
    heading = np.abs(run.error_n[..., 2])
    conv = convergence_time(t, heading, HEADING_LIMIT)
    converged = heading[:, -1] <= HEADING_LIMIT
    inside = heading <= 3.0 * r.sigma_n[..., 2]
    nees_window = run.nees[:, window]
    finite = np.isfinite(nees_window)            # a NaN NEES is no number, not a mean's
    count = finite.sum(axis=1)                   # (no empty-slice warning where none is)
    nees_ep = np.where(count > 0, np.where(finite, nees_window, 0.0).sum(axis=1)
                       / np.maximum(count, 1), np.nan)
    sel = ok if ok.any() else np.ones_like(ok)
    return {
        "rms_deg": [float(v) for v in np.sqrt(np.mean(rms[sel] ** 2, axis=0)) / deg],
        "convergence_s": float(np.median(conv)),
        "convergence_p90_s": float(np.percentile(conv, 90)),
        **status_fractions(run.status),
        "heading_outside_1deg_fraction": float(np.mean(~converged | r.diverged)),
        "nees_mean": float(np.nanmean(nees_ep[sel])) if np.isfinite(nees_ep[sel]).any()
        else None,
        "nees_dof": experiment.nees_dof(),
        "heading_inside_3sigma": float(inside[sel].mean()),
        "final_heading_error_deg": float(np.sqrt(np.mean(run.error_n[sel, -1, 2] ** 2)) / deg),
        # an episode's share, as results.csv's (its batch's chunks summed: ``chunks``)
        "ms_per_epoch": r.seconds_per_episode_epoch * 1e3,
        "ms_per_epoch_chunks": int(r.chunks),
    }


def paper004_summary(result: CampaignResult) -> dict:
    """{"fine": {FILTER: {LEVEL: run_metrics}}, "coarse": {LEVEL: ...}, "settings": ...};
    LEVEL is the swing level (or "turntable")."""
    exp = result.experiment
    level = "turntable" if exp.case == "turntable" else exp.swing
    motion = "waves" if exp.scenario_file().world == "ship-waves" else "prescribed"
    end = (float(result.runs[0].result.t[-1] + result.episodes[0].t[0]) if result.runs
           else exp.duration)
    rms_start = exp.accuracy_start(end)
    fine = {run.filter: {level: run_metrics(run, result.episodes, exp)}
            for run in result.runs}
    coarse = np.stack([e.coarse_error for e in result.episodes])
    return {"fine": fine,
            "coarse": {level: {"rms_deg": [float(v) for v in
                                           np.sqrt(np.mean(coarse ** 2, 0)) / deg],
                               "max_abs_deg": [float(v) for v in
                                               np.abs(coarse).max(0) / deg]}},
            "settings": {"case": exp.case, "swing": exp.swing, "motion": motion,
                         "misalignment": exp.misalignment, "episodes": len(result.seeds),
                         "rms_window_s": [rms_start, end]}}


def merge_levels(summaries: list[dict]) -> dict:
    """One JSON of several swing levels' ``paper004_summary``s: {"fine": {FILTER: {LEVEL:
    ...}}, "coarse": {LEVEL: ...}, "settings": the last one's, with every level named}."""
    merged: dict = {"fine": {}, "coarse": {}}
    for summary in summaries:
        for name, per_level in summary["fine"].items():
            merged["fine"].setdefault(name, {}).update(per_level)
        merged["coarse"].update(summary["coarse"])
    merged["settings"] = {**summaries[-1]["settings"],
                          "swing": [s["settings"]["swing"] for s in summaries]}
    return merged


def format_tables(result: CampaignResult) -> str:
    """Paper 004's table shape: per filter, RMS pitch/roll/heading over the window,
    heading convergence time, and the consistency columns."""
    summary = paper004_summary(result)
    exp = result.experiment
    level = next(iter(summary["coarse"]))
    coarse = summary["coarse"][level]
    window = summary["settings"]["rms_window_s"]
    motion = summary["settings"]["motion"]
    lines = [f"Paper 004, {exp.case} case, swing {level} ({motion}), {exp.misalignment} start, "
             f"{len(result.seeds)} episodes; accuracy over "
             f"[{window[0]:g}, {window[1]:g}] s",
             f"  GNSS-velocity-aided coarse alignment ({exp.coarse_duration:g} s): RMS error "
             "E/N/U " + "/".join(f"{v:.2f}" for v in coarse["rms_deg"]) + " deg",
             f"{'filter':8s}{'pitch':>9s}{'roll':>9s}{'heading':>9s} (RMS, deg)"
             f"{'conv. s':>9s}{'p90 s':>8s}{'>1 deg':>8s}{'NEES/9':>9s}{'in 3sig':>8s}"
             + STATUS_HEADER]
    for name, per_level in summary["fine"].items():
        s = per_level[level]
        nees_text = f"{s['nees_mean']:9.1f}" if s["nees_mean"] is not None else f"{'-':>9s}"
        flag = "  <- fails" if s["heading_outside_1deg_fraction"] > 0.5 else ""
        lines.append(f"{name:8s}" + "".join(f"{v:9.4f}" for v in s["rms_deg"]) + " " * 11
                     + f"{s['convergence_s']:9.0f}{s['convergence_p90_s']:8.0f}"
                     f"{s['heading_outside_1deg_fraction']:8.0%}"
                     + nees_text + f"{s['heading_inside_3sigma']:8.0%}" + status_columns(s)
                     + flag)
    return "\n".join(lines)


def consistency_plot(result: CampaignResult, out) -> list:
    """consistency.png: per filter, the RMS heading error over the episodes against the
    filter's mean 3 sigma, in time."""
    from aligngym.scenarios.figures import DPI, PNG_OPTIONS, pyplot
    plt = pyplot()

    fig, axes = plt.subplots(len(result.runs), 1, figsize=(8, 2.2 * len(result.runs)),
                             sharex=True, squeeze=False)
    for ax, run in zip(axes[:, 0], result.runs):
        t = run.result.t
        ok = ~run.result.diverged if (~run.result.diverged).any() else slice(None)
        rms = np.sqrt(np.mean(run.error_n[ok, :, 2] ** 2, axis=0)) / deg
        sigma3 = 3.0 * np.mean(run.result.sigma_n[ok, :, 2], axis=0) / deg
        ax.semilogy(t, rms, label="RMS heading error")
        ax.semilogy(t, sigma3, "--", label="filter 3 sigma (mean)")
        ax.set_ylabel(f"{run.filter}\ndeg")
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(loc="upper right")
    axes[-1, 0].set_xlabel("time, s")
    fig.suptitle(f"Paper 004, {result.experiment.case}: heading error vs the filter's 3 sigma")
    fig.tight_layout()
    path = out / "consistency.png"
    save_figure(fig, path, dpi=DPI, **PNG_OPTIONS)
    plt.close(fig)
    return [path]
