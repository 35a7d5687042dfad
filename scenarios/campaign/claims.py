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


TIMED_EPOCHS = 100
"""Epochs a filter's compute time is measured over in a round (``ms_per_epoch``): the
first of its run after ``UNTIMED_EPOCHS``."""
UNTIMED_EPOCHS = 5
"""Epochs a round runs before it times (first calls, caches)."""
TIMING_ROUNDS = 5
"""Rounds of the campaign's filters timed one after another, the least of each filter's
rounds kept (another process or the host only adds time). Paper 000's sgkf against ckf,
20 episodes: one round of 100 epochs each gave 0.77x and 0.93x, which would have put
the claim on either side of its 0.8x; five interleaved rounds, their median, 0.84-0.99x
in four runs; the least of them 0.95-1.02x in six timings of two campaigns, 0.90x
in a `reproduce`."""


def ms_per_epoch(filter_name: str) -> Callable[[object], float]:
    """A Number: the filter's compute time per epoch and episode, ms (this machine),
    timed alone (``seconds_per_epoch_alone``), not from the campaign's runs: there a
    filter may have run in chunks, each paying its fixed cost an epoch, beside another
    process, so that two filters' times depended on the campaign's plan (paper 000's sgkf,
    run in two chunks beside ckf whole: 1.29x ckf's time on two workers, 0.95x on one)."""
    def number(result) -> float:
        return 1e3 * seconds_per_epoch_alone(result, filter_name) / len(result.seeds)
    return number


def seconds_per_epoch_alone(result, filter_name: str) -> float:
    """The filter's wall time per epoch and start over the campaign's episodes, in this
    process on one BLAS thread (as a campaign's worker) with nothing else of the campaign
    running: the batch of all starts run for its first ``TIMED_EPOCHS`` epochs after
    ``UNTIMED_EPOCHS`` (fewer for a shorter run; not the whole run, whose later epochs may
    cost otherwise), divided by the starts, in ``TIMING_ROUNDS`` rounds that each time
    every filter of the campaign not timed yet (the machine's drift shared among them), the
    least of the rounds. About 9 s for paper 000's three filters on 20 episodes, growing
    with the episodes. Timed once per result and filter (``CampaignResult.timed_alone``)."""
    from aligngym.scenarios.campaign.executors import thread_budget

    if filter_name not in result.timed_alone:
        names = [name for name in dict.fromkeys([r.filter for r in result.runs]
                                                + [filter_name])
                 if name not in result.timed_alone]
        rounds: dict[str, list[float]] = {name: [] for name in names}
        with thread_budget(1):
            for _ in range(TIMING_ROUNDS):
                for name in names:
                    rounds[name].append(_timed_round(result, name))
        result.timed_alone.update({name: min(times) for name, times in rounds.items()})
    return result.timed_alone[filter_name]


def _timed_round(result, filter_name: str) -> float:
    """One round of ``seconds_per_epoch_alone``: seconds per epoch and start."""
    import numpy as np

    from aligngym.estimators.alignment import AlignmentRun
    from aligngym.scenarios.campaign.runs import member_batch, members_filter

    experiment = result.experiment
    starts = {s: result.start_errors[s] for s in experiment.starts}
    members, start_errors = member_batch(starts, result.episodes)
    run = AlignmentRun(*members_filter(filter_name, np.arange(len(members)), members,
                                       start_errors, experiment))
    warm = min(UNTIMED_EPOCHS, max(run.epochs - 1, 0))
    for _ in range(warm):
        run.step()
    before, epochs = run.compute_seconds, min(TIMED_EPOCHS, run.epochs - warm)
    for _ in range(epochs):
        run.step()
    return (run.compute_seconds - before) / max(epochs, 1) / len(starts)


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
