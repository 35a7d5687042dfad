"""Paper 002 end to end: fine alignment on a static base (the marble platform) from a
large azimuth error (58.5 deg), with the 10-state Euler-angle large-misalignment model
(ALGORITHMS 3.1) and the EKF, UKF, sparse-grid Gauss-Hermite filters (levels 2 and 4)
and the tensor-product GH filter.

As in the paper, the analytic coarse alignment is skipped: each episode's INS starts
from the true attitude turned by the Euler error [level_E, level_N, 58.5 deg] (the level
errors drawn per episode, 1 deg 1-sigma, *assumed*: the paper's P0 of 45 deg describes
the filter's prior, not the real level error left after levelling); the filter estimates
its Euler error, open loop until its heading sigma is below ``feedback_sigma_deg``, then
fed back into its own INS after every update. P0, Q and R are the paper's (Q taken as
PSDs).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from aligngym.estimators.euler_integrals import (StaticBaseIntegrals, stack_integrals,
                                                 static_base_integrals)
from aligngym.estimators.euler_kinematics import C_p_n, true_state
from aligngym.estimators.euler_large import (LAYOUT, PAPER002, EulerLargeMisalignmentModel,
                                             Paper002Tuning)
from aligngym.estimators.catalogue import make_filter
from aligngym.estimators.alignment import FineResult
from aligngym.estimators.model import wrap_angle
from aligngym.models.attitude import quat_to_dcm
from aligngym.models.units import deg, deg_per_h
from aligngym.scenarios.campaign import (CampaignResult, Experiment, PreparedEpisode, TruthMap,
                                fine_summary, format_fine_table, simulate_screened)
from aligngym.scenarios.campaign.claims import Claim, final_from_static_floor, rule_points
from aligngym.scenarios.config import ConfigError, ScenarioConfig
from aligngym.scenarios.campaign.settings import MAX_RUN, POSITIVE, bounded

START = "large-azimuth"
STATE_COUNT = 10


@dataclass
class Paper002Episode(PreparedEpisode):
    """One static-base episode (``PreparedEpisode``; C_s_b = I): start_error (3,) rad,
    the Euler error [alpha_E, alpha_N, alpha_U] of the INS's initial attitude drawn for
    it; integrals, the filter-independent INS integrals (batch of one), from which a
    filter's own INS follows for any start and any feedback."""

    start_error: np.ndarray
    integrals: StaticBaseIntegrals

    _FIELDS = ("K_axis", "Q", "Q_mid", "U")

    @property
    def fine_start(self) -> float:
        return float(self.integrals.t[0])

    def arrays(self):
        ins = self.integrals
        return {"seed": self.seed, "start_error": self.start_error, "t": ins.t,
                "t_mid": ins.t_mid, **{name: getattr(ins, name)[0] for name in self._FIELDS},
                "C_s_n_true": self.C_s_n_true, "C_b_n_true": self.C_b_n_true,
                "gyro_bias": self.gyro_bias, "accel_bias": self.accel_bias, "lat": self.lat,
                "h": self.h}

    @classmethod
    def from_arrays(cls, f):
        lat, h = float(f["lat"]), float(f["h"])
        ins = StaticBaseIntegrals(
            t=f["t"], t_mid=f["t_mid"], lat=np.array([lat]), h=np.array([h]),
            **{name: f[name][None] for name in cls._FIELDS})
        K1 = f["t"].size
        return cls(seed=int(f["seed"]), start_error=f["start_error"], integrals=ins,
                   C_s_n_true=f["C_s_n_true"], C_b_n_true=f["C_b_n_true"],
                   C_s_b=np.broadcast_to(np.eye(3), (K1, 3, 3)).copy(),
                   gyro_bias=f["gyro_bias"], accel_bias=f["accel_bias"], lat=lat, h=h)


def prepare_episode(experiment: Paper002Experiment, seed: int,
                    config: ScenarioConfig | None = None) -> Paper002Episode:
    """Simulate the static platform, draw the level errors, integrate the IMU for the
    filters' INS."""
    config = config or experiment.scenario_config()
    episode, flags = simulate_screened(config, seed)
    truth = episode.truth
    lat, h = float(truth.lat[0]), float(truth.h[0])
    rng = np.random.default_rng(np.random.SeedSequence([seed, 2]))
    start = np.array([*(rng.standard_normal(2) * experiment.level_error_sigma_deg * deg),
                      experiment.azimuth_error_deg * deg])
    step = experiment.filter_step
    per_step = int(round(step * config.imu_rate))
    integrals = static_base_integrals(episode.dtheta, episode.dv, config.imu_interval, lat,
                                      h, step)
    K1 = integrals.t.size
    return Paper002Episode(
        **flags,
        seed=seed, start_error=start, integrals=integrals,
        C_s_n_true=quat_to_dcm(truth.q_s_n[::per_step])[:K1],
        C_b_n_true=quat_to_dcm(truth.q_b_n[::per_step])[:K1],
        C_s_b=np.broadcast_to(np.eye(3), (K1, 3, 3)).copy(),
        gyro_bias=episode.imu_realization.gyro.bias,
        accel_bias=episode.imu_realization.accel.bias, lat=lat, h=h)


def point_count(name: str) -> int:
    """Evaluations of the process map per episode and epoch for the 10-state model."""
    return make_filter(name).rule.point_count(STATE_COUNT)


def paper002_summary(result: CampaignResult) -> dict:
    """{FILTER: {mean/std/rms_arcmin [3], the status fractions, convergence_s, points,
    us_per_epoch}} (the JSON's "fine" entry): final errors after the fine duration."""
    fine = fine_summary(result)
    out = {}
    for run in result.runs:
        stats = fine[run.filter][run.start]
        stats.update({
            "convergence_s": float(np.mean(run.heading_convergence)),
            "points": point_count(run.filter),
            "us_per_epoch": run.result.seconds_per_episode_epoch * 1e6})
        out[run.filter] = stats
    return out


def format_tables(result: CampaignResult) -> str:
    """The paper-shaped table: steady errors per filter, convergence and cost."""
    exp = result.experiment
    summary = paper002_summary(result)
    title = (f"Static base, {exp.azimuth_error_deg:g} deg azimuth error, "
             f"{exp.fine_duration:g} s, {len(result.seeds)} runs: final error (arcmin)")
    extra = {name: f"{s['convergence_s']:10.1f}{s['points']:8d}{s['us_per_epoch']:10.1f}"
             for name, s in summary.items()}
    chunked = list(dict.fromkeys(f"{run.filter} in {run.result.chunks}"
                                 for run in result.runs if run.result.chunks > 1))
    return (format_fine_table(result, START, title, extra,
                              f"{'conv (s)':>10s}{'points':>8s}{'us/epoch':>10s}")
            + f"\n(heading convergence: error within {exp.heading_threshold_arcmin:g}' "
            "from then on; us/epoch per episode, batched"
            + (f"; run in chunks, their times summed, each chunk paying the fixed cost "
               f"an epoch: {', '.join(chunked)}" if chunked else "") + ")")


def state_errors(result: FineResult, episodes: list[Paper002Episode],
                 error_n: np.ndarray) -> np.ndarray:
    """Truth minus estimate (B, K+1, 8) of the states the NEES compares with the truth:
    the Euler error (rad, wrapped; the true one from the INS attitude the estimate refers
    to, C_b^p = C_p^n(alpha_hat)^T C_b^n_hat), the accelerometer (x, y) bias (m/s^2) and
    the gyro bias (rad/s)."""
    K = result.t.size
    alpha_hat = result.x[:, :, LAYOUT["euler_error"]]
    C_b_p = np.swapaxes(C_p_n(alpha_hat), -1, -2) @ result.C_s_n
    C_true = np.stack([e.C_b_n_true[:K] for e in episodes])
    alpha = true_state(C_true, C_b_p)
    return np.concatenate([
        wrap_angle(alpha - result.x[:, :, LAYOUT["euler_error"]]),
        np.stack([e.accel_bias[:2] for e in episodes])[:, None]
        - result.x[:, :, LAYOUT["accel_bias"]],
        np.stack([e.gyro_bias for e in episodes])[:, None]
        - result.x[:, :, LAYOUT["gyro_bias"]]], -1)


@dataclass(frozen=True)
class Paper002Experiment(Experiment):
    """Settings (SPEC 4.4; assumed values marked). Angles in deg, times in s.

    gyro_bias_prior_deg_h: the filter's prior sigma of the gyro drift (the paper's
    0.1 deg/h, ten times the true drift: it sets the filters' final heading sigma,
    ~sigma_eps / (Omega cos L) = 30', and the size of what the large-angle transient
    leaves on the unobservable heading/east-drift direction, 1-7' here).
    feedback_sigma_deg: the estimate is fed back into each filter's INS once its heading
    sigma is below this (ALGORITHMS 3.1; None: open loop throughout).
    heading_threshold_arcmin: heading convergence = first time after which the heading
    error stays within it (60' = 1 deg, *assumed*).
    """

    scenario: str = "static-large-azimuth"
    fine_duration: float = bounded(600.0, "s", low=0.0, high=MAX_RUN, low_open=True)
    filter_step: float = bounded(1.0, "s", **POSITIVE)
    azimuth_error_deg: float = bounded(58.5, "deg", low=-180.0, high=180.0)
    level_error_sigma_deg: float = bounded(1.0, "deg", low=0.0, high=90.0)
    gyro_bias_prior_deg_h: float = bounded(0.1, "deg/h", **POSITIVE)
    feedback_sigma_deg: float | None = bounded(5.0, "deg", **POSITIVE)
    rms_window: float = bounded(60.0, "s", **POSITIVE)
    heading_threshold_arcmin: float = bounded(60.0, "arcmin", **POSITIVE)

    paper = "002"
    default_episodes = 100
    regress = {"episodes": 8, "seed": 3, "filters": ["ekf", "ukf", "sghkf-2", "sghkf-4"]}
    reproduce = {"episodes": 50, "seed": 0}
    claims = (
        Claim("From a 58.5 deg azimuth error the SGHKF aligns clearly more accurately than "
              "the EKF and slightly more than the UKF (final heading from its physical floor)",
              "002 abstract, sec. 3",
              {"sghkf-2 heading - floor RMS '": final_from_static_floor("sghkf-2"),
               "sghkf-4 '": final_from_static_floor("sghkf-4"),
               "ekf '": final_from_static_floor("ekf"), "ukf '": final_from_static_floor("ukf")},
              lambda n: (min(n["sghkf-2 heading - floor RMS '"], n["sghkf-4 '"])
                         < min(n["ekf '"], n["ukf '"])),
              "measured at 50 episodes, seed 0: sghkf-2 0.74' against ekf 4.6' and ukf 6.9' "
              "from the floors (docs/paper002.md); the other order here is a regression"),
        Claim("... and converges faster than the EKF", "002 abstract",
              {"sghkf-2 convergence s": "fine/sghkf-2/convergence_s",
               "sghkf-4 s": "fine/sghkf-4/convergence_s", "ekf s": "fine/ekf/convergence_s"},
              lambda n: min(n["sghkf-2 convergence s"], n["sghkf-4 s"]) < n["ekf s"],
              "the EKF's heading enters the 60' band first (a fast but biased start: it ends "
              "4.5' from its floor, the SGHKF 0.8'); with the corrected velocity equation "
              "(ALGORITHMS 3.5) and the paper's P0/Q every filter is inside 60' within 3 min"),
        Claim("The sparse grid needs about as many points as the UKF, far fewer than the "
              "tensor-product GH filter", "002 abstract, sec. 2",
              {"sghkf-2 points": rule_points("sghkf-2", 10), "ukf points": rule_points("ukf", 10),
               "sghkf-4 points": rule_points("sghkf-4", 10),
               "tensor GH (3 per axis) points": rule_points("ghkf-3", 10)},
              lambda n: (n["sghkf-2 points"] <= 1.1 * n["ukf points"]
                         and n["sghkf-4 points"] < 0.1 * n["tensor GH (3 per axis) points"]),
              "the point counts are the rules' own (21 = 2n + 1 for sghkf-2, 59 049 = 3^10 "
              "for the tensor rule): a change here is a change of the rules"),
    )
    """aligngym regress (ckf diverges from the 58.5 deg start: left out)."""
    worlds = ("static-platform",)
    filter_keys = ("euler_sigma", "initial_covariance")
    state_count = STATE_COUNT
    observation_features = frozenset({"selection-H"})
    filter_settings = frozenset({"feedback_sigma_deg", "gyro_bias_prior_deg_h",
                                 "heading_threshold_arcmin", "rms_window"})
    default_filters = ("ekf", "ukf", "sghkf-2", "sghkf-4")
    starts = (START,)

    episode_class = Paper002Episode
    preparation = staticmethod(prepare_episode)
    truth_map = TruthMap(LAYOUT, ("euler_error", "accel_bias", "gyro_bias"), state_errors)
    summarise = staticmethod(lambda result: {"fine": paper002_summary(result)})
    tabulate = staticmethod(format_tables)

    def tuning(self, config: ScenarioConfig | None = None) -> Paper002Tuning:
        """The paper's tuning with the drift prior of this experiment and the scenario's
        [filter] euler_sigma_deg (3 values, (0, 90] deg), if given."""
        tuning = replace(PAPER002, gyro_bias_sigma=self.gyro_bias_prior_deg_h * deg_per_h)
        table = dict((config or self.scenario_config()).filter)
        if "euler_sigma" in table:
            sigma = np.asarray(table["euler_sigma"], dtype=float)
            if sigma.shape != (3,) or not np.all((sigma > 0) & (sigma <= np.pi / 2)):
                raise ConfigError("filter.euler_sigma_deg must be 3 values in (0, 90] deg, "
                                  f"got {np.rad2deg(sigma).tolist()}")
            tuning = replace(tuning, euler_sigma=tuple(sigma))
        return tuning

    def initial_covariance(self, config: ScenarioConfig | None = None) -> np.ndarray | None:
        """The scenario's [filter] initial_covariance (10 x 10, SI, state order of
        ``estimators.euler_large``), checked symmetric positive definite; None if absent."""
        table = dict((config or self.scenario_config()).filter)
        if "initial_covariance" not in table:
            return None
        try:
            P0 = np.asarray(table["initial_covariance"], dtype=float)
        except (TypeError, ValueError):
            raise ConfigError("filter.initial_covariance must be a 10 x 10 matrix of "
                              "numbers") from None
        if P0.shape != (STATE_COUNT, STATE_COUNT) or not np.all(np.isfinite(P0)):
            raise ConfigError(f"filter.initial_covariance must be a finite 10 x 10 matrix, "
                              f"got shape {P0.shape}")
        if not np.allclose(P0, P0.T, rtol=1e-12, atol=0.0):
            raise ConfigError("filter.initial_covariance must be symmetric")
        smallest = float(np.linalg.eigvalsh(P0).min())
        if smallest <= 0.0:
            raise ConfigError("filter.initial_covariance is not positive definite (smallest "
                              f"eigenvalue {smallest:.3g}); it must be symmetric positive "
                              "definite, SI units")
        return P0

    def check(self, config):
        self.tuning(config)
        self.initial_covariance(config)

    def start_errors(self, episodes):
        return {START: np.stack([e.start_error for e in episodes])}

    def model(self, episodes, start_error, variant=""):
        start_error = np.broadcast_to(np.asarray(start_error, dtype=float),
                                      (len(episodes), 3))
        if any(not np.isclose(e.integrals.step, self.filter_step) for e in episodes):
            raise ConfigError(f"paper002: episodes were prepared with another filter step "
                              f"than {self.filter_step:g} s")
        C_b_n0 = np.stack([e.C_b_n_true[0] for e in episodes])
        C0 = np.swapaxes(C_p_n(start_error), -1, -2) @ C_b_n0   # INS start: C_b^p(0)
        config = self.scenario_config()
        feedback = (None if self.feedback_sigma_deg is None
                    else self.feedback_sigma_deg * deg)
        return EulerLargeMisalignmentModel(
            stack_integrals([e.integrals for e in episodes]), C0, self.tuning(config),
            P0=self.initial_covariance(config), feedback_below=feedback)

    def attitude_sigma(self):
        """Euler-error sigmas of a random start (the env's): the experiment's level sigma
        (P0's 45 deg would put 5 % of the starts beyond the 90 deg singularity of the
        Euler rates) and P0's heading sigma."""
        level = self.level_error_sigma_deg * deg
        return np.array([level, level, self.tuning().euler_sigma[2]])

    observed = ("euler_error", "gyro_bias", "accel_bias")


EXPERIMENT = Paper002Experiment
"""This module's experiment (``scenarios.experiments``)."""
