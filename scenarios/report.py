"""Campaign output: the paper-shaped tables, a tidy per-episode table, time series, plots
and the machine-readable JSON summary."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from models.units import arcmin
from scenarios.campaign import AXES, CampaignResult, episode_metrics

TIDY_COLUMNS = (
    ["seed", "filter", "start"]
    + [f"final_{a}_arcmin" for a in AXES] + [f"rms_{a}_arcmin" for a in AXES]
    + [f"final_sigma_{a}_arcmin" for a in AXES]
    + ["final_pitch_arcmin", "final_roll_arcmin", "final_heading_arcmin",
       "heading_convergence_s", "nees_mean", "nees_final", "diverged", "diverged_reason",
       "diverged_time_s", "covariance_repairs", "ms_per_epoch"])


def format_tables(result: CampaignResult) -> str:
    """The experiment's paper-shaped tables, and a line on the data faults flagged (when
    any): flagged episodes are counted apart from diverged ones."""
    text = result.experiment.format_tables(result)
    faults = result.faults()
    if faults["flagged_episodes"]:
        kinds = ", ".join(f"{k} {n}" for k, n in sorted(faults["by_kind"].items()))
        text += (f"\nData faults flagged: {faults['flagged_episodes']} of {faults['episodes']} "
                 f"episodes ({kinds}); IMU data are repaired before the filters, the other "
                 "faults are left to them; the diverged column above judges them apart")
    return text


def tidy_rows(result: CampaignResult) -> list[dict]:
    """One row per (episode, filter, start)."""
    return [{"seed": seed, "filter": run.filter, "start": run.start,
             **episode_metrics(run, b, result.experiment.rms_window)}
            for run in result.runs for b, seed in enumerate(result.seeds)]


def write_outputs(result: CampaignResult, out_dir: str | Path | None,
                  json_path: str | Path | None) -> list[Path]:
    """Write results.csv, coarse.csv (experiments with a coarse stage), timeseries.npz,
    error plots (PNG) to out_dir, and the JSON summary to json_path. Returns the paths
    written."""
    written = []
    if json_path is not None:
        path = Path(json_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(result.summary(), indent=2))
        written.append(path)
    if out_dir is None:
        return written
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "results.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=TIDY_COLUMNS)
        writer.writeheader()
        writer.writerows(tidy_rows(result))
    written += [out / "results.csv"]
    if all(hasattr(e, "coarse_error") for e in result.episodes):
        with open(out / "coarse.csv", "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["seed"] + [f"{a}_deg" for a in AXES])
            for seed, e in zip(result.seeds, result.episodes):
                writer.writerow([seed, *np.rad2deg(e.coarse_error)])
        written.append(out / "coarse.csv")
    series = {"t": result.runs[0].result.t - result.runs[0].result.t[0],
              "seed": np.asarray(result.seeds)}
    for run in result.runs:
        key = f"{run.filter}__{run.start}"
        series[f"{key}__error_arcmin"] = (run.error_n / arcmin).astype(np.float32)
        series[f"{key}__sigma_arcmin"] = (run.result.sigma_n / arcmin).astype(np.float32)
        series[f"{key}__factors"] = run.result.factors.astype(np.float32)
        series[f"{key}__nees"] = run.nees.astype(np.float32)
    np.savez_compressed(out / "timeseries.npz", **series)
    written.append(out / "timeseries.npz")
    written += plot_errors(result, out)
    written += result.experiment.plots(result, out)
    return written


def plot_errors(result: CampaignResult, out: Path) -> list[Path]:
    """Per starting error: each filter's misalignment on the first episode with its +-3
    sigma bound, one panel per axis (symmetric-log scale, arcmin)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    for start in result.experiment.starts:
        fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
        for i, run in enumerate(r for r in result.runs if r.start == start):
            color = f"C{i}"
            t = run.result.t - run.result.t[0]
            for axis, ax in enumerate(axes):
                ax.plot(t, run.error_n[0, :, axis] / arcmin, color=color, label=run.filter)
                bound = 3 * run.result.sigma_n[0, :, axis] / arcmin
                ax.plot(t, bound, color=color, ls="--", lw=0.8)
                ax.plot(t, -bound, color=color, ls="--", lw=0.8)
        for axis, ax in enumerate(axes):
            ax.set_yscale("symlog", linthresh=0.1)
            ax.set_ylabel(f"{AXES[axis]} (arcmin)")
            ax.grid(True, alpha=0.3)
        axes[0].legend(ncol=4, fontsize=8)
        axes[0].set_title(f"Fine alignment from the {start} start, seed "
                          f"{result.seeds[0]} (dashed: +-3 sigma)")
        axes[-1].set_xlabel("time since the start of fine alignment (s)")
        fig.tight_layout()
        path = out / f"fine_error_{start}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths
