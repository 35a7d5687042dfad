"""Euler-angle kinematics and the static-base error dynamics of seed 002's 10-state
large-misalignment model (ALGORITHMS (3.1)-(3.5), ENU/RFU; the model is ``euler_large``).

alpha = [alpha_E, alpha_N, alpha_U] (rad) defines C_p^n(alpha) = Rz(alpha_U) Rx(alpha_E)
Ry(alpha_N), p the computed ENU frame, n the true one. Here: C_p^n, C_omega and its
inverse, their partial derivatives, the level rotation; the true state of an episode
(``true_state``, ``state_vector``); the continuous error dynamics x_dot (rad/s, m/s^2)
and their analytic Jacobian; their RK4 and explicit-midpoint discretisations over an
epoch T (s); the classic small-angle model for comparison; the Jacobian of the
feedback's Euler-angle reset (``reset_jacobian``, also ``odometer_large``'s).

State (10): x = [alpha_E, alpha_N, alpha_U, dv_E, dv_N, nabla_x, nabla_y, eps_x, eps_y,
eps_z] (rad, m/s, m/s^2 in b, rad/s in b); ``ALPHA``, ``DV``, ``NABLA``, ``EPS`` are its
blocks.
"""
from __future__ import annotations

import numpy as np

from aligngym.models.attitude import cross, dcm_to_euler

ALPHA, DV, NABLA, EPS = slice(0, 3), slice(3, 5), slice(5, 7), slice(7, 10)
N_STATES = 10


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


def reset_jacobian(alpha_hat: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """d alpha' / d alpha (B, 3, 3) at alpha = alpha_hat for the feedback reset
    C_p^n(alpha') = C_p^n(alpha) C_p^n(alpha_hat)^T (alpha' = 0 at alpha_hat), by
    central differences (the six perturbed attitudes in one batch)."""
    R_t = np.swapaxes(C_p_n(alpha_hat), -1, -2)
    d = np.concatenate([np.eye(3) * step, -np.eye(3) * step])     # (6, 3): +e_j, -e_j
    euler = dcm_to_euler(C_p_n(alpha_hat[..., None, :] + d) @ R_t[..., None, :, :])
    return np.swapaxes((euler[..., :3, :] - euler[..., 3:, :]) / (2.0 * step), -1, -2)
