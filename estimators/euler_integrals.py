"""The open-loop static-base INS of seed 002's alignment (the marble platform: the position
is known and not navigated) and its filter-independent integrals over the filter epochs,
for ``euler_large``'s Euler-error model (ALGORITHMS 3.1; SPEC 4.4).

``static_base_ins`` strapdowns IMU increments (b = RFU) into the computed ENU frame p:
attitude C_b^p, epoch-mean specific force f^p (m/s^2), horizontal velocity v_EN (m/s),
without a Coriolis term (the true IMU is at rest). ``static_base_integrals`` splits the
same arithmetic so that any initial attitude C_b^p(0), including one corrected by
feedback, follows exactly; ``stack_integrals`` and ``stack_ins_inputs`` batch episodes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.model import Epoch, at_epoch, stack_episodes
from aligngym.estimators.strapdown import compensate
from aligngym.models.attitude import (cross, dcm_to_quat, quat_cumprod, quat_mul, quat_rotate,
                                      quat_to_dcm, rotvec_to_quat)
from aligngym.models.earth import OMEGA_IE


@dataclass(frozen=True)
class StaticInsInputs:
    """A batch of static-base INS runs sampled at the filter epochs (leading axis B).

    t: (K+1,) s at the epoch boundaries from 0. C_b_p: (B, K+1, 3, 3) computed attitude
    (b = RFU to p = computed ENU) at the boundaries; C_b_p_mid: (B, K, 3, 3) at
    mid-epoch. f_p: (B, K, 3) m/s^2, computed specific force C_b^p f~^b averaged over
    each epoch (ENU). v_EN: (B, K+1, 2) m/s, INS horizontal velocity at the boundaries
    (= the velocity error, the true IMU being at rest). lat: (B,) rad; h: (B,) m.
    """

    t: np.ndarray
    C_b_p: np.ndarray
    C_b_p_mid: np.ndarray
    f_p: np.ndarray
    v_EN: np.ndarray
    lat: np.ndarray
    h: np.ndarray

    @property
    def step(self) -> float:
        """Filter epoch, s."""
        return float(self.t[1] - self.t[0])


def _earth_rotation_quat(omega: np.ndarray, t: np.ndarray) -> np.ndarray:
    """q of exp(-[omega x] t): the n frame's rotation over t (s), (len(t), 4)."""
    return rotvec_to_quat(-np.asarray(t, dtype=float)[:, None] * omega[None, :])


def static_base_ins(dtheta: np.ndarray, dv: np.ndarray, dt: float, C_b_p0: np.ndarray,
                    lat: float, h: float, epoch: float) -> StaticInsInputs:
    """Open-loop strapdown of a static-base alignment (002's marble platform: the
    position is known and not navigated) from IMU increments, sampled per epoch.

    dtheta (M, 3) rad, dv (M, 3) m/s: increments in b (RFU); dt: IMU interval, s;
    C_b_p0 (3, 3): initial computed attitude; lat rad, h m: the known position; epoch:
    filter step, s (a whole number of IMU intervals; a tail shorter than an epoch is
    dropped).

    Attitude: C_b^p(t+dt) = exp(-[omega_ie^n x] dt) C_b^p(t) exp([phi x]), phi = dtheta
    with the two-sample coning term (zero on a static base); omega_ie^n = [0, Omega cos L,
    Omega sin L], no transport rate. Because the n-frame and body rotations multiply on
    opposite sides they commute, and C_b^p(t_m) = exp(-[omega_ie x] t_m) C_b^p0
    prod_{i<=m} exp([phi_i x]), accumulated as a vectorised quaternion scan.

    Velocity: v_dot = C_b^p f~ + g^n, g^n = [0, 0, -g(L, h)], with NO Coriolis (nor
    transport) term. The true IMU is at rest (v^n = 0), so the Coriolis acceleration of
    the true motion is zero, and 002's static model (ALGORITHMS (3.5)) has no Coriolis
    term: without it the INS velocity is exactly the velocity error dv of (3.5). (With
    it, the open-loop velocity of tens of m/s from a large level error would couple
    through 2 omega_ie x v into the measurement, which the model does not describe.)
    The increment over one sample in p is C_b^p(t_{i-1}) dv_b - 1/2 [omega_ie dt x]
    C_b^p(t_{i-1}) dv, dv_b with the rotation/sculling compensation.
    """
    dtheta = np.asarray(dtheta, dtype=float)
    dv = np.asarray(dv, dtype=float)
    per_epoch = int(round(epoch / dt))
    if per_epoch < 1 or abs(per_epoch * dt - epoch) > 1e-9 * max(epoch, 1.0):
        raise ValueError(f"epoch {epoch} s must be a whole number of IMU intervals {dt} s")
    M = dtheta.shape[0]
    K = M // per_epoch
    if K < 1:
        raise ValueError(f"{M} IMU samples are shorter than one epoch of {epoch} s")
    M = K * per_epoch
    dtheta, dv = dtheta[:M], dv[:M]
    omega = np.array([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    # g^n = [0, 0, -g(L, h)] (models.earth.normal_gravity) has no E, N components: the
    # horizontal velocity returned here does not depend on it.

    phi, dv_b = compensate(dtheta[None], dv[None])
    phi, dv_b = phi[0], dv_b[0]
    # Body part: Q_m = prod_{i<=m} exp([phi_i x]), Q_0 = I.
    q_body = np.concatenate([[[1.0, 0.0, 0.0, 0.0]], quat_cumprod(rotvec_to_quat(phi))])
    q0 = dcm_to_quat(np.asarray(C_b_p0, dtype=float))
    t_s = dt * np.arange(M + 1)
    # q_b^p(t_m) = q_E(t_m) q0 Q_m (M+1, 4).
    q_bp = quat_mul(_earth_rotation_quat(omega, t_s), quat_mul(q0[None], q_body))

    # Velocity increments in p per sample (M, 3); the n-frame rotation over the sample.
    dv_p = quat_rotate(q_bp[:-1], dv_b)
    dv_p -= 0.5 * dt * cross(omega, quat_rotate(q_bp[:-1], dv))
    V_f = np.concatenate([np.zeros((1, 3)), np.cumsum(dv_p, axis=0)])

    idx = per_epoch * np.arange(K + 1)
    t = dt * idx
    # Mid-epoch attitude: the sample at the midpoint, or half of the next sample's
    # rotation when an epoch has an odd number of samples.
    j = idx[:-1] + per_epoch // 2
    if per_epoch % 2 == 0:
        q_mid = q_bp[j]
    else:
        t_mid = t[:-1] + 0.5 * epoch
        q_mid = quat_mul(_earth_rotation_quat(omega, t_mid), quat_mul(
            q0[None], quat_mul(q_body[j], rotvec_to_quat(0.5 * phi[j]))))
    f_p = np.diff(V_f[idx], axis=0) / epoch
    return StaticInsInputs(t=t, C_b_p=quat_to_dcm(q_bp[idx])[None],
                           C_b_p_mid=quat_to_dcm(q_mid)[None], f_p=f_p[None],
                           v_EN=V_f[idx, :2][None], lat=np.array([float(lat)]),
                           h=np.array([float(h)]))


@dataclass(frozen=True)
class StaticBaseIntegrals:
    """Filter-independent integrals of the static-base INS of ``static_base_ins`` over
    the epochs, for a batch of B episodes: any filter's INS with initial attitude C0
    (B, 3, 3), including one corrected by feedback, follows from them exactly.

    The INS attitude is C_b^p(t) = E(t) C0 Q(t), with Q(t) the product of the body
    increments (shared) and E(t) = exp(-[omega_ie x] t) = I + s(t) K + c(t) K^2 the n-frame
    rotation (K = [n x], n the unit earth-rate axis, s = -sin(Omega t), c = 1 - cos(Omega
    t)). The epoch's specific-force integral int C_b^p f dt (with the rotation term of
    ``static_base_ins``) is then C0 U0 + K C0 U1 + K^2 C0 U2.

    t (K+1,) s; K_axis (B, 3, 3); Q (B, K+1, 3, 3) and Q_mid (B, K, 3, 3); t_mid (K,) s;
    U (B, K, 3, 3): U0, U1, U2 (m/s) stacked on axis 2; lat (B,) rad; h (B,) m. Gravity
    has no E, N component, so the horizontal velocity needs none.
    """

    t: np.ndarray
    K_axis: np.ndarray
    Q: np.ndarray
    Q_mid: np.ndarray
    t_mid: np.ndarray
    U: np.ndarray
    lat: np.ndarray
    h: np.ndarray

    @property
    def step(self) -> float:
        return float(self.t[1] - self.t[0])

    @property
    def batch(self) -> int:
        return self.Q.shape[0]

    def earth_rotation(self, t: float | np.ndarray) -> np.ndarray:
        """E(t) (B, 3, 3) at t s: one time, or one per episode (B,)."""
        t = np.asarray(t)[..., None, None]
        s, c = -np.sin(OMEGA_IE * t), 1.0 - np.cos(OMEGA_IE * t)
        K = self.K_axis
        return np.eye(3) + s * K + c * (K @ K)

    def attitude(self, C0: np.ndarray, k: Epoch) -> np.ndarray:
        """C_b^p (B, 3, 3) at boundary k of the INS started from C0 (B, 3, 3)."""
        return self.earth_rotation(self.t[k]) @ C0 @ at_epoch(self.Q, k)

    def attitude_mid(self, C0: np.ndarray, k: Epoch) -> np.ndarray:
        """C_b^p (B, 3, 3) at the middle of epoch k."""
        return self.earth_rotation(self.t_mid[k]) @ C0 @ at_epoch(self.Q_mid, k)

    def delta_v(self, C0: np.ndarray, k: Epoch) -> np.ndarray:
        """int C_b^p f~ dt over epoch k (B, 3), m/s, ENU (gravity not included)."""
        K, U = self.K_axis, at_epoch(self.U, k)
        KC = K @ C0
        return (np.einsum("bij,bj->bi", C0, U[:, 0]) + np.einsum("bij,bj->bi", KC, U[:, 1])
                + np.einsum("bij,bj->bi", K @ KC, U[:, 2]))


def static_base_integrals(dtheta: np.ndarray, dv: np.ndarray, dt: float, lat: float,
                          h: float, epoch: float) -> StaticBaseIntegrals:
    """The ``StaticBaseIntegrals`` (batch of one) of IMU increments dtheta (M, 3) rad and
    dv (M, 3) m/s in b at interval dt (s), at the known position lat (rad), h (m), for
    filter epochs of ``epoch`` s (the arithmetic of ``static_base_ins``, split so that the
    initial attitude can change)."""
    dtheta = np.asarray(dtheta, dtype=float)
    dv = np.asarray(dv, dtype=float)
    per_epoch = int(round(epoch / dt))
    if per_epoch < 1 or abs(per_epoch * dt - epoch) > 1e-9 * max(epoch, 1.0):
        raise ValueError(f"epoch {epoch} s must be a whole number of IMU intervals {dt} s")
    K_epochs = dtheta.shape[0] // per_epoch
    if K_epochs < 1:
        raise ValueError(f"{dtheta.shape[0]} IMU samples are shorter than one epoch")
    M = K_epochs * per_epoch
    dtheta, dv = dtheta[:M], dv[:M]
    axis = np.array([0.0, np.cos(lat), np.sin(lat)])
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    phi, dv_b = compensate(dtheta[None], dv[None])
    phi, dv_b = phi[0], dv_b[0]
    q_body = np.concatenate([[[1.0, 0.0, 0.0, 0.0]], quat_cumprod(rotvec_to_quat(phi))])
    t_s = dt * np.arange(M)
    s, c = -np.sin(OMEGA_IE * t_s)[:, None], (1.0 - np.cos(OMEGA_IE * t_s))[:, None]
    u = quat_rotate(q_body[:-1], dv_b)           # Q_m dv_b (M, 3)
    w = quat_rotate(q_body[:-1], dv)             # Q_m dv, for the rotation term
    half = 0.5 * dt * OMEGA_IE
    parts = np.stack([u, s * u - half * (1.0 - c) * w, c * u - half * s * w], 1)  # (M,3,3)
    U = parts.reshape(K_epochs, per_epoch, 3, 3).sum(1)
    idx = per_epoch * np.arange(K_epochs + 1)
    j = idx[:-1] + per_epoch // 2
    t = dt * idx
    if per_epoch % 2 == 0:
        q_mid = q_body[j]
    else:
        q_mid = quat_mul(q_body[j], rotvec_to_quat(0.5 * phi[j]))
    return StaticBaseIntegrals(
        t=t, K_axis=K[None], Q=quat_to_dcm(q_body[idx])[None],
        Q_mid=quat_to_dcm(q_mid)[None], t_mid=t[:-1] + 0.5 * epoch, U=U[None],
        lat=np.array([float(lat)]), h=np.array([float(h)]))


def stack_integrals(parts: list[StaticBaseIntegrals]) -> StaticBaseIntegrals:
    """One batch from several episodes' integrals (same time grid, else ValueError)."""
    return stack_episodes(parts, ("t", "t_mid"))


def stack_ins_inputs(inputs: list[StaticInsInputs]) -> StaticInsInputs:
    """One batch from several episodes' INS inputs (same time grid, else ValueError)."""
    return stack_episodes(inputs)
