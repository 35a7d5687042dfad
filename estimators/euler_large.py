"""Seed 002's large-misalignment model with Euler error angles on a static base
(ALGORITHMS 3.1, ENU/RFU restatement; SPEC 4.4), and the open-loop static-base INS it
runs on.

The computed navigation frame p is the INS's ENU estimate. The Euler error angles
alpha = [alpha_E, alpha_N, alpha_U] define C_p^n(alpha) = Rz(alpha_U) Rx(alpha_E) Ry(alpha_N)
(ALGORITHMS (3.1); PSINS ``a2mat``), so that C_b^n = C_p^n(alpha) C_b^p. The IMU is fixed
to the platform (s = b).

State (10): x = [alpha_E, alpha_N, alpha_U, dv_E, dv_N, nabla_x, nabla_y, eps_x, eps_y,
eps_z] (rad, m/s, m/s^2 in b, rad/s in b). Seed 002 orders its NED/FRD state as
[dv_N, dv_E, phi_x(N), phi_y(E), phi_z(D), nabla_x(F), nabla_y(R), eps_x, eps_y, eps_z];
the map (ALGORITHMS 0) is alpha_E = phi_E, alpha_N = phi_N, alpha_U = -phi_D,
nabla_x^RFU = nabla_y^FRD, nabla_y^RFU = nabla_x^FRD, eps^RFU = T eps^FRD. Hence the
seed's P0 sigmas (45, 45, 60 deg on phi_x, phi_y, phi_z) become 45, 45, 60 deg on
alpha_E, alpha_N, alpha_U, and the symmetric velocity / bias sigmas are unchanged.

Dynamics, static base, ALGORITHMS (3.5):
  alpha_dot = C_omega^-1 [(I - C_n^p) omega_ie^n - C_b^p (eps + w_g)]
  dv_dot_EN = [f^p - Rx(alpha_E) Ry(alpha_N) (f^p - C_b^p ([nabla_x, nabla_y, 0] + w_a))]_EN
with C_omega of ALGORITHMS (3.2) and f^p = C_b^p f~^b the computed specific force. The
velocity rows carry no heading: on a still base the true C_b^n (f~ - nabla) = g e3 and
Rz(alpha_U)^T e3 = e3, so the form equals the general (I - C_p^n) f^p + C_p^n C_b^p nabla
on the truth, but the general form's d(dv_dot)/d alpha_U = [e3 x C_p^n (f^p - C_b^p
nabla)]_EN is nonzero wherever the estimated level is off, a heading measurement that is
not there (it left the EKF 75-340' from the heading floor from 58.5 deg).
Measurement: z = v_EN of the INS = [0_2x3, I_2, 0_2x5] x + v (the true velocity is 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.model import (FilterModel, Observation, StateLayout, Transition,
                                       per_member, stack_episodes)
from aligngym.estimators.strapdown import compensate
from aligngym.models.attitude import (cross, dcm_to_euler, dcm_to_quat, quat_cumprod, quat_mul,
                             quat_rotate, quat_to_dcm, rotvec_to_quat)
from aligngym.models.earth import OMEGA_IE
from aligngym.models.units import deg, deg_per_h, mg

ALPHA, DV, NABLA, EPS = slice(0, 3), slice(3, 5), slice(5, 7), slice(7, 10)
N_STATES = 10
LAYOUT = StateLayout({"euler_error": ALPHA, "velocity_error": DV, "accel_bias": NABLA,
                      "gyro_bias": EPS}, angles=(0, 1, 2))
_H = np.hstack([np.zeros((2, 3)), np.eye(2), np.zeros((2, 5))])
_IDENTITY = np.eye(N_STATES)[None]
"""The (1, 10, 10) identity: the feedback's reset transform outside the Euler block."""


# --------------------------------------------------------------------------------------
# The open-loop static-base INS
# --------------------------------------------------------------------------------------

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

    def earth_rotation(self, t: float) -> np.ndarray:
        """E(t) (B, 3, 3)."""
        s, c = -np.sin(OMEGA_IE * t), 1.0 - np.cos(OMEGA_IE * t)
        K = self.K_axis
        return np.eye(3) + s * K + c * (K @ K)

    def attitude(self, C0: np.ndarray, k: int) -> np.ndarray:
        """C_b^p (B, 3, 3) at boundary k of the INS started from C0 (B, 3, 3)."""
        return self.earth_rotation(self.t[k]) @ C0 @ self.Q[:, k]

    def attitude_mid(self, C0: np.ndarray, k: int) -> np.ndarray:
        """C_b^p (B, 3, 3) at the middle of epoch k."""
        return self.earth_rotation(self.t_mid[k]) @ C0 @ self.Q_mid[:, k]

    def delta_v(self, C0: np.ndarray, k: int) -> np.ndarray:
        """int C_b^p f~ dt over epoch k (B, 3), m/s, ENU (gravity not included)."""
        K, U = self.K_axis, self.U[:, k]
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


# --------------------------------------------------------------------------------------
# Euler-angle kinematics
# --------------------------------------------------------------------------------------

def C_p_n(alpha: np.ndarray) -> np.ndarray:
    """C_p^n(alpha) = Rz(alpha_U) Rx(alpha_E) Ry(alpha_N), ALGORITHMS (3.1); alpha (..., 3)
    = [alpha_E, alpha_N, alpha_U] rad -> (..., 3, 3). Equals
    models.attitude.euler_to_dcm(alpha) (the PSINS sequence)."""
    sx, cx = np.sin(alpha[..., 0]), np.cos(alpha[..., 0])
    sy, cy = np.sin(alpha[..., 1]), np.cos(alpha[..., 1])
    sz, cz = np.sin(alpha[..., 2]), np.cos(alpha[..., 2])
    C = np.empty(alpha.shape[:-1] + (3, 3))
    C[..., 0, 0] = cz * cy - sz * sx * sy
    C[..., 0, 1] = -sz * cx
    C[..., 0, 2] = cz * sy + sz * sx * cy
    C[..., 1, 0] = sz * cy + cz * sx * sy
    C[..., 1, 1] = cz * cx
    C[..., 1, 2] = sz * sy - cz * sx * cy
    C[..., 2, 0] = -cx * sy
    C[..., 2, 1] = sx
    C[..., 2, 2] = cx * cy
    return C


def C_omega(alpha: np.ndarray) -> np.ndarray:
    """C_omega (..., 3, 3) of ALGORITHMS (3.2): omega_np^p = C_omega alpha_dot, where
    C_p^n_dot = C_p^n [omega_np^p x]. Singular at alpha_E = +-90 deg."""
    sE, cE = np.sin(alpha[..., 0]), np.cos(alpha[..., 0])
    sN, cN = np.sin(alpha[..., 1]), np.cos(alpha[..., 1])
    M = np.zeros(alpha.shape[:-1] + (3, 3))
    M[..., 0, 0], M[..., 0, 2] = cN, -sN * cE
    M[..., 1, 1], M[..., 1, 2] = 1.0, sE
    M[..., 2, 0], M[..., 2, 2] = sN, cN * cE
    return M


def C_omega_inv(alpha: np.ndarray) -> np.ndarray:
    """C_omega^-1 (..., 3, 3) in closed form (det C_omega = cos alpha_E)."""
    sE, cE = np.sin(alpha[..., 0]), np.cos(alpha[..., 0])
    sN, cN = np.sin(alpha[..., 1]), np.cos(alpha[..., 1])
    tE = sE / cE
    M = np.zeros(alpha.shape[:-1] + (3, 3))
    M[..., 0, 0], M[..., 0, 2] = cN, sN
    M[..., 1, 0], M[..., 1, 1], M[..., 1, 2] = sN * tE, 1.0, -cN * tE
    M[..., 2, 0], M[..., 2, 2] = -sN / cE, cN / cE
    return M


def _C_omega_inv_partials(alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d(C_omega^-1)/d alpha_E and d/d alpha_N, each (..., 3, 3) (no alpha_U dependence)."""
    sE, cE = np.sin(alpha[..., 0]), np.cos(alpha[..., 0])
    sN, cN = np.sin(alpha[..., 1]), np.cos(alpha[..., 1])
    tE, secE = sE / cE, 1.0 / cE
    dE = np.zeros(alpha.shape[:-1] + (3, 3))
    dE[..., 1, 0], dE[..., 1, 2] = sN * secE ** 2, -cN * secE ** 2
    dE[..., 2, 0], dE[..., 2, 2] = -sN * tE * secE, cN * tE * secE
    dN = np.zeros(alpha.shape[:-1] + (3, 3))
    dN[..., 0, 0], dN[..., 0, 2] = -sN, cN
    dN[..., 1, 0], dN[..., 1, 2] = cN * tE, sN * tE
    dN[..., 2, 0], dN[..., 2, 2] = -cN * secE, -sN * secE
    return dE, dN


def _C_p_n_partials(alpha: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, ...]:
    """dC_p^n/d alpha_E, d alpha_N, d alpha_U (each (..., 3, 3)) given C = C_p^n(alpha):
    Rz [e1 x] Rx Ry, C [e2 x], [e3 x] C."""
    e1 = np.array([[0.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    e2 = np.array([[0.0, 0, 1], [0, 0, 0], [-1, 0, 0]])
    e3 = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 0]])
    sz, cz = np.sin(alpha[..., 2]), np.cos(alpha[..., 2])
    Rz = np.zeros(alpha.shape[:-1] + (3, 3))
    Rz[..., 0, 0], Rz[..., 0, 1] = cz, -sz
    Rz[..., 1, 0], Rz[..., 1, 1] = sz, cz
    Rz[..., 2, 2] = 1.0
    # Rx Ry = Rz^T C, so Rz [e1 x] Rx Ry = Rz [e1 x] Rz^T C = [(Rz e1) x] C.
    dE = Rz @ e1 @ np.swapaxes(Rz, -1, -2) @ C
    return dE, C @ e2, e3 @ C


def true_state(C_b_n_true: np.ndarray, C_b_p: np.ndarray) -> np.ndarray:
    """The Euler error alpha (..., 3) rad, [alpha_E, alpha_N, alpha_U], such that
    C_b^n = C_p^n(alpha) C_b^p: C_p^n = C_b^n C_p^b, inverted as the ZXY sequence
    (alpha_E in [-90, 90] deg)."""
    return dcm_to_euler(C_b_n_true @ np.swapaxes(C_b_p, -1, -2))


def state_vector(alpha: np.ndarray, v_EN: np.ndarray, accel_bias_xy: np.ndarray,
                 gyro_bias: np.ndarray) -> np.ndarray:
    """The 10-state vector (..., 10) from its blocks (rad, m/s, m/s^2, rad/s)."""
    return np.concatenate([np.asarray(a, dtype=float) for a in
                           (alpha, v_EN, accel_bias_xy, gyro_bias)], axis=-1)


def continuous_dynamics(x: np.ndarray, C_b_p: np.ndarray, f_p: np.ndarray,
                        omega_ie: np.ndarray) -> np.ndarray:
    """x_dot (..., 10) of ALGORITHMS (3.5) without noise, batched by broadcasting.

    x (..., 10); C_b_p (..., 3, 3); f_p (..., 3) m/s^2 in p; omega_ie (..., 3) rad/s in n.
    alpha_dot = C_omega^-1 [(I - C_n^p) omega_ie - C_b^p eps],
    dv_dot = [f^p - Rx(alpha_E) Ry(alpha_N) (f^p - C_b^p [nabla_x, nabla_y, 0])]_EN.
    Written out per component on contiguous arrays (the sigma-point filters evaluate
    it on 10^5 points per epoch); ``C_p_n`` and ``C_omega_inv`` are the matrix forms.
    """
    return np.moveaxis(_dynamics(np.moveaxis(x, -1, 0), C_b_p, f_p, omega_ie), 0, -1)


def _dynamics(xs: np.ndarray, C_b_p: np.ndarray, f_p: np.ndarray,
              omega_ie: np.ndarray) -> np.ndarray:
    """``continuous_dynamics`` on the state component-first: xs (10, ...) -> (10, ...)."""
    shape = np.broadcast_shapes(xs.shape[1:], C_b_p.shape[:-2], f_p.shape[:-1],
                                omega_ie.shape[:-1])
    sE, cE = np.sin(xs[0]), np.cos(xs[0])
    sN, cN = np.sin(xs[1]), np.cos(xs[1])
    sU, cU = np.sin(xs[2]), np.cos(xs[2])
    # C_p^n = Rz(alpha_U) Rx(alpha_E) Ry(alpha_N), ALGORITHMS (3.1).
    sEsN, sEcN = sE * sN, sE * cN
    c00, c01, c02 = cU * cN - sU * sEsN, -sU * cE, cU * sN + sU * sEcN
    c10, c11, c12 = sU * cN + cU * sEsN, cU * cE, sU * sN - cU * sEcN
    c20, c21, c22 = -cE * sN, sE, cE * cN
    w = [omega_ie[..., i] for i in range(3)]
    Cb = [[C_b_p[..., i, j] for j in range(3)] for i in range(3)]
    eps = xs[7:10]
    # w_i = omega_i - (C^T omega)_i - (C_b^p eps)_i.
    ct_w = (c00 * w[0] + c10 * w[1] + c20 * w[2], c01 * w[0] + c11 * w[1] + c21 * w[2],
            c02 * w[0] + c12 * w[1] + c22 * w[2])
    r = [w[i] - ct_w[i] - (Cb[i][0] * eps[0] + Cb[i][1] * eps[1] + Cb[i][2] * eps[2])
         for i in range(3)]
    out = np.zeros((N_STATES,) + shape)
    a = sN * r[0] - cN * r[2]                                  # C_omega^-1 r written out
    out[0] = cN * r[0] + sN * r[2]
    out[1] = r[1] + a * sE / cE
    out[2] = -a / cE
    f = [f_p[..., i] for i in range(3)]
    d = [f[i] - (Cb[i][0] * xs[5] + Cb[i][1] * xs[6]) for i in range(3)]   # f - C_b^p nabla
    # Rx(alpha_E) Ry(alpha_N) = [[cN, 0, sN], [sE sN, cE, -sE cN], [.]]: no alpha_U.
    out[3] = f[0] - (cN * d[0] + sN * d[2])
    out[4] = f[1] - (sEsN * d[0] + cE * d[1] - sEcN * d[2])
    return out


def continuous_jacobian(x: np.ndarray, C_b_p: np.ndarray, f_p: np.ndarray,
                        omega_ie: np.ndarray) -> np.ndarray:
    """d(x_dot)/dx (..., 10, 10) of ``continuous_dynamics`` (analytic)."""
    alpha = x[..., ALPHA]
    C = C_p_n(alpha)
    Ct = np.swapaxes(C, -1, -2)
    Mi = C_omega_inv(alpha)
    dMi = _C_omega_inv_partials(alpha)
    dC = _C_p_n_partials(alpha, C)
    L = level_rotation(alpha)
    w = omega_ie - _mv(Ct, omega_ie) - _mv(C_b_p, x[..., EPS])
    b = C_b_p[..., :, 0] * x[..., 5:6] + C_b_p[..., :, 1] * x[..., 6:7]
    r = b - f_p
    shape = np.broadcast_shapes(x.shape[:-1], C_b_p.shape[:-2], f_p.shape[:-1])
    A = np.zeros(shape + (N_STATES, N_STATES))
    # d(Rx Ry)/d alpha_E = [e1 x] Rx Ry, d/d alpha_N = Rx Ry [e2 x], d/d alpha_U = 0.
    dL = (_E1 @ L, L @ _E2)
    for j in range(3):
        d_alpha = -_mv(Mi, _mv(np.swapaxes(dC[j], -1, -2), omega_ie))
        if j < 2:
            d_alpha = d_alpha + _mv(dMi[j], w)
            A[..., DV, j] = _mv(dL[j], r)[..., :2]
        A[..., ALPHA, j] = d_alpha
    A[..., ALPHA, EPS] = -Mi @ C_b_p
    A[..., DV, NABLA] = (L @ C_b_p)[..., :2, :2]
    return A


_E1 = np.array([[0.0, 0, 0], [0, 0, -1], [0, 1, 0]])   # [e1 x]
_E2 = np.array([[0.0, 0, 1], [0, 0, 0], [-1, 0, 0]])   # [e2 x]


def level_rotation(alpha: np.ndarray) -> np.ndarray:
    """Rx(alpha_E) Ry(alpha_N) (..., 3, 3) = Rz(alpha_U)^T C_p^n(alpha): the level part of
    the Euler error, which maps the accelerometer's specific force in the velocity rows of
    ALGORITHMS (3.5)."""
    sE, cE = np.sin(alpha[..., 0]), np.cos(alpha[..., 0])
    sN, cN = np.sin(alpha[..., 1]), np.cos(alpha[..., 1])
    L = np.zeros(alpha.shape[:-1] + (3, 3))
    L[..., 0, 0], L[..., 0, 2] = cN, sN
    L[..., 1, 0], L[..., 1, 1], L[..., 1, 2] = sE * sN, cE, -sE * cN
    L[..., 2, 0], L[..., 2, 1], L[..., 2, 2] = -cE * sN, sE, cE * cN
    return L


def _mv(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Batched matrix-vector product A (..., m, n) v (..., n) -> (..., m)."""
    if A.shape[-1] == 3:  # explicit: several times faster than einsum for 3x3 stacks
        return (A[..., 0] * v[..., None, 0] + A[..., 1] * v[..., None, 1]
                + A[..., 2] * v[..., None, 2])
    return np.einsum("...ij,...j->...i", A, v)


def rk4_step(x: np.ndarray, T: float, C_b_p: np.ndarray, f_p: np.ndarray,
             omega_ie: np.ndarray) -> np.ndarray:
    """One RK4 step of length T (s) of ``continuous_dynamics`` with the inputs held
    (computed component-first, contiguous)."""
    xs = np.ascontiguousarray(np.moveaxis(x, -1, 0))
    args = (C_b_p, f_p, omega_ie)
    k1 = _dynamics(xs, *args)
    k2 = _dynamics(xs + 0.5 * T * k1, *args)
    k3 = _dynamics(xs + 0.5 * T * k2, *args)
    k4 = _dynamics(xs + T * k3, *args)
    return np.moveaxis(xs + T / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), 0, -1)


def rk4_jacobian(x: np.ndarray, T: float, C_b_p: np.ndarray, f_p: np.ndarray,
                 omega_ie: np.ndarray) -> np.ndarray:
    """d(rk4_step)/dx (..., 10, 10), by the chain rule through the four stages."""
    I = np.eye(N_STATES)
    args = (C_b_p, f_p, omega_ie)
    k1 = continuous_dynamics(x, *args)
    D1 = continuous_jacobian(x, *args)
    x2 = x + 0.5 * T * k1
    k2 = continuous_dynamics(x2, *args)
    D2 = continuous_jacobian(x2, *args) @ (I + 0.5 * T * D1)
    x3 = x + 0.5 * T * k2
    k3 = continuous_dynamics(x3, *args)
    D3 = continuous_jacobian(x3, *args) @ (I + 0.5 * T * D2)
    D4 = continuous_jacobian(x + T * k3, *args) @ (I + T * D3)
    return I + T / 6.0 * (D1 + 2.0 * D2 + 2.0 * D3 + D4)


def midpoint_step(x: np.ndarray, T: float, C_b_p: np.ndarray, f_p: np.ndarray,
                  omega_ie: np.ndarray) -> np.ndarray:
    """One explicit midpoint (second-order Runge-Kutta) step of length T (s) with the
    inputs held: x + T f(x + T/2 f(x)). The model's discrete process: on a static base
    the Euler errors move at ~Omega |alpha| < 1e-4 rad/s, so the third-order local error
    is ~1e-13 rad and m/s per 1-s epoch (tests: the model follows the INS to 1e-8 rad over
    600 s), at half the cost of RK4 (the sparse grids evaluate it on 10^5 points)."""
    xs = np.ascontiguousarray(np.moveaxis(x, -1, 0))
    args = (C_b_p, f_p, omega_ie)
    k1 = _dynamics(xs, *args)
    return np.moveaxis(xs + T * _dynamics(xs + 0.5 * T * k1, *args), 0, -1)


def _midpoint_points(x: np.ndarray, T: float, C_b_p: np.ndarray, f_p: np.ndarray,
                     omega_ie: np.ndarray) -> np.ndarray:
    """``midpoint_step`` of points x (B, P, 10) with each episode's inputs C_b_p (B, 3, 3),
    f_p (B, 3), omega_ie (B, 3), compiled (``euler_kernel``: the same numbers where NumPy's
    sine and cosine are the C library's)."""
    from aligngym.estimators.euler_kernel import midpoint_points   # Numba: loaded when run
    x = np.ascontiguousarray(x, dtype=float)
    out = np.empty_like(x)
    B = x.shape[0]
    midpoint_points(x, float(T), np.ascontiguousarray(np.broadcast_to(C_b_p, (B, 3, 3))),
                    np.ascontiguousarray(np.broadcast_to(f_p, (B, 3))),
                    np.ascontiguousarray(np.broadcast_to(omega_ie, (B, 3))), out)
    return out


def midpoint_jacobian(x: np.ndarray, T: float, C_b_p: np.ndarray, f_p: np.ndarray,
                      omega_ie: np.ndarray) -> np.ndarray:
    """d(midpoint_step)/dx (..., 10, 10): I + T A(x_mid) (I + T/2 A(x))."""
    I = np.eye(N_STATES)
    args = (C_b_p, f_p, omega_ie)
    x_mid = x + 0.5 * T * continuous_dynamics(x, *args)
    return I + T * continuous_jacobian(x_mid, *args) @ (
        I + 0.5 * T * continuous_jacobian(x, *args))


def small_angle_dynamics(x: np.ndarray, C_b_n: np.ndarray, f_n: np.ndarray,
                         omega_ie: np.ndarray) -> np.ndarray:
    """The classic small-angle static model (ALGORITHMS (0.1)-(0.2), v = 0, no position
    error, horizontal velocity only) in this state order, for comparison:
    phi_dot = -[omega_ie x] phi - C_b^n eps, dv_dot = ([f^n x] phi + C_b^n nabla)_EN."""
    phi = x[..., ALPHA]
    out = np.zeros(x.shape)
    out[..., ALPHA] = -cross(omega_ie, phi) - _mv(C_b_n, x[..., EPS])
    b = C_b_n[..., :, 0] * x[..., 5:6] + C_b_n[..., :, 1] * x[..., 6:7]
    out[..., DV] = (cross(f_n, phi) + b)[..., :2]
    return out


# --------------------------------------------------------------------------------------
# The filter model
# --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Paper002Tuning:
    """Seed 002's tuning (SPEC 4.4, ALGORITHMS 3.1 "002 parameters"), SI, ENU order.

    P0 sigmas: velocity_sigma (m/s, E and N); euler_sigma (rad, alpha_E, alpha_N,
    alpha_U; the seed's 45, 45, 60 deg on phi_N, phi_E, phi_D map to these, see the
    module docstring); accel_bias_sigma (m/s^2, x and y); gyro_bias_sigma (rad/s, x, y, z).
    Process noise: accel_psd ((m/s^2)^2/Hz) and gyro_psd ((rad/s)^2/Hz). The seed's
    Q = diag[(0.05 mg)^2 x2, (0.01 deg/h)^2 x3] gives no units of time; it is taken here
    as the power spectral densities of white noise (an assumption, ALGORITHMS 3.1), i.e.
    densities 0.05 mg/sqrt(Hz) and 0.01 deg/h/sqrt(Hz). measurement_sigma: m/s.
    """

    velocity_sigma: float = 0.1
    euler_sigma: tuple[float, float, float] = (45 * deg, 45 * deg, 60 * deg)
    accel_bias_sigma: float = 0.02 * mg
    gyro_bias_sigma: float = 0.1 * deg_per_h
    accel_psd: float = (0.05 * mg) ** 2
    gyro_psd: float = (0.01 * deg_per_h) ** 2
    measurement_sigma: float = 0.1

    def initial_covariance(self, batch: int) -> np.ndarray:
        """P0 (batch, 10, 10), diagonal."""
        sig = np.concatenate([self.euler_sigma, [self.velocity_sigma] * 2,
                              [self.accel_bias_sigma] * 2, [self.gyro_bias_sigma] * 3])
        return np.broadcast_to(np.diag(sig ** 2), (batch, N_STATES, N_STATES)).copy()


PAPER002 = Paper002Tuning()


class EulerLargeMisalignmentModel(FilterModel):
    """The 10-state Euler-error model of seed 002 on a static base for a batch of
    episodes (module docstring; ALGORITHMS (3.1)-(3.5)), with the model's own INS.

    integrals: the episodes' ``StaticBaseIntegrals``; C0 (B, 3, 3): the INS's initial
    attitude C_b^p(0). tuning: P0 sigmas, PSDs and measurement sigma
    (``Paper002Tuning``); P0: optional (B, 10, 10) initial covariance overriding the
    tuning's; measurement_sigma: optional override, m/s. feedback_below: None runs the
    INS open loop; a heading sigma (rad) below which an episode's estimate is fed back
    after each update (ALGORITHMS 3.1: C_b^p <- C_p^n(alpha_hat) C_b^p, v <- v - dv_hat,
    alpha and dv reset to zero, the covariance of alpha mapped through the reset's
    Jacobian); before that the large-angle model runs open loop.

    Transition: one explicit-midpoint step (``midpoint_step``) over the epoch with the
    epoch's C_b^p (mid-epoch) and mean f^p held; analytic Jacobian. Process noise
    Q_k = G q G^T T with q = diag(q_a, q_a, q_g, q_g, q_g) (PSDs), G = d(x_dot)/d(w_a,
    w_g) at the latest estimate passed to ``feedback`` (x0 at the start): gyro noise
    enters alpha_dot as -C_omega^-1 C_b^p w_g, horizontal accelerometer noise enters
    dv_dot as [Rx(alpha_E) Ry(alpha_N) C_b^p [w_ax, w_ay, 0]]_EN.
    """

    layout = LAYOUT

    def __init__(self, integrals: StaticBaseIntegrals, C0: np.ndarray,
                 tuning: Paper002Tuning = PAPER002, P0: np.ndarray | None = None,
                 measurement_sigma: float | None = None,
                 feedback_below: float | None = None) -> None:
        self.integrals, self.tuning = integrals, tuning
        self.t = integrals.t
        self.batch, self.epochs = integrals.U.shape[:2]
        self.T = integrals.step
        B = self.batch
        self.C0 = np.broadcast_to(np.asarray(C0, dtype=float), (B, 3, 3)).copy()
        self.feedback_below = feedback_below
        if P0 is not None:
            P0 = np.broadcast_to(np.asarray(P0, dtype=float), (B, N_STATES, N_STATES))
        self._P0 = tuning.initial_covariance(B) if P0 is None else P0.copy()
        sigma = tuning.measurement_sigma if measurement_sigma is None else measurement_sigma
        self._R = np.broadcast_to(sigma ** 2 * np.eye(2), (B, 2, 2))
        self._Hb = np.broadcast_to(_H, (B, 2, N_STATES))
        lat = np.asarray(integrals.lat, dtype=float)
        self._omega = np.stack([np.zeros_like(lat), OMEGA_IE * np.cos(lat),
                                OMEGA_IE * np.sin(lat)], -1)          # (B, 3)
        self._x_lin = np.zeros((B, N_STATES))
        self._v = np.zeros((B, 3))       # the INS velocity, ENU, m/s (up: unused)
        self._v_epoch = -1               # last epoch whose velocity is in _v
        self.feedback_count = np.zeros(B, int)

    def initial(self):
        self._x_lin = np.zeros((self.batch, N_STATES))
        return self._x_lin.copy(), self._P0.copy()

    def _args(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The epoch's mid-epoch C_b^p (B, 3, 3), mean f^p (B, 3), omega_ie^n (B, 3)."""
        f_p = self.integrals.delta_v(self.C0, k) / self.T
        return self.integrals.attitude_mid(self.C0, k), f_p, self._omega

    def transition(self, k, q_scale=(1.0, 1.0)):
        C_b_p, f_p, omega = self._args(k)
        T = self.T
        Cb, fb, wb = C_b_p[:, None], f_p[:, None], omega[:, None]

        def fn(x: np.ndarray) -> np.ndarray:
            if x.ndim == 3:    # points of every episode: the compiled loop, same numbers
                return _midpoint_points(x, T, C_b_p, f_p, omega)
            return midpoint_step(x, T, Cb, fb, wb)

        def jacobian(x: np.ndarray) -> np.ndarray:
            return midpoint_jacobian(x, T, C_b_p, f_p, omega)

        # Q_k = G q G^T T at the latest estimate (ALGORITHMS 0, "Units").
        alpha = self._x_lin[:, ALPHA]
        G = np.zeros((self.batch, N_STATES, 5))
        G[:, DV, 0:2] = (level_rotation(alpha) @ C_b_p)[:, :2, :2]
        G[:, ALPHA, 2:5] = -C_omega_inv(alpha) @ C_b_p
        q_a = self.tuning.accel_psd * per_member(q_scale[1], self.batch)[:, 0]
        q_g = self.tuning.gyro_psd * per_member(q_scale[0], self.batch)[:, 0]
        q = np.concatenate([q_a, q_a, q_g, q_g, q_g], -1)[:, None, :]       # (B, 1, 5)
        Q = (G * q) @ np.swapaxes(G, -1, -2) * T
        return Transition(noise=0.5 * (Q + np.swapaxes(Q, -1, -2)), fn=fn,
                          jacobian=jacobian, angles=LAYOUT.angles)

    def observation(self, k, r_scale=1.0):
        """The INS's horizontal velocity at boundary k+1 (advanced once per epoch)."""
        if self._v_epoch != k:
            if k != self._v_epoch + 1:
                raise ValueError(f"observation({k}) after observation({self._v_epoch}): "
                                 "epochs must be taken in order")
            self._v = self._v + self.integrals.delta_v(self.C0, k)
            self._v_epoch = k
        return Observation(noise=per_member(r_scale, self.batch) * self._R, matrix=self._Hb,
                           z=self._v[:, :2].copy(), t=float(self.t[k + 1]))

    def feedback(self, x, P, live):
        """Keep x as the linearisation point of the process noise; with feedback_below,
        feed the estimate of the episodes whose heading sigma is below it back into this
        model's INS at the current boundary and reset alpha, dv (and P's alpha block)."""
        self._x_lin = np.where(live[:, None], x, self._x_lin)
        if self.feedback_below is None:
            return x, P
        ready = live & (np.sqrt(np.maximum(P[:, 2, 2], 0.0)) < self.feedback_below)
        if not ready.any():
            return x, P
        x, P = x.copy(), P.copy()
        b = np.flatnonzero(ready)
        alpha = x[b, ALPHA]
        R = C_p_n(alpha)                                   # C_p^n(alpha_hat)
        E = self.integrals.earth_rotation(self.t[self._v_epoch + 1])[b]
        # C_b^p <- R C_b^p at t: C0 <- E^T R E C0 (StaticBaseIntegrals).
        self.C0[b] = np.swapaxes(E, -1, -2) @ R @ E @ self.C0[b]
        self._v[b, :2] -= x[b, DV]
        J = reset_jacobian(alpha)
        Tm = np.repeat(_IDENTITY, b.size, axis=0)
        Tm[:, ALPHA, ALPHA] = J
        P[b] = Tm @ P[b] @ np.swapaxes(Tm, -1, -2)
        x[b, ALPHA] = 0.0
        x[b, DV] = 0.0
        self._x_lin[b] = x[b]
        self.feedback_count[b] += 1
        return x, P

    def attitude(self, k, x):
        """C_b^n = C_p^n(alpha_hat) C_b^p(t_k) (B, 3, 3) (s = b)."""
        return C_p_n(x[:, ALPHA]) @ self.integrals.attitude(self.C0, k)

    def attitude_sigma(self, k, P):
        """1-sigma of the Euler errors alpha_E, alpha_N, alpha_U (B, 3), rad (close to
        the misalignment sigmas along E, N, U once alpha_E and alpha_N are small)."""
        return np.sqrt(np.maximum(np.diagonal(P[:, ALPHA, ALPHA], axis1=-2, axis2=-1), 0.0))


def reset_jacobian(alpha_hat: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """d alpha' / d alpha (B, 3, 3) at alpha = alpha_hat for the feedback reset
    C_p^n(alpha') = C_p^n(alpha) C_p^n(alpha_hat)^T (alpha' = 0 at alpha_hat), by
    central differences (the six perturbed attitudes in one batch)."""
    R_t = np.swapaxes(C_p_n(alpha_hat), -1, -2)
    d = np.concatenate([np.eye(3) * step, -np.eye(3) * step])     # (6, 3): +e_j, -e_j
    euler = dcm_to_euler(C_p_n(alpha_hat[..., None, :] + d) @ R_t[..., None, :, :])
    return np.swapaxes((euler[..., :3, :] - euler[..., 3:, :]) / (2.0 * step), -1, -2)


class SmallAngleModel(EulerLargeMisalignmentModel):
    """The same states, noise and measurement with the process linearised once at
    alpha = 0 (Phi = the RK4 Jacobian at zero): the classic small-angle linear model, the
    contrast that fails from a large azimuth error."""

    def transition(self, k, q_scale=(1.0, 1.0)):
        noise = super().transition(k, q_scale).noise
        Phi = midpoint_jacobian(np.zeros((self.batch, N_STATES)), self.T, *self._args(k))
        return Transition(noise=noise, matrix=Phi)
