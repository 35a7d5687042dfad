"""Paper 003 end to end: N coarse alignments on the swaying ship (inertial-frame method,
120 s), then fine alignment (600 s) with each filter, started from the mean and from the
maximum of the coarse errors, on the same N episodes.

Episode preparation (MuJoCo truth, IMU synthesis, the filter-independent integrals and
the coarse alignment) and the batched filters run in the generic campaign engine
(``scenarios.campaign``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from aligngym.estimators.alignment import FineResult
from aligngym.estimators.inertial_fine import (EPS, LAYOUT, NABLA, FineInputs, FineTuning,
                                      InertialFineModel, SwayAwareInertialModel,
                                      SwaySpectrum, fine_inputs, stack_inputs)
from aligngym.estimators.inertial_frame import (C_n_i, attitude_from_inertial, body_frame_integrals,
                                       coarse_alignment_ib0)
from aligngym.estimators.metrics import misalignment, static_alignment_floor
from aligngym.models.attitude import quat_to_dcm, rotvec_to_dcm
from aligngym.models.units import deg
from aligngym.models.gimbal import gimbal_C_s_b
from aligngym.scenarios import campaign
from aligngym.scenarios.analyses.paper003 import coarse_summary, format_tables, signed_extreme
from aligngym.scenarios.campaign import (CampaignResult, Experiment, PreparedEpisode, TruthMap,
                                         fine_summary, simulate_screened)
from aligngym.scenarios.campaign.claims import Claim
from aligngym.scenarios.config import ConfigError, ScenarioConfig
from aligngym.scenarios.campaign.settings import MAX_RUN, POSITIVE, bounded
from aligngym.sensors.imu import ImuTuning

STARTS = ("mean", "max")
SWAY_R_MARGIN = 1.25
"""k: the measurement sigma sits this far above the peak sway velocity per local axis
(ALGORITHMS 2.2: an R below the peak makes the printed P-fading filters diverge)."""
SWAY_R_FLOOR = 0.003
"""m/s: the measurement sigma of a calm sea (lever-arm rates from gyros and encoders,
sensor noise; ALGORITHMS 2.3)."""
SWAY_AWARE_R = 5e-4
"""m/s: kf-sway's measurement sigma, the sensor-level noise of the velocity integral once
the sway is modelled (lever-arm rates from gyros and encoders, accelerometer noise)."""
PAPER_SETUP = {"setup": "paper", "scenario": "ship-sway-rotary-paper",
               "measurement_sigma": (SWAY_R_FLOOR,) * 3,
               "default_filters": ("kf", "sakf-r", "makf-r", "imakf-r")}
"""``--setup paper``: the paper's results reproduced for a stated reason (README): biases
constant in the hull frame (no modulation), a calm-sea R, fading factors on R."""


def sway_peak_velocity(motion) -> np.ndarray:
    """Peak linear sway velocity A_j 2 pi / T_j (3,) m/s per local axis E, N, U of the
    prescribed sway (``models.ship.ShipSwayMotion``) at its sway scale (the file's: a
    [[schedule]]'s changes are not known to the filter)."""
    return (motion.sway_scale * np.asarray(motion.linear_amplitude) * 2 * np.pi
            / np.asarray(motion.linear_period))


def sway_velocity_std(config: ScenarioConfig) -> np.ndarray:
    """Std (3,) m/s of the sway centre's velocity per local axis E, N, U, at least 0.1 mm/s
    (to keep P0 positive definite): A_j w_j / sqrt(2) for the prescribed sway (a
    random-phase sinusoid's velocity); for the wave-driven ship, from the sea state and
    the hull's response (``models.waves.sway_centre_velocity``)."""
    if config.world == "ship-prescribed":
        std = sway_peak_velocity(config.motion) / np.sqrt(2.0)
    elif config.world == "ship-waves":
        from aligngym.models.waves import sway_centre_velocity

        std = sway_centre_velocity(config.motion)[0]
    else:
        raise ConfigError("kf-sway needs a ship's sway; scenario "
                          f"{config.name!r} has world = {config.world!r}")
    return np.maximum(std, 1e-4)


def sway_spectrum(config: ScenarioConfig) -> SwaySpectrum:
    """The sway of the sway centre per local axis, for kf-sway: the std of
    ``sway_velocity_std``, and periods and damping ratio.

    Prescribed: the sinusoids' periods and zeta = 0: the periods are exact, so only
    their amplitudes and phases are unknown (no process noise). Measured on 20 episodes:
    zeta = 0.02 makes the filter underconfident (NEES 4.9 for 9 states: the oscillators'
    bandwidth competes with the modulated accelerometer biases), zeta = 0 is in band (9.7).
    Wave-driven: the heave velocity as a narrow-band process, the period and damping
    ratio whose oscillator fits its autocorrelation (``models.waves.heave_velocity_band``).
    """
    sigma = tuple(sway_velocity_std(config))
    if config.world == "ship-prescribed":
        return SwaySpectrum(period=tuple(config.motion.linear_period), sigma=sigma,
                            damping=0.0)
    from aligngym.models.waves import heave_velocity_band

    peak_period, damping = heave_velocity_band(config.motion)
    return SwaySpectrum(period=(peak_period,) * 3, sigma=sigma, damping=float(damping))


def sway_measurement_sigma(config: ScenarioConfig, duration: float = 600.0
                           ) -> tuple[float, float, float]:
    """The honest default R of the fine alignment, per local axis E, N, U (m/s):
    sigma_j = max(SWAY_R_FLOOR, SWAY_R_MARGIN x peak_j). The prescribed sway's peak is
    A_j x 2 pi / T_j. The wave-driven ship's is the expected largest velocity peak of its
    centre of mass over the fine alignment (duration, s): std x sqrt(2 ln(duration /
    T_z)), the largest of duration / T_z Rayleigh-distributed peaks of a narrow-band
    process, from the sea state and the hull's heave response
    (``models.waves.sway_centre_velocity``; zero along E and N, where the hull feels no
    wave force)."""
    if config.world == "ship-prescribed":
        peak = sway_peak_velocity(config.motion)
    else:
        from aligngym.models.waves import sway_centre_velocity

        std, period = sway_centre_velocity(config.motion)
        peaks = np.maximum(duration / period, np.e)   # at least one peak: factor >= 1.4
        peak = std * np.sqrt(2.0 * np.log(peaks))
    return tuple(float(s) for s in np.maximum(SWAY_R_FLOOR, SWAY_R_MARGIN * peak))


@dataclass
class Paper003Episode(PreparedEpisode):
    """One ship episode (``PreparedEpisode``; C_s_b from the gimbal encoders), with
    coarse_error (3,) rad, phi E, N, U of the coarse alignment at t_k2, and inputs, the
    shared fine-alignment integrals (batch of one)."""

    coarse_error: np.ndarray
    inputs: FineInputs

    @property
    def fine_start(self) -> float:
        return float(self.inputs.t[0])

    def arrays(self) -> dict[str, np.ndarray]:
        return {"seed": self.seed, "coarse_error": self.coarse_error, "t": self.inputs.t,
                "C_s_s0": self.inputs.C_s_s0[0], "dW": self.inputs.dW[0],
                "Psi": self.inputs.Psi[0], "Psi2": self.inputs.Psi2[0],
                "C_s_n_true": self.C_s_n_true, "C_b_n_true": self.C_b_n_true,
                "C_s_b_encoder": self.C_s_b, "gyro_bias": self.gyro_bias,
                "accel_bias": self.accel_bias, "lat": self.lat, "h": self.h}

    @classmethod
    def from_arrays(cls, f) -> "Paper003Episode":
        inputs = FineInputs(t=f["t"], C_s_s0=f["C_s_s0"][None], dW=f["dW"][None],
                            Psi=f["Psi"][None], Psi2=f["Psi2"][None])
        return cls(seed=int(f["seed"]), coarse_error=f["coarse_error"], inputs=inputs,
                   C_s_n_true=f["C_s_n_true"], C_b_n_true=f["C_b_n_true"],
                   C_s_b=f["C_s_b_encoder"], gyro_bias=f["gyro_bias"],
                   accel_bias=f["accel_bias"], lat=float(f["lat"]), h=float(f["h"]))


def prepare_episode(experiment: Paper003Experiment, seed: int,
                    config: ScenarioConfig | None = None,
                    simulated: tuple | None = None) -> Paper003Episode:
    """Simulate one episode (or take ``simulated``, what ``simulate_screened(config,
    seed)`` returned), integrate it and run the coarse alignment."""
    config = config or experiment.scenario_config()
    episode, flags = simulated or simulate_screened(config, seed)
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
    return Paper003Episode(
        **flags,
        seed=seed, coarse_error=misalignment(C_s_n_all[k2], C_s_n_coarse), inputs=inputs,
        C_s_n_true=C_s_n_all[idx], C_b_n_true=quat_to_dcm(truth.q_b_n[idx]),
        C_s_b=gimbal_C_s_b(enc),
        gyro_bias=episode.imu_realization.gyro.bias,
        accel_bias=episode.imu_realization.accel.bias, lat=lat, h=h)


def coarse_starts(episodes: list[Paper003Episode]) -> dict[str, np.ndarray]:
    """The fine stage's starts (rad, E, N, U): the mean and the largest (per axis, by
    magnitude) coarse error of the episodes."""
    coarse = np.stack([e.coarse_error for e in episodes])
    return {"mean": coarse.mean(0), "max": signed_extreme(coarse, np.argmax)}


def sensor_frame_errors(result: FineResult, episodes: list[Paper003Episode],
                        error_n: np.ndarray) -> np.ndarray:
    """Truth minus estimate (B, K+1, 9) of the inertial-frame model's misalignment (error_n
    (B, K+1, 3) rad, E, N, U, turned into i) and its sensor-frame gyro (rad/s) and
    accelerometer (m/s^2) biases, against the episodes' drawn biases."""
    lat = np.array([e.lat for e in episodes])
    phi_i = np.einsum("bkij,bkj->bki", C_n_i(result.t[None], lat[:, None]), error_n)
    return np.concatenate([
        phi_i,
        np.stack([e.gyro_bias for e in episodes])[:, None] - result.x[:, :, EPS],
        np.stack([e.accel_bias for e in episodes])[:, None] - result.x[:, :, NABLA]], -1)


def hull_frame_floor(episodes: list[Paper003Episode]) -> np.ndarray:
    """The final misalignment (B, 3) rad, E, N, U, that biases fixed in the hull frame
    leave: the static floor of those biases (``static_alignment_floor``) at the hull's mean
    attitude over the fine run, which the filter's average sees through the sway."""
    return np.stack([static_alignment_floor(e.C_b_n_true.mean(0), e.gyro_bias,
                                            e.accel_bias, e.lat, e.h) for e in episodes])


def about_floor_errors(result: FineResult, episodes: list[Paper003Episode],
                       error_n: np.ndarray) -> np.ndarray:
    """The misalignment's error (B, K+1, 3) rad about the hull-frame biases' floor
    (``hull_frame_floor``), turned into i."""
    lat = np.array([e.lat for e in episodes])
    floor = hull_frame_floor(episodes)
    return np.einsum("bkij,bkj->bki", C_n_i(result.t[None], lat[:, None]),
                     error_n - floor[:, None])


SENSOR_FRAME_TRUTH = TruthMap(LAYOUT, ("misalignment", "gyro_bias", "accel_bias"),
                              sensor_frame_errors)
"""The NEES of the attitude and the sensor-frame biases (9), in the filter's frames."""
HULL_FRAME_TRUTH = TruthMap(LAYOUT, ("misalignment",), about_floor_errors)
"""The NEES of the attitude alone (3), about the floor, when the scenario's biases are
fixed in the hull frame (the model's sensor-frame bias states then have no true value)."""


def start_attitude(episodes: list[Paper003Episode], start_error: np.ndarray) -> np.ndarray:
    """Initial estimate C_s^i(t1) (B, 3, 3): the truth turned by a starting misalignment
    phi E, N, U (rad), common (3,) or per episode (B, 3)."""
    C_true = np.stack([e.C_s_n_true[0] for e in episodes])
    t1 = episodes[0].inputs.t[0]
    lat = np.array([e.lat for e in episodes])
    return C_n_i(t1, lat) @ rotvec_to_dcm(-np.asarray(start_error)) @ C_true


def run_filter(name: str, start: str, start_error: np.ndarray,
               episodes: list[Paper003Episode], experiment: Paper003Experiment,
               tuning: FineTuning | None = None) -> campaign.FilterRun:
    """One filter on all episodes from a starting misalignment phi E, N, U (rad): common
    (3,) or per episode (B, 3); tuning: the experiment's unless given."""
    return campaign.run_filter(name, start, start_error, episodes, experiment,
                               tuning=tuning)


def run_campaign(episodes: int = 50, seed: int = 0, filters: list[str] | None = None,
                 out_dir: str | Path | None = None, resume: bool = False,
                 workers: int | None = None, experiment: Paper003Experiment | None = None,
                 progress: bool = True) -> CampaignResult:
    """Run the paper-003 experiment (``scenarios.campaign.run_campaign``)."""
    return campaign.run_campaign(experiment or Paper003Experiment(), episodes, seed,
                                 filters, out_dir, resume, workers, progress)


@dataclass(frozen=True)
class Paper003Experiment(Experiment):
    """The experiment's settings (SPEC 4.1; values the paper omits are marked assumed).

    Times in s; attitude_sigma (deg) is the filter's initial misalignment sigma along
    E, N, U (assumed, ALGORITHMS 2.2); measurement_sigma (m/s) along E, N, U: None
    derives it from the scenario's sway (``sway_measurement_sigma``); start_sway_sigma
    (m/s, E, N, U): the sway velocity's std at the start of the fine alignment, added to
    P0 of the velocity integral (None: ``sway_velocity_std``, in the paper's setup too:
    the paper sees the sway as white measurement noise, but its velocity at the fine start
    enters every measurement as a constant, -C_n^i(t1) v_D(t1), that no R-scaling can
    absorb; ALGORITHMS 2.3); heading_threshold
    in arcmin; default_filters: the campaign's filter list; setup: "default" or "paper"
    (``PAPER_SETUP``).
    """

    scenario: str = "ship-sway-rotary"
    coarse_duration: float = bounded(120.0, "s", low=0.0, high=MAX_RUN, low_open=True)
    t_k1: float = bounded(50.0, "s", **POSITIVE)
    t_k2: float = bounded(120.0, "s", **POSITIVE)
    fine_duration: float = bounded(600.0, "s", low=0.0, high=MAX_RUN, low_open=True)
    filter_step: float = bounded(1.0, "s", **POSITIVE)
    attitude_sigma_deg: tuple[float, float, float] = bounded((1.0, 1.0, 5.0), "deg",
                                                             **POSITIVE)
    velocity_sigma: float = bounded(0.01, "m/s", **POSITIVE)
    measurement_sigma: tuple[float, float, float] | None = bounded(None, "m/s", **POSITIVE)
    start_sway_sigma: tuple[float, float, float] | None = bounded(None, "m/s", low=0.0)
    rho: float = bounded(0.95, low=0.0, high=1.0, low_open=True)
    rms_window: float = bounded(60.0, "s", **POSITIVE)
    heading_threshold_arcmin: float = bounded(5.0, "arcmin", **POSITIVE)
    default_filters: tuple[str, ...] = ("kf", "sakf", "makf", "imakf")
    setup: str = "default"

    paper = "003"
    regress = {"episodes": 4, "seed": 7,
               "filters": ["kf", "sakf", "makf", "imakf", "makf-n", "kf-sway", "sakf-r",
                           "makf-r"],
               "experiment": {"fine_duration": 300.0}}
    reproduce = {"episodes": 50, "seed": 0}
    claims = (
        Claim("Under angular and linear sway the conventional KF diverges",
              "003 sec. 4", {"kf diverged": "fine/kf/mean/diverged_fraction",
                             "kf lost": "fine/kf/mean/lost_fraction"},
              lambda n: n["kf diverged"] + n["kf lost"] >= 0.2,
              "not with an R at the sway's peak velocity (our default): nothing diverges; "
              "it does with the calm-sea R of the paper setup (next rows)"),
        Claim("Under angular and linear sway the conventional KF diverges",
              "003 sec. 4", {"kf diverged": "fine/kf/mean/diverged_fraction",
                             "kf lost": "fine/kf/mean/lost_fraction"},
              lambda n: n["kf diverged"] + n["kf lost"] >= 0.2,
              "the calm-sea R under the sway should make the KF lose its heading while "
              "confident; docs/paper003.md has it at 42-62 % (seeds 7, 0)", setup="paper"),
        Claim("The single fading factor (SAKF) keeps the alignment converged", "003 sec. 4",
              {"sakf-r diverged": "fine/sakf-r/mean/diverged_fraction",
               "sakf-r lost": "fine/sakf-r/mean/lost_fraction",
               "sakf-r heading RMS '": "fine/sakf-r/mean/rms_arcmin/2"},
              lambda n: n["sakf-r diverged"] + n["sakf-r lost"] == 0.0,
              "the factor on R should keep every episode converged (0 of 50 at seeds 0 and "
              "7, docs/paper003.md); an episode flagged here is a regression", setup="paper"),
        Claim("Multiple fading factors (MAKF, IMAKF) align more accurately than the single "
              "one", "003 sec. 3-4",
              {"makf-r heading RMS '": "fine/makf-r/mean/rms_arcmin/2",
               "imakf-r '": "fine/imakf-r/mean/rms_arcmin/2",
               "sakf-r '": "fine/sakf-r/mean/rms_arcmin/2"},
              lambda n: max(n["makf-r heading RMS '"], n["imakf-r '"]) < n["sakf-r '"],
              "measured at seeds 0 and 7: 2.8-3.2' against 3.7-4.0' (docs/paper003.md); "
              "the other order here is a regression", setup="paper"),
        Claim("The improved multiple factors (IMAKF) beat the MAKF", "003 sec. 3-4, abstract",
              {"imakf-r heading RMS '": "fine/imakf-r/mean/rms_arcmin/2",
               "makf-r '": "fine/makf-r/mean/rms_arcmin/2"},
              lambda n: n["imakf-r heading RMS '"] < n["makf-r '"],
              "with the factors on R (the form whose results match the paper's) the two "
              "coincide: IMAKF differs only in whether Q is faded, and R-scaling fades no Q "
              "(ALGORITHMS 2.3)", setup="paper"),
    )
    setups = {"paper": PAPER_SETUP}
    worlds = ("ship-prescribed", "ship-waves")
    state_count = 12
    member_points = 30.0    # sakf's 6.9 us a member-epoch, 2026-12-06 (bench_member_cost.py)
    filter_costs = {'kf': (7.2, 0.29), 'sakf': (2.6, 0.71), 'makf': (8.4, 0.4), 'imakf': (7.2, 0.47)}
    # (us a member-epoch, ms an epoch), 2026-12-06 (bench_member_cost.py)
    observation_features = frozenset({"selection-H", "unit-selection-H", "axes",
                                      "conditionally-linear"})
    filter_settings = Experiment.filter_settings | {
        "attitude_sigma_deg", "measurement_sigma", "rho", "start_sway_sigma", "velocity_sigma"}
    starts = STARTS

    episode_class = Paper003Episode
    preparation = staticmethod(prepare_episode)
    summarise = staticmethod(lambda result: {"coarse": coarse_summary(result),
                                             "fine": fine_summary(result)})
    tabulate = staticmethod(format_tables)
    start_errors = staticmethod(coarse_starts)

    @property
    def duration(self) -> float:
        return self.coarse_duration + self.fine_duration

    def tuning(self, config: ScenarioConfig) -> FineTuning:
        imu = ImuTuning.from_spec(config.imu)
        sigma = self.measurement_sigma or sway_measurement_sigma(config, self.fine_duration)
        start = self.start_sway_sigma
        if start is None:
            start = sway_velocity_std(config)
        return FineTuning(velocity_sigma=self.velocity_sigma, start_sway_sigma=tuple(start),
                          attitude_sigma=tuple(a * deg for a in self.attitude_sigma_deg),
                          gyro_bias_sigma=imu.gyro_bias_sigma,
                          accel_bias_sigma=imu.accel_bias_sigma,
                          gyro_noise_density=imu.gyro_noise_density,
                          accel_noise_density=imu.accel_noise_density,
                          measurement_sigma=sigma,
                          step=self.filter_step)

    model_variants = ("sway-aware",)

    def model(self, episodes, start_error, variant="", tuning: FineTuning | None = None):
        """The 12-state model, or ("sway-aware") the 18-state model with the scenario's
        sway as narrow-band states and the calm-sea R."""
        inputs = stack_inputs([e.inputs for e in episodes])
        config = self.scenario_config()
        if tuning is None:
            tuning = self.tuning(config)
            if variant == "sway-aware":  # the sway is modelled: sensor-level R, and the
                # oscillators carry the start velocity
                tuning = replace(tuning, measurement_sigma=(SWAY_AWARE_R,) * 3,
                                 start_sway_sigma=(0.0,) * 3)
        args = (inputs, start_attitude(episodes, start_error), tuning,
                np.array([e.lat for e in episodes]), np.array([e.h for e in episodes]))
        if variant == "":
            return InertialFineModel(*args)
        if variant == "sway-aware":
            return SwayAwareInertialModel(*args, sway=sway_spectrum(config))
        raise ValueError(f"paper003 has no model variant {variant!r}")

    @property
    def truth_map(self) -> TruthMap:
        """The attitude and biases (``SENSOR_FRAME_TRUTH``), or the attitude alone about
        the floor when the scenario's biases are fixed in the hull frame
        (``HULL_FRAME_TRUTH``)."""
        if self.scenario_config().imu_bias_frame == "hull":
            return HULL_FRAME_TRUTH
        return SENSOR_FRAME_TRUTH

    def unmodelled_floor(self, episodes):
        """With biases fixed in the hull frame (the paper setup) the model's sensor-frame
        bias states cannot hold the unmodulated part: a converged filter ends on the static
        floor of the hull-frame biases (``hull_frame_floor``; ~3' spread in heading against
        sigma_U 0.2-0.4'). None otherwise."""
        if self.scenario_config().imu_bias_frame != "hull":
            return None
        return hull_frame_floor(episodes)

    def check(self, config):
        if self.setup == "paper" and config.imu_bias_frame != "hull":
            raise ConfigError(f"--setup paper needs a scenario with [imu] bias_frame = "
                              f"\"hull\"; {config.name!r} has {config.imu_bias_frame!r}")

    def filter_options(self):
        return {"rho": self.rho}


EXPERIMENT = Paper003Experiment
"""This module's experiment (``scenarios.experiments``)."""
