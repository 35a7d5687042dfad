"""An experiment (a paper's definition: scenario, episode preparation = simulation +
coarse stage, the fine model, the filters, starting errors, truth for the metrics and
the paper-shaped tables) and the results of its campaign: one ``FilterRun`` per filter
and start, gathered in a ``CampaignResult``; the generic fine-alignment table."""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from aligngym.estimators.alignment import FineResult
from aligngym.estimators.adaptation import OBSERVATION_FEATURES
from aligngym.estimators.filters import UnknownFilter, filter_entry, filter_names, filter_needs
from aligngym.estimators.model import FilterModel, StateLayout
from aligngym.estimators.rules import MAX_POINTS
from aligngym.models.units import arcmin
from aligngym.scenarios.campaign.episodes import PreparedEpisode
from aligngym.scenarios.config import ConfigError, ScenarioConfig, load_scenario

AXES = ("phi_E", "phi_N", "phi_U")


def setting(default: Any, doc: str, *, unit: str = "", choices: tuple = (),
            sweep: bool = False, minimum: float | None = None) -> Any:
    """A setting of an experiment with its own ``bench`` option, ``--NAME`` (underscores as
    dashes; every other setting is ``--set NAME=VALUE``): a dataclass field whose
    metadata holds its doc (the option's help), its unit, the values it takes (choices)
    or its lower bound (minimum, numbers), and sweep (with choices: the option also takes
    "all", one campaign per choice, ``Experiment.merge_sweep`` joins their summaries)."""
    return field(default=default, metadata={"doc": doc, "unit": unit, "choices": tuple(choices),
                                            "sweep": sweep, "minimum": minimum})


class Experiment(ABC):
    """A paper's experiment (see the module docstring). Subclasses are frozen
    dataclasses of settings (their ``asdict`` is the campaign manifest)."""

    paper: str
    scenario: str
    default_filters: tuple[str, ...]
    starts: tuple[str, ...]
    rms_window: float
    heading_threshold_arcmin: float
    episode_class: type[PreparedEpisode]

    worlds: tuple[str, ...] = ()
    """The MuJoCo worlds the experiment's pipeline runs on."""
    filter_keys: tuple[str, ...] = ()
    """Keys the experiment accepts in a scenario's [filter] table."""
    model_variants: tuple[str, ...] = ()
    """Model variants (``FilterEntry.model``) the experiment can build besides its own."""
    state_count: int = 0
    """Dimension of the experiment's fine-alignment state."""
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

    @classmethod
    def flagged_settings(cls) -> list:
        """The settings declared with ``setting`` (their dataclass fields), which ``bench``
        offers as options of their own."""
        return [f for f in fields(cls) if "doc" in f.metadata]

    @classmethod
    def merge_sweep(cls, name: str, summaries: list[dict]) -> dict:
        """One JSON summary of a sweep (``bench --NAME all``) over a setting's choices,
        given the campaigns' summaries in choice order: {"sweep": name, value: summary}."""
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
        config = self.scenario_file().with_options(duration=self.duration)
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
    @abstractmethod
    def duration(self) -> float:
        """Simulated length of an episode, s."""

    @abstractmethod
    def prepare_episode(self, seed: int, config: ScenarioConfig | None = None
                        ) -> PreparedEpisode:
        """Simulate one episode and run everything that does not depend on the filter."""

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

    @abstractmethod
    def attitude_sigma(self) -> np.ndarray:
        """The filter's initial 1-sigma misalignment E, N, U (3,), rad."""

    @abstractmethod
    def observed_states(self, layout: StateLayout) -> np.ndarray:
        """Indices (<= 9) of the attitude and sensor-bias states, for the env's
        observation."""

    def filter_options(self) -> dict[str, Any]:
        """Options of the adaptation policies (e.g. rho)."""
        return {}

    def nees(self, result: FineResult, episodes: list[PreparedEpisode],
             error_n: np.ndarray) -> np.ndarray:
        """NEES (B, K+1) of the states the truth knows; NaN where not defined."""
        return np.full(error_n.shape[:2], np.nan)

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
        return 0

    def summary(self, result: "CampaignResult") -> dict:
        """The JSON summary."""
        return {"fine": fine_summary(result)}

    def format_tables(self, result: "CampaignResult") -> str:
        """The paper-shaped tables."""
        return format_fine_table(result, self.starts[0])

    def plots(self, result: "CampaignResult", out: Path) -> list[Path]:
        """The experiment's own plots (PNG) in out, besides the error curves; none by
        default."""
        return []

    def check(self, config: ScenarioConfig) -> None:
        """One-line ConfigError for settings of the scenario the experiment cannot use
        (called before any episode is simulated)."""

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


@dataclass
class FilterRun:
    """Results of one filter from one starting error, for all episodes."""

    filter: str
    start: str
    result: FineResult
    error_n: np.ndarray        # (B, K+1, 3) rad
    euler_error: np.ndarray    # (B, K+1, 3) rad: body pitch, roll, heading
    nees: np.ndarray           # (B, K+1)
    diverged: np.ndarray       # (B,)
    reason: list[str]
    heading_convergence: np.ndarray  # (B,) s after the start of fine alignment
    floor: np.ndarray | None = None  # (B, 3) rad: ``Experiment.unmodelled_floor``


@dataclass
class CampaignResult:
    experiment: Experiment
    seeds: list[int]
    episodes: list[PreparedEpisode]
    start_errors: dict[str, np.ndarray]
    runs: list[FilterRun] = field(default_factory=list)
    seed: int | None = None
    """The campaign seed the episode seeds derive from (``episode_seeds``)."""

    def summary(self) -> dict:
        """The experiment's JSON summary, with the data faults flagged ("data_faults")."""
        return {**self.experiment.summary(self), "data_faults": self.faults()}

    def faults(self) -> dict:
        """The data faults the pipeline's screen flagged (IMU, gimbal, GNSS, odometer):
        episodes flagged (counted apart from the diverged ones, which the filters' tables
        count), per kind, and per flagged seed the (kind, time s) list in time order."""
        flagged = {seed: [(str(k), float(t)) for k, t in zip(e.fault_kind, e.fault_time)]
                   for seed, e in zip(self.seeds, self.episodes) if len(e.fault_kind)}
        kinds: dict[str, int] = {}
        for flags in flagged.values():
            for kind, _ in flags:
                kinds[kind] = kinds.get(kind, 0) + 1
        return {"flagged_episodes": len(flagged), "episodes": len(self.seeds),
                "by_kind": kinds, "flags": {str(s): f for s, f in flagged.items()}}


def fine_summary(result: CampaignResult, window: float | None = None) -> dict:
    """Per filter and start: mean, std, RMS of the final error per axis (arcmin), or of
    the per-episode RMS over the last ``window`` s, and the fraction diverged."""
    out: dict[str, dict[str, dict]] = {}
    for run in result.runs:
        if window is None:
            final = run.error_n[:, -1] / arcmin
        else:
            t = run.result.t
            sel = t >= t[-1] - window - 1e-9
            final = np.sqrt(np.mean(run.error_n[:, sel] ** 2, axis=1)) / arcmin
        out.setdefault(run.filter, {})[run.start] = {
            "mean_arcmin": list(final.mean(0)), "std_arcmin": list(final.std(0)),
            "rms_arcmin": list(np.sqrt((final ** 2).mean(0))),
            "diverged_fraction": float(run.diverged.mean())}
    return out


def format_fine_table(result: CampaignResult, start: str, title: str | None = None,
                      extra: dict[str, str] | None = None, extra_header: str = "") -> str:
    """Final error per filter (mean, std, RMS per axis, arcmin) from one start; extra:
    per filter, text appended to its first row under extra_header."""
    fine = fine_summary(result)
    lines = [title or f"Fine alignment from the {start} start: final error (arcmin)",
             f"{'filter':9s}{'stat':6s}" + "".join(f"{a:>12s}" for a in AXES)
             + f"{'diverged':>10s}" + extra_header]
    for name, per_start in fine.items():
        s = per_start[start]
        for stat in ("mean", "std", "rms"):
            tail = (f"{s['diverged_fraction']:10.0%}" + (extra or {}).get(name, "")
                    if stat == "mean" else "")
            lines.append(f"{name if stat == 'mean' else '':9s}{stat:6s}"
                         + "".join(f"{v:12.4f}" for v in s[f"{stat}_arcmin"]) + tail)
    return "\n".join(lines)


