"""The results of a campaign: one ``FilterRun`` per filter and start, gathered in a
``CampaignResult``; the generic fine-alignment summary and table (final errors per axis,
arcmin, and the episodes' status fractions)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aligngym.estimators.alignment import FineResult
from aligngym.estimators.metrics import status_fractions
from aligngym.models.units import arcmin
from aligngym.scenarios.campaign.episodes import PreparedEpisode

AXES = ("phi_E", "phi_N", "phi_U")


@dataclass
class FilterRun:
    """Results of one filter from one starting error, for all episodes."""

    filter: str
    start: str
    result: FineResult
    error_n: np.ndarray        # (B, K+1, 3) rad
    euler_error: np.ndarray    # (B, K+1, 3) rad: body pitch, roll, heading
    nees: np.ndarray           # (B, K+1)
    status: np.ndarray         # (B,) str: ``metrics.STATUSES`` (``metrics.StatusRule``)
    reason: list[str]          # why each episode has its status ("" if converged)
    heading_convergence: np.ndarray  # (B,) s after the start of fine alignment
    floor: np.ndarray | None = None  # (B, 3) rad: ``Experiment.unmodelled_floor``

    @property
    def diverged(self) -> np.ndarray:
        """(B,) the episodes whose status is diverged: the filter broke, or its sigma
        cannot be trusted (left out of the figures' bands and the report's statistics;
        a lost episode's error is drawn with the rest)."""
        return self.status == "diverged"


@dataclass
class CampaignResult:
    experiment: Any
    """The campaign's ``Experiment``."""
    seeds: list[int]
    episodes: list[PreparedEpisode]
    start_errors: dict[str, np.ndarray]
    runs: list[FilterRun] = field(default_factory=list)
    seed: int | None = None
    """The campaign seed the episode seeds derive from (``episode_seeds``)."""
    timed_alone: dict[str, float] = field(default_factory=dict, init=False, repr=False,
                                          compare=False)
    """Filter name -> its wall time per epoch and start over the campaign's episodes, s,
    timed alone in this process (``claims.seconds_per_epoch_alone``), once asked for (a
    copy made by ``dataclasses.replace`` starts empty)."""

    def summary(self) -> dict:
        """The experiment's JSON summary, with the data faults flagged ("data_faults")."""
        return {**self.experiment.summary(self), "data_faults": self.faults()}

    def faults(self) -> dict:
        """The data faults the pipeline's screen flagged (IMU, gimbal, GNSS, odometer):
        episodes flagged (counted apart from the diverged ones, which the filters' tables
        count), per kind, and per flagged seed the (kind, time s) list in time order."""
        flagged = {seed: [(str(k), float(t)) for k, t in zip(e.fault_kind, e.fault_time)]
                   for seed, e in zip(self.seeds, self.episodes) if len(e.fault_kind)}
        kinds: dict[str, int] = {}
        for flags in flagged.values():
            for kind, _ in flags:
                kinds[kind] = kinds.get(kind, 0) + 1
        return {"flagged_episodes": len(flagged), "episodes": len(self.seeds),
                "by_kind": kinds, "flags": {str(s): f for s, f in flagged.items()}}


def fine_summary(result: CampaignResult, window: float | None = None) -> dict:
    """Per filter and start: mean, std, RMS of the final error per axis (arcmin), or of
    the per-episode RMS over the last ``window`` s, and the fraction of the episodes in
    each status (``metrics.status_fractions``)."""
    out: dict[str, dict[str, dict]] = {}
    for run in result.runs:
        if window is None:
            final = run.error_n[:, -1] / arcmin
        else:
            t = run.result.t
            sel = t >= t[-1] - window - 1e-9
            final = np.sqrt(np.mean(run.error_n[:, sel] ** 2, axis=1)) / arcmin
        out.setdefault(run.filter, {})[run.start] = {
            "mean_arcmin": list(final.mean(0)), "std_arcmin": list(final.std(0)),
            "rms_arcmin": list(np.sqrt((final ** 2).mean(0))),
            **status_fractions(run.status)}
    return out


STATUS_HEADER = f"{'conv.':>7s}{'not conv.':>10s}{'diverged':>9s}{'lost':>6s}"
"""The header of the status columns of a table (docs/estimators.md, "Episode status")."""


def status_columns(fractions: dict) -> str:
    """The percentages of ``metrics.status_fractions`` under ``STATUS_HEADER``."""
    return (f"{fractions['converged_fraction']:7.0%}{fractions['not_converged_fraction']:10.0%}"
            f"{fractions['diverged_fraction']:9.0%}{fractions['lost_fraction']:6.0%}")


def format_fine_table(result: CampaignResult, start: str, title: str | None = None,
                      extra: dict[str, str] | None = None, extra_header: str = "") -> str:
    """Final error per filter (mean, std, RMS per axis, arcmin) from one start; extra:
    per filter, text appended to its first row under extra_header."""
    fine = fine_summary(result)
    lines = [title or f"Fine alignment from the {start} start: final error (arcmin)",
             f"{'filter':9s}{'stat':6s}" + "".join(f"{a:>12s}" for a in AXES)
             + STATUS_HEADER + extra_header]
    for name, per_start in fine.items():
        s = per_start[start]
        for stat in ("mean", "std", "rms"):
            tail = (status_columns(s) + (extra or {}).get(name, "")
                    if stat == "mean" else "")
            lines.append(f"{name if stat == 'mean' else '':9s}{stat:6s}"
                         + "".join(f"{v:12.4f}" for v in s[f"{stat}_arcmin"]) + tail)
    return "\n".join(lines)
