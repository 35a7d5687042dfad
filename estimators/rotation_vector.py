"""Paper 004's GNSS-aided fine alignment on seed 004's rotation-vector large-misalignment
model (ALGORITHMS 6): the filter model the STEKF, the STUKF and the classic large-angle
UKF/EKF of paper 004 run on (``RotationVectorGnssModel`` in one of ``VARIANTS``: GNSS
velocity and position at the antenna, ENU m/s and m, the lever arm in the IMU frame), its
tuning (SI) and the inputs of an IMU turned by an indexer. The 15-state error state (ENU:
phi rad, dv m/s, dp = (dL, dlambda, dh), eps rad/s and nabla m/s^2 in the body frame), its
transformation, derivatives and matrices are ``rotation_vector_dynamics``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from aligngym.estimators.model import (Epoch, FilterModel, Observation, Transition, at_epoch,
                                       epoch_of, epoch_time, per_member, set_at_epoch)
from aligngym.estimators.loose_gps import GpsInsInputs
from aligngym.estimators.rotation_vector_dynamics import (DP, DV, EPS, LAYOUT, N_STATES, NABLA,
                                                          PHI, InsQuantities,
                                                          reset_jacobian, st_to_classic,
                                                          stekf_matrix)
from aligngym.estimators.strapdown import body_rate_at
from aligngym.models.attitude import cross, dcm_to_quat, quat_to_dcm, rotvec_to_dcm, skew
from aligngym.models.earth import earth_rate_n, metres_per_geodetic, transport_rate_n


Derivative = Callable[[np.ndarray, InsQuantities], np.ndarray]
"""An error-state derivative x (..., 15) -> x_dot (..., 15) given the INS's quantities
(``st_derivative``, ``classic_derivative``)."""


def numpy_runge_kutta_step(derivative: Derivative, x: np.ndarray, T: float,
                           quantities: tuple[InsQuantities, ...]) -> np.ndarray:
    """One classical Runge-Kutta step of T s of ``derivative`` at points x (B, P, 15), the
    INS's quantities at the step's start, middle and end (each (B, 1, ...)), in NumPy: the
    reference of the compiled ``runge_kutta_step``, and how a variant of the model's rows
    is integrated."""
    q0, qm, q1 = quantities
    a = derivative(x, q0)
    b = derivative(x + 0.5 * T * a, qm)
    c = derivative(x + 0.5 * T * b, qm)
    d = derivative(x + T * c, q1)
    return x + T / 6.0 * (a + 2 * b + 2 * c + d)


def _stages(quantities: tuple[InsQuantities, ...]) -> tuple[np.ndarray, ...]:
    """The INS's quantities at a step's start, middle and end (each with one point axis,
    ``RotationVectorGnssModel._quantities``) stacked for ``runge_kutta_step``: C_b_p
    (3, B, 3, 3), f_b, v, omega_ie, omega_en, g and d(L, lambda, h)/dt (3, B, 3), lat, h
    (3, B)."""
    rates = [q.rates() + (q.position_rate(),) for q in quantities]
    fields = ([q.C_b_p for q in quantities], [q.f_b for q in quantities],
              [q.v for q in quantities], *zip(*rates))
    return (*(np.stack([a[:, 0] for a in field]) for field in fields),
            np.stack([q.lat[:, 0] for q in quantities]),
            np.stack([q.h[:, 0] for q in quantities]))


def runge_kutta_step(x: np.ndarray, T: float, transformed: bool,
                     stages: tuple[np.ndarray, ...]) -> np.ndarray:
    """One classical Runge-Kutta step of T s of the error state at points x (B, ..., 15)
    of ``st_derivative`` (transformed) or ``classic_derivative`` with the INS's quantities
    of ``_stages`` for B episodes, compiled (``rotation_vector_kernel``: on 31 points,
    8-12x faster than ``numpy_runge_kutta_step`` for one episode, 4-7x for 32; the same
    numbers within 4e-12 of each component's largest increment, a test)."""
    from aligngym.estimators.rotation_vector_kernel import runge_kutta_points  # Numba
    x = np.asarray(x, dtype=float)
    B = stages[-1].shape[1]
    if x.ndim < 2 or x.shape[0] != B or x.shape[-1] != N_STATES or any(
            a.shape[:2] != (3, B) for a in stages):
        raise ValueError(f"points {x.shape} for stages of {B} episodes: need (B, ..., "
                         f"{N_STATES}) and (3, B, ...) stages")
    # C order and writable: the one signature load_compiled_kernels compiles
    points = np.require(x.reshape(B, int(np.prod(x.shape[1:-1])), N_STATES),
                        requirements=("C", "W"))
    out = np.empty_like(points)
    runge_kutta_points(points, float(T), bool(transformed), *stages, out)
    return out.reshape(x.shape)


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
                 feedback_below: float | None = None,
                 derivative: Derivative | None = None) -> None:
        """derivative: a NumPy error-state derivative to integrate in place of the
        variant's compiled one (``numpy_runge_kutta_step``; a study of the model's rows),
        for the nonlinear variants."""
        if variant not in VARIANTS:
            raise ValueError(f"variant {variant!r}; valid: " + ", ".join(VARIANTS))
        if derivative is not None and variant == "st-linear":
            raise ValueError("variant 'st-linear' has no derivative to replace")
        self.inputs, self.tuning, self.variant = inputs, tuning, variant
        self.derivative = derivative
        self.feedback_below = feedback_below
        self.layout = LAYOUT
        B, K = inputs.dtheta.shape[:2]
        self.batch, self.epochs, self.t = B, K, inputs.t
        self.T = float(inputs.t[1] - inputs.t[0])
        self.ins = inputs.strapdown()
        self._C_b_p = np.empty((B, K + 1, 3, 3))
        self._C_b_p[:, 0] = quat_to_dcm(self.ins.state.q_b_n)
        self._rate = np.zeros((B, 3))
        self._k = np.zeros(B, int)   # each episode's boundary after its last update
        self.feedback_count = np.zeros(B, int)
        self._bias = {name: np.zeros((B, K + 1, 3)) for name in ("gyro_bias", "accel_bias")}

    def series(self) -> dict[str, np.ndarray]:
        """The INS's accumulated bias estimates gyro_bias (rad/s) and accel_bias (m/s^2),
        (B, K+1, 3) at the epoch boundaries after feedback (the state holds the rest)."""
        return self._bias

    def _lever(self, k: Epoch) -> tuple[np.ndarray, np.ndarray]:
        """Lever arm l (B, 3) m in the IMU frame and the IMU's rate relative to the hull
        (B, 3) rad/s at epoch boundary k."""
        inp = self.inputs
        if isinstance(inp, IndexedGpsInsInputs):
            return at_epoch(inp.lever_arm_b, k), at_epoch(inp.omega_bs_s, k)
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
        out, dtheta, dv = self.ins.run_compensated(at_epoch(inp.dtheta, k),
                                                   at_epoch(inp.dv, k))
        S = dtheta.shape[1]
        mid = S // 2
        self._rate = body_rate_at(dtheta, dt, [S])[:, 0]
        set_at_epoch(self._C_b_p, k + 1, quat_to_dcm(out["q_b_n"][:, -1]))
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
        if self.derivative is not None:
            derivative, quantities = self.derivative, (q0, qm, q1)

            def fn(x: np.ndarray) -> np.ndarray:
                return numpy_runge_kutta_step(derivative, x, T, quantities)
        else:
            stages, transformed = _stages((q0, qm, q1)), self.variant == "st"

            def fn(x: np.ndarray) -> np.ndarray:
                return runge_kutta_step(x, T, transformed, stages)

        return Transition(noise=Q, fn=fn)

    def observation(self, k, r_scale=1.0):
        inp, tu = self.inputs, self.tuning
        self._k = k + 1
        s = self.ins.state
        C_b_p = at_epoch(self._C_b_p, k + 1)
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
        z[:, :3] = s.v_n + lever_v - at_epoch(inp.gps_v_n, k + 1)
        dp = np.stack([s.lon - at_epoch(inp.gps_lon, k + 1),
                       s.lat - at_epoch(inp.gps_lat, k + 1),
                       s.h - at_epoch(inp.gps_h, k + 1)], -1)
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
            return Observation(noise=R, matrix=H, z=z, t=epoch_time(self.t, k + 1))
        Vb, Lv, Lp, Db = v_ins[:, None], lever_v[:, None], lever_p[:, None], D[:, None]

        def fn(x: np.ndarray) -> np.ndarray:
            C_p_n = rotvec_to_dcm(x[..., PHI])
            turn = lambda a: a - np.einsum("...ij,...j->...i", C_p_n, a)  # noqa: E731
            dv = st_to_classic(x, Vb)[..., DV] if variant == "st" else x[..., DV]
            return np.concatenate([dv + turn(Lv), np.einsum("...ij,...j->...i", Db,
                                                            x[..., DP]) + turn(Lp)], -1)

        return Observation(noise=R, fn=fn, z=z, t=epoch_time(self.t, k + 1))

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
        C_b_n = rotvec_to_dcm(x[b, PHI]) @ self._C_b_p[b, epoch_of(k, b)]
        s.q_b_n[b] = dcm_to_quat(C_b_n)
        self._C_b_p[b, epoch_of(k, b)] = C_b_n
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

    def _record_bias(self, k: Epoch) -> None:
        set_at_epoch(self._bias["gyro_bias"], k, self.ins.gyro_bias)
        set_at_epoch(self._bias["accel_bias"], k, self.ins.accel_bias)

    def attitude(self, k, x):
        return rotvec_to_dcm(x[:, PHI]) @ at_epoch(self._C_b_p, k)

    def attitude_sigma(self, k, P):
        return np.sqrt(np.maximum(np.diagonal(P[:, PHI, PHI], axis1=-2, axis2=-1), 0.0))

