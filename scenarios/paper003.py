"""Paper 003 end to end: N coarse alignments on the swaying ship (inertial-frame method,
120 s), then fine alignment (600 s) with each filter, started from the mean and from the
maximum of the coarse errors, on the same N episodes.

Episode preparation (MuJoCo truth, IMU synthesis, the filter-independent integrals and
the coarse alignment) runs in parallel processes and is written to disk one episode at a
time, so an interrupted campaign keeps what finished and ``resume`` continues it. The
filters then run batched over all episodes.
"""
from __future__ import annotations

import json
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from estimators.filters import FILTERS, make_filter
from estimators.inertial_fine import (EPS, NABLA, PHI, FineInputs, FineResult, FineTuning,
                                      fine_inputs, run_fine_alignment, stack_inputs)
from estimators.inertial_frame import (C_n_i, attitude_from_inertial, body_frame_integrals,
                                       coarse_alignment_ib0)
from estimators.metrics import (DivergenceRule, convergence_time, euler_error, misalignment,
                                nees)
from models.attitude import quat_to_dcm, rot_x, rot_z, rotvec_to_dcm
from models.units import arcmin, deg
from scenarios.config import ConfigError, ScenarioConfig, load_scenario
from scenarios.simulate import simulate
from sensors.imu import ImuTuning

STARTS = ("mean", "max")
AXES = ("phi_E", "phi_N", "phi_U")


@dataclass(frozen=True)
class Paper003Experiment:
    """The experiment's settings (SPEC 4.1; values the paper omits are marked assumed).

    Times in s; attitude_sigma (deg) is the filter's initial misalignment sigma along
    E, N, U (assumed, ALGORITHMS 2.2); measurement_sigma (m/s) along E, N, U (assumed:
    about the linear sway velocity amplitudes); heading_threshold in arcmin.
    """

    scenario: str = "ship-sway-rotary"
    coarse_duration: float = 120.0
    t_k1: float = 50.0
    t_k2: float = 120.0
    fine_duration: float = 600.0
    filter_step: float = 1.0
    attitude_sigma_deg: tuple[float, float, float] = (1.0, 1.0, 5.0)
    velocity_sigma: float = 0.01
    measurement_sigma: tuple[float, float, float] = (0.03, 0.03, 0.2)
    rho: float = 0.95
    rms_window: float = 60.0
    heading_threshold_arcmin: float = 5.0

    def scenario_config(self) -> ScenarioConfig:
        config = load_scenario(self.scenario)
        return config.with_options(duration=self.coarse_duration + self.fine_duration)

    def tuning(self, config: ScenarioConfig) -> FineTuning:
        imu = ImuTuning.from_spec(config.imu)
        return FineTuning(velocity_sigma=self.velocity_sigma,
                          attitude_sigma=tuple(a * deg for a in self.attitude_sigma_deg),
                          gyro_bias_sigma=imu.gyro_bias_sigma,
                          accel_bias_sigma=imu.accel_bias_sigma,
                          gyro_noise_density=imu.gyro_noise_density,
                          accel_noise_density=imu.accel_noise_density,
                          measurement_sigma=self.measurement_sigma, step=self.filter_step)


@dataclass
class PreparedEpisode:
    """What the filters need of one episode, plus its truth at the filter steps.

    coarse_error: (3,) rad, phi E, N, U of the coarse alignment at t_k2.
    inputs: the shared fine-alignment integrals (batch of one).
    C_s_n_true, C_b_n_true: (K+1, 3, 3) at the filter steps; C_s_b_encoder: (K+1, 3, 3)
    from the encoder readings; gyro_bias (3,) rad/s, accel_bias (3,) m/s^2: the drawn
    constant errors; lat (rad), h (m): the known position.
    """

    seed: int
    coarse_error: np.ndarray
    inputs: FineInputs
    C_s_n_true: np.ndarray
    C_b_n_true: np.ndarray
    C_s_b_encoder: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    lat: float
    h: float

    def save(self, path: Path) -> None:
        arrays = {"seed": self.seed, "coarse_error": self.coarse_error, "t": self.inputs.t,
                  "C_s_s0": self.inputs.C_s_s0[0], "dW": self.inputs.dW[0],
                  "Psi": self.inputs.Psi[0], "Psi2": self.inputs.Psi2[0],
                  "C_s_n_true": self.C_s_n_true, "C_b_n_true": self.C_b_n_true,
                  "C_s_b_encoder": self.C_s_b_encoder, "gyro_bias": self.gyro_bias,
                  "accel_bias": self.accel_bias, "lat": self.lat, "h": self.h}
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, **arrays)
        os.replace(tmp, path)  # atomic: a file on disk is always a complete episode

    @classmethod
    def load(cls, path: Path) -> "PreparedEpisode":
        f = np.load(path)
        inputs = FineInputs(t=f["t"], C_s_s0=f["C_s_s0"][None], dW=f["dW"][None],
                            Psi=f["Psi"][None], Psi2=f["Psi2"][None])
        return cls(seed=int(f["seed"]), coarse_error=f["coarse_error"], inputs=inputs,
                   C_s_n_true=f["C_s_n_true"], C_b_n_true=f["C_b_n_true"],
                   C_s_b_encoder=f["C_s_b_encoder"], gyro_bias=f["gyro_bias"],
                   accel_bias=f["accel_bias"], lat=float(f["lat"]), h=float(f["h"]))


def prepare_episode(experiment: Paper003Experiment, seed: int,
                    config: ScenarioConfig | None = None) -> PreparedEpisode:
    """Simulate one episode, integrate it and run the coarse alignment."""
    config = config or experiment.scenario_config()
    episode = simulate(config, seed=seed)
    truth = episode.truth
    lat, h = float(truth.lat[0]), float(truth.h[0])  # known position of the IMU at t0
    integrals = body_frame_integrals(episode.dtheta, episode.dv, episode.gimbal_encoder,
                                     np.asarray(config.motion.lever_arm_b),
                                     config.imu_interval)
    C_s0_i = coarse_alignment_ib0(integrals, lat, h, experiment.t_k1, experiment.t_k2)
    k2 = int(round(experiment.t_k2 / config.imu_interval))
    C_s_n_coarse = attitude_from_inertial(C_s0_i, integrals, k2, lat)
    C_s_n_all = quat_to_dcm(truth.q_s_n)
    inputs = fine_inputs(integrals, experiment.coarse_duration, experiment.fine_duration,
                         experiment.filter_step)
    idx = np.rint(inputs.t / config.imu_interval).astype(int)
    enc = episode.gimbal_encoder[idx]
    return PreparedEpisode(
        seed=seed, coarse_error=misalignment(C_s_n_all[k2], C_s_n_coarse), inputs=inputs,
        C_s_n_true=C_s_n_all[idx], C_b_n_true=quat_to_dcm(truth.q_b_n[idx]),
        C_s_b_encoder=rot_z(enc[:, 0]) @ rot_x(enc[:, 1]),
        gyro_bias=episode.imu_realization.gyro.bias,
        accel_bias=episode.imu_realization.accel.bias, lat=lat, h=h)


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
    euler_error: np.ndarray    # (B, K+1, 3) rad: hull pitch, roll, heading
    nees: np.ndarray           # (B, K+1)
    diverged: np.ndarray       # (B,)
    reason: list[str]
    heading_convergence: np.ndarray  # (B,) s after the start of fine alignment


@dataclass
class CampaignResult:
    experiment: Paper003Experiment
    seeds: list[int]
    coarse_errors: np.ndarray  # (N, 3) rad
    start_errors: dict[str, np.ndarray]
    runs: list[FilterRun] = field(default_factory=list)

    def coarse_summary(self) -> dict[str, list[float]]:
        """Mean, max and min of the coarse errors per axis, deg (max/min by magnitude)."""
        e = self.coarse_errors
        return {"mean_deg": list(e.mean(0) / deg),
                "max_deg": list(signed_extreme(e, np.argmax) / deg),
                "min_deg": list(signed_extreme(e, np.argmin) / deg)}

    def fine_summary(self) -> dict[str, dict[str, dict]]:
        """Per filter and start: mean, std, RMS of the final error per axis (arcmin) and
        the fraction of diverged episodes."""
        out: dict[str, dict[str, dict]] = {}
        for run in self.runs:
            final = run.error_n[:, -1] / arcmin
            out.setdefault(run.filter, {})[run.start] = {
                "mean_arcmin": list(final.mean(0)), "std_arcmin": list(final.std(0)),
                "rms_arcmin": list(np.sqrt((final ** 2).mean(0))),
                "diverged_fraction": float(run.diverged.mean())}
        return out

    def summary(self) -> dict:
        return {"coarse": self.coarse_summary(), "fine": self.fine_summary()}


def signed_extreme(errors: np.ndarray, pick) -> np.ndarray:
    """Per axis, the signed error whose magnitude is picked (argmax or argmin) (3,)."""
    idx = pick(np.abs(errors), axis=0)
    return errors[idx, np.arange(errors.shape[1])]


def start_attitude(episodes: list[PreparedEpisode], start_error: np.ndarray) -> np.ndarray:
    """Initial estimate C_s^i(t1) (B, 3, 3): the truth turned by a starting misalignment
    phi E, N, U (rad), common (3,) or per episode (B, 3)."""
    C_true = np.stack([e.C_s_n_true[0] for e in episodes])
    t1 = episodes[0].inputs.t[0]
    lat = np.array([e.lat for e in episodes])
    return C_n_i(t1, lat) @ rotvec_to_dcm(-np.asarray(start_error)) @ C_true


def analyse_run(name: str, start: str, result: FineResult, episodes: list[PreparedEpisode],
                experiment: Paper003Experiment,
                divergence: DivergenceRule = DivergenceRule()) -> FilterRun:
    """Errors, hull Euler errors, NEES, divergence and convergence time of a run."""
    K = result.t.size
    C_true = np.stack([e.C_s_n_true[:K] for e in episodes])
    lat = np.array([e.lat for e in episodes])
    error_n = misalignment(C_true, result.C_s_n)
    C_b_n_est = result.C_s_n @ np.swapaxes(np.stack([e.C_s_b_encoder[:K] for e in episodes]),
                                           -1, -2)
    eul = euler_error(np.stack([e.C_b_n_true[:K] for e in episodes]), C_b_n_est)
    # NEES over attitude and biases, in the filter's frames (phi in i).
    C_ni = C_n_i(result.t[None], lat[:, None])
    err = np.concatenate([
        np.einsum("bkij,bkj->bki", C_ni, error_n),
        np.stack([e.gyro_bias for e in episodes])[:, None] - result.x[:, :, EPS],
        np.stack([e.accel_bias for e in episodes])[:, None] - result.x[:, :, NABLA]], -1)
    sub = np.r_[PHI, EPS, NABLA]
    nees_t = nees(err, result.P[:, :, sub][:, :, :, sub])
    diverged, reason = divergence.apply(error_n[:, -1], result.sigma_n[:, -1],
                                        result.diverged, result.diverged_reason)
    heading = convergence_time(result.t - result.t[0], error_n[:, :, 2],
                               experiment.heading_threshold_arcmin * arcmin)
    return FilterRun(filter=name, start=start, result=result, error_n=error_n,
                     euler_error=eul, nees=nees_t, diverged=diverged, reason=reason,
                     heading_convergence=heading)


def run_filter(name: str, start: str, start_error: np.ndarray,
               episodes: list[PreparedEpisode], experiment: Paper003Experiment,
               tuning: FineTuning) -> FilterRun:
    """One filter on all episodes from a starting misalignment phi E, N, U (rad): common
    (3,) or per episode (B, 3)."""
    inputs = stack_inputs([e.inputs for e in episodes])
    filt = make_filter(name, rho=experiment.rho)
    result = run_fine_alignment(filt, inputs, start_attitude(episodes, start_error), tuning,
                                np.array([e.lat for e in episodes]),
                                np.array([e.h for e in episodes]))
    return analyse_run(name, start, result, episodes, experiment)


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
    row.update({
        "heading_convergence_s": float(run.heading_convergence[b]),
        "nees_mean": float(np.mean(run.nees[b, 1:])), "nees_final": float(run.nees[b, -1]),
        "diverged": bool(run.diverged[b]), "diverged_reason": run.reason[b],
        "diverged_time_s": float(r.diverged_time[b] - t[0]) if r.diverged[b] else None,
        "ms_per_epoch": r.seconds_per_epoch * 1e3 / r.C_s_n.shape[0]})
    return row


def prepare_all(experiment: Paper003Experiment, seeds: list[int], out_dir: Path | None,
                resume: bool, workers: int, progress: bool = True) -> list[PreparedEpisode]:
    """Prepare the episodes in parallel; each is saved as soon as it finishes. With
    resume, episodes already on disk are loaded instead."""
    from tqdm import tqdm

    episode_dir = out_dir / "episodes" if out_dir is not None else None
    if episode_dir is not None:
        episode_dir.mkdir(parents=True, exist_ok=True)

    def path(s: int) -> Path:
        return episode_dir / f"seed_{s}.npz"

    done = {s: PreparedEpisode.load(path(s)) for s in seeds
            if resume and episode_dir is not None and path(s).is_file()}
    todo = [s for s in seeds if s not in done]
    bar = tqdm(total=len(seeds), initial=len(done), disable=not progress, desc="episodes")

    def finish(s: int, episode: PreparedEpisode) -> None:
        if episode_dir is not None:
            episode.save(path(s))
        done[s] = episode
        bar.update()

    if workers <= 1 or len(todo) <= 1:
        for s in todo:
            finish(s, prepare_episode(experiment, s))
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = {pool.submit(prepare_episode, experiment, s): s for s in todo}
            for fut in as_completed(futures):
                finish(futures[fut], fut.result())
    bar.close()
    return [done[s] for s in seeds]


def run_campaign(episodes: int = 50, seed: int = 0, filters: list[str] | None = None,
                 out_dir: str | Path | None = None, resume: bool = False,
                 workers: int | None = None, experiment: Paper003Experiment | None = None,
                 progress: bool = True) -> CampaignResult:
    """Run the paper-003 experiment; see the module docstring."""
    from tqdm import tqdm

    experiment = experiment or Paper003Experiment()
    filters = filters or ["kf", "sakf", "makf", "imakf"]
    unknown = [f for f in filters if f not in FILTERS]
    if unknown:
        raise ConfigError(f"unknown filter {unknown[0]!r}; known filters: "
                          + ", ".join(sorted(FILTERS)))
    if episodes < 1:
        raise ConfigError(f"--episodes = {episodes} must be >= 1")
    workers = workers or os.cpu_count() or 1
    out = Path(out_dir) if out_dir is not None else None
    if out is not None:
        _check_manifest(out, experiment, seed, resume)
    seeds = episode_seeds(seed, episodes)
    prepared = prepare_all(experiment, seeds, out, resume, workers, progress)
    coarse = np.stack([p.coarse_error for p in prepared])
    result = CampaignResult(experiment, seeds, coarse, {
        "mean": coarse.mean(0), "max": signed_extreme(coarse, np.argmax)})
    config = experiment.scenario_config()
    tuning = experiment.tuning(config)
    jobs = [(f, s) for f in filters for s in STARTS]
    for name, start in tqdm(jobs, disable=not progress, desc="filters"):
        result.runs.append(run_filter(name, start, result.start_errors[start], prepared,
                                      experiment, tuning))
    return result


def _check_manifest(out: Path, experiment: Paper003Experiment, seed: int, resume: bool) -> None:
    out.mkdir(parents=True, exist_ok=True)
    manifest = out / "campaign.json"
    current = {"experiment": asdict(experiment), "seed": seed}
    current = json.loads(json.dumps(current))
    if resume and manifest.is_file():
        saved = json.loads(manifest.read_text())
        if saved != current:
            raise ConfigError(f"--resume: {manifest} was written by a different experiment "
                              "or seed; use a new --out directory")
    manifest.write_text(json.dumps(current, indent=2))
