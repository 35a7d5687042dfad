"""One filter over a batch of prepared episodes (episodes x starts): the batched run, or
the run of some of its members (``run_members``, the tasks of ``campaign.filtering``),
and its analysis (errors, NEES, divergence, convergence time, one tidy row per
episode)."""
from __future__ import annotations

from typing import Any

import numpy as np

from aligngym.estimators.alignment import FineResult, run_alignment
from aligngym.estimators.catalogue import filter_entry, make_filter
from aligngym.estimators.filters import GaussianFilter
from aligngym.estimators.model import FilterModel
from aligngym.estimators.metrics import StatusRule, convergence_time, euler_error, misalignment
from aligngym.models.units import arcmin
from aligngym.scenarios.campaign.episodes import PreparedEpisode
from aligngym.scenarios.campaign.experiment import Experiment
from aligngym.scenarios.campaign.results import AXES, FilterRun


def analyse_run(name: str, start: str, result: FineResult, episodes: list[PreparedEpisode],
                experiment: Experiment, rule: StatusRule = StatusRule()) -> FilterRun:
    """Errors, body Euler errors, NEES, each episode's status and convergence time of a
    run; the status judged on the final error less the experiment's ``unmodelled_floor``,
    with the experiment's heading convergence threshold as its band."""
    K = result.t.size
    C_true = np.stack([e.C_s_n_true[:K] for e in episodes])
    error_n = misalignment(C_true, result.C_s_n)
    C_b_n_est = result.C_s_n @ np.swapaxes(np.stack([e.C_s_b[:K] for e in episodes]), -1, -2)
    eul = euler_error(np.stack([e.C_b_n_true[:K] for e in episodes]), C_b_n_est)
    floor = experiment.unmodelled_floor(episodes)
    final = error_n[:, -1] if floor is None else error_n[:, -1] - floor
    status, reason = rule.apply(final, result.sigma_n[:, -1],
                                experiment.heading_threshold_arcmin * arcmin,
                                result.diverged, result.diverged_reason)
    if floor is not None:
        reason = [r.replace("final error", "final error - floor") for r in reason]
    heading = convergence_time(result.t - result.t[0], error_n[:, :, 2],
                               experiment.heading_threshold_arcmin * arcmin)
    return FilterRun(filter=name, start=start, result=result, error_n=error_n,
                     euler_error=eul, nees=experiment.nees(result, episodes, error_n),
                     status=status, reason=reason, heading_convergence=heading,
                     floor=floor)


def run_filter(name: str, start: str, start_error: np.ndarray,
               episodes: list[PreparedEpisode], experiment: Experiment,
               threads: int = 1, **model_options: Any) -> FilterRun:
    """One filter on all episodes from a starting error (rad; common (3,) or per episode
    (B, 3)); model_options go to ``experiment.model`` (e.g. paper 003's tuning)."""
    return run_filter_starts(name, {start: start_error}, episodes, experiment, threads,
                             **model_options)[0]


def run_filter_starts(name: str, start_errors: dict[str, np.ndarray],
                      episodes: list[PreparedEpisode], experiment: Experiment,
                      threads: int = 1, **model_options: Any) -> list[FilterRun]:
    """One filter from every start (name -> start error, rad: common (3,) or per episode
    (B, 3)) as one batch of episodes x starts, one FilterRun per start in the given order.
    The episodes of a batch are independent, so each start's run is the one it would be
    alone, at the per-epoch cost of one batch (a few starts of a few episodes cost little
    more than one); seconds_per_epoch is shared in proportion. With threads > 1 the batch
    is split into that many chunks run in threads (NumPy releases the GIL in its array
    loops), with the same result; a campaign runs its filters in processes instead
    (``campaign.filtering``). model_options go to ``experiment.model``."""
    members, starts = member_batch(start_errors, episodes)
    chunks = [c for c in np.array_split(np.arange(len(members)), max(1, threads)) if c.size]

    def run_chunk(idx: np.ndarray) -> FineResult:
        return run_members(name, idx, members, starts, experiment, **model_options)

    if len(chunks) == 1:
        result = run_chunk(chunks[0])
    else:
        from concurrent.futures import ThreadPoolExecutor
        with ThreadPoolExecutor(len(chunks)) as pool:
            result = concatenate_results(list(pool.map(run_chunk, chunks)))
    return analyse_starts(name, list(start_errors), result, episodes, experiment)


def member_batch(start_errors: dict[str, np.ndarray], episodes: list[PreparedEpisode]
                 ) -> tuple[list[PreparedEpisode], np.ndarray]:
    """The batch of episodes x starts (each start's B episodes in turn) and each
    member's start error (B x starts, 3) rad."""
    B = len(episodes)
    starts = np.concatenate([np.broadcast_to(np.asarray(error, dtype=float), (B, 3))
                             for error in start_errors.values()])
    return [episodes[i % B] for i in range(B * len(start_errors))], starts


def members_filter(name: str, index: np.ndarray, members: list[PreparedEpisode],
                   starts: np.ndarray, experiment: Experiment, **model_options: Any
                   ) -> tuple[GaussianFilter, FilterModel]:
    """The named filter and its model over the members ``index`` of a batch
    (``member_batch``), as a campaign makes them, not yet run."""
    filt = make_filter(name, **experiment.filter_options())
    return filt, experiment.model([members[i] for i in index], starts[index],
                                  filter_entry(name).model, **model_options)


def run_members(name: str, index: np.ndarray, members: list[PreparedEpisode],
                starts: np.ndarray, experiment: Experiment, **model_options: Any
                ) -> FineResult:
    """The named filter over the members ``index`` of a batch (``member_batch``)."""
    return run_alignment(*members_filter(name, index, members, starts, experiment,
                                         **model_options))


def analyse_starts(name: str, start_names: list[str], result: FineResult,
                   episodes: list[PreparedEpisode], experiment: Experiment) -> list[FilterRun]:
    """One FilterRun per start (in order) from a whole batch's result."""
    B = len(episodes)
    return [analyse_run(name, s, batch_slice(result, slice(k * B, (k + 1) * B)), episodes,
                        experiment) for k, s in enumerate(start_names)]


def batch_slice(result: FineResult, index: slice) -> FineResult:
    """The episodes ``index`` of a batched result; seconds_per_epoch their share."""
    B = result.C_s_n.shape[0]
    share = (len(range(B)[index]) / B) if B else 0.0
    take = lambda name: getattr(result, name)[index]  # noqa: E731
    return FineResult(t=result.t, C_s_n=take("C_s_n"), P=take("P"), sigma_n=take("sigma_n"),
                      x=take("x"), factors=take("factors"), diverged=take("diverged"),
                      diverged_time=take("diverged_time"),
                      diverged_reason=result.diverged_reason[index], repairs=take("repairs"),
                      seconds_per_epoch=result.seconds_per_epoch * share,
                      series={k: v[index] for k, v in result.series.items()},
                      nis=None if result.nis is None else result.nis[index],
                      nis_dof=None if result.nis_dof is None else result.nis_dof[index],
                      chunks=result.chunks)


def concatenate_results(parts: list[FineResult]) -> FineResult:
    """One result from batch chunks (same epochs); seconds_per_epoch is the chunks'
    summed compute time per epoch, chunks their count."""
    width = max(p.factors.shape[-1] for p in parts)
    factors = [np.pad(p.factors, ((0, 0), (0, 0), (0, width - p.factors.shape[-1])),
                      constant_values=np.nan) for p in parts]
    cat = lambda name: np.concatenate([getattr(p, name) for p in parts])  # noqa: E731
    return FineResult(t=parts[0].t, C_s_n=cat("C_s_n"), P=cat("P"), sigma_n=cat("sigma_n"),
                      x=cat("x"), factors=np.concatenate(factors), diverged=cat("diverged"),
                      diverged_time=cat("diverged_time"),
                      diverged_reason=sum((p.diverged_reason for p in parts), []),
                      repairs=cat("repairs"),
                      seconds_per_epoch=sum(p.seconds_per_epoch for p in parts),
                      series={name: np.concatenate([p.series[name] for p in parts])
                              for name in parts[0].series},
                      nis=cat("nis"), nis_dof=cat("nis_dof"),
                      chunks=sum(p.chunks for p in parts))


def episode_metrics(run: FilterRun, b: int, experiment: Experiment,
                    fine_start: float) -> dict:
    """The per-episode metrics of episode b of a run (one row of the tidy table): final
    errors and sigmas; RMS errors and the mean NEES over the experiment's
    ``accuracy_window``; times (convergence, divergence) in s since the fine start
    (fine_start: its scenario time, s)."""
    r = run.result
    t = r.t - r.t[0]
    in_window = experiment.accuracy_window(t, fine_start)
    rms = np.sqrt(np.mean(run.error_n[b, in_window] ** 2, axis=0)) / arcmin
    row = {}
    for prefix, values in (("final", run.error_n[b, -1] / arcmin), ("rms", rms),
                           ("final_sigma", r.sigma_n[b, -1] / arcmin)):
        row.update({f"{prefix}_{a}_arcmin": float(v) for a, v in zip(AXES, values)})
    row.update({f"final_{a}_arcmin": float(v) for a, v in
                zip(("pitch", "roll", "heading"), run.euler_error[b, -1] / arcmin)})
    nees = run.nees[b, in_window]
    row.update({
        "heading_convergence_s": float(run.heading_convergence[b]),
        "nees_mean": float(np.nanmean(nees)) if np.isfinite(nees).any() else None,
        "nees_final": float(run.nees[b, -1]) if np.isfinite(run.nees[b, -1]) else None,
        "status": str(run.status[b]), "status_reason": run.reason[b],
        "diverged": bool(run.status[b] == "diverged"),
        "diverged_time_s": float(r.diverged_time[b] - r.t[0]) if r.diverged[b] else None,
        "covariance_repairs": int(r.repairs[b]),
        "ms_per_epoch": r.seconds_per_episode_epoch * 1e3,
        "ms_per_epoch_chunks": int(r.chunks)})
    return row


