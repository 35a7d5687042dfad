"""An experiment, declared: a paper's definition (scenario, settings, the episode
preparation = simulation + coarse stage, the start errors, the fine model recipe, the
truth the NEES compares with by the model's state names, what it requires of a scenario,
its summary, tables and claims) as a frozen dataclass of settings with role objects; the
base derives the rest (the NEES and its degrees of freedom, the observed states, the
scenario and filter checks). Its results: ``campaign.results``; its settings:
``campaign.settings``."""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Callable, ClassVar

import numpy as np

from aligngym.estimators.alignment import FineResult
from aligngym.estimators.adaptation import OBSERVATION_FEATURES
from aligngym.estimators.catalogue import UnknownFilter, filter_entry, filter_names, filter_needs
from aligngym.estimators.metrics import nees
from aligngym.estimators.model import FilterModel, StateLayout
from aligngym.estimators.rules import MAX_POINTS
from aligngym.scenarios.campaign.episodes import PreparedEpisode
from aligngym.scenarios.campaign.results import CampaignResult, fine_summary, format_fine_table
from aligngym.scenarios.campaign.settings import _whole, validate_settings
from aligngym.scenarios.config import (ConfigError, ScenarioConfig, SettingError,
                                       load_scenario)


@dataclass(frozen=True)
class TruthMap:
    """The states an experiment's NEES compares with the truth, declared by the model's
    layout names, and how their errors are read from a run.

    layout: the model's ``StateLayout``; states: its block names, in the order
    ``errors`` returns them; errors(result, episodes, error_n): the estimate's error
    against the truth of those states, (B, K+1, n) in the layout's units (rad, m/s, ...;
    its sign does not matter to the NEES), with error_n (B, K+1, 3) rad the attitude
    error E, N, U of the run."""

    layout: StateLayout
    states: tuple[str, ...]
    errors: Callable[[FineResult, list[PreparedEpisode], np.ndarray], np.ndarray]

    @property
    def indices(self) -> np.ndarray:
        """The states' indices in the model's state vector."""
        return self.layout.indices(*self.states)

    def nees(self, result: FineResult, episodes: list[PreparedEpisode],
             error_n: np.ndarray) -> np.ndarray:
        """NEES (B, K+1) of the declared states (chi-square with ``indices.size`` dof)."""
        k = self.indices
        return nees(self.errors(result, episodes, error_n), result.P[:, :, k][:, :, :, k])


class Experiment(ABC):
    """A paper's experiment (see the module docstring). Subclasses are frozen
    dataclasses of settings (their ``asdict`` is the campaign manifest) that declare their
    roles as class attributes (``preparation``, ``truth_map``, ``summarise``,
    ``tabulate``, ...) and write methods only for their science (``start_errors``,
    ``model``, and where a paper needs them ``duration``, ``check``, ...).

    Settings every experiment has (dataclass fields of the subclass): scenario (a shipped
    name or a .toml path), default_filters, rms_window s, heading_threshold_arcmin, and
    the fine stage's fine_duration s (None: to the scenario's end, where the experiment
    allows it) and filter_step s (the env's step and the filters' epoch)."""

    paper: str
    scenario: str
    default_filters: tuple[str, ...]
    starts: tuple[str, ...]
    rms_window: float
    heading_threshold_arcmin: float
    fine_duration: float | None
    filter_step: float

    episode_class: ClassVar[type[PreparedEpisode]]
    """The prepared episode's type (its ``arrays`` and ``from_arrays`` store it)."""
    preparation: ClassVar[Callable[[Any, int, ScenarioConfig], PreparedEpisode]]
    """preparation(experiment, seed, config) -> the episode: the simulation and everything
    that does not depend on the filter (a module function, declared with
    ``staticmethod``)."""
    truth_map: ClassVar[TruthMap | None] = None
    """The states the NEES compares with the truth (None: no NEES); a property where it
    depends on the scenario (paper 003's, by its IMU's bias frame)."""
    summarise: ClassVar[Callable[["CampaignResult"], dict]] = staticmethod(
        lambda result: {"fine": fine_summary(result)})
    """summarise(result) -> the JSON summary (default: the final errors per filter and
    start)."""
    tabulate: ClassVar[Callable[["CampaignResult"], str] | None] = None
    """tabulate(result) -> the paper-shaped tables (None: the generic table of the first
    start)."""
    sweep_summary: ClassVar[Callable[[list[dict]], dict] | None] = None
    """sweep_summary(summaries) -> one JSON summary of a sweep over a setting's choices,
    given the campaigns' summaries in choice order (None: ``merge_sweep``'s)."""
    own_plots: ClassVar[Callable[["CampaignResult", Path], list[Path]] | None] = None
    """own_plots(result, out) -> the experiment's own PNG plots written in out, besides
    the error curves (None: none)."""

    worlds: tuple[str, ...] = ()
    """The MuJoCo worlds the experiment's pipeline runs on."""
    filter_keys: tuple[str, ...] = ()
    """Keys the experiment accepts in a scenario's [filter] table."""
    model_variants: tuple[str, ...] = ()
    """Model variants (``FilterEntry.model``) the experiment can build besides its own."""
    state_count: int = 0
    """Dimension of the experiment's fine-alignment state."""
    member_points: float = 1.0
    """The least work per member and epoch of its default filters, in integration points
    of paper 002's model (0.23 us each on the 2-core x86_64 machine of 2026-12-06, 0.27
    on the earlier one; measured by benchmarks/bench_member_cost.py): the
    filter phase splits a batch by it where its models' maps cost more than a point of
    paper 002's (``filtering.member_points``)."""
    filter_costs: ClassVar[dict[str, tuple[float, float]]] = {}
    """Measured costs of its filters (benchmarks/bench_member_cost.py, on the 2-core x86_64
    machine of 2026-12-06): name -> (us a member and epoch, ms an epoch whatever the
    batch). The filter phase's plan weighs and orders a named filter's tasks by them
    (``filtering.member_points``, ``epoch_points``): paper 004's four filters cost 4.6 to
    15 s each on 32 episodes, which ``member_points`` alone counts as equal."""
    filter_settings: frozenset[str] = frozenset({"default_filters", "rms_window",
                                                 "heading_threshold_arcmin"})
    """Settings that concern the filters or the analysis only: the prepared episodes do
    not depend on them, and the episode bank's key leaves them out (retuning a filter
    never simulates again; tests/test_bank_key.py checks that ``prepare_episode`` reads
    none of them)."""
    observation_features: frozenset[str] = frozenset()
    """What its model gives the filters (keys of ``adaptation.OBSERVATION_FEATURES``:
    e.g. "axes", the measurement's local-level axes); a filter needing more is refused
    before any episode is simulated (a test runs every filter to confirm the
    declaration)."""
    default_episodes: int = 50
    """Monte Carlo episodes of ``bench`` without --episodes."""
    setups: dict[str, dict] = {}
    """Named setups besides "default": settings each overrides (``bench --setup``)."""
    regress: dict | None = None
    """The regression campaign (``aligngym regress``): episodes, seed, filters and the
    settings that differ from the defaults ("experiment"); None: not in regress."""
    claims: tuple = ()
    """The paper's claims (``scenarios.campaign.claims.Claim``), checked by ``aligngym
    reproduce``."""
    reproduce: dict | None = None
    """The claims' campaigns: {"episodes", "seed"} (``aligngym reproduce``)."""
    requires: tuple = ()
    """What it needs of a scenario (``campaign.requirements``: a sensor's table, a
    strapdown IMU, a filter step on the GNSS fixes), checked by ``check``."""
    observed: tuple[str, ...] = ("misalignment", "gyro_bias", "accel_bias")
    """The model's state blocks (layout names) the env observes: the attitude error and
    the sensor biases."""

    def __post_init__(self) -> None:
        validate_settings(type(self), self)

    @classmethod
    def flagged_settings(cls) -> list:
        """The settings declared with ``setting`` (their dataclass fields), which ``bench``
        offers as options of their own."""
        return [f for f in fields(cls) if f.metadata.get("option")]

    @classmethod
    def merge_sweep(cls, name: str, summaries: list[dict]) -> dict:
        """One JSON summary of a sweep (``bench --NAME all``) over a setting's choices,
        given the campaigns' summaries in choice order: {"sweep": name, value: summary},
        or the experiment's ``sweep_summary``."""
        if cls.sweep_summary is not None:
            return cls.sweep_summary(summaries)
        choices = next(f.metadata["choices"] for f in fields(cls) if f.name == name)
        return {"sweep": name, **dict(zip(choices, summaries))}

    def scenario_file(self) -> ScenarioConfig:
        """The scenario as its file gives it (a shipped name or a .toml path), parsed
        and validated once per experiment."""
        cached = self.__dict__.get("_scenario_file")
        if cached is None:
            cached = self.__dict__["_scenario_file"] = load_scenario(self.scenario)
        return cached

    def holding(self, loaded: ScenarioConfig) -> "Experiment":
        """This experiment with its scenario file already loaded (``loaded``, the file
        ``self.scenario`` names, as ``load_scenario`` gave it): not parsed again."""
        self.__dict__["_scenario_file"] = loaded
        return self

    def scenario_config(self) -> ScenarioConfig:
        """The scenario (a shipped name or a .toml path), with the experiment's
        duration; its world and [filter] table checked against the experiment. Loaded
        once per experiment (the settings are frozen; ``dataclasses.replace`` makes a
        new experiment, which loads its own)."""
        cached = self.__dict__.get("_scenario_config")
        if cached is not None:
            return cached
        try:
            config = self.scenario_file().with_options(duration=self.duration)
        except ConfigError as exc:     # the run the settings make: name the fine stage's
            if getattr(self, "fine_duration", None) is None:
                raise
            raise SettingError("fine_duration", self.fine_duration,
                               f"makes a run of {self.duration:g} s on scenario "
                               f"{self.scenario_file().name!r}: {exc}") from None
        step = getattr(self, "filter_step", None)
        if step is not None and not _whole(step * config.imu_rate):
            raise SettingError("filter_step", step, "must be a whole number (>= 1) of the "
                               f"scenario's IMU intervals of {config.imu_interval:g} s, "
                               f"got {step!r}")
        if config.world not in self.worlds:
            raise ConfigError(f"paper{self.paper} runs on the {' or '.join(self.worlds)} "
                              f"world; scenario {config.name!r} has world = {config.world!r}")
        for key, _ in config.filter:
            if key not in self.filter_keys:
                raise ConfigError(f"filter.{key} is not a parameter of paper{self.paper}; "
                                  "valid: " + (", ".join(self.filter_keys) or "none"))
        self.__dict__["_scenario_config"] = config       # frozen dataclass: no setattr
        return config

    @property
    def duration(self) -> float:
        """Simulated length of an episode, s: the fine stage's (experiments with a coarse
        stage before it add its length)."""
        return self.fine_duration

    def prepare_episode(self, seed: int, config: ScenarioConfig | None = None
                        ) -> PreparedEpisode:
        """Simulate one episode and run everything that does not depend on the filter
        (``preparation``; config: the scenario, default ``scenario_config()``)."""
        return type(self).preparation(self, seed, config or self.scenario_config())

    @abstractmethod
    def start_errors(self, episodes: list[PreparedEpisode]) -> dict[str, np.ndarray]:
        """Starting misalignment phi E, N, U (rad) of the fine stage per start name,
        common (3,) or per episode (B, 3)."""

    @abstractmethod
    def model(self, episodes: list[PreparedEpisode], start_error: np.ndarray,
              variant: str = "") -> FilterModel:
        """The fine-alignment model (or a variant) for a batch of episodes from a
        starting error."""

    def episode_start(self, episode: PreparedEpisode) -> np.ndarray:
        """The default starting misalignment (3,) rad of one episode (the env's)."""
        start = self.start_errors([episode])[self.starts[0]]
        return np.asarray(start, dtype=float).reshape(-1, 3)[0]

    def attitude_sigma(self) -> np.ndarray:
        """The filter's initial 1-sigma misalignment E, N, U (3,), rad (default: the
        setting attitude_sigma_deg)."""
        return np.deg2rad(self.attitude_sigma_deg)

    def observed_states(self, layout: StateLayout) -> np.ndarray:
        """Indices (<= 9) of the attitude and sensor-bias states (``observed``), for the
        env's observation."""
        return layout.indices(*self.observed)

    def filter_options(self) -> dict[str, Any]:
        """Options of the adaptation policies (e.g. rho)."""
        return {}

    def nees(self, result: FineResult, episodes: list[PreparedEpisode],
             error_n: np.ndarray) -> np.ndarray:
        """NEES (B, K+1) of the states the truth knows (``truth_map``); NaN where not
        defined."""
        if self.truth_map is None:
            return np.full(error_n.shape[:2], np.nan)
        return self.truth_map.nees(result, episodes, error_n)

    def unmodelled_floor(self, episodes: list[PreparedEpisode]) -> np.ndarray | None:
        """The final misalignment (B, 3) rad, E, N, U, that the episodes' sensor errors
        leave and the model's states cannot represent (a converged filter ends on it with a
        sigma that ignores it); None where there is none. The divergence judgement measures
        the final error from it."""
        return None

    def accuracy_window(self, t: np.ndarray, fine_start: float) -> np.ndarray:
        """The epochs (bool over t, s since the fine start; fine_start: its scenario time,
        s) over which results.csv's RMS errors and mean NEES are taken (paper 004's tables
        and JSON use the same; the other papers' tables report final values, and paper
        001's its moving epochs). Here the run's last rms_window s."""
        return t >= t[-1] - self.rms_window - 1e-9

    def nees_dof(self) -> int:
        """Dimension of the states ``nees`` compares with the truth: its chi-square degrees
        of freedom (0: no NEES)."""
        return 0 if self.truth_map is None else int(self.truth_map.indices.size)

    def summary(self, result: "CampaignResult") -> dict:
        """The JSON summary (``summarise``)."""
        return type(self).summarise(result)

    def format_tables(self, result: "CampaignResult") -> str:
        """The paper-shaped tables (``tabulate``)."""
        if type(self).tabulate is None:
            return format_fine_table(result, self.starts[0])
        return type(self).tabulate(result)

    def plots(self, result: "CampaignResult", out: Path) -> list[Path]:
        """The experiment's own plots (PNG) in out (``own_plots``), besides the error
        curves."""
        return [] if type(self).own_plots is None else type(self).own_plots(result, out)

    def check(self, config: ScenarioConfig) -> None:
        """One-line ConfigError for settings of the scenario the experiment cannot use
        (called before any episode is simulated): its ``requires``; an experiment with
        checks of its own calls this first."""
        for requirement in self.requires:
            requirement.check(self, config)

    def runnable_filters(self) -> list[str]:
        """The catalogue's filters this experiment's model can run (models and needs;
        the parametrised families as their pattern)."""
        out = []
        for name in filter_names():
            probe = name.replace("-N", "-2")
            entry = filter_entry(probe)
            if entry.model and entry.model not in self.model_variants:
                continue
            if filter_needs(probe, **self.filter_options()) <= self.observation_features:
                out.append(name)
        return out

    def check_filters(self, filters: list[str]) -> None:
        """One-line ConfigError for an unknown filter, or one whose rule needs more points
        than ``rules.MAX_POINTS`` for this model's dimension."""
        for name in filters:
            try:
                entry = filter_entry(name)
            except UnknownFilter as exc:
                raise ConfigError(str(exc)) from None
            if entry.model and entry.model not in self.model_variants:
                raise ConfigError(f"filter {name!r} needs the {entry.model} model, which "
                                  f"paper{self.paper} does not build for scenario "
                                  f"{self.scenario!r}")
            missing = sorted(filter_needs(name, **self.filter_options())
                             - self.observation_features)
            if missing:
                raise ConfigError(f"filter {name!r} ({entry.description}) needs "
                                  f"{OBSERVATION_FEATURES[missing[0]]}, which paper"
                                  f"{self.paper}'s model does not give; filters that run "
                                  "here: " + ", ".join(self.runnable_filters()))
            rule = entry.rule()
            count = rule.point_count(self.state_count)
            if count > MAX_POINTS:
                raise ConfigError(f"filter {name!r} needs {count:.3g} points per episode for "
                                  f"the {self.state_count}-state model of paper{self.paper} "
                                  f"(at most {MAX_POINTS}); use a sparse grid (sghkf-L)")
