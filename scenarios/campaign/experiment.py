"""An experiment (a paper's definition: scenario, episode preparation = simulation +
coarse stage, the fine model, the filters, starting errors, truth for the metrics and
the paper-shaped tables) and the results of its campaign: one ``FilterRun`` per filter
and start, gathered in a ``CampaignResult``; the generic fine-alignment table."""
from __future__ import annotations

import types
import typing
from abc import ABC, abstractmethod
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from aligngym.estimators.alignment import FineResult
from aligngym.estimators.adaptation import OBSERVATION_FEATURES
from aligngym.estimators.catalogue import UnknownFilter, filter_entry, filter_names, filter_needs
from aligngym.estimators.metrics import status_fractions
from aligngym.estimators.model import FilterModel, StateLayout
from aligngym.estimators.rules import MAX_POINTS
from aligngym.models.units import arcmin
from aligngym.scenarios.campaign.episodes import PreparedEpisode
from aligngym.scenarios.config import (ConfigError, ScenarioConfig, SettingError,
                                       load_scenario)

AXES = ("phi_E", "phi_N", "phi_U")


def setting(default: Any, doc: str, *, unit: str = "", choices: tuple = (),
            sweep: bool = False, low: float | None = None, high: float | None = None,
            low_open: bool = False, option: bool = True, minimum: float | None = None
            ) -> Any:
    """A declared setting of an experiment: a dataclass field whose metadata holds its doc
    (the option's help), its unit, the values it takes (choices) or its range (numbers, and
    each number of a tuple: low <= value <= high, low < value with low_open; minimum: an
    older name of low), and sweep (with choices: the option also takes "all", one campaign
    per choice, ``Experiment.merge_sweep`` joins their summaries). With option (the
    default) ``bench`` offers it as ``--NAME`` (underscores as dashes); every setting is
    also ``--set NAME=VALUE``. ``validate_settings`` checks every value against its field's
    type and this declaration when the experiment is made."""
    return field(default=default, metadata={
        "doc": doc, "unit": unit, "choices": tuple(choices), "sweep": sweep,
        "low": low if low is not None else minimum, "high": high, "low_open": low_open,
        "option": option})


def bounded(default: Any, unit: str = "", *, low: float | None = None,
            high: float | None = None, low_open: bool = False, choices: tuple = ()) -> Any:
    """A setting without an option of its own (``--set NAME=VALUE`` only) with a declared
    range or choices (see ``setting``)."""
    return setting(default, "", unit=unit, choices=choices, low=low, high=high,
                   low_open=low_open, option=False)


POSITIVE = {"low": 0.0, "low_open": True}
"""``bounded(x, "s", **POSITIVE)``: a number > 0."""
MAX_RUN = 86400.0
"""s: the longest run a scenario takes (``config.ScenarioConfig.validate``)."""


def _whole(ratio: float) -> bool:
    return abs(ratio - round(ratio)) < 1e-6 and round(ratio) >= 1


def _is_number(value: Any) -> bool:
    return (isinstance(value, (int, float, np.integer, np.floating))
            and not isinstance(value, (bool, np.bool_)))


def _range_text(meta: dict) -> str:
    low, high, unit = meta.get("low"), meta.get("high"), meta.get("unit", "")
    if low is not None and high is not None:
        text = f" in {'(' if meta.get('low_open') else '['}{low:g}, {high:g}]"
    elif low is not None:
        text = f" {'>' if meta.get('low_open') else '>='} {low:g}"
    elif high is not None:
        text = f" <= {high:g}"
    else:
        text = ""
    return text + (f" {unit}" if unit and text else "")


def _in_range(value: float, meta: dict) -> bool:
    low, high = meta.get("low"), meta.get("high")
    if low is not None and not (value > low if meta.get("low_open") else value >= low):
        return False
    return high is None or value <= high


def _check_value(name: str, value: Any, kind: Any, meta: dict, default: Any) -> Any:
    """The value, checked against its field's type (kind) and declaration (meta); a list
    for a tuple becomes a tuple. A SettingError naming the setting otherwise."""
    optional = False
    if typing.get_origin(kind) in (types.UnionType, typing.Union):
        args = typing.get_args(kind)
        optional = type(None) in args
        rest = [a for a in args if a is not type(None)]
        kind = rest[0] if len(rest) == 1 else None
    if value is None:
        if optional or kind is None:
            return value
        raise SettingError(name, value, f"must be {_expected(kind, meta)}, got none")
    tail = " or none" if optional else ""
    choices = meta.get("choices") or ()
    if choices and value != default and value not in choices:
        raise SettingError(name, value, f"must be one of {', '.join(map(str, choices))}"
                                        f"{tail}, got {value!r}")
    if kind in (float, int):
        if not _is_number(value) or (kind is int and not float(value).is_integer()):
            raise SettingError(name, value, f"must be {_expected(kind, meta)}{tail}, "
                                            f"got {value!r}")
        if not (np.isfinite(value) and _in_range(float(value), meta)):
            raise SettingError(name, value, f"must be {_expected(kind, meta)}{tail}, "
                                            f"got {value!r}")
        return value
    if kind in (str, bool):
        if not isinstance(value, kind):
            raise SettingError(name, value, f"must be {_expected(kind, meta)}{tail}, "
                                            f"got {value!r}")
        return value
    if typing.get_origin(kind) is tuple:
        args = typing.get_args(kind)
        count = None if len(args) == 2 and args[1] is Ellipsis else len(args)
        item = args[0] if args else None
        ok = isinstance(value, (tuple, list)) and (count is None or len(value) == count)
        if ok:
            try:
                value = tuple(_check_value(name, v, item, meta, None) for v in value)
            except Exception:
                ok = False
        if not ok:
            raise SettingError(name, value, f"must be {_expected(kind, meta)}{tail}, "
                                            f"got {value!r}")
        return value
    return value


def _expected(kind: Any, meta: dict) -> str:
    """What a value of this type and declaration must be, in words."""
    if kind is float:
        return "a finite number" + _range_text(meta)
    if kind is int:
        return "an integer" + _range_text(meta)
    if kind is str:
        return "a string"
    if kind is bool:
        return "true or false"
    if typing.get_origin(kind) is tuple:
        args = typing.get_args(kind)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_expected(args[0], meta).removeprefix('a ')}s"
        return f"a list of {len(args)} " + _expected(args[0], meta).removeprefix(
            "a ").replace("number", "numbers", 1)
    return "a valid value"


def validate_settings(cls: type, experiment: Any) -> None:
    """Every setting of an experiment (a frozen dataclass) checked, in one place, before
    any work: its type (a bool or a string is not a number; numbers finite; tuples of the
    declared length), its declared choices and range (``setting``, ``bounded``), and the
    filter step against the fine run (0 < filter_step <= fine_duration). A list for a
    tuple becomes a tuple. Raises the first ``config.SettingError``."""
    import typing
    hints = cls.__dict__.get("_setting_types")
    if hints is None:
        try:
            hints = typing.get_type_hints(cls)
        except Exception:             # an unresolvable annotation: types left unchecked
            hints = {}
        cls._setting_types = hints
    for f in fields(cls):
        value = getattr(experiment, f.name)
        checked = _check_value(f.name, value, hints.get(f.name), dict(f.metadata), f.default)
        if checked is not value:
            object.__setattr__(experiment, f.name, checked)
    step = getattr(experiment, "filter_step", None)
    fine = getattr(experiment, "fine_duration", None)
    if _is_number(step) and _is_number(fine) and step > fine:
        defaults = {f.name: f.default for f in fields(cls)}
        if step == defaults.get("filter_step"):          # name the one that was changed
            raise SettingError("fine_duration", fine, f"must be >= {{other}} ({step:g} s), "
                                                      f"got {fine!r}", other="filter_step")
        raise SettingError("filter_step", step, f"must be <= {{other}} ({fine:g} s), "
                                                f"got {step!r}", other="fine_duration")


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

    def observed_states(self, layout: StateLayout) -> np.ndarray:
        """Indices (<= 9) of the attitude and sensor-bias states (``observed``), for the
        env's observation."""
        return layout.indices(*self.observed)

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


@dataclass
class FilterRun:
    """Results of one filter from one starting error, for all episodes."""

    filter: str
    start: str
    result: FineResult
    error_n: np.ndarray        # (B, K+1, 3) rad
    euler_error: np.ndarray    # (B, K+1, 3) rad: body pitch, roll, heading
    nees: np.ndarray           # (B, K+1)
    status: np.ndarray         # (B,) str: ``metrics.STATUSES`` (``metrics.StatusRule``)
    reason: list[str]          # why each episode has its status ("" if converged)
    heading_convergence: np.ndarray  # (B,) s after the start of fine alignment
    floor: np.ndarray | None = None  # (B, 3) rad: ``Experiment.unmodelled_floor``

    @property
    def diverged(self) -> np.ndarray:
        """(B,) the episodes whose status is diverged: the filter broke, or its sigma
        cannot be trusted (left out of the figures' bands and the report's statistics;
        a lost episode's error is drawn with the rest)."""
        return self.status == "diverged"


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
    the per-episode RMS over the last ``window`` s, and the fraction of the episodes in
    each status (``metrics.status_fractions``)."""
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
            **status_fractions(run.status)}
    return out


STATUS_HEADER = f"{'conv.':>7s}{'not conv.':>10s}{'diverged':>9s}{'lost':>6s}"
"""The header of the status columns of a table (docs/estimators.md, "Episode status")."""


def status_columns(fractions: dict) -> str:
    """The percentages of ``metrics.status_fractions`` under ``STATUS_HEADER``."""
    return (f"{fractions['converged_fraction']:7.0%}{fractions['not_converged_fraction']:10.0%}"
            f"{fractions['diverged_fraction']:9.0%}{fractions['lost_fraction']:6.0%}")


def format_fine_table(result: CampaignResult, start: str, title: str | None = None,
                      extra: dict[str, str] | None = None, extra_header: str = "") -> str:
    """Final error per filter (mean, std, RMS per axis, arcmin) from one start; extra:
    per filter, text appended to its first row under extra_header."""
    fine = fine_summary(result)
    lines = [title or f"Fine alignment from the {start} start: final error (arcmin)",
             f"{'filter':9s}{'stat':6s}" + "".join(f"{a:>12s}" for a in AXES)
             + STATUS_HEADER + extra_header]
    for name, per_start in fine.items():
        s = per_start[start]
        for stat in ("mean", "std", "rms"):
            tail = (status_columns(s) + (extra or {}).get(name, "")
                    if stat == "mean" else "")
            lines.append(f"{name if stat == 'mean' else '':9s}{stat:6s}"
                         + "".join(f"{v:12.4f}" for v in s[f"{stat}_arcmin"]) + tail)
    return "\n".join(lines)


