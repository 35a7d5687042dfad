"""The Monte Carlo campaign engine, generic over experiments (SPEC 6).

An ``Experiment`` (a paper's definition: scenario, episode preparation = simulation +
coarse stage, the fine model, the filters, starting errors, truth for the metrics and
the paper-shaped tables) is run here: episodes are prepared in parallel processes and
written to disk one at a time (atomically), so an interrupted campaign keeps what
finished and ``resume`` continues it; the filters then run batched over all episodes;
``scenarios.report`` writes the tidy table, time series, plots and JSON.
"""
from __future__ import annotations

import json
import os
from abc import ABC, abstractmethod
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from aligngym.estimators.alignment import FineResult, run_alignment
from aligngym.estimators.filters import UnknownFilter, filter_entry, make_filter
from aligngym.estimators.metrics import DivergenceRule, convergence_time, euler_error, misalignment
from aligngym.estimators.model import FilterModel, StateLayout
from aligngym.estimators.rules import MAX_POINTS
from aligngym.models.units import arcmin
from aligngym.scenarios.config import ConfigError, ScenarioConfig, load_scenario

AXES = ("phi_E", "phi_N", "phi_U")


@dataclass
class PreparedEpisode(ABC):
    """What the filters need of one episode and its truth at the filter epochs.

    Every prepared episode has: seed; C_s_n_true, C_b_n_true, C_s_b (K+1, 3, 3) at the
    epoch boundaries (truth IMU and body attitude, the gimbal as the encoders read it);
    gyro_bias (3,) rad/s and accel_bias (3,) m/s^2, the drawn constant sensor errors;
    lat (rad) and h (m), the known position. Experiments add their own fields. It saves
    itself as one .npz, atomically: by default every field as one array (fields annotated
    int or float come back as numbers); episodes holding structures override ``arrays``
    and ``from_arrays`` (the fault flags are saved and restored for every episode).
    """

    seed: int
    C_s_n_true: np.ndarray
    C_b_n_true: np.ndarray
    C_s_b: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    lat: float
    h: float
    fault_kind: np.ndarray = field(default_factory=lambda: np.array([], str), kw_only=True)
    fault_time: np.ndarray = field(default_factory=lambda: np.zeros(0), kw_only=True)
    """The data faults the pipeline's screen flagged (``estimators.screen``): kind
    (F,) str and the time (F,) s of each one's first sample."""

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything needed to rebuild the episode, as arrays."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_arrays(cls, f: Any) -> "PreparedEpisode":
        """Rebuild from ``arrays()`` (an npz file or a dict)."""
        number = {"int": int, "float": float}
        return cls(**{field.name: number.get(field.type, np.asarray)(f[field.name])
                      for field in fields(cls)})

    def save(self, path: Path) -> None:
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, **{**self.arrays(), "fault_kind": np.asarray(self.fault_kind, str),
                         "fault_time": np.asarray(self.fault_time, float)})
        os.replace(tmp, path)  # atomic: a file on disk is always a complete episode

    @classmethod
    def load(cls, path: Path) -> "PreparedEpisode":
        with np.load(path) as f:
            episode = cls.from_arrays(f)
            if "fault_kind" in f.files:
                episode.fault_kind, episode.fault_time = f["fault_kind"], f["fault_time"]
            return episode


@dataclass
class GnssEpisode(PreparedEpisode):
    """An episode cut into filter epochs with GNSS fixes at their boundaries: t (K+1,) s
    epoch boundaries; imu_dt s; dtheta, dv (K, S, 3) raw increments per epoch; gps_lat,
    gps_lon (rad), gps_h (m), gps_v_n (m/s, ENU) of the antenna at the boundaries (NaN
    without a fix)."""

    t: np.ndarray
    imu_dt: float
    dtheta: np.ndarray
    dv: np.ndarray
    gps_lat: np.ndarray
    gps_lon: np.ndarray
    gps_h: np.ndarray
    gps_v_n: np.ndarray

    def gnss_inputs(self) -> dict[str, np.ndarray]:
        """The fields every GNSS-aided model input takes (``loose_gps.GpsInsInputs``), as
        a batch of one, the time from the first epoch."""
        return {"t": self.t - self.t[0], "imu_dt": self.imu_dt, "dtheta": self.dtheta[None],
                "dv": self.dv[None], "gps_lat": self.gps_lat[None],
                "gps_lon": self.gps_lon[None], "gps_h": self.gps_h[None],
                "gps_v_n": self.gps_v_n[None]}


def simulate_screened(config: ScenarioConfig, seed: int):
    """``simulate`` one episode and screen its data as a pipeline must before any filter
    (``estimators.screen``): the IMU (repaired), the gimbal encoders against the
    commands, the odometer against the IMU, the GNSS fixes. Returns the episode with the
    repaired increments on the run's grid, and the flags {"fault_kind", "fault_time"}
    (time order) for the prepared episode."""
    from aligngym.estimators.screen import screen_gimbal, screen_gnss, screen_imu, screen_odometer
    from aligngym.scenarios.simulate import imu_rails, simulate
    episode = simulate(config, seed=seed)
    screened = screen_imu(episode.imu_t, episode.dtheta, episode.dv, config.imu_interval,
                          config.imu_samples, *imu_rails(config))
    episode = replace(episode, imu_t=screened.imu_t, dtheta=screened.dtheta, dv=screened.dv)
    flags = [(screened.kind, screened.start)]
    if config.motion.has_gimbal:
        t = np.arange(config.imu_samples + 1) * config.imu_interval
        flags.append(screen_gimbal(t, episode.gimbal_encoder,
                                   config.motion.expected_gimbal_angles(t),
                                   config.encoder.resolution))
    if "odo_distance" in episode.extra:
        forward = np.array([0.0, 1.0, 0.0])         # the body's forward axis (R, F, U)
        if config.motion.has_gimbal:                # in s: C_s_b^T e_F, mid-interval
            from aligngym.models.world import gimbal_C_s_b
            enc = episode.gimbal_encoder
            forward = gimbal_C_s_b(0.5 * (enc[:-1] + enc[1:]))[:, 1, :]
        flags.append(screen_odometer(config.imu_interval, episode.extra["odo_distance"],
                                     np.sum(episode.dv * forward, axis=-1)))
    if "gps_t" in episode.extra:
        x = episode.extra
        flags.append(screen_gnss(x["gps_t"], x["gps_lat"], x["gps_lon"], x["gps_h"],
                                 x["gps_v_n"], x["gps_valid"]))
    kind = np.concatenate([k for k, _ in flags])
    time = np.concatenate([t for _, t in flags])
    order = np.argsort(time, kind="stable")
    return episode, {"fault_kind": kind[order], "fault_time": time[order]}


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
    default_episodes: int = 50
    """Monte Carlo episodes of ``bench`` without --episodes."""
    setups: dict[str, dict] = {}
    """Named setups besides "default": settings each overrides (``bench --setup``)."""
    regress: dict | None = None
    """The regression campaign (``aligngym regress``): episodes, seed, filters and the
    settings that differ from the defaults ("experiment"); None: not in regress."""

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
            rule = entry.rule()
            count = rule.point_count(self.state_count)
            if count > MAX_POINTS:
                raise ConfigError(f"filter {name!r} needs {count:.3g} points per episode for "
                                  f"the {self.state_count}-state model of paper{self.paper} "
                                  f"(at most {MAX_POINTS}); use a sparse grid (sghkf-L)")


def episode_seeds(seed: int, episodes: int) -> list[int]:
    """Seeds of the campaign's episodes (episode i of campaign seed S: S * 10^6 + i)."""
    return [seed * 1_000_000 + i for i in range(episodes)]


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


def analyse_run(name: str, start: str, result: FineResult, episodes: list[PreparedEpisode],
                experiment: Experiment, divergence: DivergenceRule = DivergenceRule()
                ) -> FilterRun:
    """Errors, body Euler errors, NEES, divergence and convergence time of a run."""
    K = result.t.size
    C_true = np.stack([e.C_s_n_true[:K] for e in episodes])
    error_n = misalignment(C_true, result.C_s_n)
    C_b_n_est = result.C_s_n @ np.swapaxes(np.stack([e.C_s_b[:K] for e in episodes]), -1, -2)
    eul = euler_error(np.stack([e.C_b_n_true[:K] for e in episodes]), C_b_n_est)
    diverged, reason = divergence.apply(error_n[:, -1], result.sigma_n[:, -1],
                                        result.diverged, result.diverged_reason)
    heading = convergence_time(result.t - result.t[0], error_n[:, :, 2],
                               experiment.heading_threshold_arcmin * arcmin)
    return FilterRun(filter=name, start=start, result=result, error_n=error_n,
                     euler_error=eul, nees=experiment.nees(result, episodes, error_n),
                     diverged=diverged, reason=reason, heading_convergence=heading)


def run_filter(name: str, start: str, start_error: np.ndarray,
               episodes: list[PreparedEpisode], experiment: Experiment,
               threads: int = 1, **model_options: Any) -> FilterRun:
    """One filter on all episodes from a starting error (rad; common (3,) or per episode
    (B, 3)); model_options go to ``experiment.model`` (e.g. paper 003's tuning). With
    threads > 1 the batch is split into that many chunks run in threads (NumPy releases
    the GIL in its array loops; the episodes are independent, so the result is the same
    as one batch)."""
    start_error = np.asarray(start_error, dtype=float)
    per_episode = np.broadcast_to(start_error, (len(episodes), 3))
    chunks = [c for c in np.array_split(np.arange(len(episodes)), max(1, threads)) if c.size]

    variant = filter_entry(name).model

    def run_chunk(idx: np.ndarray) -> FineResult:
        filt = make_filter(name, **experiment.filter_options())
        return run_alignment(filt, experiment.model([episodes[i] for i in idx],
                                                    per_episode[idx], variant,
                                                    **model_options))

    if len(chunks) == 1:
        result = run_chunk(chunks[0])
    else:
        from concurrent.futures import ThreadPoolExecutor
        with ThreadPoolExecutor(len(chunks)) as pool:
            result = concatenate_results(list(pool.map(run_chunk, chunks)))
    return analyse_run(name, start, result, episodes, experiment)


def filter_threads(name: str, experiment: Experiment, workers: int) -> int:
    """Threads worth giving a filter: all workers for rules with >= 100 points per
    episode (their array work dominates), one otherwise (thread overhead would)."""
    points = filter_entry(name).rule().point_count(experiment.state_count)
    return workers if points >= 100 else 1


def concatenate_results(parts: list[FineResult]) -> FineResult:
    """One result from batch chunks (same epochs); seconds_per_epoch is the chunks'
    summed compute time per epoch."""
    width = max(p.factors.shape[-1] for p in parts)
    factors = [np.pad(p.factors, ((0, 0), (0, 0), (0, width - p.factors.shape[-1])),
                      constant_values=np.nan) for p in parts]
    cat = lambda name: np.concatenate([getattr(p, name) for p in parts])  # noqa: E731
    return FineResult(t=parts[0].t, C_s_n=cat("C_s_n"), P=cat("P"), sigma_n=cat("sigma_n"),
                      x=cat("x"), factors=np.concatenate(factors), diverged=cat("diverged"),
                      diverged_time=cat("diverged_time"),
                      diverged_reason=sum((p.diverged_reason for p in parts), []),
                      repairs=cat("repairs"),
                      seconds_per_epoch=sum(p.seconds_per_epoch for p in parts),
                      series={name: np.concatenate([p.series[name] for p in parts])
                              for name in parts[0].series},
                      nis=cat("nis"), nis_dof=cat("nis_dof"))


def episode_metrics(run: FilterRun, b: int, rms_window: float) -> dict:
    """The per-episode metrics of episode b of a run (one row of the tidy table)."""
    r = run.result
    t = r.t
    in_window = t >= t[-1] - rms_window - 1e-9
    rms = np.sqrt(np.mean(run.error_n[b, in_window] ** 2, axis=0)) / arcmin
    row = {}
    for prefix, values in (("final", run.error_n[b, -1] / arcmin), ("rms", rms),
                           ("final_sigma", r.sigma_n[b, -1] / arcmin)):
        row.update({f"{prefix}_{a}_arcmin": float(v) for a, v in zip(AXES, values)})
    row.update({f"final_{a}_arcmin": float(v) for a, v in
                zip(("pitch", "roll", "heading"), run.euler_error[b, -1] / arcmin)})
    nees = run.nees[b, 1:]
    row.update({
        "heading_convergence_s": float(run.heading_convergence[b]),
        "nees_mean": float(np.mean(nees)) if np.isfinite(nees).any() else None,
        "nees_final": float(run.nees[b, -1]) if np.isfinite(run.nees[b, -1]) else None,
        "diverged": bool(run.diverged[b]), "diverged_reason": run.reason[b],
        "diverged_time_s": float(r.diverged_time[b] - t[0]) if r.diverged[b] else None,
        "covariance_repairs": int(r.repairs[b]),
        "ms_per_epoch": r.seconds_per_epoch * 1e3 / r.C_s_n.shape[0]})
    return row


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


EXECUTORS = ("local", "ray")


def prepare_all(experiment: Experiment, seeds: list[int], out_dir: Path | None,
                resume: bool, workers: int, progress: bool = True, executor: str = "local",
                address: str | None = None) -> list[PreparedEpisode]:
    """Prepare the episodes in parallel, in local processes or as Ray tasks
    (``executor``; ``address``: a Ray cluster's, None starts a local instance with
    ``workers`` CPUs); each episode is saved by this process as soon as it arrives, so
    an interrupted campaign keeps its finished episodes whichever executor ran them.
    With resume, episodes already on disk are loaded instead."""
    from tqdm import tqdm

    episode_dir = out_dir / "episodes" if out_dir is not None else None
    if episode_dir is not None:
        episode_dir.mkdir(parents=True, exist_ok=True)

    def path(s: int) -> Path:
        return episode_dir / f"seed_{s}.npz"

    load = experiment.episode_class.load
    done = {s: load(path(s)) for s in seeds
            if resume and episode_dir is not None and path(s).is_file()}
    todo = [s for s in seeds if s not in done]
    bar = tqdm(total=len(seeds), initial=len(done), disable=not progress, desc="episodes")

    def finish(s: int, episode: PreparedEpisode) -> None:
        if episode_dir is not None:
            episode.save(path(s))
        done[s] = episode
        bar.update()

    if executor == "ray":
        _prepare_on_ray(experiment, todo, finish, workers, address)
    elif workers <= 1 or len(todo) <= 1:
        for s in todo:
            finish(s, experiment.prepare_episode(s))
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = {pool.submit(experiment.prepare_episode, s): s for s in todo}
            for fut in as_completed(futures):
                finish(futures[fut], fut.result())
    bar.close()
    return [done[s] for s in seeds]


def _prepare_task(experiment: Experiment, seed: int) -> PreparedEpisode:
    return experiment.prepare_episode(seed)


def _prepare_on_ray(experiment: Experiment, seeds: list[int], finish, workers: int,
                    address: str | None) -> None:
    """One Ray task per episode; results are handed to finish as they complete. A task
    whose worker dies is retried by Ray (3 times); if it still fails the campaign stops
    with Ray's error, the episodes already finished being on disk. An initialised Ray
    (or RAY_ADDRESS) is used as it is: workers only size a local instance we start."""
    if not seeds:                  # all resumed: nothing to run
        return
    try:
        import ray
    except ImportError:
        raise ConfigError("--executor ray needs Ray: pip install -e '.[ray]'") from None
    address = address or os.environ.get("RAY_ADDRESS")
    if not ray.is_initialized():
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    task = ray.remote(max_retries=3)(_prepare_task)
    shared = ray.put(experiment)   # pickled once for all tasks
    pending = {task.remote(shared, s): s for s in seeds}
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            finish(pending.pop(ref), ray.get(ref))


def run_campaign(experiment: Experiment, episodes: int = 50, seed: int = 0,
                 filters: list[str] | None = None, out_dir: str | Path | None = None,
                 resume: bool = False, workers: int | None = None,
                 progress: bool = True, executor: str = "local",
                 address: str | None = None, force: bool = False) -> CampaignResult:
    """Run an experiment's campaign; see the module docstring. executor: "local"
    (processes) or "ray" (tasks on a local Ray instance, or the cluster at address)."""
    from tqdm import tqdm

    filters = list(filters or experiment.default_filters)
    experiment.check_filters(filters)
    experiment.check(experiment.scenario_config())
    if episodes < 1:
        raise ConfigError(f"--episodes = {episodes} must be >= 1")
    if executor not in EXECUTORS:
        raise ConfigError(f"--executor {executor!r} is unknown; valid: " + ", ".join(EXECUTORS))
    if address is not None and executor != "ray":
        raise ConfigError("--address needs --executor ray")
    workers = workers or os.cpu_count() or 1
    out = Path(out_dir) if out_dir is not None else None
    if out is not None:
        _check_manifest(out, experiment, seed, resume, force)
    seeds = episode_seeds(seed, episodes)
    prepared = prepare_all(experiment, seeds, out, resume, workers, progress, executor,
                           address)
    result = CampaignResult(experiment, seeds, prepared, experiment.start_errors(prepared),
                            seed=seed)
    jobs = [(f, s) for f in filters for s in experiment.starts]
    for name, start in tqdm(jobs, disable=not progress, desc="filters"):
        result.runs.append(run_filter(name, start, result.start_errors[start], prepared,
                                      experiment, filter_threads(name, experiment, workers)))
    return result


def _check_manifest(out: Path, experiment: Experiment, seed: int, resume: bool,
                    force: bool = False) -> None:
    """Create out, or check that it may be used: a directory holding a campaign needs
    resume (the same experiment and seed, from its campaign.json) or force (its episode
    files, tables, series, plots, settings and report are removed, so nothing of another
    seed mixes in)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--out {out}: cannot create the directory ({exc.strerror})") from None
    if not os.access(out, os.W_OK):
        raise ConfigError(f"--out {out}: the directory is not writable")
    manifest = out / "campaign.json"
    episodes = [p for p in (out / "episodes").glob("seed_*.npz")
                if not p.name.endswith(".tmp.npz")]          # not half-written leftovers
    held = manifest.is_file() or bool(episodes)
    if held and not (resume or force):
        raise ConfigError(f"--out {out} holds a campaign; use --resume to continue it or "
                          "--force to replace it")
    if resume and episodes and not manifest.is_file():
        raise ConfigError(f"--resume: {out} has episode files but no campaign.json, so "
                          "their experiment and seed are unknown; use --force to replace them")
    current = {"paper": experiment.paper, "experiment": asdict(experiment), "seed": seed}
    current = json.loads(json.dumps(current))
    if resume and manifest.is_file():
        saved = json.loads(manifest.read_text())
        saved.setdefault("paper", current["paper"])
        if saved != current:
            raise ConfigError(f"--resume: {manifest} was written by a different experiment "
                              "or seed; use a new --out directory")
    if force and not resume:      # nothing of the old campaign survives to mix in
        for old in [*(out / "episodes").glob("seed_*.npz"), *out.glob("*.csv"),
                    *out.glob("*.png"), out / "timeseries.npz", out / "tables.txt",
                    out / "summary.json", out / "settings.json", out / "report.html",
                    manifest]:
            old.unlink(missing_ok=True)
    tmp = manifest.with_suffix(".tmp")
    tmp.write_text(json.dumps(current, indent=2))
    os.replace(tmp, manifest)      # atomic
