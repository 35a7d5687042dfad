"""Paper 000 end to end: odometer-aided in-motion alignment of a FOG SINS on a car driving
the ring road (``ring-road-odometer``: 10 min of driving, then a stop and 5 min still).

Each episode: the odometer-aided coarse alignment while driving (ALGORITHMS 1.13, the
lever arm from the rear axle compensated; the heading comes from the earth's rotation
only, so it leaves a large heading error and small level errors), then the fine
alignment from the end of that window to the end of the run with the large-heading model
of ALGORITHMS 4.1 (``estimators.odometer_large``; with the odometer's residual mounting
pitch and heading as two more states, since the physics mounts the IMU case with the
scenario's angles). The paper's protocol: the filter's attitude when the car stops is
compared with the truth and with the analytic static alignment over the 5 min still
after the stop (the paper's reference). Filters: ``sgkf`` (000's SGKF: reduced-dimension
GH on phi_U with strong tracking), ``rdghkf`` (without strong tracking), ``ckf`` (000's
comparator), ``ekf``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from aligngym.estimators.euler_kinematics import C_p_n, true_state
from aligngym.estimators.inertial_frame import odometer_aided_alignment, static_coarse_alignment
from aligngym.estimators.alignment import FineResult
from aligngym.estimators.model import stack_episodes, wrap_angle
from aligngym.estimators.odometer_large import (EPS, LAYOUT, NABLA, PHI, OdometerInputs,
                                                OdometerLargeHeadingModel, OdometerTuning)
from aligngym.models.attitude import dcm_to_quat, quat_to_dcm
from aligngym.models.earth import TangentPlane
from aligngym.models.units import deg
from aligngym.scenarios.analyses.paper000 import (format_tables, paper000_summary,
                                                plot_sensor_estimates)
from aligngym.scenarios.campaign import (Experiment, PreparedEpisode, TruthMap, setting,
                                         simulate_screened)
from aligngym.scenarios.campaign.requirements import SensorTable, StrapdownImu
from aligngym.scenarios.campaign.settings import MAX_RUN, POSITIVE, bounded
from aligngym.scenarios.campaign.claims import Claim, ms_per_epoch, rule_points
from aligngym.scenarios.config import ConfigError, ScenarioConfig
from aligngym.sensors.imu import ImuTuning

STARTS = ("coarse", "large")
START_VELOCITIES = ("drawn", "odometer")
DISTURBANCES = ("none", "slip", "all")
SLIP_BURSTS = ((200.0, 0.3, 0.5), (350.0, 0.3, 0.5), (500.0, 0.3, 0.5))
"""--disturbance slip: a driven wheel spins for 0.3 s three times, the odometer counting
0.5 m the car did not travel each time (time s, duration s, extra m)."""
ROUGH_ROAD_RMS = 0.004
"""--disturbance all: slips plus a rough road (heightfield RMS, m): vibration."""


@dataclass
class Paper000Episode(PreparedEpisode):
    """One ring-road episode from the end of the coarse window (``PreparedEpisode``;
    C_s_b = the mounting, constant). t (K+1,) s; dtheta, dv (K, S, 3); distance (K, S) m
    per IMU interval; coarse_C_b_n (3, 3) the coarse alignment's attitude at t[0]; v0_body
    (3,) the IMU's start velocity in its own frame (odometer and gyros), m/s; lat0, lon0, h0 the
    start position (known); k_stop: the epoch 5 s after the car stops (the last one if
    the run ends sooner); C_reference (3, 3) the static alignment over the still after
    the stop (the paper's reference; NaN if the run has less than 60 s of it); coarse_error (3,)
    rad, Euler error E, N, U of the coarse alignment; odometer_scale_true: odometer
    distance / true rear-axle path over the drive - 1; mounting (2,) rad: the true
    mounting pitch and heading; lever_arm_b (3,) m; imu_dt s; slips (n, 3): the bursts;
    true_v_n (K+1, 3) m/s, the IMU's velocity at the boundaries."""

    t: np.ndarray
    imu_dt: float
    dtheta: np.ndarray
    dv: np.ndarray
    distance: np.ndarray
    coarse_C_b_n: np.ndarray
    v0_body: np.ndarray
    lat0: float
    lon0: float
    h0: float
    k_stop: int
    C_reference: np.ndarray
    coarse_error: np.ndarray
    odometer_scale_true: float
    mounting: np.ndarray
    lever_arm_b: np.ndarray
    slips: np.ndarray
    true_v_n: np.ndarray


def _rear_path(truth, lever_b: np.ndarray, start: int, end: int) -> float:
    """Length (m) of the path of the point -lever_b from the IMU (chassis frame b) between
    IMU boundaries start and end."""
    plane = TangentPlane(truth.lat[0], truth.lon[0], truth.h[0])
    site = plane.from_geodetic(truth.lat[start:end + 1], truth.lon[start:end + 1],
                               truth.h[start:end + 1])
    point = site - np.einsum("kij,j->ki", quat_to_dcm(truth.q_b_n[start:end + 1]), lever_b)
    return float(np.sum(np.linalg.norm(np.diff(point, axis=0), axis=1)))


def prepare_episode(experiment: Paper000Experiment, seed: int,
                    config: ScenarioConfig | None = None) -> Paper000Episode:
    """Simulate the drive, align coarsely while driving, take the static reference after
    the stop, cut the data into the filter's epochs."""
    config = config or experiment.scenario_config()
    episode, flags = simulate_screened(config, seed)
    truth, dt = episode.truth, config.imu_interval
    motion, odo = config.motion, config.odometer
    distance = episode.measurements["odometer"].distance
    lever_b = np.subtract(motion.imu_offset_b, motion.car_params().rear_axle_b)
    i_start = int(round(experiment.coarse_start / dt))
    i0 = int(round((experiment.coarse_start + experiment.coarse_duration) / dt))
    C_coarse, _ = odometer_aided_alignment(
        episode.dtheta[i_start:i0], episode.dv[i_start:i0], dt, distance[i_start:i0 + 1],
        config.latitude, config.height, lever_arm_b=lever_b)
    per = int(round(experiment.filter_step / dt))
    epochs = (truth.t.size - 1 - i0) // per
    idx = i0 + per * np.arange(epochs + 1)
    increments = np.diff(distance)
    # Start velocity: the odometer's (centred over 1 s) resolved with the coarse attitude.
    half = int(round(0.5 / dt))
    speed = (distance[i0 + half] - distance[i0 - half]) / (2 * half * dt)
    rate = episode.dtheta[i0 - half: i0 + half].sum(0) / (2 * half * dt)
    v0_body = np.array([0.0, speed, 0.0]) + np.cross(rate, lever_b)
    # The stop and the paper's reference: static alignment over the still after it (a
    # run that ends sooner has none: NaN, and its "stop" is its last epoch).
    k_stop = min(int(np.searchsorted(truth.t[idx], motion.stop_time + 5.0)), epochs)
    r0 = int(round((motion.stop_time + experiment.reference_settle) / dt))
    n_ref = truth.t.size - 1 - r0
    C_reference = np.full((3, 3), np.nan)
    if n_ref * dt >= 60.0:
        C_reference = static_coarse_alignment(episode.dv[r0:].sum(0) / (n_ref * dt),
                                              episode.dtheta[r0:].sum(0) / (n_ref * dt),
                                              float(truth.lat[r0]))
    drive = (i0, min(int(round(motion.stop_time / dt)), truth.t.size - 1))
    # Distance the slip bursts added (the wheel spun, the car did not travel): not scale.
    slipped = sum(extra for start, _, extra in odo.slips
                  if truth.t[drive[0]] <= start <= truth.t[drive[1]]) * (
        1.0 + float(episode.measurements["odometer"].scale_error))
    C_s_n = quat_to_dcm(truth.q_s_n[idx])
    C_b_n = quat_to_dcm(truth.q_b_n[idx])
    return Paper000Episode(
        **flags,
        seed=seed, t=truth.t[idx], imu_dt=dt,
        dtheta=episode.dtheta[i0: idx[-1]].reshape(epochs, per, 3),
        dv=episode.dv[i0: idx[-1]].reshape(epochs, per, 3),
        distance=increments[i0: idx[-1]].reshape(epochs, per), coarse_C_b_n=C_coarse,
        v0_body=v0_body, lat0=float(truth.lat[i0]), lon0=float(truth.lon[i0]), h0=float(truth.h[i0]),
        k_stop=k_stop, C_reference=C_reference,
        coarse_error=true_state(C_s_n[0], C_coarse),
        odometer_scale_true=float((distance[drive[1]] - distance[drive[0]] - slipped)
                                  / _rear_path(truth, lever_b, *drive) - 1.0),
        mounting=np.array([odo.mounting_pitch, odo.mounting_heading]), lever_arm_b=lever_b,
        slips=np.array(odo.slips, dtype=float).reshape(-1, 3), true_v_n=truth.v_n[idx],
        C_s_n_true=C_s_n, C_b_n_true=C_b_n, C_s_b=np.swapaxes(C_b_n, -1, -2) @ C_s_n,
        gyro_bias=episode.imu_realization.gyro.bias,
        accel_bias=episode.imu_realization.accel.bias,
        lat=float(truth.lat[0]), h=float(truth.h[0]))


def model_inputs(episodes: list[Paper000Episode], start_error: np.ndarray,
                 start_velocity: str, velocity_sigma: float) -> OdometerInputs:
    """The model's inputs; each INS starts from the true attitude turned by its Euler error
    (E, N, U, rad: C_b^n' = C_p_n(phi)^T C_b^n), the known start position and, by
    ``start_velocity``, the true velocity plus a draw of ``velocity_sigma`` (m/s, per ENU
    axis, from the episode's seed: "drawn") or the odometer's velocity turned by the
    coarse attitude ("odometer"; see ``Paper000Experiment``)."""
    parts = []
    for e, phi in zip(episodes, start_error):
        C0 = np.swapaxes(C_p_n(phi), -1, -2) @ e.C_s_n_true[0]
        if start_velocity == "drawn":
            rng = np.random.default_rng(np.random.SeedSequence([e.seed, 3]))
            v0 = e.true_v_n[0] + velocity_sigma * rng.standard_normal(3)
        else:
            v0 = e.coarse_C_b_n @ e.v0_body
        parts.append(OdometerInputs(
            t=e.t - e.t[0], imu_dt=e.imu_dt, dtheta=e.dtheta[None], dv=e.dv[None],
            distance=e.distance[None], C_m_b=np.eye(3)[None], lever_arm_b=e.lever_arm_b[None],
            q_b_n0=dcm_to_quat(C0)[None], v_n0=v0[None], lat0=np.array([e.lat0]),
            lon0=np.array([e.lon0]), h0=np.array([e.h0])))
    return stack_episodes(parts, shared=("t", "imu_dt"))


# --- metrics ---------------------------------------------------------------------------------


def state_errors(result: FineResult, episodes: list[Paper000Episode],
                 error_n: np.ndarray) -> np.ndarray:
    """Estimate minus truth (B, K+1, 9) of the states the NEES compares with the truth:
    the Euler errors (rad, wrapped; the true ones from C_est = C_p_n(phi^) C_b^n' and
    C_true = C_p_n(phi) C_b^n'), the gyro drift (rad/s) and the accelerometer bias (m/s^2)
    (accumulated estimate + state - drawn)."""
    K = result.t.size
    C_true = np.stack([e.C_s_n_true[:K] for e in episodes])
    x = result.x
    C_ins = np.swapaxes(C_p_n(x[..., PHI]), -1, -2) @ result.C_s_n
    phi = true_state(C_true, C_ins)
    s = result.series
    return np.concatenate([
        wrap_angle(x[..., PHI] - phi),
        s["gyro_bias"] + x[..., EPS] - np.stack([e.gyro_bias for e in episodes])[:, None],
        s["accel_bias"] + x[..., NABLA]
        - np.stack([e.accel_bias for e in episodes])[:, None]], -1)


@dataclass(frozen=True)
class Paper000Experiment(Experiment):
    """Settings (SPEC 4.2; assumed values marked). Times in s, angles in deg.

    coarse_start, coarse_duration: the odometer-aided coarse window while driving (from
    10 s after the car starts, 60 s: *assumed*); fine_duration: the fine alignment after
    it (None: to the end of the run); attitude_sigma_deg: the filter's P0 of the Euler
    errors E, N, U (*assumed*: 0.5, 0.5, 30; ALGORITHMS 4.3 suggests 30-60 deg for phi_U);
    large_heading_deg: the "large" start's heading error (the coarse start's level errors
    kept); mounting_sigma_deg: P0 of the residual odometer mounting pitch and heading
    states (None: 000's 16-state model); measurement_sigma: per axis of the 1 s
    position-increment difference, m (*assumed*: encoder quantization and tyre slip are
    millimetres to centimetres); feedback_sigma_deg: closed loop once the heading sigma
    is below it; disturbance: "none", "slip" (odometer slip bursts, ``SLIP_BURSTS``) or
    "all" (slips and a rough road); reference_settle: s after the stop before the static
    reference window; starts: the fine alignment's starts (``STARTS``).
    start_velocity: the INS's velocity at the fine start. "drawn" (*assumed*; the paper
    gives none): the true velocity plus a draw of P0's velocity sigma per axis, the error
    the filter's P0 describes, as the attitude start is the truth turned by a drawn or
    coarse error. "odometer": the odometer's velocity turned by the coarse attitude, all
    an INS has at the end of the in-motion coarse window; its error |v| times the coarse
    heading error (0.3-2.6 m/s) lies outside P0's 0.1 m/s, and no Gaussian P0 describes
    it (it lies on a circle in the heading): rdghkf and ekf then end 12-24' off in
    heading on ideal data where the drawn start leaves 1'.
    """

    scenario: str = "ring-road-odometer"
    coarse_start: float = bounded(15.0, "s", low=0.0, high=MAX_RUN)
    coarse_duration: float = bounded(60.0, "s", low=10.0, high=MAX_RUN)
    fine_duration: float | None = bounded(None, "s", low=0.0, high=MAX_RUN, low_open=True)
    filter_step: float = bounded(1.0, "s", **POSITIVE)
    attitude_sigma_deg: tuple[float, float, float] = bounded((0.5, 0.5, 30.0), "deg",
                                                             **POSITIVE)
    large_heading_deg: float = bounded(30.0, "deg", low=-180.0, high=180.0)
    velocity_sigma: float = bounded(0.1, "m/s", **POSITIVE)
    position_sigma: float = bounded(1.0, "m", **POSITIVE)
    scale_sigma: float = bounded(0.005, **POSITIVE)
    mounting_sigma_deg: float | None = bounded(1.0, "deg", low=0.0, high=10.0, low_open=True)
    measurement_sigma: float = bounded(0.02, "m/s", **POSITIVE)
    feedback_sigma_deg: float | None = bounded(5.0, "deg", **POSITIVE)
    disturbance: str = setting("none", "odometer slip bursts (slip), and a rough road as "
                               "well (all)", choices=DISTURBANCES)
    reference_settle: float = bounded(5.0, "s", low=0.0)
    rms_window: float = bounded(60.0, "s", **POSITIVE)
    heading_threshold_arcmin: float = bounded(10.0, "arcmin", **POSITIVE)
    start_velocity: str = bounded("drawn", choices=START_VELOCITIES)
    default_filters: tuple[str, ...] = ("sgkf", "rdghkf", "ckf", "ekf")
    starts: tuple[str, ...] = STARTS

    paper = "000"
    regress = {"episodes": 2, "seed": 5, "filters": ["sgkf", "rdghkf", "ekf"],
               "experiment": {"fine_duration": 200.0, "starts": ["coarse"]}}
    reproduce = {"episodes": 20, "seed": 0}
    claims = (
        Claim("The strong-tracking reduced-dimension GH filter (SGKF) aligns more accurately "
              "than the CKF (heading at the stop against the 5 min static alignment after it)",
              "000 sec. 3, abstract",
              {"sgkf heading vs reference RMS '": "fine/sgkf/vs_reference/rms_arcmin/2",
               "ckf '": "fine/ckf/vs_reference/rms_arcmin/2",
               "sgkf vs truth '": "fine/sgkf/vs_truth/rms_arcmin/2",
               "ckf vs truth '": "fine/ckf/vs_truth/rms_arcmin/2"},
              lambda n: n["sgkf heading vs reference RMS '"] < n["ckf '"],
              "the reference itself carries the still's gyro-drift error (5.4' std, 20x the "
              "filters' own); against the truth both end within 0.4' (docs/paper000.md)",
              settings={"starts": ("coarse",)}, filters=("sgkf", "rdghkf", "ckf")),
        Claim("The reduced dimension lowers the computation: GH points on the heading alone",
              "000 sec. 2.2, conclusion",
              {"sgkf points": rule_points("sgkf", 18), "ckf points": rule_points("ckf", 18),
               "sgkf ms/epoch": ms_per_epoch("sgkf"), "ckf ms/epoch": ms_per_epoch("ckf")},
              lambda n: (n["sgkf points"] < n["ckf points"]
                         and n["sgkf ms/epoch"] < 0.8 * n["ckf ms/epoch"]),
              "7 points against 36, but the time per epoch is about the CKF's (0.90-1.02x "
              "on 20 episodes, each filter timed alone, the least of five interleaved "
              "rounds; a lower computation is taken as below 0.8x, outside the timing "
              "noise): each GH point carries its "
              "conditional covariance through F(zeta_i) Sigma_c F(zeta_i)^T (ALGORITHMS "
              "4.9), a 17 x 17 product per point, where a cubature point is one state "
              "vector", settings={"starts": ("coarse",)},
              filters=("sgkf", "rdghkf", "ckf")),
        Claim("Strong tracking keeps the filter stable through abrupt changes: with "
              "odometer slip bursts the SGKF at least as accurate as the GH filter without it",
              "000 abstract, conclusion",
              {"sgkf heading vs truth RMS '": "fine/sgkf/vs_truth/rms_arcmin/2",
               "rdghkf '": "fine/rdghkf/vs_truth/rms_arcmin/2",
               "sgkf diverged": "fine/sgkf/diverged_fraction",
               "sgkf lost": "fine/sgkf/lost_fraction",
               "rdghkf diverged": "fine/rdghkf/diverged_fraction",
               "rdghkf lost": "fine/rdghkf/lost_fraction"},
              lambda n: (n["sgkf diverged"] + n["sgkf lost"]
                         <= n["rdghkf diverged"] + n["rdghkf lost"]
                         and n["sgkf heading vs truth RMS '"] <= 1.05 * n["rdghkf '"]),
              "a 0.5 m slip is a one-epoch outlier (the innovation test flags it), and "
              "strong tracking takes it for a change of state: lambda ~1400 at each burst, "
              "the heading sigma 26' -> 460', the heading lost (-190' +- 580' at the stop in "
              "every episode) where the GH filter without it ends at 0.4'; the paper's "
              "abrupt changes are the state's, not the sensor's (sgkf-gated, which skips "
              "outliers, ends at 0.41': docs/paper000.md)",
              settings={"starts": ("coarse",), "disturbance": "slip"},
              filters=("sgkf", "rdghkf")),
    )
    """aligngym regress: ckf diverges from the large start and is left out, with that start
    (a diverging filter amplifies last bits without bound: not reproducible); sgkf is in
    since its warm-up (it diverged in 30 % of the coarse starts before)."""
    worlds = ("car",)
    requires = (SensorTable("odometer"), StrapdownImu())
    state_count = 18
    member_points = 650.0    # rdghkf's 150 us a member-epoch, 2026-12-06 (bench_member_cost.py)
    observation_features = frozenset({"conditionally-linear"})
    filter_settings = Experiment.filter_settings | {
        "attitude_sigma_deg", "feedback_sigma_deg", "measurement_sigma", "position_sigma",
        "scale_sigma"}

    episode_class = Paper000Episode
    preparation = staticmethod(prepare_episode)
    truth_map = TruthMap(LAYOUT, ("misalignment", "gyro_bias", "accel_bias"), state_errors)
    summarise = staticmethod(paper000_summary)
    tabulate = staticmethod(format_tables)
    own_plots = staticmethod(plot_sensor_estimates)

    @property
    def duration(self) -> float:
        if self.fine_duration is None:
            return self.scenario_file().duration
        return self.coarse_start + self.coarse_duration + self.fine_duration

    def scenario_config(self) -> ScenarioConfig:
        """The scenario with this experiment's duration and disturbance, checked."""
        config = super().scenario_config()
        self.check(config)
        if self.disturbance in ("slip", "all"):
            config = replace(config, odometer=replace(
                config.odometer, slips=config.odometer.slips + SLIP_BURSTS))
        if self.disturbance == "all":
            config = replace(config, motion=replace(config.motion,
                                                    roughness_rms=ROUGH_ROAD_RMS))
        return config

    def check(self, config: ScenarioConfig) -> None:
        super().check(config)
        if (not self.starts or set(self.starts) - set(STARTS)
                or len(set(self.starts)) != len(self.starts)):
            raise ConfigError(f"starts = {self.starts}; valid: each of "
                              + ", ".join(STARTS) + " at most once")
        motion = config.motion
        if not motion.speed > 0.0:
            raise ConfigError(f"motion.speed = {motion.speed:g} m/s: paper000's "
                              "odometer-aided alignment needs the car to drive (speed > 0)")
        start, end = self.coarse_start, self.coarse_start + self.coarse_duration
        driving_end = min(motion.stop_time, config.duration)
        if not (motion.start_time <= start and self.coarse_duration >= 10.0
                and end < driving_end):
            raise ConfigError(f"the coarse window [{start:g}, {end:g}] s must lie in the "
                              f"driving phase [{motion.start_time:g}, {driving_end:g}) s "
                              "and last >= 10 s")
        if self.fine_duration is not None and not self.fine_duration >= self.filter_step:
            raise ConfigError(f"fine_duration = {self.fine_duration:g} s must be >= "
                              f"filter_step = {self.filter_step:g} s")
        if self.disturbance != "none":
            last = max(t + d for t, d, _ in SLIP_BURSTS)
            if not (end < SLIP_BURSTS[0][0] and last < driving_end):
                raise ConfigError(f"--disturbance {self.disturbance}: the slip bursts "
                                  f"({SLIP_BURSTS[0][0]:g}-{last:g} s) must fall in the "
                                  f"fine alignment's driving phase ({end:g}, "
                                  f"{driving_end:g}) s")
        sigma = self.mounting_sigma_deg
        if sigma is not None and not 0.0 < sigma <= 10.0:
            raise ConfigError(f"mounting_sigma_deg = {sigma:g} must be in (0, 10] deg")

    def tuning(self, config: ScenarioConfig) -> OdometerTuning:
        imu = ImuTuning.from_spec(config.imu)
        return OdometerTuning(
            attitude_sigma=tuple(a * deg for a in self.attitude_sigma_deg),
            velocity_sigma=self.velocity_sigma, position_sigma=self.position_sigma,
            gyro_bias_sigma=imu.gyro_bias_sigma, accel_bias_sigma=imu.accel_bias_sigma,
            scale_sigma=self.scale_sigma, gyro_noise_density=imu.gyro_noise_density,
            accel_noise_density=imu.accel_noise_density,
            measurement_sigma=self.measurement_sigma,
            mounting_sigma=(None if self.mounting_sigma_deg is None
                            else self.mounting_sigma_deg * deg))

    def start_errors(self, episodes):
        coarse = np.stack([e.coarse_error for e in episodes])
        large = coarse.copy()
        large[:, 2] = self.large_heading_deg * deg
        return {"coarse": coarse, "large": large}

    def model(self, episodes, start_error, variant=""):
        if variant:
            raise ValueError(f"paper000 has no model variant {variant!r}")
        start_error = np.broadcast_to(np.asarray(start_error, float), (len(episodes), 3))
        config = self.scenario_config()
        feedback = None if self.feedback_sigma_deg is None else self.feedback_sigma_deg * deg
        inputs = model_inputs(episodes, start_error, self.start_velocity,
                              self.velocity_sigma)
        return OdometerLargeHeadingModel(inputs, self.tuning(config), feedback_below=feedback)


EXPERIMENT = Paper000Experiment
"""This module's experiment (``scenarios.experiments``)."""
