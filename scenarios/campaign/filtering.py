"""The filter phase of a campaign: every filter from every start over the whole batch of
episodes, planned as tasks (a filter on a chunk of the batch) and run in local worker
processes alongside each other.

Batching amortises the per-epoch cost of the Python and NumPy calls over the episodes,
so a batch is split only where each chunk keeps enough work per epoch
(``MIN_CHUNK_POINTS``, in points of paper 002's model: ``member_points``) or where a
split shortens the phase as its work estimate schedules it, never into more chunks than
there are processes, and the processes never outnumber the cores: asking for more workers cannot
make a run slower.
A campaign whose filters are little work (``PARALLEL_MIN_WORK``) runs them here, one
after another, as does a platform other than Linux (the workers are forked, to inherit
the prepared episodes without copying them) and a process that has started Ray (a Ray
driver must not fork). Each run is the one a single batch gives, to the bit: the
episodes of a batch are independent.
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Any

import numpy as np

from aligngym.estimators.alignment import FineResult
from aligngym.estimators.catalogue import filter_entry
from aligngym.scenarios.campaign.episodes import PreparedEpisode
from aligngym.scenarios.campaign.executors import (can_fork_workers, run_waiting_work,
                                                   start_worker, stopped_on_error,
                                                   usable_cores)
from aligngym.scenarios.campaign.experiment import Experiment
from aligngym.scenarios.campaign.results import FilterRun
from aligngym.scenarios.campaign.transport import shared_arrays
from aligngym.scenarios.campaign.runs import (analyse_starts, concatenate_results,
                                              member_batch, run_members)
from aligngym.scenarios.interrupts import raise_if_interrupted

EPOCH_OVERHEAD_POINTS = 5000
"""The per-epoch cost of a filter step that does not grow with the batch, in integration
points (one evaluation of the model's map at one point): measured on paper 002's model,
the UKF at a batch of 3 (63 points) takes 1.4 ms an epoch and sghkf-4 0.27 us per point
more, so the fixed part is about 5000 points' worth."""
MIN_CHUNK_POINTS = 4 * EPOCH_OVERHEAD_POINTS
"""Points per epoch a chunk of a batch keeps, to a member (its fixed cost about a fifth of
its work at most): sghkf-4 (1981 points) splits in two from 21 members on, a UKF of 21
points from 1905."""
SPLIT_GAIN = 0.95
"""A batch is split further only where the estimate shortens the phase by 5 % or more:
the estimate's fixed cost is paper 002's UKF's, and an EKF's is larger (its Jacobian), so
a split that gains less may lose (paper 002's EKF split in two: 0.03 % by the estimate,
slower measured)."""
POINT_US = 0.23
"""us an integration point of paper 002's model takes (sghkf-4 on the 2-core x86_64
machine of 2026-12-06): the unit the plan counts in, to which ``Experiment.filter_costs``
(measured in us and ms) are converted."""
PARALLEL_MIN_WORK = 4e6
"""Point-epochs (with each task's fixed cost, ``task_work``) below which the filters run
in this process: starting workers and returning their runs costs about what 1 s of
filtering does."""


@dataclass(frozen=True)
class FilterTask:
    """One filter over the members ``index`` of the batch (episodes x starts); work: its
    point-epochs, fixed cost included (``task_work``)."""

    name: str
    index: np.ndarray
    work: float


def task_work(points: float, members: int, epochs: int,
              fixed: float = EPOCH_OVERHEAD_POINTS) -> float:
    """Point-epochs of a filter of ``points`` per member over ``members`` for ``epochs``
    epochs, its fixed per-epoch cost (``fixed`` points an epoch) included."""
    return float(epochs) * (fixed + members * points)


def member_points(name: str, experiment: Experiment) -> float:
    """A filter's work per member and epoch as the plan counts it: the larger of its
    rule's points and the experiment's measured floor (``Experiment.member_points``, in
    points of paper 002's model, ``EPOCH_OVERHEAD_POINTS``' unit). The rule's points are
    counted as if a point cost what one of paper 002's does, so a filter dearer than the
    floor is under-estimated: the floor errs towards fewer chunks. A filter whose cost the
    experiment has measured (``Experiment.filter_costs``) counts that instead."""
    if name in experiment.filter_costs:       # a noisy measure is never below one point
        return max(experiment.filter_costs[name][0] / POINT_US, 1.0)
    points = filter_entry(name).rule().point_count(experiment.state_count)
    return float(max(points, experiment.member_points))


def epoch_points(name: str, experiment: Experiment) -> float:
    """A filter's fixed cost an epoch (whatever the batch) in points as the plan counts it:
    the experiment's measured one (``Experiment.filter_costs``), else
    ``EPOCH_OVERHEAD_POINTS``."""
    if name in experiment.filter_costs:       # a noisy measure is never below zero
        return max(experiment.filter_costs[name][1] * 1e3 / POINT_US, 0.0)
    return float(EPOCH_OVERHEAD_POINTS)


def plan_filter_tasks(filters: list[str], experiment: Experiment, members: int,
                      epochs: int, processes: int) -> list[FilterTask]:
    """The tasks of a campaign's filter phase: each filter's batch of ``members`` in as
    many chunks as the processes allow and each chunk's work (``member_points``, at
    least ``MIN_CHUNK_POINTS`` a chunk) justifies; then, where there are more tasks than
    processes, one filter's batch more split (below MIN_CHUNK_POINTS, never into more
    chunks than processes) while that shortens the phase (by ``SPLIT_GAIN``) as the work
    estimate (``task_work``) schedules it (``makespan``: largest tasks first). There a
    split rebalances tasks a process would otherwise run one after another; with no more
    tasks than processes the floor stands, keeping a chunk's fixed per-epoch cost under a
    fifth of its work (paper 001: three filters of one task each on two processes, one of
    them split in two). In filter order, chunks in member order."""
    points = {name: member_points(name, experiment) for name in filters}
    fixed = {name: epoch_points(name, experiment) for name in filters}
    chunks = {name: int(max(1, min(processes, members * points[name] // MIN_CHUNK_POINTS,
                                    members))) for name in filters}

    def tasks(counts: dict[str, int]) -> list[FilterTask]:
        return [FilterTask(name, index, task_work(points[name], index.size, epochs,
                                                  fixed[name]))
                for name in filters
                for index in np.array_split(np.arange(members), counts[name])]

    best = makespan([task.work for task in tasks(chunks)], processes)
    while sum(chunks.values()) > processes:
        trials = [(makespan([task.work for task in tasks({**chunks, name: chunks[name] + 1})],
                            processes), name)
                  for name in filters if chunks[name] < min(processes, members)]
        if not trials:
            break
        trial, name = min(trials, key=lambda trial: trial[0])   # ties: the first filter
        if trial > SPLIT_GAIN * best:
            break
        best = trial
        chunks[name] += 1
    return tasks(chunks)


def makespan(works: list[float], processes: int) -> float:
    """The longest process's work when the tasks (their works) go, largest first, each to
    the process with the least so far (how ``run_filters`` hands them out)."""
    loads = [0.0] * max(1, processes)
    for work in sorted(works, reverse=True):
        loads[loads.index(min(loads))] += work
    return max(loads)


_SHARED: tuple | None = None
"""A filter worker's (experiment, members, starts, episodes, start names), set when it
starts (``_filter_worker``): a task carries only a filter name and member indices."""


def _run_task(name: str, index: np.ndarray) -> FineResult | list[FilterRun]:
    """A task's run in a worker: a whole batch analysed there too (its FilterRuns, one per
    start), a chunk as it is (analysed once its filter's chunks are joined)."""
    experiment, members, starts, episodes, start_names = _SHARED
    result = run_members(name, index, members, starts, experiment)
    if index.size < len(members):
        return result
    return analyse_starts(name, start_names, result, episodes, experiment)


def run_filters(filters: list[str], start_errors: dict[str, np.ndarray],
                episodes: list[PreparedEpisode], experiment: Experiment, workers: int,
                epochs: int, progress: bool = False) -> list[FilterRun]:
    """Every filter from every start (name -> error, rad) over the episodes, as
    ``run_filter_starts`` would give them one after another (the same runs, in filter then
    start order), with at most ``workers`` processes (and the cores); epochs: the fine
    run's filter epochs, to plan the work."""
    from tqdm import tqdm

    if not episodes or not filters:
        return []
    members, starts = member_batch(start_errors, episodes)
    processes = max(1, min(workers, usable_cores()))
    tasks = plan_filter_tasks(filters, experiment, len(members), epochs, processes)
    parallel = (processes > 1 and len(tasks) > 1 and can_fork_workers()
                and sum(t.work for t in tasks) >= PARALLEL_MIN_WORK)
    results: dict[int, FineResult | list[FilterRun]] = {}
    bar = tqdm(total=len(tasks), disable=not progress, desc="filter runs (chunks)")
    try:
        if not parallel:
            for i, task in enumerate(tasks):
                raise_if_interrupted()
                results[i] = run_members(task.name, task.index, members, starts, experiment)
                bar.update()
        else:
            _run_in_processes(tasks, min(processes, len(tasks)), results, bar,
                              (experiment, members, starts, episodes, list(start_errors)))
    finally:
        bar.close()
    runs: list[FilterRun] = []
    for name in filters:
        parts = [results[i] for i, task in enumerate(tasks) if task.name == name]
        if len(parts) == 1 and isinstance(parts[0], list):   # analysed by its worker
            runs += parts[0]
            continue
        result = parts[0] if len(parts) == 1 else concatenate_results(parts)
        runs += analyse_starts(name, list(start_errors), result, episodes, experiment)
    return runs


def _run_in_processes(tasks: list[FilterTask], processes: int,
                      results: dict[int, FineResult | list[FilterRun]], bar: Any,
                      shared: tuple) -> None:
    """Forked workers (one BLAS thread each, Ctrl-C left to this process) that inherit
    ``shared`` (experiment, members, starts, episodes, start names), the largest tasks
    first (a whole batch's runs analysed there: ``_run_task``); on an
    interruption or an error the pool is stopped at once. The runs come back as shared
    files (``transport.shared_arrays``)."""
    with shared_arrays():
        pool = ProcessPoolExecutor(max_workers=processes,
                                   mp_context=multiprocessing.get_context("fork"),
                                   initializer=_filter_worker,
                                   initargs=(os.getpid(), shared))
        with stopped_on_error(pool):
            order = sorted(range(len(tasks)), key=lambda i: -tasks[i].work)
            futures = {pool.submit(_run_task, tasks[i].name, tasks[i].index): i
                       for i in order}
            run_waiting_work()
            for future in as_completed(futures):
                raise_if_interrupted()
                results[futures[future]] = future.result()
                bar.update()


def _filter_worker(parent: int, shared: tuple) -> None:
    """A filter worker's start (``executors.start_worker``: one BLAS thread) and the batch
    it filters (inherited from the fork, not copied)."""
    global _SHARED
    start_worker(parent)
    _SHARED = shared
