"""A paper's claim as the testbed checks it (``aligngym reproduce``; declared by each
experiment, ``Experiment.claims``)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping

Number = str | Callable[["object"], float]
"""A summary path ("fine/sgkf/vs_reference/rms_arcmin/2") or a function of the
CampaignResult."""


@dataclass(frozen=True)
class Claim:
    """One claim of a paper and how the testbed checks it.

    text: the claim, in the paper's words as far as our notes give them; where: where the
    paper makes it; numbers: {label: Number}, what is measured (label with its unit);
    holds: the test on those numbers; reason: why it does not hold here, measured (shown
    with a "not reproduced" verdict); setup, settings, filters: the campaign it needs
    (the experiment's named setup, its settings, the filters; () for the defaults)."""

    text: str
    where: str
    numbers: Mapping[str, Number]
    holds: Callable[[dict[str, float]], bool]
    reason: str = ""
    setup: str = "default"
    settings: Mapping[str, object] = field(default_factory=dict)
    filters: tuple[str, ...] = ()

    def campaign_key(self) -> tuple:
        return (self.setup, tuple(sorted((k, repr(v)) for k, v in self.settings.items())),
                self.filters)


def ms_per_epoch(filter_name: str) -> Callable[[object], float]:
    """A Number: the filter's compute time per epoch and episode, ms (this machine)."""
    def number(result) -> float:
        runs = [r for r in result.runs if r.filter == filter_name]
        return 1e3 * sum(r.result.seconds_per_epoch for r in runs) / len(runs) / len(
            result.seeds)
    return number


def rule_points(filter_name: str, states: int) -> Callable[[object], float]:
    """A Number: the points the filter's integration rule propagates for that many states."""
    def number(result) -> float:
        from aligngym.estimators.catalogue import filter_entry
        return float(filter_entry(filter_name).rule().point_count(states))
    return number


def final_from_static_floor(filter_name: str, axis: int = 2) -> Callable[[object], float]:
    """A Number for a static base: RMS over the episodes of the final misalignment minus
    the episode's static self-alignment floor (``static_alignment_floor``), arcmin; axis
    0, 1, 2 = E, N, U."""
    def number(result) -> float:
        import numpy as np

        from aligngym.estimators.metrics import static_alignment_floor
        from aligngym.models.units import arcmin
        run = next(r for r in result.runs if r.filter == filter_name)
        floor = np.stack([static_alignment_floor(e.C_s_n_true[-1], e.gyro_bias, e.accel_bias,
                                                 e.lat, e.h) for e in result.episodes])
        d = run.error_n[:, -1, axis] - floor[:, axis]
        return float(np.sqrt(np.mean(d ** 2)) / arcmin)
    return number
