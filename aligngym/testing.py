"""Alignment bounds as test assertions, for users' CI (see the pytest plugin's fixture
``aligngym_episode`` in ``aligngym.pytest_plugin``)."""
from __future__ import annotations

import numpy as np


class AlignmentBoundExceeded(AssertionError):
    """A filter's alignment error exceeded a bound; str() holds the per-episode table."""


def assert_alignment(filter: str, scenario: str, episodes: int = 5, seed: int = 0,
                     heading_rms_arcmin: float | None = None,
                     level_rms_arcmin: float | None = None, **settings) -> dict:
    """Run a small campaign of the scenario's paper experiment (``experiment_for``;
    settings override its defaults, e.g. fine_duration) with one filter (a catalogue
    name, a registered one, or module.path:factory) and check the RMS over the episodes
    of the final misalignment: heading (U) against heading_rms_arcmin, each level axis
    (E, N) against level_rms_arcmin. A diverged episode fails the bound. Returns the
    measured {"heading_rms_arcmin", "level_rms_arcmin": [E, N], "diverged"}; raises
    AlignmentBoundExceeded with a per-episode table when a bound is exceeded."""
    from aligngym.models.units import arcmin
    from aligngym.scenarios.campaign import run_campaign
    from aligngym.scenarios.experiments import experiment_for

    _check_arguments(filter, scenario, episodes, seed, heading_rms_arcmin, level_rms_arcmin)
    exp = experiment_for(scenario, **settings)
    result = run_campaign(exp, episodes=episodes, seed=seed, filters=[filter],
                          workers=1, progress=False)
    (run,) = result.runs
    final = run.error_n[:, -1] / arcmin                       # (B, 3) E, N, U arcmin
    rms = np.sqrt(np.mean(final ** 2, axis=0))
    measured = {"heading_rms_arcmin": float(rms[2]),
                "level_rms_arcmin": [float(rms[0]), float(rms[1])],
                "diverged": int(run.diverged.sum())}
    failures = []
    if heading_rms_arcmin is not None and not rms[2] <= heading_rms_arcmin:
        failures.append(f"heading RMS {rms[2]:.3f}' > {heading_rms_arcmin:g}'")
    if level_rms_arcmin is not None and not np.all(rms[:2] <= level_rms_arcmin):
        failures.append(f"level RMS E/N {rms[0]:.3f}'/{rms[1]:.3f}' > {level_rms_arcmin:g}'")
    if run.diverged.any():
        failures.append(f"{run.diverged.sum()} of {episodes} episodes diverged")
    if failures:
        lines = [f"{filter} on {scenario} ({episodes} episodes, seed {seed}): "
                 + "; ".join(failures),
                 f"{'episode seed':>14s}{'E':>10s}{'N':>10s}{'U':>12s}  final error, arcmin"]
        for s, err, bad, why in zip(result.seeds, final, run.diverged, run.reason):
            lines.append(f"{s:14d}{err[0]:10.3f}{err[1]:10.3f}{err[2]:12.3f}"
                         + (f"  diverged: {why}" if bad else ""))
        lines.append(f"{'RMS':>14s}{rms[0]:10.3f}{rms[1]:10.3f}{rms[2]:12.3f}")
        raise AlignmentBoundExceeded("\n".join(lines))
    return measured


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
