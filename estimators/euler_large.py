"""Seed 002's large-misalignment model with Euler error angles on a static base
(ALGORITHMS 3.1, ENU/RFU restatement; SPEC 4.4): the filter model, its tuning and the
feedback into its INS. The open-loop static-base INS it runs on is
``euler_integrals``; the Euler-angle kinematics and the error dynamics below are
``euler_kinematics``.

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

from aligngym.estimators.euler_integrals import StaticBaseIntegrals
from aligngym.estimators.euler_kinematics import (ALPHA, DV, EPS, N_STATES, NABLA, C_omega_inv,
                                                  C_p_n, level_rotation, midpoint_jacobian,
                                                  midpoint_step, reset_jacobian)
from aligngym.estimators.model import (Epoch, FilterModel, Observation, StateLayout,
                                       Transition, add_once_per_epoch, epoch_time,
                                       per_member)
from aligngym.models.earth import OMEGA_IE
from aligngym.models.units import deg, deg_per_h, mg

LAYOUT = StateLayout({"euler_error": ALPHA, "velocity_error": DV, "accel_bias": NABLA,
                      "gyro_bias": EPS}, angles=(0, 1, 2))
_H = np.hstack([np.zeros((2, 3)), np.eye(2), np.zeros((2, 5))])
_IDENTITY = np.eye(N_STATES)[None]
"""The (1, 10, 10) identity: the feedback's reset transform outside the Euler block."""


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
        self._v_epoch = np.full(B, -1)   # each episode's last epoch whose velocity is in _v
        self.feedback_count = np.zeros(B, int)

    def initial(self):
        self._x_lin = np.zeros((self.batch, N_STATES))
        return self._x_lin.copy(), self._P0.copy()

    def _args(self, k: Epoch) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
        self._v, self._v_epoch = add_once_per_epoch(
            self._v, self._v_epoch, k, lambda: self.integrals.delta_v(self.C0, k))
        return Observation(noise=per_member(r_scale, self.batch) * self._R, matrix=self._Hb,
                           z=self._v[:, :2].copy(), t=epoch_time(self.t, k + 1))

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


class SmallAngleModel(EulerLargeMisalignmentModel):
    """The same states, noise and measurement with the process linearised once at
    alpha = 0 (Phi = the RK4 Jacobian at zero): the classic small-angle linear model, the
    contrast that fails from a large azimuth error."""

    def transition(self, k, q_scale=(1.0, 1.0)):
        noise = super().transition(k, q_scale).noise
        Phi = midpoint_jacobian(np.zeros((self.batch, N_STATES)), self.T, *self._args(k))
        return Transition(noise=noise, matrix=Phi)
