"""Campaigns planned, then executed.

A plan turns what a command asks for into ``CampaignSpec``s: ``bench`` an experiment
with its setup and settings, one campaign per value of a swept setting
(``bench_plan``); ``regress`` each named paper's declared regression campaign
(``regress_plan``); ``reproduce`` the campaigns each paper's claims need, claims that
need the same campaign sharing it (``claims_plan``). Each plan checks all its specs
(``CampaignSpec.check``: the scenario, the filters, the episodes, the memory) as it is
made, and the commands make the whole plan before they run its first campaign, so a
bad setting or a campaign too large for the machine is refused before any work; a spec
is then executed by ``CampaignSpec.run`` (``run_campaign``, with the executor, the
workers and the output directory).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from aligngym.scenarios.campaign.claims import Claim
from aligngym.scenarios.campaign.experiment import Experiment
from aligngym.scenarios.campaign.results import CampaignResult
from aligngym.scenarios.config import ConfigError


@dataclass(frozen=True)
class CampaignSpec:
    """One campaign: the experiment (its setup and settings applied), its episodes and
    seed, the filters (the experiment's defaults where none were asked for), and a label
    saying where it comes from in its plan (a sweep value, a claim group; "" alone)."""

    experiment: Experiment
    episodes: int
    seed: int
    filters: tuple[str, ...]
    label: str = ""

    def check(self) -> None:
        """One-line ConfigError for a campaign that cannot run (``engine.check_campaign``)."""
        from aligngym.scenarios.campaign.engine import check_campaign
        check_campaign(self.experiment, self.episodes, list(self.filters))

    def run(self, **execution: Any) -> CampaignResult:
        """Execute the campaign (``run_campaign``; execution: out_dir, resume, workers,
        progress, executor, address, force)."""
        from aligngym.scenarios.campaign.engine import run_campaign
        return run_campaign(self.experiment, episodes=self.episodes, seed=self.seed,
                            filters=list(self.filters), **execution)


def checked(specs: list[CampaignSpec]) -> list[CampaignSpec]:
    """The specs, each checked (``CampaignSpec.check``) before any of them runs."""
    for spec in specs:
        spec.check()
    return specs


@dataclass(frozen=True)
class BenchPlan:
    """``bench``'s campaigns: one, or one per value of the swept setting (``sweep``, its
    name; each spec's label is its value)."""

    specs: list[CampaignSpec]
    sweep: str | None = None


def bench_plan(paper: str, setup: str, settings: dict[str, Any], episodes: int | None,
               seed: int, filters: list[str] | None) -> BenchPlan:
    """The campaigns of ``bench PAPER --setup SETUP`` with settings (a declared sweep
    setting set to "all" gives one campaign per choice), episodes (None: the
    experiment's default), seed and filters (None: the experiment's), each checked."""
    from aligngym.scenarios.experiments import experiment, experiment_class
    cls = experiment_class(paper)
    sweep = next((f for f in cls.flagged_settings()
                  if f.metadata["sweep"] and settings.get(f.name) == "all"), None)
    levels = [None] if sweep is None else list(sweep.metadata["choices"])
    specs = []
    for level in levels:
        exp = experiment(paper, setup,
                         **(settings if level is None else {**settings, sweep.name: level}))
        chosen = tuple(exp.default_filters if filters is None else filters)
        if not chosen:
            raise ConfigError("--filters is empty; give at least one filter name")
        specs.append(CampaignSpec(exp, episodes or cls.default_episodes, seed, chosen,
                                  "" if level is None else str(level)))
    return BenchPlan(checked(specs), None if sweep is None else sweep.name)


def regress_plan(papers: list[str]) -> dict[str, CampaignSpec]:
    """Each named paper's regression campaign (``Experiment.regress``: episodes, seed,
    filters and the settings that differ from its defaults), each checked."""
    from aligngym.scenarios.experiments import experiment, regress_campaigns
    declared = regress_campaigns()
    specs = {paper: CampaignSpec(experiment(paper, **declared[paper].get("experiment", {})),
                                 declared[paper]["episodes"], declared[paper]["seed"],
                                 tuple(declared[paper]["filters"]))
             for paper in papers}
    checked(list(specs.values()))
    return specs


@dataclass(frozen=True)
class ClaimCampaign:
    """A campaign a paper's claims need, and those claims."""

    paper: str
    spec: CampaignSpec
    claims: list[Claim] = field(default_factory=list)


def claims_plan(papers: list[str], episodes: int | None = None, seed: int | None = None
                ) -> list[ClaimCampaign]:
    """Every named paper's claim campaigns, in paper then first-claim order: one per
    distinct (setup, settings, filters) a claim asks for, with each paper's episodes and
    seed (``reproduce_counts``) unless given; each checked before any runs."""
    from aligngym.scenarios.experiments import experiment, experiment_class
    plan = []
    for paper in papers:
        count, campaign_seed = reproduce_counts(paper, episodes, seed)
        groups: dict[tuple, list[Claim]] = {}
        for claim in experiment_class(paper).claims:
            groups.setdefault(claim.campaign_key(), []).append(claim)
        for i, claims in enumerate(groups.values()):
            first = claims[0]
            exp = experiment(paper, first.setup, **first.settings)
            spec = CampaignSpec(exp, count, campaign_seed,
                                tuple(first.filters or exp.default_filters),
                                f"{first.setup}-{i + 1}")
            plan.append(ClaimCampaign(paper, spec, claims))
    checked([c.spec for c in plan])
    return plan


def reproduce_counts(paper: str, episodes: int | None = None, seed: int | None = None
                     ) -> tuple[int, int]:
    """(episodes, seed) of a paper's claim campaigns: the given ones, else its own
    (``Experiment.reproduce``; 20 episodes, seed 0 where it declares none)."""
    from aligngym.scenarios.experiments import experiment_class
    declared = experiment_class(paper).reproduce or {}
    return (episodes or declared.get("episodes", 20),
            declared.get("seed", 0) if seed is None else seed)
