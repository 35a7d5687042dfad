"""The error-state mathematics of seed 004's rotation-vector large-misalignment model and
its state transformation (ALGORITHMS 6); the filter model that runs on it is
``rotation_vector``.

State x (15, ENU): [phi (3), dv (3), dp = (dL, dlambda, dh), eps (3), nabla (3)]. phi is a
rotation vector of any size with C_p^n = exp([phi x]) (p: the INS's computed frame, so
the true C_b^n = exp([phi x]) C_b^p). dv is either the classic velocity error
dv = v~ - v or the transformed one dv_ST = v~ - C_n^p v (6.3); dp = p~ - p; eps and nabla
the gyro drift (rad/s) and accelerometer bias (m/s^2) in the body frame. Here: the state's
slices and layout, the SO(3) Jacobians J_r^-1 and J_l, the feedback's reset Jacobian
(6.8), the INS's quantities at one instant, the dv <-> dv_ST transforms (6.3), the exact
derivatives of the transformed (6.1, 6.4, 6.5) and classic (6.1, 6.2, 6.5) states, their
matrices (ALGORITHMS (0.1)-(0.3) and (6.7)) and the velocity measurement (6.6).

The derivatives here are exact given the INS's quantities (``InsQuantities``): the true
earth rate, transport rate, gravity and velocity are evaluated at the true position and
velocity the error state implies (the differences dw_ie, dw_en, dg are exact, not
linearised), so a model integrated with them follows two simulated INSs (a test).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.model import StateLayout
from aligngym.models.attitude import cross, rotvec_to_dcm, skew
from aligngym.models.earth import earth_rate_n, gravity_n, radii, transport_rate_n

PHI, DV, DP, EPS, NABLA = (slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12),
                           slice(12, 15))
N_STATES = 15
LAYOUT = StateLayout({"misalignment": PHI, "velocity": DV, "position": DP,
                      "gyro_bias": EPS, "accel_bias": NABLA})
"""004's 15 states: misalignment phi (rad), velocity (m/s) and position (m) errors, gyro
(rad/s) and accelerometer (m/s^2) biases."""


def J_r_inv(phi: np.ndarray) -> np.ndarray:
    """Inverse right Jacobian of SO(3) (..., 3, 3) at rotation vectors phi (..., 3):
    I + [phi x]/2 + (1/|phi|^2 - (1 + cos|phi|)/(2 |phi| sin|phi|)) [phi x]^2
    (series 1/12 + |phi|^2/720 below 1e-4 rad); phi_dot = J_r^-1 omega for
    C_dot = C [omega x], C = exp([phi x])."""
    phi = np.asarray(phi, dtype=float)
    angle = np.linalg.norm(phi, axis=-1)
    small = angle < 1e-4
    a = np.where(small, 1.0, angle)
    coefficient = np.where(small, 1.0 / 12.0 + angle ** 2 / 720.0,
                           1.0 / a ** 2 - (1.0 + np.cos(a)) / (2.0 * a * np.sin(a)))
    K = skew(phi)
    return np.eye(3) + 0.5 * K + coefficient[..., None, None] * (K @ K)


def J_l(phi: np.ndarray) -> np.ndarray:
    """Left Jacobian of SO(3) (..., 3, 3) at rotation vectors phi (..., 3):
    I + (1 - cos|phi|)/|phi|^2 [phi x] + (|phi| - sin|phi|)/|phi|^3 [phi x]^2 (series
    1/2 - |phi|^2/24 and 1/6 - |phi|^2/120 below 1e-4 rad); exp([(phi + d) x]) =
    exp([(J_l(phi) d) x]) exp([phi x]) to first order in d."""
    phi = np.asarray(phi, dtype=float)
    angle = np.linalg.norm(phi, axis=-1)
    small = angle < 1e-4
    a = np.where(small, 1.0, angle)
    first = np.where(small, 0.5 - angle ** 2 / 24.0, (1.0 - np.cos(a)) / a ** 2)
    second = np.where(small, 1.0 / 6.0 - angle ** 2 / 120.0, (a - np.sin(a)) / a ** 3)
    K = skew(phi)
    return np.eye(3) + first[..., None, None] * K + second[..., None, None] * (K @ K)


def reset_jacobian(x_hat: np.ndarray, variant: str) -> np.ndarray:
    """G (..., 15, 15) of the feedback's reset (6.8): the error state after the estimate
    x_hat is fed back is G (x - x_hat) to first order, so P becomes G P G^T. Attitude:
    exp([phi+ x]) = exp([phi x]) exp(-[phi^ x]), phi+ ~ J_l(phi^)(phi - phi^); the ST
    velocity error turns with the attitude correction, dv_ST+ = exp([phi^ x])(dv_ST -
    dv_ST^) (the classic velocity error is shifted only: identity); position and biases
    are shifted only."""
    x_hat = np.asarray(x_hat, dtype=float)
    G = np.broadcast_to(np.eye(N_STATES), x_hat.shape[:-1] + (N_STATES, N_STATES)).copy()
    G[..., PHI, PHI] = J_l(x_hat[..., PHI])
    if variant != "classic":
        G[..., DV, DV] = rotvec_to_dcm(x_hat[..., PHI])
    return G


@dataclass(frozen=True)
class InsQuantities:
    """What the INS knows at one instant (broadcastable over episodes and points):
    C_b_p (..., 3, 3) its attitude; f_b (..., 3) its specific force, m/s^2 (compensated
    with its bias estimates); v (..., 3) m/s ENU; lat, lon (rad), h (m)."""

    C_b_p: np.ndarray
    f_b: np.ndarray
    v: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray

    def rates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The INS's omega_ie, omega_en (rad/s) and gravity (m/s^2) in its frame
        (computed once: the derivatives evaluate them at every stage and point)."""
        cached = self.__dict__.get("_rates")
        if cached is None:
            cached = self.__dict__["_rates"] = (
                earth_rate_n(self.lat), transport_rate_n(self.lat, self.h, self.v),
                gravity_n(self.lat, self.h))
        return cached

    def position_rate(self) -> np.ndarray:
        """d(L, lambda, h)/dt (..., 3) of the INS (computed once)."""
        cached = self.__dict__.get("_position_rate")
        if cached is None:
            cached = self.__dict__["_position_rate"] = _position_rate(self.lat, self.h,
                                                                      self.v)
        return cached


def _position_rate(lat: np.ndarray, h: np.ndarray, v: np.ndarray) -> np.ndarray:
    """d(L, lambda, h)/dt (..., 3) for ENU velocity v."""
    R_M, R_N = radii(lat)
    return np.stack([v[..., 1] / (R_M + h), v[..., 0] / ((R_N + h) * np.cos(lat)),
                     v[..., 2]], -1)


def st_to_classic(x: np.ndarray, v_ins: np.ndarray, C_p_n: np.ndarray | None = None
                  ) -> np.ndarray:
    """x with dv_ST replaced by dv = (I - C_p^n) v~ + C_p^n dv_ST (6.3); C_p_n: the DCM
    of x's phi if already formed."""
    C_p_n = rotvec_to_dcm(x[..., PHI]) if C_p_n is None else C_p_n
    out = np.array(x, dtype=float, copy=True)
    out[..., DV] = (v_ins - np.einsum("...ij,...j->...i", C_p_n, v_ins)
                    + np.einsum("...ij,...j->...i", C_p_n, x[..., DV]))
    return out


def classic_to_st(x: np.ndarray, v_ins: np.ndarray) -> np.ndarray:
    """x with dv replaced by dv_ST = v~ - C_n^p (v~ - dv) (6.3)."""
    C_n_p = np.swapaxes(rotvec_to_dcm(x[..., PHI]), -1, -2)
    out = np.array(x, dtype=float, copy=True)
    out[..., DV] = v_ins - np.einsum("...ij,...j->...i", C_n_p, v_ins - x[..., DV])
    return out


def _truth(x_classic: np.ndarray, q: InsQuantities):
    """The true position and velocity an error state implies, and the true rates."""
    lat = q.lat - x_classic[..., 6]
    h = q.h - x_classic[..., 8]
    v = q.v - x_classic[..., DV]
    return lat, h, v, earth_rate_n(lat), transport_rate_n(lat, h, v), gravity_n(lat, h)


def _attitude_rate(x: np.ndarray, q: InsQuantities, w_ie_t: np.ndarray,
                   w_en_t: np.ndarray, C_n_p: np.ndarray) -> np.ndarray:
    """(6.1): phi_dot = J_r^-1(phi) [omega^_in - C_n^p omega_in - C_b^p eps]; C_n_p the
    transpose of the DCM of x's phi."""
    w_ie, w_en, _ = q.rates()
    omega_np = (w_ie + w_en - np.einsum("...ij,...j->...i", C_n_p, w_ie_t + w_en_t)
                - np.einsum("...ij,...j->...i", q.C_b_p, x[..., EPS]))
    return np.einsum("...ij,...j->...i", J_r_inv(x[..., PHI]), omega_np)


def st_derivative(x: np.ndarray, q: InsQuantities) -> np.ndarray:
    """x_dot (..., 15) of the transformed state [phi, dv_ST, dp, eps, nabla] ((6.1), (6.4),
    (6.5); the noise-free part): f~ does not appear, gravity does."""
    C_p_n = rotvec_to_dcm(x[..., PHI])
    C_n_p = np.swapaxes(C_p_n, -1, -2)
    xc = st_to_classic(x, q.v, C_p_n)
    lat_t, h_t, v_t, w_ie_t, w_en_t, g_t = _truth(xc, q)
    w_ie, w_en, g = q.rates()
    mv = lambda A, b: np.einsum("...ij,...j->...i", A, b)  # noqa: E731
    eps_p = mv(q.C_b_p, x[..., EPS])
    out = np.zeros(np.broadcast_shapes(x.shape, q.v.shape[:-1] + (N_STATES,)))
    out[..., PHI] = _attitude_rate(x, q, w_ie_t, w_en_t, C_n_p)
    # dv_ST_dot = C_b^p nabla + g^ - C_n^p g - (w^_ie - C_n^p w_ie) x v~ + v~ x (C_b^p eps)
    #             - (w^_in + C_n^p w_ie - C_b^p eps) x dv_ST
    out[..., DV] = (mv(q.C_b_p, x[..., NABLA]) + g - mv(C_n_p, g_t)
                    - cross(w_ie - mv(C_n_p, w_ie_t), q.v) + cross(q.v, eps_p)
                    - cross(w_ie + w_en + mv(C_n_p, w_ie_t) - eps_p, x[..., DV]))
    out[..., DP] = q.position_rate() - _position_rate(lat_t, h_t, v_t)
    return out


def classic_derivative(x: np.ndarray, q: InsQuantities) -> np.ndarray:
    """x_dot (..., 15) of the classic state [phi, dv, dp, eps, nabla] ((6.1), (6.2),
    (6.5)): the specific force appears, through the erroneous attitude."""
    lat_t, h_t, v_t, w_ie_t, w_en_t, g_t = _truth(x, q)
    w_ie, w_en, g = q.rates()
    C_p_n = rotvec_to_dcm(x[..., PHI])
    mv = lambda A, b: np.einsum("...ij,...j->...i", A, b)  # noqa: E731
    f_p = mv(q.C_b_p, q.f_b)
    out = np.zeros(np.broadcast_shapes(x.shape, q.v.shape[:-1] + (N_STATES,)))
    out[..., PHI] = _attitude_rate(x, q, w_ie_t, w_en_t, np.swapaxes(C_p_n, -1, -2))
    out[..., DV] = (f_p - mv(C_p_n, f_p) + mv(C_p_n, mv(q.C_b_p, x[..., NABLA]))
                    - cross(2 * w_ie + w_en, q.v) + cross(2 * w_ie_t + w_en_t, v_t)
                    + g - g_t)
    out[..., DP] = q.position_rate() - _position_rate(lat_t, h_t, v_t)
    return out


def _blocks(q: InsQuantities):
    """M_av, M_p1, M_p2, M_pv, M_pp of ALGORITHMS 0 at the INS's position and velocity."""
    lat, h, v = q.lat, q.h, q.v
    R_M, R_N = radii(lat)
    R_Mh, R_Nh = R_M + h, R_N + h
    tL, secL = np.tan(lat), 1.0 / np.cos(lat)
    w = earth_rate_n(lat)[..., 1:]
    z = np.zeros_like(lat)
    M = lambda rows: np.stack([np.stack(r, -1) for r in rows], -2)  # noqa: E731
    M_av = M([[z, -1 / R_Mh, z], [1 / R_Nh, z, z], [tL / R_Nh, z, z]])
    M_p1 = M([[z, z, z], [-w[..., 1], z, z], [w[..., 0], z, z]])
    M_p2 = M([[z, z, v[..., 1] / R_Mh ** 2], [z, z, -v[..., 0] / R_Nh ** 2],
              [v[..., 0] * secL ** 2 / R_Nh, z, -v[..., 0] * tL / R_Nh ** 2]])
    M_pv = M([[z, 1 / R_Mh, z], [secL / R_Nh, z, z], [z, z, z + 1]])
    M_pp = M([[z, z, -v[..., 1] / R_Mh ** 2], [v[..., 0] * secL * tL / R_Nh, z,
                                                -v[..., 0] * secL / R_Nh ** 2], [z, z, z]])
    return M_av, M_p1, M_p2, M_pv, M_pp


def classic_matrix(q: InsQuantities) -> np.ndarray:
    """F (..., 15, 15) of the classic small-angle model (ALGORITHMS (0.1)-(0.3))."""
    w_ie, w_en, g = q.rates()
    M_av, M_p1, M_p2, M_pv, M_pp = _blocks(q)
    V = skew(q.v)
    F = np.zeros(q.lat.shape + (N_STATES, N_STATES))
    F[..., PHI, PHI] = -skew(w_ie + w_en)
    F[..., PHI, DV] = M_av
    F[..., PHI, DP] = M_p1 + M_p2
    F[..., PHI, EPS] = -q.C_b_p
    F[..., DV, PHI] = skew(np.einsum("...ij,...j->...i", q.C_b_p, q.f_b))
    F[..., DV, DV] = V @ M_av - skew(2 * w_ie + w_en)
    F[..., DV, DP] = V @ (2 * M_p1 + M_p2)
    F[..., DV, NABLA] = q.C_b_p
    F[..., DP, DV] = M_pv
    F[..., DP, DP] = M_pp
    return F


def stekf_matrix(q: InsQuantities) -> np.ndarray:
    """F (..., 15, 15) of the transformed model linearised at phi = 0 (ALGORITHMS (6.7))."""
    w_ie, w_en, g = q.rates()
    M_av, M_p1, M_p2, M_pv, M_pp = _blocks(q)
    V = skew(q.v)
    F = np.zeros(q.lat.shape + (N_STATES, N_STATES))
    F[..., PHI, PHI] = -skew(w_ie + w_en) + M_av @ V
    F[..., PHI, DV] = M_av
    F[..., PHI, DP] = M_p1 + M_p2
    F[..., PHI, EPS] = -q.C_b_p
    F[..., DV, PHI] = -skew(g) - V @ skew(w_ie)
    F[..., DV, DV] = -skew(2 * w_ie + w_en)
    F[..., DV, DP] = V @ M_p1
    F[..., DV, EPS] = V @ q.C_b_p
    F[..., DV, NABLA] = q.C_b_p
    F[..., DP, PHI] = M_pv @ V
    F[..., DP, DV] = M_pv
    F[..., DP, DP] = M_pp
    return F


def st_velocity_measurement(x: np.ndarray, v_ins: np.ndarray) -> np.ndarray:
    """h_v(x) (..., 3) = (I - C_p^n(phi)) v~ + C_p^n(phi) dv_ST: the INS velocity error a
    velocity fix sees (6.6); its Jacobian at phi = 0 is [[v~ x], I] (6.7)."""
    return st_to_classic(x, v_ins)[..., DV]
