"""Inertial-frame alignment of a swaying, rotating IMU (paper 003; ALGORITHMS.md 1.1, 2.1).

Frames: s = IMU sensor frame, s0 = s frozen at t0 (the paper's i_b0), b = hull body
(RFU), n = ENU at the known position, i = inertial frame equal to the earth frame at t0
with its x axis in the local meridian (003 eqs. 11-12).

The work is split so that everything that does not depend on a filter is computed once
per episode and shared by all filters (``body_frame_integrals``): the attitude of s
relative to s0, the integral of the specific force in s0 and the lever-arm velocity.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.strapdown import body_rate_at, compensate
from aligngym.models.attitude import (cross, quat_cumprod, quat_rotate, quat_to_dcm, rotvec_to_quat)
from aligngym.models.earth import OMEGA_IE, normal_gravity
from aligngym.models.gimbal import gimbal_C_s_b, gimbal_rate_in_sensor  # noqa: F401  (re-exported)


# --- earth rotation in the inertial frame ------------------------------------------------

def C_n_i(t: np.ndarray, lat: np.ndarray | float) -> np.ndarray:
    """C_n^i(t) = (C_e^n C_i^e(t))^T (003 eqs. 11-12) for time since t0 (s) and latitude
    (rad), broadcast against each other -> (..., 3, 3)."""
    t, lat = np.broadcast_arrays(np.asarray(t, dtype=float), np.asarray(lat, dtype=float))
    sL, cL = np.sin(lat), np.cos(lat)
    c, s = np.cos(OMEGA_IE * t), np.sin(OMEGA_IE * t)
    z = np.zeros_like(c)
    # Rows of C_n^i: E, N, U of n expressed in i.
    return np.stack([np.stack([-s, c, z], -1),
                     np.stack([-sL * c, -sL * s, cL], -1),
                     np.stack([cL * c, cL * s, sL], -1)], -1)


def gravity_velocity_i(t: np.ndarray, lat: np.ndarray | float, h: np.ndarray | float
                       ) -> np.ndarray:
    """V^i(t) = integral from t0 of -g^i: the specific-force velocity a still IMU senses in
    i (003 eq. 20), (..., 3) m/s; t (s since t0), lat (rad), h (m) broadcast together."""
    t, lat, h = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (t, lat, h)))
    g = normal_gravity(lat, h)
    w = OMEGA_IE
    return np.stack([g * np.cos(lat) / w * np.sin(w * t),
                     g * np.cos(lat) / w * (1.0 - np.cos(w * t)),
                     g * np.sin(lat) * t], -1)


def gravity_i(t: np.ndarray, lat: np.ndarray | float, h: np.ndarray | float) -> np.ndarray:
    """g^i(t) = C_n^i(t) [0, 0, -g], (..., 3) m/s^2 (arguments broadcast together)."""
    t, lat, h = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (t, lat, h)))
    return -normal_gravity(lat, h)[..., None] * C_n_i(t, lat)[..., :, 2]


# --- shared per-episode integrals --------------------------------------------------------

@dataclass(frozen=True)
class BodyFrameIntegrals:
    """One episode's filter-independent integrals at the IMU interval boundaries.

    t: (M+1,) s since t0. C_s_s0: (M+1, 3, 3) attitude of s relative to s0 (from the gyros).
    V_f: (M+1, 3) m/s, integral of C_s^s0 f~ (003 eq. 17). V_la: (M+1, 3) m/s, lever-arm
    velocity C_s^s0 (omega_ib^s x r^s) (ALGORITHMS 1.5, first term). Psi_cum: (M+1, 3, 3) s,
    running integral of C_s^s0 (trapezoid).
    """

    t: np.ndarray
    C_s_s0: np.ndarray
    V_f: np.ndarray
    V_la: np.ndarray
    Psi_cum: np.ndarray


def gimbal_rate_s(gimbal_angles: np.ndarray, dt: float, span: int = 10) -> np.ndarray:
    """omega_bs^s (N, 3) rad/s, the gimbal's rate from encoder angles (N, 2) rad (outer
    about b z, inner about x; C_s^b = Rz(outer) Rx(inner)). Rates are central differences
    over +-span samples, which averages encoder quantization down."""
    angles = np.asarray(gimbal_angles, dtype=float)
    n = angles.shape[0]
    span = max(1, min(span, (n - 1) // 2))
    rates = np.empty_like(angles)
    rates[span:-span] = (angles[2 * span:] - angles[:-2 * span]) / (2 * span * dt)
    rates[:span] = (angles[span] - angles[0]) / (span * dt)
    rates[-span:] = (angles[-1] - angles[-1 - span]) / (span * dt)
    return gimbal_rate_in_sensor(rates, angles[:, 1])


def body_frame_integrals(dtheta: np.ndarray, dv: np.ndarray, gimbal_angles: np.ndarray | None,
                         lever_arm_b: np.ndarray, dt: float) -> BodyFrameIntegrals:
    """Integrals of one episode from IMU increments (M, 3) and encoder angles (M+1, 2).

    gimbal_angles None means a strapdown IMU fixed to the hull (C_s^b = I).
    lever_arm_b: (3,) m, IMU position from the sway centre in the hull frame.
    """
    dtheta = np.asarray(dtheta, dtype=float)
    dv = np.asarray(dv, dtype=float)
    M = dtheta.shape[0]
    if not (np.all(np.isfinite(dtheta)) and np.all(np.isfinite(dv))):
        raise ValueError("IMU increments contain NaN or inf")
    phi, dv_b = compensate(dtheta[None], dv[None])
    steps = rotvec_to_quat(phi[0])
    q = np.empty((M + 1, 4))
    q[0] = [1.0, 0.0, 0.0, 0.0]
    q[1:] = quat_cumprod(steps)
    dV = quat_rotate(q[:-1], dv_b[0])
    V_f = np.concatenate([np.zeros((1, 3)), np.cumsum(dV, axis=0)])
    C = quat_to_dcm(q)
    Psi_cum = np.concatenate([np.zeros((1, 3, 3)),
                              np.cumsum(0.5 * dt * (C[:-1] + C[1:]), axis=0)])
    # Inertial rate at the boundaries: mean of the two adjacent intervals inside, linear
    # extrapolation at the ends (both O(T^2); a one-sided dtheta/T would be O(T) off,
    # ~5 cm/s of lever-arm velocity here).
    rate = np.empty((M + 1, 3))
    rate[1:-1] = (dtheta[:-1] + dtheta[1:]) / (2.0 * dt)
    rate[0] = (3.0 * dtheta[0] - dtheta[1]) / (2.0 * dt)
    rate[-1] = (3.0 * dtheta[-1] - dtheta[-2]) / (2.0 * dt)
    lever = np.asarray(lever_arm_b, dtype=float)
    if gimbal_angles is None:
        omega_ib_s, r_s = rate, np.broadcast_to(lever, rate.shape)
    else:
        angles = np.asarray(gimbal_angles, dtype=float)
        omega_ib_s = rate - gimbal_rate_s(angles, dt)
        C_s_b = gimbal_C_s_b(angles)
        r_s = np.einsum("nji,j->ni", C_s_b, lever)
    V_la = np.einsum("nij,nj->ni", C, cross(omega_ib_s, r_s))
    return BodyFrameIntegrals(t=np.arange(M + 1) * dt, C_s_s0=C, V_f=V_f, V_la=V_la,
                              Psi_cum=Psi_cum)


# --- coarse alignment (003 eqs. 10-22) ---------------------------------------------------

def nearest_rotation(C: np.ndarray) -> np.ndarray:
    """Closest proper rotation (Frobenius norm) to (..., 3, 3)."""
    U, _, Vt = np.linalg.svd(C)
    U[..., :, -1] *= np.sign(np.linalg.det(U @ Vt))[..., None]
    return U @ Vt


def triad(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Orthonormal triad (3, 3) with columns u1/|u1|, (u1 x u2)/|.|, and their cross."""
    a1 = u1 / np.linalg.norm(u1)
    a2 = cross(u1, u2)
    a2 = a2 / np.linalg.norm(a2)
    return np.stack([a1, a2, cross(a1, a2)], -1)


def coarse_alignment_ib0(integrals: BodyFrameIntegrals, lat: float, h: float,
                         t_k1: float, t_k2: float) -> np.ndarray:
    """Inertial-frame (i_b0) coarse alignment with lever-arm compensation.

    Returns C_s0^i (3, 3) from the velocity vectors at t_k1 < t_k2 (s) in both frames
    (003 eq. 22), in its orthonormal (TRIAD) form: the two vectors are nearly parallel
    (~2e-3 rad apart), so eq. 22's inverse amplifies any error in their cross product into
    every axis; the triad keeps it to the rotation about V(t_k1).
    V^ib0(t) = V_f(t) - [V_la(t) - V_la(t0)] (ALGORITHMS 1.5-1.6).
    """
    if not 0.0 < t_k1 < t_k2 <= integrals.t[-1] + 1e-9:
        raise ValueError(f"need 0 < t_k1 < t_k2 <= {integrals.t[-1]:g} s, got {t_k1}, {t_k2}")
    dt = integrals.t[1] - integrals.t[0]
    k1, k2 = int(round(t_k1 / dt)), int(round(t_k2 / dt))
    V_b = [integrals.V_f[k] - (integrals.V_la[k] - integrals.V_la[0]) for k in (k1, k2)]
    V_i = [gravity_velocity_i(integrals.t[k], lat, h) for k in (k1, k2)]
    return triad(*V_i) @ triad(*V_b).T


def attitude_from_inertial(C_s0_i: np.ndarray, integrals: BodyFrameIntegrals, index,
                           lat: float) -> np.ndarray:
    """C_s^n (..., 3, 3) at IMU boundary index (003 eq. 10): C_i^n(t) C_s0^i C_s^s0(t)."""
    t = integrals.t[index]
    return np.swapaxes(C_n_i(t, lat), -1, -2) @ C_s0_i @ integrals.C_s_s0[index]


def static_coarse_alignment(f_b: np.ndarray, omega_ib_b: np.ndarray, lat: float
                            ) -> np.ndarray:
    """Analytic coarse alignment on a static base: C_b^n (3, 3) from the mean specific force
    f_b (3,) m/s^2 and mean inertial rate omega_ib_b (3,) rad/s. The specific force (up)
    is the primary vector, the earth rate fixes the heading (TRIAD), so the level error is
    the accelerometer bias over g and the heading error the east drift over Omega cos L."""
    f_n = np.array([0.0, 0.0, 1.0])
    w_n = np.array([0.0, np.cos(lat), np.sin(lat)])
    return triad(f_n, w_n) @ triad(np.asarray(f_b, float), np.asarray(omega_ib_b, float)).T


# --- moving base: velocity-integration alignment (ALGORITHMS 1.2) --------------------------

def _body_integrals(dtheta: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """C_b^b0 (M+1, 3, 3) at the IMU boundaries of a window of increments (M, 3) and
    alpha (M+1, 3) = int_0^t C_b^b0 f dtau (coning and sculling compensated)."""
    phi, dv_b = compensate(dtheta[None], dv[None])
    q = quat_cumprod(np.concatenate([[[1.0, 0.0, 0.0, 0.0]], rotvec_to_quat(phi[0])]))
    C_b_b0 = quat_to_dcm(q)
    alpha = np.concatenate([np.zeros((1, 3)), np.cumsum(
        np.einsum("kij,kj->ki", C_b_b0[:-1], dv_b[0]), axis=0)])
    return C_b_b0, alpha


def _wahba(beta: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, float]:
    """The rotation C minimising sum |beta_k - C alpha_k|^2 (SVD) and the RMS residual."""
    U, _, Vt = np.linalg.svd(beta.T @ alpha)
    C = U @ np.diag([1.0, 1.0, 1.0 if np.linalg.det(U @ Vt) >= 0.0 else -1.0]) @ Vt
    return C, float(np.sqrt(np.mean(np.sum((beta - alpha @ C.T) ** 2, axis=-1))))


def velocity_aided_alignment(dtheta: np.ndarray, dv: np.ndarray, dt: float,
                             fix_index: np.ndarray, lat: np.ndarray, h: np.ndarray,
                             v_n: np.ndarray, lever_arm_b: np.ndarray | None = None
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Coarse alignment on a moving base from GNSS velocity (ALGORITHMS 1.10-1.12, 1.14).

    dtheta, dv (M, 3): the window's IMU increments (rad, m/s, body frame b) of interval
    dt (s); fix_index (K,) int: the IMU boundary (0..M) of each GNSS fix, the first at 0;
    lat (rad), h (m) (K,) and v_n (K, 3) m/s ENU: the fixes (the antenna's velocity when
    lever_arm_b (3,) m, from the IMU to the antenna in b, is given).

    C = C_b0^n0 solves beta(t_k) = C alpha(t_k) in the least-squares sense (SVD, Wahba):
    alpha(t) = int_0^t C_b^b0 f dtau (+ C_b^b0(t)(w(t) x l) - w(0) x l with a lever arm),
    beta(t) = C_n(t)^n0 v^n(t) - v^n(0) + int_0^t C_n^n0 (w_ie^n x v^n - g^n) dtau,
    C_n^n0 from the fixes' w_in (trapezoid rule between fixes). Returns C_b^n at the last
    fix (3, 3) and the fit's RMS residual (m/s).
    """
    from aligngym.models.attitude import rotvec_to_dcm
    from aligngym.models.earth import earth_rate_n, gravity_n, transport_rate_n

    fix_index = np.rint(np.asarray(fix_index, dtype=float)).astype(int)
    if fix_index.size < 3 or fix_index[0] != 0 or np.any(np.diff(fix_index) <= 0):
        raise ValueError("need >= 3 fixes at increasing IMU boundaries, the first at 0")
    C_b_b0, alpha_all = _body_integrals(dtheta, dv)
    alpha = alpha_all[fix_index]
    if lever_arm_b is not None:
        lever = cross(body_rate_at(dtheta, dt, fix_index), lever_arm_b)
        alpha = alpha + np.einsum("kij,kj->ki", C_b_b0[fix_index], lever) - lever[0]
    # C_n(t)^n0 and the integral, fix to fix.
    t = fix_index * dt
    w_ie = earth_rate_n(lat)
    w_in = w_ie + transport_rate_n(lat, h, v_n)
    integrand_n = cross(w_ie, v_n) - gravity_n(lat, h)
    K = fix_index.size
    C_n_n0 = np.empty((K, 3, 3))
    C_n_n0[0] = np.eye(3)
    integral = np.zeros((K, 3))
    for k in range(1, K):
        T = t[k] - t[k - 1]
        C_n_n0[k] = C_n_n0[k - 1] @ rotvec_to_dcm(0.5 * T * (w_in[k - 1] + w_in[k]))
        integral[k] = integral[k - 1] + 0.5 * T * (C_n_n0[k - 1] @ integrand_n[k - 1]
                                                   + C_n_n0[k] @ integrand_n[k])
    beta = np.einsum("kij,kj->ki", C_n_n0, v_n) - v_n[0] + integral
    C, residual = _wahba(beta, alpha)                                # C_b0^n0
    return C_n_n0[-1].T @ C @ C_b_b0[fix_index[-1]], residual


def odometer_aided_alignment(dtheta: np.ndarray, dv: np.ndarray, dt: float,
                             distance: np.ndarray, lat: float, h: float,
                             C_m_b: np.ndarray | None = None,
                             lever_arm_b: np.ndarray | None = None,
                             pair_interval: float = 1.0, iterations: int = 2
                             ) -> tuple[np.ndarray, float]:
    """Coarse alignment while driving, aided by the odometer (ALGORITHMS 1.13-1.14).

    dtheta, dv (M, 3): the window's IMU increments (rad, m/s, body frame b) of interval
    dt (s); distance (M+1,) m: the odometer's cumulative distance at the IMU boundaries;
    lat (rad), h (m): the (known) position, whose change over the window is neglected
    (omega_en = 0: C_n(t)^n0 = exp(t [w_ie x])); C_m_b: odometer (vehicle) axes to b, the
    nominal mounting (identity: forward = y); lever_arm_b (3,) m: the IMU from the
    odometer's point (the driven axle's centre) in b. The IMU's velocity is
    v^b = C_m^b [0, v, 0] + w^b x l^b, v the distance's and w the gyro's centred means
    over +-pair_interval / 2 (in a turn the lever arm is not negligible: 1.65 m ahead of
    the rear axle on a 100 m ring at 8 m/s is 0.13 m/s sideways).

    With v^b moved to the body side, alpha(t) = int C_b^b0 f - C_b^b0(t) v^b(t) + v^b(0)
    and beta(t) = -int C_n^n0 g^n + w_ie^n x C int C_b^b0 v^b (the Coriolis term with the
    previous estimate of C, ``iterations`` passes) give beta = C alpha at every
    pair_interval; C by SVD. The heading information is the earth's rotation only, as on
    a static base. Returns C_b^n at the window's end (3, 3) and the residual (m/s).
    """
    from aligngym.models.attitude import rotvec_to_dcm
    from aligngym.models.earth import earth_rate_n, gravity_n

    M = dtheta.shape[0]
    C_m_b = np.eye(3) if C_m_b is None else np.asarray(C_m_b, dtype=float)
    step = max(1, int(round(pair_interval / dt)))
    if M < 3 * step:
        raise ValueError(f"the window ({M * dt:g} s) must hold >= 3 pair intervals")
    C_b_b0, alpha_all = _body_integrals(dtheta, dv)
    t = np.arange(M + 1) * dt
    half = max(1, step // 2)
    ahead = np.minimum(np.arange(M + 1) + half, M)
    behind = np.maximum(np.arange(M + 1) - half, 0)
    span = (ahead - behind) * dt
    speed = (distance[ahead] - distance[behind]) / span
    v_b = speed[:, None] * C_m_b[:, 1]
    if lever_arm_b is not None:
        turned = np.concatenate([np.zeros((1, 3)), np.cumsum(dtheta, axis=0)])
        rate = (turned[ahead] - turned[behind]) / span[:, None]
        v_b = v_b + cross(rate, np.asarray(lever_arm_b, dtype=float))
    w_ie = earth_rate_n(lat)
    C_n_n0 = rotvec_to_dcm(t[:, None] * w_ie)
    g_n0 = np.einsum("kij,j->ki", C_n_n0, gravity_n(lat, h))
    body_v = np.einsum("kij,kj->ki", C_b_b0, v_b)                    # C_b^b0 v^b

    def cumulative(y: np.ndarray) -> np.ndarray:
        return np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * dt * (y[1:] + y[:-1]), 0)])

    pairs = np.arange(0, M + 1, step)
    alpha = (alpha_all - body_v + v_b[0])[pairs]
    gravity_part = -cumulative(g_n0)[pairs]
    displacement = cumulative(body_v)[pairs]                         # int C_b^b0 v^b
    C, residual = _wahba(gravity_part, alpha)
    for _ in range(iterations):
        beta = gravity_part + cross(w_ie, displacement @ C.T)
        C, residual = _wahba(beta, alpha)
    return C_n_n0[-1].T @ C @ C_b_b0[-1], residual
