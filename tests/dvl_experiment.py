"""A test-only experiment that is not a paper's: DVL-aided fine alignment on the swaying
ship, built from the library's parts with no subclass of a paper's experiment.

Paper 003's inertial-frame model measures the velocity integral z(t) = v^i(t) - v^i(t1)
of the sway centre and, knowing nothing of the sway, counts that velocity as measurement
noise (an R at the sway's peak velocity). A Doppler velocity log ([dvl]) measures the
hull's velocity over the seabed at its transducers, so the aided measurement takes the
sway out:

    z'(t) = [z(t) - z(t_r)] - C^_b^i(t) v_c^b(t) + C^_b^i(t_r) v_c^b(t_r),
    v_c^b = v_dvl^b - omega_ib^b x (l_imu + l_dvl),

with t_r the first epoch with a ping (t1 unless that ping is lost), C^_b^i = C^_s0^i
C_s^s0 C_b^s the filter's own attitude (gyros and encoders), omega_ib^b the hull's rate
from the gyros less the gimbal's (encoders), l_imu the IMU's and l_dvl the transducers'
lever arms (hull frame, m). The residual is the DVL's noise, its scale factor times the
velocity change, and [dv^i x] phi (second order: 1 deg of misalignment on 0.3 m/s of sway
is 5 mm/s, below the noise once the filter has converged to arcminutes); the DVL's bias
cancels in the difference (up to the earth's rotation of C^_b^i over the run). Lost pings
are missing measurements. R: the DVL's white noise, with a floor of ``R_FLOOR``.
The DVL's bias does not cancel: the hull's sway turns it (10 deg of roll on 5 mm/s is
0.9 mm/s, at the sway's periods: 1' of heading error when left out, measured), so it
is a state (``DvlAidedModel``), seen through the sway.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.inertial_fine import (FineInputs, FineTuning, InertialFineModel,
                                               stack_inputs)
from aligngym.estimators.inertial_frame import gimbal_rate_s
from aligngym.estimators.model import Observation, StateLayout, Transition
from aligngym.models.attitude import cross
from aligngym.models.units import deg
from aligngym.models.gimbal import gimbal_C_s_b
from aligngym.scenarios.campaign import Experiment, simulate_screened
from aligngym.scenarios.campaign.settings import MAX_RUN, POSITIVE, bounded, setting
from aligngym.scenarios.campaign.requirements import SensorTable
from aligngym.scenarios.experiments import paper003
from aligngym.sensors.imu import ImuTuning

N = 15
"""States: paper 003's 12 and the DVL's bias (3)."""
BIAS_FLOOR = 1e-4
"""m/s: the smallest 1 sigma of the DVL bias state."""
R_FLOOR = 1e-3
"""m/s: the smallest measurement sigma (an ideal DVL still leaves the lever arm's rate
from gyros and encoders and the terms the model leaves out, ~1e-4 m/s)."""


@dataclass
class DvlEpisode(paper003.Paper003Episode):
    """Paper 003's ship episode (coarse alignment and the fine-alignment integrals) with
    the sway centre's velocity from the DVL at the fine epochs: v_centre_b (K+1, 3) m/s in
    the hull frame, NaN where the ping is lost or no ping falls on the epoch."""

    v_centre_b: np.ndarray = None
    dvl_bias: np.ndarray = None
    """The DVL's drawn bias (3,) m/s, hull frame (truth, for the checks)."""

    def arrays(self) -> dict[str, np.ndarray]:
        return {**super().arrays(), "v_centre_b": self.v_centre_b, "dvl_bias": self.dvl_bias}

    @classmethod
    def aided(cls, base: paper003.Paper003Episode, v_centre_b: np.ndarray,
              dvl_bias: np.ndarray) -> "DvlEpisode":
        """Paper 003's episode with the DVL's arrays."""
        return cls(**{k: getattr(base, k) for k in base.__dataclass_fields__},
                   v_centre_b=v_centre_b, dvl_bias=dvl_bias)

    @classmethod
    def from_arrays(cls, f) -> "DvlEpisode":
        return cls.aided(paper003.Paper003Episode.from_arrays(f), f["v_centre_b"],
                         f["dvl_bias"])


def sway_centre_velocity(episode, config, epoch_t: np.ndarray) -> np.ndarray:
    """v_c^b (K+1, 3) m/s at the epochs epoch_t (s): the DVL's ping there less the lever
    arm's velocity omega_ib^b x (l_imu + l_dvl), omega_ib^b from the gyros less the
    gimbal's rate (encoders; ``inertial_frame.gimbal_rate_s``); NaN without a valid ping."""
    record = episode.measurements["dvl"]
    dt = config.imu_interval
    dtheta = episode.dtheta
    imu_k = np.rint(epoch_t / dt).astype(int)
    # the inertial rate at an IMU boundary: the mean of its two intervals
    rate = (dtheta[np.maximum(imu_k - 1, 0)] + dtheta[np.minimum(imu_k, len(dtheta) - 1)]) \
        / (2.0 * dt)
    angles = episode.gimbal_encoder
    omega_s = rate - gimbal_rate_s(angles, dt)[imu_k]
    C_s_b = gimbal_C_s_b(angles[imu_k])
    omega_b = np.einsum("kij,kj->ki", C_s_b, omega_s)
    arm = np.asarray(config.motion.lever_arm_b) + np.asarray(config.sensor_specs()["dvl"].lever_arm_b)
    ping = np.searchsorted(record.t, epoch_t - 1e-9)
    ping = np.minimum(ping, record.t.size - 1)
    on_epoch = np.abs(record.t[ping] - epoch_t) < 1e-6
    v = record.v_b[ping] - cross(omega_b, np.broadcast_to(arm, omega_b.shape))
    v[~(on_epoch & record.valid[ping])] = np.nan
    return v


DVL_BIAS = slice(12, 15)
LAYOUT = StateLayout({**InertialFineModel.layout.blocks, "dvl_bias": DVL_BIAS})


class DvlAidedModel(InertialFineModel):
    """Paper 003's 12 states and the DVL's bias b (hull frame, m/s; constant), with the
    DVL-aided velocity-integral measurement (module docstring): z' = dV - [C^_b^i(t) -
    C^_b^i(t_r)] b + noise, the bias seen through the hull's sway and the earth's turn.
    v_centre_b: (B, K+1, 3) m/s; C_s_b: (B, K+1, 3, 3) the gimbal at the epochs
    (encoders); bias_sigma: the DVL bias's 1 sigma per axis, m/s."""

    layout = LAYOUT

    def __init__(self, inputs: FineInputs, C_s_i_start, tuning: FineTuning, lat, h,
                 v_centre_b: np.ndarray, C_s_b: np.ndarray, bias_sigma: float) -> None:
        super().__init__(inputs, C_s_i_start, tuning, lat, h)
        self.v_centre_b, self.C_b_s = v_centre_b, np.swapaxes(C_s_b, -1, -2)
        self.bias_sigma = bias_sigma
        have = np.isfinite(v_centre_b).all(-1)                      # (B, K+1)
        self.reference = np.where(have.any(1), have.argmax(1), v_centre_b.shape[1])
        self._z_reference = np.zeros((self.batch, 3))

    def initial(self):
        x, P12 = super().initial()
        P = np.zeros((self.batch, N, N))
        P[:, :12, :12] = P12
        P[:, DVL_BIAS, DVL_BIAS] = np.eye(3) * max(self.bias_sigma, BIAS_FLOOR) ** 2
        return np.zeros((self.batch, N)), P

    def transition(self, k, q_scale=(1.0, 1.0)):
        plain = super().transition(k, q_scale)
        Phi = np.zeros((self.batch, N, N))
        Phi[:, :12, :12] = plain.matrix
        Phi[:, DVL_BIAS, DVL_BIAS] = np.eye(3)
        Q = np.zeros((self.batch, N, N))
        Q[:, :12, :12] = plain.noise
        return Transition(noise=Q, matrix=Phi)

    def _hull_i(self, k: np.ndarray | int) -> np.ndarray:
        """C^_b^i (B, 3, 3) at epoch k (one per episode) with the current attitude."""
        b = np.arange(self.batch)
        return self.C_s0_i @ self.inputs.C_s_s0[b, k] @ self.C_b_s[b, k]

    def observation(self, k, r_scale=1.0):
        plain = super().observation(k, r_scale)
        epoch, b = k + 1, np.arange(self.batch)
        at_reference = self.reference == epoch
        self._z_reference[at_reference] = plain.z[at_reference]
        ref = np.minimum(self.reference, self.epochs)
        C_now, C_ref = self._hull_i(epoch), self._hull_i(ref)
        z = (plain.z - self._z_reference
             - np.einsum("bij,bj->bi", C_now, self.v_centre_b[b, epoch])
             + np.einsum("bij,bj->bi", C_ref, self.v_centre_b[b, ref]))
        z[epoch <= self.reference] = np.nan       # before and at the reference: nothing
        H = np.zeros((self.batch, 3, N))
        H[:, :, :12] = plain.matrix
        H[:, :, DVL_BIAS] = -(C_now - C_ref)
        return Observation(noise=plain.noise, matrix=H, z=z, t=plain.t, axes=plain.axes)


def prepare_dvl_episode(experiment: "DvlAidedExperiment", seed: int, config) -> DvlEpisode:
    """Paper 003's preparation, and the sway centre's velocity from the DVL."""
    simulated = simulate_screened(config, seed)
    base = paper003.prepare_episode(experiment, seed, config, simulated)
    v = sway_centre_velocity(simulated[0], config, base.inputs.t)
    return DvlEpisode.aided(base, v, simulated[0].measurements["dvl"].bias)


@dataclass(frozen=True)
class DvlAidedExperiment(Experiment):
    """DVL-aided fine alignment on the swaying ship (module docstring): paper 003's
    coarse stage and starts, its 12-state model with the DVL's measurement. Times in s,
    sigmas as paper 003's."""

    scenario: str = "ship-sway-rotary"
    coarse_duration: float = bounded(120.0, "s", low=0.0, high=MAX_RUN, low_open=True)
    t_k1: float = bounded(50.0, "s", **POSITIVE)
    t_k2: float = bounded(120.0, "s", **POSITIVE)
    fine_duration: float = setting(300.0, "the fine alignment's length", unit="s",
                                   low=0.0, high=MAX_RUN, low_open=True)
    filter_step: float = bounded(1.0, "s", **POSITIVE)
    attitude_sigma_deg: tuple[float, float, float] = bounded((1.0, 1.0, 5.0), "deg",
                                                             **POSITIVE)
    velocity_sigma: float = bounded(0.01, "m/s", **POSITIVE)
    rms_window: float = bounded(60.0, "s", **POSITIVE)
    heading_threshold_arcmin: float = bounded(5.0, "arcmin", **POSITIVE)
    default_filters: tuple[str, ...] = ("kf", "sakf")

    paper = "-dvl"
    worlds = ("ship-prescribed", "ship-waves")
    requires = (SensorTable("dvl"),)
    starts = paper003.STARTS
    state_count = N
    observation_features = frozenset({"axes", "conditionally-linear"})
    episode_class = DvlEpisode
    default_episodes = 4
    preparation = staticmethod(prepare_dvl_episode)
    start_errors = staticmethod(paper003.coarse_starts)
    truth_map = paper003.SENSOR_FRAME_TRUTH

    @property
    def duration(self) -> float:
        return self.coarse_duration + self.fine_duration

    def model(self, episodes, start_error, variant=""):
        config = self.scenario_config()
        imu = ImuTuning.from_spec(config.imu)
        dvl = config.sensor_specs()["dvl"]
        sigma = max(dvl.velocity_sigma, R_FLOOR)
        # the reference ping's noise is a constant in every measurement: an initial
        # velocity-integral error, in P0; the current ping's is the white noise, in R
        tuning = FineTuning(velocity_sigma=float(np.hypot(self.velocity_sigma, sigma)),
                            attitude_sigma=tuple(a * deg for a in self.attitude_sigma_deg),
                            gyro_bias_sigma=imu.gyro_bias_sigma,
                            accel_bias_sigma=imu.accel_bias_sigma,
                            gyro_noise_density=imu.gyro_noise_density,
                            accel_noise_density=imu.accel_noise_density,
                            measurement_sigma=(sigma,) * 3,
                            step=self.filter_step)
        return DvlAidedModel(stack_inputs([e.inputs for e in episodes]),
                             paper003.start_attitude(episodes, start_error), tuning,
                             np.array([e.lat for e in episodes]),
                             np.array([e.h for e in episodes]),
                             np.stack([e.v_centre_b for e in episodes]),
                             np.stack([e.C_s_b for e in episodes]), dvl.bias_sigma)
