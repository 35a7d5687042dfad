"""Campaign output: the paper-shaped tables, a tidy per-episode table, time series, the
campaign figures (``scenarios.figures``), the machine-readable JSON summary and the
settings that make an output directory self-describing (``aligngym report`` reads
them)."""
from __future__ import annotations

import csv
import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from aligngym.models.units import arcmin
from aligngym.scenarios.atomic import atomic_path, write_json, write_text
from aligngym.scenarios.campaign import AXES, CampaignResult, episode_metrics
from aligngym.scenarios.figure_jobs import FigureDrawing, figure_jobs
from aligngym.scenarios.figure_statistics import nees_band_summary

TIDY_COLUMNS = (
    ["seed", "filter", "start"]
    + [f"final_{a}_arcmin" for a in AXES] + [f"rms_{a}_arcmin" for a in AXES]
    + [f"final_sigma_{a}_arcmin" for a in AXES]
    + ["final_pitch_arcmin", "final_roll_arcmin", "final_heading_arcmin",
       "heading_convergence_s", "nees_mean", "nees_final", "status", "status_reason",
       "diverged", "diverged_time_s", "covariance_repairs", "ms_per_epoch",
       "ms_per_epoch_chunks"])


def format_tables(result: CampaignResult) -> str:
    """The experiment's paper-shaped tables, and a line on the data faults flagged (when
    any): flagged episodes are counted apart from the episodes' statuses."""
    text = result.experiment.format_tables(result)
    faults = result.faults()
    if faults["flagged_episodes"]:
        kinds = ", ".join(f"{k} {n}" for k, n in sorted(faults["by_kind"].items()))
        text += (f"\nData faults flagged: {faults['flagged_episodes']} of {faults['episodes']} "
                 f"episodes ({kinds}); IMU data are repaired before the filters, the other "
                 "faults are left to them; the status columns above judge them apart")
    return text


def tidy_rows(result: CampaignResult) -> list[dict]:
    """One row per (episode, filter, start)."""
    return [{"seed": seed, "filter": run.filter, "start": run.start,
             **episode_metrics(run, b, result.experiment, result.episodes[b].fine_start)}
            for run in result.runs for b, seed in enumerate(result.seeds)]


def campaign_settings(result: CampaignResult, command: list[str] | None = None) -> dict:
    """What a campaign directory needs to describe itself: paper, scenario (name, source
    file and its TOML text), the experiment's settings, campaign seed, episode seeds,
    filters, starts, the command line, the versions and the time written (UTC)."""
    import platform
    import sys
    from datetime import datetime, timezone
    from importlib.metadata import PackageNotFoundError, version

    exp = result.experiment
    config = exp.scenario_config()
    from aligngym.scenarios.config import scenario_path
    source = scenario_path(exp.scenario).resolve()
    versions = {"python": platform.python_version()}
    for package in ("aligngym", "numpy", "scipy", "mujoco", "matplotlib"):
        try:
            versions[package] = version(package)
        except PackageNotFoundError:
            versions[package] = "not installed"
    return {
        "paper": f"paper{exp.paper}", "scenario": config.name, "scenario_file": str(source),
        "scenario_toml": source.read_text(), "experiment": json.loads(json.dumps(
            asdict(exp), default=str)),
        "seed": result.seed, "episodes": len(result.seeds), "seeds": list(result.seeds),
        "filters": list(dict.fromkeys(run.filter for run in result.runs)),
        "starts": list(exp.starts), "nees_dof": exp.nees_dof(),
        "command": command,
        "platform": f"{platform.system()} {platform.machine()}, {sys.implementation.name}",
        "versions": versions,
        "written_utc": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S")}


def write_outputs(result: CampaignResult, out_dir: str | Path | None,
                  json_path: str | Path | None, command: list[str] | None = None,
                  figures: bool = True, processes: int | None = None) -> list[Path]:
    """Write to out_dir results.csv, coarse.csv (experiments with a coarse stage),
    timeseries.npz, tables.txt (``format_tables``), summary.json (the JSON summary),
    settings.json (``campaign_settings``; command: the command line, for the record), the
    campaign figures (``scenarios.figure_jobs``, drawn in up to ``processes`` worker
    processes while the rest is written; None: the cores) and the experiment's own (PNG;
    figures=False leaves them out); and the JSON summary to json_path. Returns the paths
    written."""
    written = []
    # summary.json: the experiment's summary, and the mean NEES against its band (not in
    # result.summary(), whose paths are regress's metrics)
    summary = {**result.summary(), "nees_band": nees_band_summary(result)}
    if json_path is not None:
        path = Path(json_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        written.append(write_json(path, summary))
    if out_dir is None:
        return written
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # the figures are drawn in worker processes while the tables and series are written
    drawing = None
    try:
        if figures:
            drawing = FigureDrawing.start(figure_jobs(result, out), processes)
    except Exception:              # the figures failed before drawing: the tables first
        _write_tables(result, out, summary, command)
        raise
    try:
        written += _write_tables(result, out, summary, command)
    except BaseException:
        if drawing is not None:
            drawing.cancel()
        raise
    if drawing is not None:
        written += drawing.finish()
        written += result.experiment.plots(result, out)
    return written


def _write_tables(result: CampaignResult, out: Path, summary: dict,
                  command: list[str] | None) -> list[Path]:
    """results.csv, coarse.csv, timeseries.npz, tables.txt, summary.json and
    settings.json in out (``write_outputs``)."""
    written = []
    with atomic_path(out / "results.csv") as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=TIDY_COLUMNS)
        writer.writeheader()
        writer.writerows(tidy_rows(result))
    written += [out / "results.csv"]
    if all(hasattr(e, "coarse_error") for e in result.episodes):
        with atomic_path(out / "coarse.csv") as tmp, open(tmp, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["seed"] + [f"{a}_deg" for a in AXES])
            for seed, e in zip(result.seeds, result.episodes):
                writer.writerow([seed, *np.rad2deg(e.coarse_error)])
        written.append(out / "coarse.csv")
    t = result.runs[0].result.t - result.runs[0].result.t[0]
    fine_start = np.array([e.fine_start for e in result.episodes])
    series = {"t": t, "fine_start_s": fine_start, "seed": np.asarray(result.seeds),
              "accuracy_window": result.experiment.accuracy_window(t, float(fine_start[0]))}
    for run in result.runs:
        key = f"{run.filter}__{run.start}"
        series[f"{key}__error_arcmin"] = (run.error_n / arcmin).astype(np.float32)
        series[f"{key}__sigma_arcmin"] = (run.result.sigma_n / arcmin).astype(np.float32)
        series[f"{key}__factors"] = run.result.factors.astype(np.float32)
        series[f"{key}__nees"] = run.nees.astype(np.float32)
        series[f"{key}__diverged"] = np.asarray(run.diverged, bool)
        series[f"{key}__status"] = np.asarray(run.status)
    with atomic_path(out / "timeseries.npz") as tmp:
        np.savez_compressed(tmp, **series)
    written.append(out / "timeseries.npz")
    written += [write_text(out / "tables.txt", format_tables(result) + "\n"),
                write_json(out / "summary.json", summary),
                write_json(out / "settings.json", campaign_settings(result, command))]
    return written
