"""Paper 003's own analysis of a campaign: the coarse alignment's errors (mean and the
extremes per axis, deg) and the paper-shaped coarse and fine tables
(``scenarios.experiments.paper003`` declares them)."""
from __future__ import annotations

import numpy as np

from aligngym.models.units import arcmin, deg
from aligngym.scenarios.campaign import AXES, CampaignResult, format_fine_table


def signed_extreme(errors: np.ndarray, pick) -> np.ndarray:
    """Per axis, the signed error whose magnitude is picked (argmax or argmin) (3,)."""
    idx = pick(np.abs(errors), axis=0)
    return errors[idx, np.arange(errors.shape[1])]


def coarse_errors(result: CampaignResult) -> np.ndarray:
    """(N, 3) rad coarse-alignment errors of the campaign's episodes."""
    return np.stack([e.coarse_error for e in result.episodes])


def coarse_summary(result: CampaignResult) -> dict[str, list[float]]:
    """Mean, max and min of the coarse errors per axis, deg (max/min by magnitude)."""
    e = coarse_errors(result)
    return {"mean_deg": list(e.mean(0) / deg),
            "max_deg": list(signed_extreme(e, np.argmax) / deg),
            "min_deg": list(signed_extreme(e, np.argmin) / deg)}


def format_tables(result: CampaignResult) -> str:
    """The coarse and fine tables, shaped like the paper's."""
    exp = result.experiment
    n = len(result.seeds)
    coarse = coarse_summary(result)
    lines = [f"Coarse alignment (inertial frame, {exp.coarse_duration:g} s), {n} runs: "
             "error (deg)", f"{'':8s}" + "".join(f"{a:>14s}" for a in AXES)]
    for key, label in (("mean_deg", "mean"), ("max_deg", "max"), ("min_deg", "min")):
        lines.append(f"{label:8s}" + "".join(f"{v:14.5f}" for v in coarse[key]))
    floor = exp.unmodelled_floor(result.episodes) if result.episodes else None
    if floor is not None:
        lines += ["", "Hull-frame biases leave every episode a floor the model's sensor-frame "
                  "states cannot hold; diverged = final error - floor > 5 x 3 sigma. Floor "
                  "(arcmin) " + ", ".join(f"{a} RMS {v:.4f}" for a, v in
                                          zip(AXES, np.sqrt(np.mean(floor ** 2, 0)) / arcmin))]
    for start in exp.starts:
        err = result.start_errors[start] / arcmin
        lines += ["", format_fine_table(
            result, start, f"Fine alignment ({exp.fine_duration:g} s) from the {start} "
            f"coarse error [{', '.join(f'{e:.2f}' for e in err)}] arcmin: final error "
            "(arcmin)")]
    return "\n".join(lines)
