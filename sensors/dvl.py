"""Doppler velocity log (DVL) in bottom-track mode: the hull's velocity over the seabed at
the DVL's transducers, in the carrier frame (R, F, U), with a constant bias and a scale
factor drawn per episode, white noise, and lost pings (random, and windows without bottom
lock). A sensor added in this one file plus a [dvl] table in a scenario file."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aligngym.models.attitude import quat_conj, quat_mul, quat_rotate, quat_to_rotvec
from aligngym.sensors import number_rows
from aligngym.sensors.base import (Sensor, SensorRecord, SensorTruth, outside_windows,
                                   register_sensor, window_faults)


@dataclass(frozen=True)
class DvlSpec:
    """rate: pings per second, Hz; velocity_sigma: white noise per axis, m/s; bias_sigma:
    1 sigma per axis of the constant bias drawn per episode, m/s; scale_factor_sigma: 1
    sigma of the scale-factor error drawn per episode (relative); dropout_probability: the
    chance that a ping is lost; dropouts: (start s, end s) windows without bottom lock;
    lever_arm_b: the transducers' position from the IMU in the carrier frame (R, F, U), m."""

    rate: float = 2.0
    velocity_sigma: float = 0.01
    bias_sigma: float = 0.005
    scale_factor_sigma: float = 0.002
    dropout_probability: float = 0.0
    dropouts: tuple[tuple[float, float], ...] = ()
    lever_arm_b: tuple[float, float, float] = (0.0, 0.0, -2.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "dropouts", number_rows(self.dropouts, 2, "dvl.dropouts",
                                                      "(start_s, end_s)"))
        if not 0.0 < self.rate <= 50.0:
            raise ValueError(f"dvl.rate = {self.rate:g} Hz is out of range (0, 50]")
        for name, high in (("velocity_sigma", 1.0), ("bias_sigma", 1.0),
                           ("scale_factor_sigma", 0.1)):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= high):
                raise ValueError(f"dvl.{name} = {value:g} is out of range [0, {high:g}]")
        if not 0.0 <= self.dropout_probability < 1.0:
            raise ValueError(f"dvl.dropout_probability = {self.dropout_probability:g} is out "
                             "of range [0, 1)")
        for start, end in self.dropouts:
            if not end > start:
                raise ValueError(f"dvl.dropouts: window ({start:g}, {end:g}) must have "
                                 "end > start")
        arm = tuple(self.lever_arm_b)
        if len(arm) != 3 or not all(math.isfinite(v) and abs(v) <= 100.0 for v in arm):
            raise ValueError("dvl.lever_arm_b must be 3 numbers within +-100 m")


@dataclass(frozen=True)
class DvlVelocities(SensorRecord):
    """The DVL's pings (P,): times t s; v_b (P, 3) m/s, the transducers' velocity over the
    seabed in the carrier frame (R, F, U), NaN where the ping is lost; valid (P,); the
    episode's drawn bias (3,) m/s and scale-factor error."""

    PREFIX = "dvl_"
    t: np.ndarray
    v_b: np.ndarray
    valid: np.ndarray
    bias: np.ndarray
    scale_error: np.ndarray


def transducer_velocity_b(truth: SensorTruth, every: int, lever_arm_b: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
    """Times (P,) s and the true velocity (P, 3) m/s over the ground of the point at
    lever_arm_b (m, carrier frame, from the IMU) in the carrier frame, at every
    ``every``-th sample of the truth (uniform in time, >= 3 samples): C_n^b v_n +
    omega_nb^b x l, the body rate from the attitude's second-order differences in the
    body frame at the sample (central inside, one-sided at the ends)."""
    tr = truth.truth
    n, dt = tr.t.size, float(tr.t[1] - tr.t[0])
    k = np.arange(0, n, every)

    def turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The body's rotation from sample a to sample b, in body axes at a (rad)."""
        return quat_to_rotvec(quat_mul(quat_conj(tr.q_b_n[a]), tr.q_b_n[b]))
    omega_b = np.empty((k.size, 3))
    inner = (k > 0) & (k < n - 1)
    i = k[inner]
    omega_b[inner] = (turn(i, i + 1) - turn(i, i - 1)) / (2.0 * dt)
    if k[0] == 0:
        omega_b[0] = (4.0 * turn(k[:1], k[:1] + 1) - turn(k[:1], k[:1] + 2))[0] / (2.0 * dt)
    if k[-1] == n - 1:
        last = k[-1:]
        omega_b[-1] = -(4.0 * turn(last, last - 1) - turn(last, last - 2))[0] / (2.0 * dt)
    v_b = quat_rotate(quat_conj(tr.q_b_n[k]), tr.v_n[k])
    return tr.t[k], v_b + np.cross(omega_b, lever_arm_b)


@register_sensor
class DopplerVelocityLog(Sensor):
    """A hull-mounted DVL in bottom-track mode ([dvl]); the ships only."""

    section = "dvl"
    spec_type = DvlSpec
    units = {"rate": "_hz", "velocity_sigma": "", "bias_sigma": "",
             "scale_factor_sigma": "", "dropout_probability": "", "dropouts": "_s",
             "lever_arm_b": "_m"}
    needs = frozenset({"hull"})
    stream = "dvl"

    def check(self, duration: float, imu_rate: float, world: str) -> None:
        ratio = imu_rate / self.spec.rate
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(f"dvl.rate = {self.spec.rate:g} Hz must divide run.imu_rate_hz "
                             f"= {imu_rate:g} Hz")

    def measure(self, truth: SensorTruth, rng: np.random.Generator, ideal: bool
                ) -> DvlVelocities:
        spec = self.spec
        dt = float(truth.truth.t[1] - truth.truth.t[0])
        every = max(1, int(round(1.0 / (spec.rate * dt))))
        t, v_b = transducer_velocity_b(truth, every, np.asarray(spec.lever_arm_b))
        valid = outside_windows(t, spec.dropouts)
        if ideal:
            bias, scale = np.zeros(3), 0.0
        else:
            bias = spec.bias_sigma * rng.standard_normal(3)
            scale = float(spec.scale_factor_sigma * rng.standard_normal())
            v_b = (1.0 + scale) * v_b + bias + spec.velocity_sigma * rng.standard_normal(
                v_b.shape)
            valid &= rng.random(t.size) >= spec.dropout_probability
        return DvlVelocities(t=t, v_b=np.where(valid[:, None], v_b, np.nan), valid=valid,
                             bias=bias, scale_error=np.array(scale))

    def faults(self, record: SensorRecord, duration: float
               ) -> list[tuple[str, float, float]]:
        return window_faults("dvl_dropout", self.spec.dropouts, duration)
