"""MuJoCo worlds and their IMU kinematics.

Prescribed worlds (``PrescribedWorld``) read MuJoCo's sensors on analytic motion;
dynamic worlds (the car, the wave-driven ship) record MuJoCo's discrete steps
(``DiscreteRun``) whose IMU increments ``discrete_imu`` integrates exactly.


MuJoCo's world frame is the earth-fixed tangent plane ``t`` (ENU axes at the scenario
origin). A prescribed world gives MuJoCo analytic joint positions, velocities and
accelerations and reads the IMU site's pose, velocity, gyro and accelerometer, exact to
rounding (gyro to ~1e-12 rad/s). It does so for all sample times in one
``mujoco.rollout`` call (C threads, no Python per sample) on a kinematic twin of the
model: every body nearly massless, every joint with a large armature A and the
applied generalised force A qacc, so that one forward-dynamics step's acceleration is
the prescribed qacc to rounding (relative error ~M/A ~1e-21) and the sensors of that
step read the prescribed state.
"""
from __future__ import annotations

import copy
import os
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np

from aligngym.models.attitude import (cross, quat_cumprod, quat_rotate, quat_to_dcm, rot_x, rot_z,
                             rotvec_to_dcm, rotvec_to_quat, skew)

if TYPE_CHECKING:                   # MuJoCo is loaded when a world is built
    import mujoco


@dataclass(frozen=True)
class WorldSamples:
    """Kinematics of the IMU site and the carrier body at sample times, in plane frame t.

    t: (N,) s. r_t, v_t, a_t: (N, 3) IMU position (m), velocity (m/s) and acceleration
    (m/s^2) relative to the earth-fixed plane. q_s_t, q_b_t: (N, 4) IMU sensor frame and
    carrier body to plane. omega_ts_s: (N, 3) angular rate of s relative to t in s, rad/s.
    gimbal_angles: (N, 2) rad (outer, inner); zeros without a gimbal. antenna_r_t,
    antenna_v_t: (N, 3) the GNSS antenna's position (m) and velocity (m/s) in t, where the
    world has an antenna (else None).
    """

    t: np.ndarray
    r_t: np.ndarray
    v_t: np.ndarray
    a_t: np.ndarray
    q_s_t: np.ndarray
    q_b_t: np.ndarray
    omega_ts_s: np.ndarray
    gimbal_angles: np.ndarray
    antenna_r_t: np.ndarray | None = None
    antenna_v_t: np.ndarray | None = None


GimbalMotion = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""The double-axis gimbal's motion relative to the carrier: times t (N,) s -> angles
(rad), angle rates (rad/s) and angle accelerations (rad/s^2), (N, 2) each (outer about
body z, inner about x; C_s_b = Rz(outer) Rx(inner))."""


STALL_RAMP = 0.2
"""s: a stalled gimbal decelerates to rest, and later re-accelerates, over this time
(a septic smoothstep; with the catch-up, built from its derivative, the angles keep
three continuous derivatives)."""
STALL_CATCH_UP = 2.0
"""After a stall of duration d the gimbal catches up with its schedule over
STALL_CATCH_UP x d (s), at up to 1 + 2.19 / STALL_CATCH_UP times its scheduled rate."""


def smoothstep(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The septic smoothstep S(x) = 35x^4 - 84x^5 + 70x^6 - 20x^7 on [0, 1] (0 before, 1
    after; its first three derivatives vanish at both ends), its derivatives
    S'(x) = 140 x^3 (1 - x)^3 and S''(x) = 420 x^2 (1 - x)^2 (1 - 2x), and its integral
    from 0 (1/2 + (x - 1) beyond 1)."""
    inside = np.clip(x, 0.0, 1.0)
    value = inside ** 4 * (35.0 + inside * (-84.0 + inside * (70.0 - 20.0 * inside)))
    slope = 140.0 * inside ** 3 * (1.0 - inside) ** 3
    curvature = 420.0 * inside ** 2 * (1.0 - inside) ** 2 * (1.0 - 2.0 * inside)
    integral = (inside ** 5 * (7.0 + inside * (-14.0 + inside * (10.0 - 2.5 * inside)))
                + np.maximum(x - 1.0, 0.0))
    return value, slope, curvature, integral


def stalled(motion: GimbalMotion, stalls: tuple[tuple[float, float], ...]) -> GimbalMotion:
    """The gimbal ``motion`` with stalls (start s, duration d s; d >= STALL_RAMP): in
    each, every axis stops (a STALL_RAMP deceleration from the start) and stays until
    start + d, then re-accelerates and catches up with its schedule over
    STALL_CATCH_UP x d, as a servo following its command does (a stall of an axis at
    rest changes nothing). A time warp tau(t) with weight w = dtau/dt >= 0:
    angle = base(tau), rate = base_rate(tau) w,
    acceleration = base_accel(tau) w^2 + base_rate(tau) w'."""
    if not stalls:
        return motion

    def state(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        tau, w, dw = t.copy(), np.ones_like(t), np.zeros_like(t)
        for start, duration in stalls:
            for sign, edge in ((1.0, start), (-1.0, start + duration)):    # the stop
                value, slope, _, integral = smoothstep((t - edge) / STALL_RAMP)
                tau -= sign * STALL_RAMP * integral
                w -= sign * value
                dw -= sign * slope / STALL_RAMP
            catch_up = STALL_CATCH_UP * duration                           # the lag made up
            value, slope, curvature, _ = smoothstep((t - start - duration) / catch_up)
            tau += duration * value
            w += duration / catch_up * slope
            dw += duration / catch_up ** 2 * curvature
        angle, rate, accel = motion(tau)
        return angle, rate * w[:, None], accel * (w ** 2)[:, None] + rate * dw[:, None]

    return state


class GimbalRates:
    """Mixin for motions that carry ``gimbal_outer_rate`` and ``gimbal_inner_rate`` (rad/s):
    the double-axis gimbal under the IMU (outer about body z, inner about x,
    C_s_b = Rz(outer) Rx(inner)), turning at constant rates from zero at t = 0."""

    gimbal_outer_rate: float
    gimbal_inner_rate: float
    indexer = None
    """A single-axis azimuth indexer on the outer axis instead (``models.indexer``), where
    the motion has one."""
    gimbal_stalls: tuple[tuple[float, float], ...] = ()
    """Injected stalls (start s, duration s) of the gimbal, where the motion has the field
    (the scenario's [faults] gimbal_stalls; ``stalled``)."""

    @property
    def has_gimbal(self) -> bool:
        return (self.indexer is not None or self.gimbal_outer_rate != 0.0
                or self.gimbal_inner_rate != 0.0)

    def check_indexer(self) -> None:
        """ValueError if an indexer and constant gimbal rates are both given."""
        if self.indexer is not None and (self.gimbal_outer_rate or self.gimbal_inner_rate):
            raise ValueError("motion: with an [indexer] the gimbal rates "
                             "(gimbal_outer_rate_deg_s, gimbal_inner_rate_deg_s) must be 0")

    def gimbal_angles(self, t: np.ndarray) -> np.ndarray:
        """Gimbal angles (N, 2) rad (outer, inner) at times t (N,) s."""
        t = np.asarray(t, dtype=float)
        return np.stack([self.gimbal_outer_rate * t, self.gimbal_inner_rate * t], -1)

    def gimbal_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The gimbal's motion (``GimbalMotion``) at times t (N,) s: the constant rates,
        with the motion's gimbal stalls (fault injection, ``stalled``)."""
        return stalled(self._constant_rates, self.gimbal_stalls)(t)

    def _constant_rates(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        zeros = np.zeros((t.size, 2))
        rates = np.array([self.gimbal_outer_rate, self.gimbal_inner_rate])
        return self.gimbal_angles(t), zeros + rates, zeros

    def expected_gimbal_angles(self, t: np.ndarray) -> np.ndarray:
        """The angles (N, 2) rad a pipeline expects the encoders to read (less their
        offsets) at times t (N,) s, from the commands alone: the constant rates, or the
        indexer servo's response to its command on a fixed base (MuJoCo's servo without
        the hull's excitation, once per process; the inner axis at rest). A stalled
        gimbal falls behind them (``estimators.screen.screen_gimbal``)."""
        t = np.asarray(t, dtype=float)
        if self.indexer is None:
            return self.gimbal_angles(t)
        from aligngym.models.indexer import indexer_run
        return np.stack([indexer_run(self.indexer, t).state(t)[0], np.zeros(t.size)], -1)


def gimbal_C_s_b(angles: np.ndarray) -> np.ndarray:
    """C_s^b (..., 3, 3) = Rz(outer) Rx(inner) of the double-axis gimbal at angles (..., 2)
    rad (outer, inner)."""
    return rot_z(angles[..., 0]) @ rot_x(angles[..., 1])


def gimbal_rate_in_sensor(angle_rates: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """omega_bs^s (..., 3) rad/s of the double-axis gimbal from its angle rates (..., 2)
    rad/s (outer, inner) at inner angles (...) rad:
    omega_bs^s = Rx(inner)^T [0, 0, outer_rate] + [inner_rate, 0, 0]."""
    outer_rate, inner_rate = angle_rates[..., 0], angle_rates[..., 1]
    return np.stack([inner_rate, np.sin(inner) * outer_rate, np.cos(inner) * outer_rate], -1)


# Sensors every world's MJCF declares, in this order, on site "imu" and body "carrier".
IMU_SENSORS_MJCF = """
  <sensor>
    <gyro name="imu_gyro" site="imu"/>
    <accelerometer name="imu_accel" site="imu"/>
    <framepos name="imu_pos" objtype="site" objname="imu"/>
    <framequat name="imu_quat" objtype="site" objname="imu"/>
    <framelinvel name="imu_linvel" objtype="site" objname="imu"/>
    <framequat name="carrier_quat" objtype="xbody" objname="carrier"/>
  </sensor>
"""


def skip_sensors(model: "mujoco.MjModel") -> None:
    """Stop MuJoCo computing the declared sensors at each step (``mjDSBL_SENSOR``). The
    dynamic worlds record qpos and qvel and derive the IMU from them
    (``discrete_imu``), so their sensor stage, the accelerometer's post-constraint
    pass above all, is wasted: skipping it leaves the motion bit for bit the same and
    saves about a fifth of the car's step."""
    import mujoco
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR.value


# Optional sensors of a GNSS antenna on site "antenna" (read where the MJCF declares them).
ANTENNA_SENSORS_MJCF = """
  <sensor>
    <framepos name="antenna_pos" objtype="site" objname="antenna"/>
    <framelinvel name="antenna_linvel" objtype="site" objname="antenna"/>
  </sensor>
"""


KINEMATIC_ARMATURE = 1e9
"""Armature of the kinematic twin's joints (kg m^2 or kg); its bodies weigh 1e-12 kg."""


def kinematic_twin(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of model whose forward dynamics follow an applied generalised force
    qfrc = KINEMATIC_ARMATURE qacc exactly: bodies of 1e-12 kg and 1e-15 kg m^2, joints
    of armature KINEMATIC_ARMATURE, constraints, contacts, springs, dampers, actuators and
    warm starts off, Euler integration (the step's result is not used)."""
    import mujoco
    twin = copy.deepcopy(model)
    twin.body_mass[1:] = 1e-12
    twin.body_inertia[1:] = 1e-15
    twin.dof_armature[:] = KINEMATIC_ARMATURE
    bits = mujoco.mjtDisableBit
    for flag in (bits.mjDSBL_CONSTRAINT, bits.mjDSBL_CONTACT, bits.mjDSBL_EQUALITY,
                 bits.mjDSBL_FRICTIONLOSS, bits.mjDSBL_LIMIT, bits.mjDSBL_SPRING,
                 bits.mjDSBL_DAMPER, bits.mjDSBL_ACTUATION, bits.mjDSBL_WARMSTART):
        twin.opt.disableflags |= flag.value
    twin.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER.value
    return twin


ROLLOUT_THREADS = max(1, min(4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                               else os.cpu_count() or 1))
"""Threads of the prescribed worlds' sensor rollout."""


class PrescribedWorld(ABC):
    """A MuJoCo model whose joints follow analytic trajectories."""

    gimbal_joints: tuple[str, str] | None = None

    def __init__(self, mjcf: str) -> None:
        import mujoco
        self.model = mujoco.MjModel.from_xml_string(mjcf)
        self.data = mujoco.MjData(self.model)
        self._twin = kinematic_twin(self.model)
        names = [self.model.sensor(i).name for i in range(self.model.nsensor)]
        self._adr = {name: (self.model.sensor(name).adr[0], self.model.sensor(name).dim[0])
                     for name in ("imu_gyro", "imu_accel", "imu_pos", "imu_quat",
                                  "imu_linvel", "carrier_quat", "antenna_pos",
                                  "antenna_linvel") if name in names}
        self._gimbal_qpos = ([self.model.joint(j).qposadr[0] for j in self.gimbal_joints]
                             if self.gimbal_joints else None)

    @abstractmethod
    def joint_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Analytic (qpos, qvel, qacc) at times t (N,) s: (N, nq), (N, nv), (N, nv)."""

    def sample(self, t: np.ndarray) -> WorldSamples:
        """Run MuJoCo at times t (N,) s and read the IMU kinematics."""
        import mujoco
        t = np.asarray(t, dtype=float)
        qpos, qvel, qacc = self.joint_state(t)
        m, twin = self.model, self._twin
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        state = np.zeros((t.size, mujoco.mj_stateSize(twin, full)))
        state[:, 0] = t                        # FULLPHYSICS: time, qpos, qvel, ...
        state[:, 1:1 + m.nq] = qpos
        state[:, 1 + m.nq:1 + m.nq + m.nv] = qvel
        force = (KINEMATIC_ARMATURE * qacc)[:, None, :]
        threads = [mujoco.MjData(twin) for _ in range(min(ROLLOUT_THREADS, t.size))]
        from mujoco import rollout
        _, sensordata = rollout.rollout(twin, threads, state, force, nstep=1,
                                        control_spec=mujoco.mjtState.mjSTATE_QFRC_APPLIED.value)
        sensordata = sensordata[:, 0]

        def read(name: str) -> np.ndarray:
            adr, dim = self._adr[name]
            return sensordata[:, adr:adr + dim]

        q_s_t = read("imu_quat")
        # MuJoCo's accelerometer reads C_t_s (a - g_model); recover the kinematic a_t.
        a_t = quat_rotate(q_s_t, read("imu_accel")) + m.opt.gravity
        gimbal = (qpos[:, self._gimbal_qpos] if self._gimbal_qpos is not None
                  else np.zeros((t.size, 2)))
        antenna = ((read("antenna_pos"), read("antenna_linvel"))
                   if "antenna_pos" in self._adr else (None, None))
        # Views into the rollout's fresh output (no copies: 6 strided copies cost 18 ms).
        return WorldSamples(t=t, r_t=read("imu_pos"), v_t=read("imu_linvel"), a_t=a_t,
                            q_s_t=q_s_t, q_b_t=read("carrier_quat"),
                            omega_ts_s=read("imu_gyro"), gimbal_angles=gimbal,
                            antenna_r_t=antenna[0], antenna_v_t=antenna[1])


# --- dynamic worlds: exact IMU increments of MuJoCo's discrete motion ------------------

@dataclass
class DiscreteRun:
    """Recorded discrete motion of a MuJoCo free body (the carrier) at the physics steps.

    t (n+1,) s; pos (n+1, 3) chassis origin in the plane; quat (n+1, 4) chassis to
    plane; vel (n+2, 3) world velocity of the chassis origin over each step (vel[k] moves
    the car from t_{k-1} to t_k; vel[0] is the initial state); omega (n+2, 3) body rate,
    same indexing; imu_offset_b (3,) m: the IMU's point on the carrier; wheel_angles
    (n+1, 4) rad (fl, fr, rl, rr, unwrapped) and cross_track (n+1,) m for a car; gimbal:
    the gimbal's simulated motion where MuJoCo drives it (a servo), else None.
    """

    dt: float
    t: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    vel: np.ndarray
    omega: np.ndarray
    imu_offset_b: np.ndarray
    wheel_angles: np.ndarray | None = None
    cross_track: np.ndarray | None = None
    gimbal: GimbalMotion | None = None
    qpos: np.ndarray | None = None
    """(n+1, nq): every joint at every step (steering and suspension included), for
    pictures; None where not recorded."""

    def point_kinematics(self, r_b: np.ndarray, index: np.ndarray | slice = slice(None)
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Plane position (m) and velocity (m/s) of the chassis point r_b (3,) m at sample
        times, in the truth's continuous-motion convention (see ``discrete_imu``): the
        origin's velocity changes linearly over each step, so its path lags MuJoCo's
        positions by (vel[k] - vel[0]) dt / 2; the body rate over step k is omega[k+1]."""
        R = quat_to_dcm(self.quat[index])
        vel = self.vel[:-1][index]
        origin = self.pos[index] - (vel - self.vel[0]) * self.dt / 2.0
        r_b = np.asarray(r_b, dtype=float)
        return (origin + np.einsum("nij,j->ni", R, r_b),
                vel + np.einsum("nij,nj->ni", R, cross(self.omega[1:][index], r_b)))

    def imu_trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        """The IMU point's truth: velocity (n+1, 3) m/s from ``point_kinematics`` at the
        samples, changing linearly over each step (constant acceleration), and the
        position (n+1, 3) m that integrates it exactly (trapezoid) from MuJoCo's at t0."""
        site, v_site = self.point_kinematics(self.imu_offset_b)
        steps = 0.5 * (v_site[:-1] + v_site[1:]) * self.dt
        return site[0] + np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)]), v_site

    def imu_increments(self, omega_ie_t: np.ndarray, gravity_t: np.ndarray,
                       gimbal: GimbalMotion | None = None) -> tuple[np.ndarray, np.ndarray]:
        """IMU increments per physics step (``discrete_imu``): dtheta, dv (n, 3)."""
        return discrete_imu(self, self.imu_trajectory()[1], omega_ie_t, gravity_t, gimbal)


def rotation_integral(omega: np.ndarray, dt: float) -> np.ndarray:
    """E = integral_0^dt exp(-[omega x] tau) dtau (..., 3, 3) for a constant rate (..., 3)."""
    w = np.linalg.norm(omega, axis=-1)[..., None, None]
    K = skew(omega)
    th = w * dt
    small = w < 1e-6
    safe = np.where(small, 1.0, w)
    a = np.where(small, dt * dt / 2 - w * w * dt ** 4 / 24, (1 - np.cos(th)) / safe ** 2)
    b = np.where(small, dt ** 3 / 6 - w * w * dt ** 5 / 120, (dt - np.sin(th) / safe) / safe ** 2)
    return dt * np.eye(3) - a * K + b * (K @ K)


def to_sensor(t: np.ndarray, omega_ib_b: np.ndarray, f_b: np.ndarray,
              gimbal: GimbalMotion | None) -> tuple[np.ndarray, np.ndarray]:
    """Body-axis inertial rate and specific force (N, 3) at times t (N,) s to the axes of
    the IMU on the gimbal (C_s_b = Rz(outer) Rx(inner), plus the gimbal's own rate
    omega_bs^s): omega_is^s and f^s (N, 3). No gimbal (None): unchanged."""
    if gimbal is None:
        return omega_ib_b, f_b
    angles, rates, _ = gimbal(t)
    C_s_b = gimbal_C_s_b(angles)
    return (np.einsum("...ji,...j->...i", C_s_b, omega_ib_b)
            + gimbal_rate_in_sensor(rates, angles[:, 1]),
            np.einsum("...ji,...j->...i", C_s_b, f_b))


def discrete_imu(run: DiscreteRun, v_site: np.ndarray, omega_ie_t: np.ndarray,
                 gravity_t: np.ndarray, gimbal: GimbalMotion | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """IMU increments per physics step, consistent with the recorded discrete motion.

    The IMU sits at the carrier point r = imu_offset_b, fixed to it (sensor = body axes)
    or on the double-axis gimbal moving as ``gimbal`` (``GimbalMotion``; C_s_b =
    Rz(outer) Rx(inner)). Over step k MuJoCo turns the carrier at the
    constant body rate omega = omega[k+1]: the attitude is exact. MuJoCo changes the
    velocities at once at each step; a strapdown (continuous motion) would integrate such
    jumps in the wrong frame (1/2 omega x dv per step: ~0.1 mm/s per s in a car's turn,
    cm/s on a ship's 33 m lever arm), so the truth moves the IMU point with a constant
    acceleration a_k over each step, between its velocities at the samples
    (``DiscreteRun.imu_trajectory``, whose velocities v_site (n+1, 3) are passed in).
    Per step, in body axes:
    omega_ib = omega + C_t_b(tau) omega_ie,  f_b = C_t_b(tau) (a_k + 2 omega_ie x v - g),
    C_t_b(tau) = exp(-[omega x] tau) R_k^T, g the true gravity at the step (gravity_t
    (n, 3)). Without a gimbal the integrals are closed-form (the rotation integral E); with
    one, Simpson's rule in sensor axes (the gimbal turns < 1e-3 rad per step, error
    ~1e-15; a smooth gimbal motion is assumed). Returns dtheta (n, 3) rad and dv (n, 3) m/s in the sensor frame.
    """
    dt = run.dt
    R = quat_to_dcm(run.quat)                  # (n+1, 3, 3) carrier to plane at t_k
    Rt = np.swapaxes(R[:-1], -1, -2)
    w = run.omega[1:-1]                        # (n, 3) rate over step k
    force_t = ((v_site[1:] - v_site[:-1]) / dt
               + 2.0 * cross(omega_ie_t, 0.5 * (v_site[1:] + v_site[:-1])) - gravity_t)
    if gimbal is None:
        E = rotation_integral(w, dt)           # (n, 3, 3)
        dtheta = w * dt + np.einsum("nij,j->ni", E @ Rt, omega_ie_t)
        return dtheta, np.einsum("nij,nj->ni", E @ Rt, force_t)
    t0 = run.t[:-1]
    dtheta = np.zeros_like(w)
    dv = np.zeros_like(w)
    for tau, weight in ((0.0, dt / 6), (dt / 2, 4 * dt / 6), (dt, dt / 6)):
        C_t_b = rotvec_to_dcm(-w * tau) @ Rt
        omega_b = w + np.einsum("nij,j->ni", C_t_b, omega_ie_t)
        f_b = np.einsum("nij,nj->ni", C_t_b, force_t)
        rate, force = to_sensor(t0 + tau, omega_b, f_b, gimbal)
        dtheta += weight * rate
        dv += weight * force
    return dtheta, dv


# Gauss-Legendre nodes (fractions of a step) and weights on [0, 1].
_GAUSS2 = (0.5 - np.sqrt(3.0) / 6.0, 0.5 + np.sqrt(3.0) / 6.0)
_GAUSS3 = ((0.5 - np.sqrt(0.15), 5.0 / 18.0), (0.5, 8.0 / 18.0),
           (0.5 + np.sqrt(0.15), 5.0 / 18.0))


class SmoothRun:
    """MuJoCo's discrete motion as the smooth motion it samples: the truth of a floating
    hull, whose rates MuJoCo holds constant over each step.

    A strapdown reads a piecewise-constant rate as spurious coning (h^2 / 12 omega x
    omega_dot per unit time: 0.46 arcsec over 600 s on the wave-driven ship with its
    gimbal at 2 ms steps); real hulls turn smoothly. Here the body rate is the derivative
    of a quintic spline through the summed rotation increments, Theta_k, whose steps are
    MuJoCo's rotation vectors omega[k+1] h less the coning of the smooth rate itself
    (fourth-order Magnus, ~1e-12 rad a step), so that each step turns as MuJoCo's did;
    the carrier origin follows a quintic spline through MuJoCo's positions (its mean
    velocity over each step is MuJoCo's). Attitudes integrate the smooth rotations from
    MuJoCo's first (``quat``); the IMU increments are Gauss-Legendre integrals (3 nodes a
    step; the quadrature is exact to ~1e-15) of the smooth rate and specific force. Within
    a step the attitude is exp of the rate's integral, without the step's coning (~1e-12
    rad; measured against MuJoCo's sensors: 6e-16 rad and 3e-11 m/s per 10 ms).
    """

    def __init__(self, run: DiscreteRun) -> None:
        from scipy.interpolate import make_interp_spline   # lazy: reading a scenario stays light
        self.run = run
        self.dt = run.dt
        self.t = run.t
        n = run.t.size - 1
        turn = run.omega[1:n + 1] * run.dt       # MuJoCo's rotation vector of each step
        coning = np.zeros_like(turn)
        for _ in range(2):   # the rate's integral is the turn minus its own coning
            self._theta = make_interp_spline(
                run.t, np.concatenate([np.zeros((1, 3)), np.cumsum(turn - coning, 0)]), k=5)
            previous, coning = coning, self._coning()
        self._origin = make_interp_spline(run.t, run.pos, k=5)
        step = turn - previous + coning
        self.quat = quat_cumprod(np.concatenate([run.quat[:1], rotvec_to_quat(step)]))
        self.cross_track = run.cross_track
        self.wheel_angles = run.wheel_angles
        self.gimbal = run.gimbal

    def _coning(self) -> np.ndarray:
        """Rotation vector of each step minus the rate's integral (n, 3) rad: the
        fourth-order Magnus term sqrt(3) / 12 h^2 omega(t_a) x omega(t_b) at the two
        Gauss nodes."""
        t0, h = self.t[:-1], self.dt
        w_a, w_b = (self._theta(t0 + c * h, 1) for c in _GAUSS2)
        return np.sqrt(3.0) / 12.0 * h * h * cross(w_a, w_b)

    def _attitude(self, t: np.ndarray, k: np.ndarray) -> np.ndarray:
        """C_b_t (..., 3, 3) at times t within steps k (t_k <= t <= t_k+1)."""
        turn = self._theta(t) - self._theta(self.t[k])
        return quat_to_dcm(self.quat[k]) @ rotvec_to_dcm(turn)

    def _point(self, t: np.ndarray, k: np.ndarray, r_b: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Carrier attitude C_b_t, body rate omega_tb^b (rad/s) and the plane position (m),
        velocity (m/s) and acceleration (m/s^2) of carrier point r_b at times t."""
        R = self._attitude(t, k)
        w, w_dot = self._theta(t, 1), self._theta(t, 2)
        w_r = cross(w, r_b)
        position = self._origin(t) + np.einsum("...ij,j->...i", R, r_b)
        velocity = self._origin(t, 1) + np.einsum("...ij,...j->...i", R, w_r)
        accel = self._origin(t, 2) + np.einsum("...ij,...j->...i", R,
                                               cross(w_dot, r_b) + cross(w, w_r))
        return R, w, position, velocity, accel

    def point_kinematics(self, r_b: np.ndarray, index: np.ndarray | slice = slice(None)
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Plane position (m) and velocity (m/s) of the carrier point r_b (3,) m at the
        samples t[index]."""
        k = np.arange(self.t.size)[index]
        _, _, position, velocity, _ = self._point(self.t[k], k,
                                                  np.asarray(r_b, dtype=float))
        return position, velocity

    def imu_trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        """The IMU point's position (n+1, 3) m and velocity (n+1, 3) m/s at the samples."""
        return self.point_kinematics(self.run.imu_offset_b)

    def imu_increments(self, omega_ie_t: np.ndarray, gravity_t: np.ndarray,
                       gimbal: GimbalMotion | None = None,
                       chunk: int = 20000) -> tuple[np.ndarray, np.ndarray]:
        """IMU increments per physics step in sensor axes: dtheta (n, 3) rad and dv (n, 3)
        m/s, f = a + 2 omega_ie x v - g with g the true gravity per step (gravity_t
        (n, 3), plane axes); the gimbal as in ``discrete_imu``."""
        n = self.t.size - 1
        r_b = np.asarray(self.run.imu_offset_b, dtype=float)
        dtheta, dv = np.zeros((n, 3)), np.zeros((n, 3))
        for start in range(0, n, chunk):
            k = np.arange(start, min(start + chunk, n))
            for node, weight in _GAUSS3:
                t = self.t[k] + node * self.dt
                R, w, _, velocity, accel = self._point(t, k, r_b)
                force_t = accel + 2.0 * cross(omega_ie_t, velocity) - gravity_t[k]
                omega_b = w + np.einsum("nji,j->ni", R, omega_ie_t)
                f_b = np.einsum("nji,nj->ni", R, force_t)
                rate, force = to_sensor(t, omega_b, f_b, gimbal)
                dtheta[k] += weight * self.dt * rate
                dv[k] += weight * self.dt * force
        return dtheta, dv
