"""Alignment bounds as test assertions, for users' CI (see the pytest plugin's fixture
``aligngym_episode`` in ``aligngym.pytest_plugin``)."""
from __future__ import annotations

from dataclasses import fields, replace

import numpy as np


class AlignmentBoundExceeded(AssertionError):
    """A filter's alignment error exceeded a bound; str() holds the per-episode table."""


def assert_alignment(filter: str, scenario: str, episodes: int = 5, seed: int = 0,
                     heading_rms_arcmin: float | None = None,
                     level_rms_arcmin: float | None = None, start: str | None = None,
                     **settings) -> dict:
    """Run a small campaign of the scenario's paper experiment (``experiment_for``;
    settings override its defaults, e.g. fine_duration) with one filter (a catalogue
    name, a registered one, or module.path:factory) and check the RMS over the episodes
    of the final misalignment: heading (U) against heading_rms_arcmin, each level axis
    (E, N) against level_rms_arcmin. An episode whose status (docs/estimators.md,
    "Episode status") is diverged or lost fails the check, whatever the bounds.

    start: the fine alignment's starting error, one of the experiment's start names
    (``Experiment.starts``: paper 000 "coarse" / "large", paper 003 "mean" / "max", ...);
    None (the default) is the experiment's first start, the one its env uses; "all"
    checks every start against the same bounds. A name the experiment lacks is a
    one-line ValueError naming the valid ones.

    Returns the measured {"start", "heading_rms_arcmin", "level_rms_arcmin": [E, N],
    "converged", "not_converged", "diverged", "lost"} (arcmin; episodes per status), or
    with start="all" {start name: that dict} in the experiment's order; raises AlignmentBoundExceeded with a per-episode table of every
    start that exceeds a bound."""
    from aligngym.scenarios.campaign import run_campaign
    from aligngym.scenarios.config import SettingError
    from aligngym.scenarios.experiments import experiment_for

    _check_arguments(filter, scenario, episodes, seed, heading_rms_arcmin, level_rms_arcmin)
    try:                      # settings checked where the experiment is made (one line)
        exp = experiment_for(scenario, **settings)
    except SettingError as exc:
        raise exc.as_written(lambda name: f"assert_alignment: {name}") from None
    chosen = _chosen_starts(exp, start)
    if "starts" in {f.name for f in fields(exp)} and "starts" not in settings:
        exp = replace(exp, starts=chosen).holding(exp.scenario_file())  # those alone
    result = run_campaign(exp, episodes=episodes, seed=seed, filters=[filter],
                          workers=1, progress=False)
    runs = {run.start: run for run in result.runs if run.filter == filter}
    measured, failures = {}, []
    for name in chosen:
        measured[name], table = _check_run(runs[name], filter, scenario, name, episodes,
                                           seed, result.seeds, heading_rms_arcmin,
                                           level_rms_arcmin)
        if table:
            failures.append(table)
    if failures:
        raise AlignmentBoundExceeded("\n\n".join(failures))
    return measured if start == "all" else measured[chosen[0]]


def _chosen_starts(exp, start: str | None) -> tuple[str, ...]:
    """The experiment's start names that ``start`` selects (see ``assert_alignment``)."""
    valid = tuple(exp.starts)
    if start is None:
        return valid[:1]
    if start == "all":
        return valid
    if not isinstance(start, str) or start not in valid:
        raise ValueError(f"assert_alignment: start = {start!r} is not a start of "
                         f"paper{exp.paper}; valid: " + ", ".join((*valid, "all")))
    return (start,)


def _check_run(run, filter: str, scenario: str, start: str, episodes: int, seed: int,
               seeds: list[int], heading: float | None, level: float | None
               ) -> tuple[dict, str]:
    """The measured dict of one start's run and its failure table ("" when within)."""
    from aligngym.estimators.metrics import FAILED, STATUSES
    from aligngym.models.units import arcmin
    final = run.error_n[:, -1] / arcmin                       # (B, 3) E, N, U arcmin
    rms = np.sqrt(np.mean(final ** 2, axis=0))
    counts = {s.replace(" ", "_"): int(np.sum(run.status == s)) for s in STATUSES}
    measured = {"start": start, "heading_rms_arcmin": float(rms[2]),
                "level_rms_arcmin": [float(rms[0]), float(rms[1])], **counts}
    failures = []
    if heading is not None and not rms[2] <= heading:
        failures.append(f"heading RMS {rms[2]:.3f}' > {heading:g}'")
    if level is not None and not np.all(rms[:2] <= level):
        failures.append(f"level RMS E/N {rms[0]:.3f}'/{rms[1]:.3f}' > {level:g}'")
    for status in FAILED:
        if counts[status]:
            failures.append(f"{counts[status]} of {episodes} episodes {status}")
    if not failures:
        return measured, ""
    lines = [f"{filter} on {scenario} from the {start} start ({episodes} episodes, seed "
             f"{seed}): " + "; ".join(failures),
             f"{'episode seed':>14s} {'E':>11s} {'N':>11s} {'U':>12s}  final error, arcmin;"
             " status"]
    for s, err, status, why in zip(seeds, final, run.status, run.reason):
        lines.append(f"{s:14d} {err[0]:11.3f} {err[1]:11.3f} {err[2]:12.3f}  {status}"
                     + (f": {why}" if why else ""))
    lines.append(f"{'RMS':>14s} {rms[0]:11.3f} {rms[1]:11.3f} {rms[2]:12.3f}")
    return measured, "\n".join(lines)


def _check_arguments(filter, scenario, episodes, seed, heading, level) -> None:
    """One-line TypeError/ValueError naming the argument, before any work."""
    import math
    import os
    for name, value in (("filter", filter), ("scenario", scenario)):
        if not isinstance(value, (str, os.PathLike)) or not str(value):
            raise TypeError(f"assert_alignment: {name} must be a non-empty name or path, "
                            f"got {value!r}")
    for name, value, low in (("episodes", episodes, 1), ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"assert_alignment: {name} must be an integer >= {low}, "
                            f"got {value!r}")
        if value < low:
            raise ValueError(f"assert_alignment: {name} = {value} must be >= {low}")
    for name, value in (("heading_rms_arcmin", heading), ("level_rms_arcmin", level)):
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating,
                                                             np.integer)):
            raise TypeError(f"assert_alignment: {name} must be a number > 0 (arcmin), "
                            f"got {value!r}")
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"assert_alignment: {name} = {value} must be finite and > 0 "
                             "(arcmin)")
