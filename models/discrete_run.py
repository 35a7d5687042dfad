"""Dynamic worlds' truth: exact IMU increments of MuJoCo's discrete motion.

The dynamic worlds (the car, the wave-driven ship) record MuJoCo's physics steps
(``DiscreteRun``: the carrier's position (m), attitude and velocity (m/s) in the
earth-fixed plane frame t, its body rate in rad/s). ``discrete_imu`` integrates the IMU
increments of that discrete motion exactly; ``SmoothRun`` takes the smooth motion
MuJoCo's steps sample instead (a floating hull). Increments are per physics step in the
sensor frame s, dtheta in rad and dv in m/s, through the double-axis gimbal where there
is one (``models.gimbal``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.models.attitude import (cross, quat_cumprod, quat_to_dcm, rotvec_to_dcm,
                                      rotvec_to_quat, skew)
from aligngym.models.gimbal import GimbalMotion, gimbal_C_s_b, gimbal_rate_in_sensor


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
