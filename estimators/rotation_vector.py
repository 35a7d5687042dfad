"""The rotation-vector large-misalignment error model of seed 004 and its state
transformation (ALGORITHMS 6): the equations the STEKF, the STUKF and the classic
large-angle UKF/EKF of paper 004 run on.

State x (15, ENU): [phi (3), dv (3), dp = (dL, dlambda, dh), eps (3), nabla (3)]. phi is a
rotation vector of any size with C_p^n = exp([phi x]) (p: the INS's computed frame, so
the true C_b^n = exp([phi x]) C_b^p). dv is either the classic velocity error
dv = v~ - v or the transformed one dv_ST = v~ - C_n^p v (6.3); dp = p~ - p; eps and nabla
the gyro drift (rad/s) and accelerometer bias (m/s^2) in the body frame.

The derivatives here are exact given the INS's quantities (``InsQuantities``): the true
earth rate, transport rate, gravity and velocity are evaluated at the true position and
velocity the error state implies (the differences dw_ie, dw_en, dg are exact, not
linearised), so a model integrated with them follows two simulated INSs (a test).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.model import (FilterModel, Observation, StateLayout, Transition,
                                       per_member)
from aligngym.estimators.loose_gps import GpsInsInputs
from aligngym.estimators.strapdown import body_rate_at
from aligngym.models.attitude import cross, dcm_to_quat, quat_to_dcm, rotvec_to_dcm, skew
from aligngym.models.earth import (earth_rate_n, gravity_n, metres_per_geodetic, radii,
                          transport_rate_n)

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


# --- the GNSS-aided filter model of paper 004 ---------------------------------------------------
@dataclass
class IndexedGpsInsInputs(GpsInsInputs):
    """``GpsInsInputs`` of an IMU turned on the hull by an indexer or a gimbal (read by its
    encoder): lever_arm_b (B, K+1, 3) m, IMU to antenna in the IMU frame at each epoch
    boundary; omega_bs_s (B, K+1, 3) rad/s, the IMU's rate relative to the hull at each
    boundary (paper 004: from the encoder over ``ENCODER_RATE_WINDOW`` s)."""

    omega_bs_s: np.ndarray


VARIANTS = ("st", "st-linear", "classic")
"""st: the transformed model (6.1, 6.4, 6.5) integrated by RK4, nonlinear measurement
(STUKF, or any rule); st-linear: (6.7) with its H (STEKF); classic: (6.1, 6.2, 6.5) and
the classic velocity error (the plain UKF, and the EKF linearising it at the estimate)."""


@dataclass(frozen=True)
class RotationVectorTuning:
    """What the filter believes, SI: P0 sigmas (attitude (3,) rad as a rotation vector E,
    N, U; velocity m/s; position m; gyro drift rad/s; accelerometer bias m/s^2), white
    noise densities (gyro rad/sqrt(s), accelerometer m/s/sqrt(s)) and bias random walks
    (rad/s/sqrt(s), m/s^2/sqrt(s); ALGORITHMS 6 caution: keep nabla's non-zero); GNSS
    sigmas (horizontal and vertical position m, velocity m/s per axis)."""

    attitude_sigma: tuple[float, float, float]
    velocity_sigma: float
    position_sigma: float
    gyro_bias_sigma: float
    accel_bias_sigma: float
    gyro_noise_density: float
    accel_noise_density: float
    gyro_bias_walk: float
    accel_bias_walk: float
    gnss_position_sigma_h: float
    gnss_position_sigma_v: float
    gnss_velocity_sigma: float


class RotationVectorGnssModel(FilterModel):
    """Paper 004's fine alignment on B episodes: the 15-state
    rotation-vector model in one of ``VARIANTS``, GNSS velocity and position (ENU, m/s and
    m, at the antenna: the lever arm's attitude dependence is in h), the model's own
    strapdown on bias-compensated increments; open loop while the heading sigma is above
    feedback_below (rad; None: closed loop from the start), then the estimate is fed back
    after every update (6.8) and the state reset."""

    def __init__(self, inputs: GpsInsInputs, tuning: RotationVectorTuning, variant: str = "st",
                 feedback_below: float | None = None) -> None:
        if variant not in VARIANTS:
            raise ValueError(f"variant {variant!r}; valid: " + ", ".join(VARIANTS))
        self.inputs, self.tuning, self.variant = inputs, tuning, variant
        self.feedback_below = feedback_below
        self.layout = LAYOUT
        B, K = inputs.dtheta.shape[:2]
        self.batch, self.epochs, self.t = B, K, inputs.t
        self.T = float(inputs.t[1] - inputs.t[0])
        self.ins = inputs.strapdown()
        self._C_b_p = np.empty((B, K + 1, 3, 3))
        self._C_b_p[:, 0] = quat_to_dcm(self.ins.state.q_b_n)
        self._rate = np.zeros((B, 3))
        self._k = 0
        self.feedback_count = np.zeros(B, int)
        self._bias = {name: np.zeros((B, K + 1, 3)) for name in ("gyro_bias", "accel_bias")}

    def series(self) -> dict[str, np.ndarray]:
        """The INS's accumulated bias estimates gyro_bias (rad/s) and accel_bias (m/s^2),
        (B, K+1, 3) at the epoch boundaries after feedback (the state holds the rest)."""
        return self._bias

    def _lever(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Lever arm l (B, 3) m in the IMU frame and the IMU's rate relative to the hull
        (B, 3) rad/s at epoch boundary k."""
        inp = self.inputs
        if isinstance(inp, IndexedGpsInsInputs):
            return inp.lever_arm_b[:, k], inp.omega_bs_s[:, k]
        return inp.lever_arm_b, np.zeros((self.batch, 3))

    def initial(self):
        tu, B = self.tuning, self.batch
        s = self.ins.state
        sig = np.zeros((B, N_STATES))
        sig[:, PHI] = tu.attitude_sigma
        sig[:, DV] = tu.velocity_sigma
        sig[:, DP] = tu.position_sigma / metres_per_geodetic(s.lat, s.h)
        sig[:, EPS] = tu.gyro_bias_sigma
        sig[:, NABLA] = tu.accel_bias_sigma
        return np.zeros((B, N_STATES)), sig[:, :, None] ** 2 * np.eye(N_STATES)

    def _quantities(self, out, f_b, i: int) -> InsQuantities:
        return InsQuantities(C_b_p=quat_to_dcm(out["q_b_n"][:, i])[:, None],
                             f_b=f_b[:, None], v=out["v_n"][:, i][:, None],
                             lat=out["lat"][:, i][:, None], lon=out["lon"][:, i][:, None],
                             h=out["h"][:, i][:, None])

    def transition(self, k, q_scale=(1.0, 1.0)):
        inp, dt, T = self.inputs, self.inputs.imu_dt, self.T
        out, dtheta, dv = self.ins.run_compensated(inp.dtheta[:, k], inp.dv[:, k])
        S = dtheta.shape[1]
        mid = S // 2
        self._rate = body_rate_at(dtheta, dt, [S])[:, 0]
        self._C_b_p[:, k + 1] = quat_to_dcm(out["q_b_n"][:, -1])
        f = dv / dt
        q0 = self._quantities(out, f[:, 0], 0)
        qm = self._quantities(out, 0.5 * (f[:, mid - 1] + f[:, mid]), mid)
        q1 = self._quantities(out, f[:, -1], S)
        tu = self.tuning
        qd = np.zeros((self.batch, N_STATES))
        qd[:, PHI] = tu.gyro_noise_density ** 2 * per_member(q_scale[0], self.batch)[:, 0]
        qd[:, DV] = tu.accel_noise_density ** 2 * per_member(q_scale[1], self.batch)[:, 0]
        qd[:, EPS] = tu.gyro_bias_walk ** 2
        qd[:, NABLA] = tu.accel_bias_walk ** 2
        Q = qd[:, :, None] * np.eye(N_STATES) * T
        if self.variant == "st-linear":
            quantities = InsQuantities(C_b_p=qm.C_b_p[:, 0], f_b=qm.f_b[:, 0], v=qm.v[:, 0],
                                       lat=qm.lat[:, 0], lon=qm.lon[:, 0], h=qm.h[:, 0])
            FT = stekf_matrix(quantities) * T
            Phi = np.eye(N_STATES) + FT + 0.5 * FT @ FT
            return Transition(noise=Q, matrix=Phi)
        derivative = st_derivative if self.variant == "st" else classic_derivative

        def fn(x: np.ndarray) -> np.ndarray:
            a = derivative(x, q0)
            b = derivative(x + 0.5 * T * a, qm)
            c = derivative(x + 0.5 * T * b, qm)
            d = derivative(x + T * c, q1)
            return x + T / 6.0 * (a + 2 * b + 2 * c + d)

        return Transition(noise=Q, fn=fn)

    def observation(self, k, r_scale=1.0):
        inp, tu = self.inputs, self.tuning
        self._k = k + 1
        s = self.ins.state
        C_b_p = self._C_b_p[:, k + 1]
        l, w_bs = self._lever(k + 1)
        w_ie = earth_rate_n(s.lat)
        # the lever turns with the hull: w_nh = w_ns - w_hs, in IMU axes
        w_nb = self._rate - w_bs - np.einsum("bji,bj->bi", C_b_p, w_ie + transport_rate_n(
            s.lat, s.h, s.v_n))
        lever_p = np.einsum("bij,bj->bi", C_b_p, l)                 # C_b^p l
        lever_v = np.einsum("bij,bj->bi", C_b_p, cross(w_nb, l))  # C_b^p (w x l)
        metres = metres_per_geodetic(s.lat, s.h)
        # z: INS antenna minus GNSS (ENU m/s, and m along E, N, U).
        z = np.full((self.batch, 6), np.nan)
        z[:, :3] = s.v_n + lever_v - inp.gps_v_n[:, k + 1]
        dp = np.stack([s.lon - inp.gps_lon[:, k + 1], s.lat - inp.gps_lat[:, k + 1],
                       s.h - inp.gps_h[:, k + 1]], -1)
        z[:, 3:] = dp * metres[:, [1, 0, 2]] + lever_p
        R = np.zeros((self.batch, 6, 6))
        R[:, :3, :3] = np.eye(3) * tu.gnss_velocity_sigma ** 2
        R[:, 3:, 3:] = np.diag([tu.gnss_position_sigma_h ** 2] * 2
                               + [tu.gnss_position_sigma_v ** 2])
        R = R * per_member(r_scale, self.batch)
        v_ins = s.v_n
        variant = self.variant
        # E, N, U metres of dp = (dL, dlambda, dh): rows [0, Rn cos L, 0], [R_M + h, 0, 0].
        D = np.zeros((self.batch, 3, 3))
        D[:, 0, 1], D[:, 1, 0], D[:, 2, 2] = metres[:, 1], metres[:, 0], 1.0
        if variant == "st-linear":
            H = np.zeros((self.batch, 6, N_STATES))
            H[:, :3, PHI] = skew(v_ins + lever_v)
            H[:, :3, DV] = np.eye(3)
            H[:, 3:, PHI] = skew(lever_p)
            H[:, 3:, DP] = D
            return Observation(noise=R, matrix=H, z=z, t=float(self.t[k + 1]))
        Vb, Lv, Lp, Db = v_ins[:, None], lever_v[:, None], lever_p[:, None], D[:, None]

        def fn(x: np.ndarray) -> np.ndarray:
            C_p_n = rotvec_to_dcm(x[..., PHI])
            turn = lambda a: a - np.einsum("...ij,...j->...i", C_p_n, a)  # noqa: E731
            dv = st_to_classic(x, Vb)[..., DV] if variant == "st" else x[..., DV]
            return np.concatenate([dv + turn(Lv), np.einsum("...ij,...j->...i", Db,
                                                            x[..., DP]) + turn(Lp)], -1)

        return Observation(noise=R, fn=fn, z=z, t=float(self.t[k + 1]))

    def feedback(self, x, P, live):
        """(6.8) for the episodes whose heading sigma is below feedback_below (all with
        None): C_b^n <- exp([phi x]) C_b^p, v <- v~ - dv (the classic velocity error),
        p <- p~ - dp, biases accumulated, the state reset and P <- G P G^T
        (``reset_jacobian``: the error state changes with a large estimate)."""
        k = self._k
        ready = live.copy()
        if self.feedback_below is not None:
            ready &= np.sqrt(np.maximum(P[:, 2, 2], 0.0)) < self.feedback_below
        if not ready.any():
            self._record_bias(k)
            return x, P
        x = x.copy()
        b = np.flatnonzero(ready)
        s = self.ins.state
        dv = (st_to_classic(x[b], s.v_n[b])[:, DV] if self.variant != "classic"
              else x[b, DV])
        if self.variant == "st-linear":     # (6.8)'s small-angle form
            dv = x[b, DV] + cross(s.v_n[b], x[b, PHI])
        C_b_n = rotvec_to_dcm(x[b, PHI]) @ self._C_b_p[b, k]
        s.q_b_n[b] = dcm_to_quat(C_b_n)
        self._C_b_p[b, k] = C_b_n
        s.v_n[b] -= dv
        s.lat[b] -= x[b, 6]
        s.lon[b] -= x[b, 7]
        s.h[b] -= x[b, 8]
        self.ins.gyro_bias[b] += x[b, EPS]
        self.ins.accel_bias[b] += x[b, NABLA]
        G = reset_jacobian(x[b], self.variant)
        P = P.copy()
        P[b] = G @ P[b] @ np.swapaxes(G, -1, -2)
        x[b] = 0.0
        self.feedback_count[b] += 1
        self._record_bias(k)
        return x, P

    def _record_bias(self, k: int) -> None:
        self._bias["gyro_bias"][:, k] = self.ins.gyro_bias
        self._bias["accel_bias"][:, k] = self.ins.accel_bias

    def attitude(self, k, x):
        return rotvec_to_dcm(x[:, PHI]) @ self._C_b_p[:, k]

    def attitude_sigma(self, k, P):
        return np.sqrt(np.maximum(np.diagonal(P[:, PHI, PHI], axis1=-2, axis2=-1), 0.0))

