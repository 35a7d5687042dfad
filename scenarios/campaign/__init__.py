"""The Monte Carlo campaign, generic over experiments (SPEC 6).

An ``Experiment`` (``experiment``) is run by ``run_campaign`` (``engine``): the output
directory is claimed through its manifest (``manifest``), the episodes are prepared in
parallel (``executors``: local processes, Ray, or one registered) and written to disk one at a time,
atomically (``episodes``), so an interrupted campaign keeps what finished and ``resume``
continues it; the filters then run batched over all episodes, alongside each other in
worker processes (``filtering``, ``runs``);
``scenarios.report`` writes the tidy table, time series, plots and JSON. The commands plan
their campaigns first (``plan``: bench's sweep, regress, reproduce's claims), every one
checked before the first runs.
"""
from aligngym.scenarios.campaign.engine import run_campaign
from aligngym.scenarios.campaign.episodes import (GnssEpisode, PreparedEpisode, episode_seeds,
                                                  simulate_screened)
from aligngym.scenarios.campaign.executors import (EXECUTORS, Executor, prepare_all,
                                                   register_executor)
from aligngym.scenarios.campaign.experiment import Experiment, TruthMap
from aligngym.scenarios.campaign.results import (AXES, CampaignResult, FilterRun, fine_summary,
                                                 format_fine_table)
from aligngym.scenarios.campaign.filtering import run_filters
from aligngym.scenarios.campaign.runs import (analyse_run, concatenate_results, episode_metrics,
                                              run_filter)
from aligngym.scenarios.campaign.settings import setting

__all__ = ["AXES", "EXECUTORS", "CampaignResult", "Executor", "Experiment", "FilterRun", "GnssEpisode",
           "PreparedEpisode", "analyse_run", "concatenate_results", "episode_metrics",
           "episode_seeds", "fine_summary", "format_fine_table", "prepare_all", "register_executor",
           "run_campaign", "run_filter", "run_filters", "setting", "simulate_screened",
           "TruthMap"]
