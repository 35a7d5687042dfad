"""The campaign engine: settings checked, the directory claimed (created, locked, its
manifest checked), the episodes prepared (executors, stored as they finish), then every
filter run once, batched over all episodes from all starts."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from aligngym.estimators.model import whole_steps
from aligngym.scenarios.campaign.episodes import episode_seeds
from aligngym.scenarios.campaign.executors import (can_fork_workers, executor_named,
                                                   prepare_all, thread_budget)
from aligngym.scenarios.campaign.experiment import Experiment
from aligngym.scenarios.campaign.results import CampaignResult
from aligngym.scenarios.campaign.manifest import campaign_lock, check_manifest
from aligngym.scenarios.campaign.filtering import run_filters
from aligngym.scenarios.config import ConfigError


def run_campaign(experiment: Experiment, episodes: int = 50, seed: int = 0,
                 filters: list[str] | None = None, out_dir: str | Path | None = None,
                 resume: bool = False, workers: int | None = None,
                 progress: bool = True, executor: str = "local",
                 address: str | None = None, force: bool = False) -> CampaignResult:
    """Run an experiment's campaign; see the module docstring. executor: the name of a
    registered one (``executors.EXECUTORS``): "local" (processes), "ray" (tasks on a local
    Ray instance, or the cluster at address) or one of ``register_executor``'s."""
    filters = list(filters or experiment.default_filters)
    check_campaign(experiment, episodes, filters)
    executor_named(executor, address)        # a known name, and an address it takes
    workers = workers or os.cpu_count() or 1
    out = Path(out_dir) if out_dir is not None else None
    if out is None:
        return _run(experiment, episodes, seed, filters, None, resume, workers, progress,
                    executor, address)
    claim_directory(out)
    with campaign_lock(out):           # one writer at a time
        same = check_manifest(out, experiment, seed, resume, force, filters)
        if same and progress:
            print(f"{out} holds this campaign already (the same settings, scenario and "
                  "seed): its finished episodes are reused", file=sys.stderr)
        return _run(experiment, episodes, seed, filters, out, resume or same, workers, progress,
                    executor, address)


def check_campaign(experiment: Experiment, episodes: int, filters: list[str]) -> None:
    """One-line ConfigError, before anything is simulated or written, for a campaign that
    cannot run: the scenario against the experiment (first: the cheaper check), the
    filters against its model (a sparse grid counts its points), the episodes, and the
    memory it would take (``check_campaign_memory``)."""
    experiment.check(experiment.scenario_config())
    experiment.check_filters(filters)
    if episodes < 1:
        raise ConfigError(f"--episodes = {episodes} must be >= 1")
    check_campaign_memory(experiment, episodes, filters)


def campaign_epochs(experiment: Experiment) -> int:
    """Filter epochs (K + 1) of a campaign's fine run, from its settings: the fine
    duration (the run less its coarse stage where the setting leaves it open) over the
    filter step."""
    step = float(getattr(experiment, "filter_step", 0.0) or 0.0)
    fine = getattr(experiment, "fine_duration", None)
    if fine is None:
        fine = experiment.duration - float(getattr(experiment, "coarse_start", 0.0) or 0.0) \
            - float(getattr(experiment, "coarse_duration", 0.0) or 0.0)
    return whole_steps(fine, step) + 1 if step > 0.0 and fine > 0.0 else 1


def episode_bytes(experiment: Experiment, filters: list[str]) -> float:
    """Bytes one episode of a campaign holds until its end (a lower estimate): its
    prepared episode (the truth and gimbal attitudes at the K + 1 epochs, and the raw
    IMU increments of the fine run for episodes that keep them) and, per filter and
    start, the run's stored series (attitude, covariance, state, sigma, the errors,
    NEES and NIS at every epoch)."""
    from dataclasses import fields

    epochs = campaign_epochs(experiment)
    n = int(getattr(experiment, "state_count", 0) or 0)
    prepared = 3 * 9 * 8 * epochs
    names = {f.name for f in fields(experiment.episode_class)}
    if {"dtheta", "dv"} <= names:                 # (K, S, 3) each, 8 bytes a number
        step = float(getattr(experiment, "filter_step", 0.0) or 0.0)
        prepared += 2 * 3 * 8 * (epochs - 1) * step * experiment.scenario_config().imu_rate
    per_run = 8 * epochs * (9 + n * n + n + 3 + 3 + 3 + 1 + 1)
    return prepared + per_run * len(filters) * max(len(experiment.starts), 1)


def check_campaign_memory(experiment: Experiment, episodes: int, filters: list[str]) -> None:
    """One-line ConfigError, before anything is allocated or written, for more episodes
    than the machine can hold: the campaign keeps every prepared episode and every
    run in memory (``episode_bytes`` each), and may use at most
    ``simulate.MEMORY_SHARE`` of the memory available now (``simulate.available_memory``;
    no limit where it is unknown)."""
    from aligngym.scenarios import simulate
    have = simulate.available_memory()
    if have is None:
        return
    per = episode_bytes(experiment, filters)
    limit = int(simulate.MEMORY_SHARE * have // per)
    if episodes > limit:
        runs = len(filters) * max(len(experiment.starts), 1)
        raise ConfigError(
            f"--episodes {episodes} needs about {episodes * per / 1e9:.3g} GB "
            f"({per / 1e6:.3g} MB an episode: the prepared episode and {runs} filter "
            f"run(s) of {campaign_epochs(experiment)} epochs), more than "
            f"{simulate.MEMORY_SHARE:.0%} of the {have / 1e9:.1f} GB available: at most "
            f"{limit} episodes on this machine")


SEED_BYTES = 48
"""Bytes a seed takes in a list of episode seeds (the int and its pointers)."""


def check_seed_memory(episodes: int) -> None:
    """One-line ConfigError for a list of seeds the machine cannot hold (an episode
    bank, which prepares its episodes a chunk at a time, still lists them all)."""
    from aligngym.scenarios import simulate
    have = simulate.available_memory()
    limit = None if have is None else int(simulate.MEMORY_SHARE * have // SEED_BYTES)
    if limit is not None and episodes > limit:
        raise ConfigError(f"--episodes {episodes} needs about {episodes * SEED_BYTES / 1e9:.3g}"
                          f" GB to list the seeds, more than {simulate.MEMORY_SHARE:.0%} of "
                          f"the {have / 1e9:.1f} GB available: at most {limit} episodes on "
                          "this machine")


def claim_directory(out: Path) -> None:
    """Create the campaign directory (one-line error if it cannot be made or written)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--out {out}: cannot create the directory ({exc.strerror})") from None
    if not os.access(out, os.W_OK):
        raise ConfigError(f"--out {out}: the directory is not writable")


def _run(experiment: Experiment, episodes: int, seed: int, filters: list[str],
         out: Path | None, resume: bool, workers: int, progress: bool, executor: str,
         address: str | None) -> CampaignResult:
    seeds = episode_seeds(seed, episodes)
    if workers > 1 and executor == "local" and can_fork_workers():
        # once here: the forked preparation and filter workers inherit them
        from aligngym.estimators.kernels import load_compiled_kernels
        load_compiled_kernels()
    with thread_budget(workers):          # --workers K: at most K cores, here or in workers
        prepared = prepare_all(experiment, seeds, out, resume, workers, progress, executor,
                               address)
        result = CampaignResult(experiment, seeds, prepared,
                                experiment.start_errors(prepared), seed=seed)
        starts = {s: result.start_errors[s] for s in experiment.starts}
        result.runs += run_filters(filters, starts, prepared, experiment, workers,
                                   campaign_epochs(experiment), progress)
    return result
