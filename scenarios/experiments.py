"""Which experiment (paper pipeline) runs on which scenario: the campaign CLI, the
gymnasium env and ``scenarios.evaluate`` are built from these."""
from __future__ import annotations

from typing import TYPE_CHECKING

from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.registry import PAPERS, SCENARIO_PAPER  # noqa: F401  (re-exported)

if TYPE_CHECKING:
    from aligngym.scenarios.campaign import Experiment



SETUPS = ("default", "paper")


def experiment(paper: str, setup: str = "default", **settings) -> "Experiment":
    """A paper's experiment with its default settings, or a named setup ("paper": the
    paper's own setup, reproduced for a stated reason; paper003 only), overridden by
    ``settings``."""
    if setup not in SETUPS:
        raise ConfigError(f"--setup {setup!r} is unknown; valid choices: " + ", ".join(SETUPS))
    if setup == "paper" and paper != "paper003":
        raise ConfigError(f"--setup paper exists for paper003 only, not {paper}")
    if paper == "paper003":
        from aligngym.scenarios.paper003 import PAPER_SETUP, Paper003Experiment
        cls = Paper003Experiment
        if setup == "paper":
            settings = {**PAPER_SETUP, **settings}
    elif paper == "paper000":
        from aligngym.scenarios.paper000 import Paper000Experiment
        cls = Paper000Experiment
    elif paper == "paper001":
        from aligngym.scenarios.paper001 import Paper001Experiment
        cls = Paper001Experiment
    elif paper == "paper002":
        from aligngym.scenarios.paper002 import Paper002Experiment
        cls = Paper002Experiment
    elif paper == "paper004":
        from aligngym.scenarios.paper004 import Paper004Experiment
        cls = Paper004Experiment
    else:
        raise ConfigError(f"unknown paper {paper!r}; valid choices: " + ", ".join(PAPERS))
    return cls(**settings)


def experiment_for(scenario: str, **settings) -> "Experiment":
    """The experiment that runs on a scenario (a shipped name or a .toml path): the one
    its file names in its ``experiment`` key."""
    from aligngym.scenarios.config import load_scenario
    config = load_scenario(scenario)
    if not config.experiment:
        raise ConfigError(f"scenario {config.name!r} names no experiment (its file has no "
                          "experiment key; valid: " + ", ".join(PAPERS) + "); shipped "
                          "scenarios with one: " + ", ".join(sorted(SCENARIO_PAPER)))
    return experiment(config.experiment, scenario=scenario, **settings)
