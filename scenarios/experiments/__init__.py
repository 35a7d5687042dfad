"""The experiments: one module each in this package (``paper000`` ... ``paper004``), whose
``EXPERIMENT`` is its ``campaign.Experiment`` subclass, or one registered at run time
(``register_experiment``). The class declares everything else once: its settings (the
dataclass fields, with their docs), its default episode count (``default_episodes``),
its named setups (``setups``) and its regression campaign (``regress``); ``bench``,
``regress``, the scenario files' ``experiment`` key and the env are built from these."""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.registry import _REGISTERED, SCENARIO_PAPER, experiment_names

if TYPE_CHECKING:
    from aligngym.scenarios.campaign import Experiment


def register_experiment(name: str, cls: type) -> None:
    """Make ``cls`` (a frozen-dataclass subclass of ``campaign.Experiment``) runnable as
    ``name`` everywhere: ``bench NAME``, ``regress``, a scenario file's ``experiment =
    "NAME"``, the generic env id."""
    from aligngym.scenarios.campaign import Experiment
    if not (isinstance(cls, type) and issubclass(cls, Experiment)):
        raise ConfigError(f"register_experiment({name!r}): {cls!r} is not an Experiment "
                          "subclass")
    if not name or not name.replace("-", "").replace("_", "").isalnum():
        raise ConfigError(f"register_experiment: name {name!r} must be letters, digits, "
                          "- or _")
    if name in experiment_names() and _REGISTERED.get(name) is not cls:
        raise ConfigError(f"register_experiment: {name!r} is taken")
    _REGISTERED[name] = cls


def experiment_class(name: str) -> type:
    """The Experiment subclass of an experiment name."""
    if name in _REGISTERED:
        return _REGISTERED[name]
    if name not in experiment_names():
        raise ConfigError(f"unknown experiment {name!r}; valid choices: "
                          + ", ".join(experiment_names()))
    return importlib.import_module(f"{__name__}.{name}").EXPERIMENT


def experiment(name: str, setup: str = "default", **settings) -> "Experiment":
    """An experiment with its default settings, or one of its named setups (``setups``,
    e.g. paper003's "paper": the paper's own setup), overridden by ``settings``."""
    cls = experiment_class(name)
    if setup != "default":
        if setup not in cls.setups:
            raise ConfigError(f"--setup {setup!r} is not a setup of {name}; valid choices: "
                              + ", ".join(["default", *cls.setups]))
        settings = {**cls.setups[setup], **settings}
    return cls(**settings)


def regress_campaigns() -> dict[str, dict]:
    """{experiment: its regression campaign} for the experiments that declare one."""
    out = {}
    for name in experiment_names():
        campaign = experiment_class(name).regress
        if campaign is not None:
            out[name] = campaign
    return out


def setup_for(scenario_name: str) -> tuple[str, str] | None:
    """(experiment, setup) of the named setup that runs on a scenario whose file names no
    experiment (e.g. ship-sway-rotary-paper: paper003's --setup paper); None if none."""
    for name in experiment_names():
        for setup, overrides in experiment_class(name).setups.items():
            if str(overrides.get("scenario", "")) == scenario_name:
                return name, setup
    return None


def experiment_for(scenario: str, config=None, **settings) -> "Experiment":
    """The experiment that runs on a scenario (a shipped name or a .toml path): the one
    its file names in its ``experiment`` key, or for a file without one the named setup
    made for it (``setup_for``: ``figure8-gps-paper`` is paper001's ``--setup paper``);
    config: the file already loaded."""
    from aligngym.scenarios.config import load_scenario
    config = load_scenario(scenario) if config is None else config
    if not config.experiment:
        named = setup_for(config.name)
        if named is not None:
            return experiment(named[0], setup=named[1], **{**settings, "scenario": scenario}
                              ).holding(config)
        raise ConfigError(f"scenario {config.name!r} names no experiment (its file has no "
                          "experiment key; valid: " + ", ".join(experiment_names()) + "); shipped "
                          "scenarios with one: " + ", ".join(sorted(SCENARIO_PAPER))
                          + "; the *-paper files run their experiment's paper setup")
    return experiment(config.experiment, scenario=scenario, **settings).holding(config)


def env_experiment(scenario: str, episode_length: float, epoch_length: float,
                   settings: dict | None = None, config=None) -> "Experiment":
    """The experiment an env (and its episode bank) runs: the scenario's, its fine stage
    episode_length s in epochs of epoch_length s, with the other settings; a setting
    those arguments fix, or one the experiment does not have, is a one-line error."""
    settings = dict(settings or {})
    clash = sorted({"fine_duration", "filter_step", "scenario"} & set(settings))
    if clash:
        raise ConfigError(f"settings key {clash[0]!r} is set by episode_length "
                          "(--episode-length), epoch_length (--epoch-length) or the scenario")
    try:
        return experiment_for(scenario, config=config, fine_duration=episode_length,
                              filter_step=epoch_length, **settings)
    except TypeError as exc:              # a settings key the experiment does not have
        raise ConfigError(f"settings: {exc}") from None
