"""The campaign engine: settings checked, the directory claimed (created, locked, its
manifest checked), the episodes prepared (executors, stored as they finish), then every
filter run once, batched over all episodes from all starts."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from aligngym.scenarios.interrupts import raise_if_interrupted
from aligngym.scenarios.campaign.episodes import episode_seeds
from aligngym.scenarios.campaign.executors import EXECUTORS, prepare_all
from aligngym.scenarios.campaign.experiment import CampaignResult, Experiment
from aligngym.scenarios.campaign.manifest import campaign_lock, check_manifest
from aligngym.scenarios.campaign.runs import filter_threads, run_filter_starts
from aligngym.scenarios.config import ConfigError


def run_campaign(experiment: Experiment, episodes: int = 50, seed: int = 0,
                 filters: list[str] | None = None, out_dir: str | Path | None = None,
                 resume: bool = False, workers: int | None = None,
                 progress: bool = True, executor: str = "local",
                 address: str | None = None, force: bool = False) -> CampaignResult:
    """Run an experiment's campaign; see the module docstring. executor: "local"
    (processes) or "ray" (tasks on a local Ray instance, or the cluster at address)."""
    filters = list(filters or experiment.default_filters)
    experiment.check(experiment.scenario_config())   # the file first: it is the cheaper
    experiment.check_filters(filters)                # (a sparse grid counts its points)
    if episodes < 1:
        raise ConfigError(f"--episodes = {episodes} must be >= 1")
    if executor not in EXECUTORS:
        raise ConfigError(f"--executor {executor!r} is unknown; valid: " + ", ".join(EXECUTORS))
    if address is not None and executor != "ray":
        raise ConfigError("--address needs --executor ray")
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
    prepared = prepare_all(experiment, seeds, out, resume, workers, progress, executor,
                           address)
    result = CampaignResult(experiment, seeds, prepared, experiment.start_errors(prepared),
                            seed=seed)
    from tqdm import tqdm          # after the checks: their errors answer at once
    starts = {s: result.start_errors[s] for s in experiment.starts}
    for name in tqdm(filters, disable=not progress, desc="filters"):
        raise_if_interrupted()
        result.runs += run_filter_starts(name, starts, prepared, experiment,
                                         filter_threads(name, experiment, workers))
    return result
