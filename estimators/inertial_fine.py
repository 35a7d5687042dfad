"""Fine alignment in the inertial frame: the 12-state model of paper 003 (eqs. 26-35,
ALGORITHMS.md 2.1) with the velocity-integral measurement, run for a batch of episodes.

State X = [dV^i (3), phi^i (3), eps (3), nabla (3)]: velocity-integral error and
misalignment in i, gyro drift and accelerometer bias in the sensor frame s.

Each filter keeps its own estimate of C_s0^i (the attitude of the frozen sensor frame in
i); the misalignment is fed back into it after every update (C_s0^i <- exp([phi x])
C_s0^i, phi <- 0), so the small-angle model stays valid while the gyro-derived C_s^s0 and
the specific-force integrals stay shared by all filters. Biases stay in the state.

The transition over one filter step of length T is integrated with the IMU-rate
integrals Psi = int C_s^i dt and Psi2 = int int C_s^i, exact for the 18 deg/s rotation:
dV_k = dV - [g x] T phi + [g x] Psi2 eps + Psi nabla, phi_k = phi - Psi eps.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.alignment import FineResult, run_alignment
from aligngym.estimators.filters import GaussianFilter
from aligngym.estimators.model import (FilterModel, Observation, StateLayout, Transition,
                                       add_once_per_epoch, at_epoch, epoch_time,
                                       per_member, stack_episodes, whole_steps)
from aligngym.estimators.inertial_frame import (BodyFrameIntegrals, C_n_i, gravity_i,
                                       gravity_velocity_i)
from aligngym.models.attitude import rotvec_to_dcm, skew

V, PHI, EPS, NABLA = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)
_I3 = np.eye(3)
N_STATES = 12
LAYOUT = StateLayout({"velocity_integral": V, "misalignment": PHI, "gyro_bias": EPS,
                      "accel_bias": NABLA})


@dataclass(frozen=True)
class FineTuning:
    """Filter tuning, SI. Sigmas of the initial covariance: velocity integral (m/s),
    misalignment E, N, U in n (rad), gyro drift (rad/s), accelerometer bias (m/s^2).
    White-noise densities (rad/sqrt(s), m/s/sqrt(s)). Measurement sigmas along E, N, U
    (m/s). step: filter period, s (a whole number of IMU intervals). start_sway_sigma: see
    ``initial_covariance``."""

    velocity_sigma: float
    attitude_sigma: tuple[float, float, float]
    gyro_bias_sigma: float
    accel_bias_sigma: float
    gyro_noise_density: float
    accel_noise_density: float
    measurement_sigma: tuple[float, float, float]
    step: float = 1.0
    start_sway_sigma: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def initial_covariance(self, C_n_i0: np.ndarray) -> np.ndarray:
        """P0 (B, 12, 12); the attitude block rotated from n to i at the start. The
        velocity block adds the sway centre's velocity at the start (start_sway_sigma,
        std along E, N, U, m/s): the measurement carries -C_n^i(t1) v_sway(t1) as a
        constant through the whole alignment, an initial error of dV, not white noise."""
        batch = C_n_i0.shape[0]
        P = np.zeros((batch, N_STATES, N_STATES))
        P[:, V, V] = np.eye(3) * self.velocity_sigma ** 2 + C_n_i0 @ np.diag(
            np.square(self.start_sway_sigma)) @ np.swapaxes(C_n_i0, -1, -2)
        P[:, PHI, PHI] = C_n_i0 @ np.diag(np.square(self.attitude_sigma)) @ np.swapaxes(
            C_n_i0, -1, -2)
        P[:, EPS, EPS] = np.eye(3) * self.gyro_bias_sigma ** 2
        P[:, NABLA, NABLA] = np.eye(3) * self.accel_bias_sigma ** 2
        return P


@dataclass(frozen=True)
class FineInputs:
    """A batch of episodes' shared integrals at the filter-step boundaries.

    t: (K+1,) s since t0. C_s_s0: (B, K+1, 3, 3). dW: (B, K, 3) m/s, specific-force
    integral minus lever-arm velocity change over each step, in s0. Psi, Psi2:
    (B, K, 3, 3) in s0 (s and s^2).
    """

    t: np.ndarray
    C_s_s0: np.ndarray
    dW: np.ndarray
    Psi: np.ndarray
    Psi2: np.ndarray


def fine_inputs(integrals: BodyFrameIntegrals, t1: float, duration: float,
                step: float) -> FineInputs:
    """Cut one episode's integrals into filter steps from t1 (s) for duration (s); the
    result has a batch axis of one (see ``stack_inputs``)."""
    t = integrals.t
    dt = t[1] - t[0]
    per_step = int(round(step / dt))
    if per_step < 1 or abs(per_step * dt - step) > 1e-9:
        raise ValueError(f"filter step {step} s must be a whole number of IMU intervals")
    K = whole_steps(duration, step)
    idx = int(round(t1 / dt)) + per_step * np.arange(K + 1)
    if idx[-1] >= t.size:
        raise ValueError(f"the data end at {t[-1]:g} s, before t1 + duration = "
                         f"{t1 + duration:g} s")
    C = integrals.C_s_s0
    W = integrals.V_f[idx] - integrals.V_la[idx]
    Psi = np.diff(integrals.Psi_cum[idx], axis=0)
    # Psi2 over [t_a, t_b] = int C (t_b - tau) dtau = t_b Psi - int C tau dtau.
    tau_mid = 0.5 * (t[:-1] + t[1:])
    C_tau = np.concatenate([np.zeros((1, 3, 3)), np.cumsum(
        0.5 * dt * (C[:-1] + C[1:]) * tau_mid[:, None, None], axis=0)])[idx]
    Psi2 = t[idx[1:], None, None] * Psi - np.diff(C_tau, axis=0)
    return FineInputs(t=t[idx], C_s_s0=C[idx][None], dW=np.diff(W, axis=0)[None],
                      Psi=Psi[None], Psi2=Psi2[None])


def stack_inputs(inputs: list[FineInputs]) -> FineInputs:
    """One batch from several episodes' inputs (same time grid)."""
    return stack_episodes(inputs)


class InertialFineModel(FilterModel):
    """The 12-state inertial-frame model for a batch of episodes (linear: Phi and H).

    C_s_i_start: (B, 3, 3) initial attitude estimate C_s^i(t1); lat (rad) and h (m): the
    known position of each episode's IMU, (B,) or scalar. The observation's axes are
    C_i^n, for per-axis fading factors along local East, North, Up.
    """

    layout = LAYOUT

    def __init__(self, inputs: FineInputs, C_s_i_start: np.ndarray, tuning: FineTuning,
                 lat: np.ndarray | float, h: np.ndarray | float) -> None:
        self.inputs, self.tuning = inputs, tuning
        t = self.t = inputs.t
        self.batch, self.epochs = inputs.dW.shape[:2]
        B = self.batch
        # C_s0^i estimate per episode: C_s^i(t1) C_s0^s(t1).
        self.C_s0_i = C_s_i_start @ np.swapaxes(inputs.C_s_s0[:, 0], -1, -2)
        lat = np.broadcast_to(np.asarray(lat, dtype=float), (B,))[:, None]
        h = np.broadcast_to(np.asarray(h, dtype=float), (B,))[:, None]
        self._C_n_i = C_n_i(t[None], lat)                          # (B, K+1, 3, 3)
        self._C_i_n = np.swapaxes(self._C_n_i, -1, -2)
        self._g_mid = gravity_i(0.5 * (t[:-1] + t[1:])[None], lat, h)  # (B, K, 3)
        self._V_grav = gravity_velocity_i(t[None], lat, h)           # (B, K+1, 3)
        self._H = np.broadcast_to(np.hstack([np.eye(3), np.zeros((3, 9))]), (B, 3, N_STATES))
        self._R_n = np.diag(np.square(tuning.measurement_sigma))
        self._Z_acc = np.zeros((B, 3))
        self._Z_epoch = np.full(B, -1)   # each episode's last epoch in _Z_acc

    def initial(self):
        return (np.zeros((self.batch, N_STATES)),
                self.tuning.initial_covariance(self._C_n_i[:, 0]))

    def transition(self, k, q_scale=(1.0, 1.0)):
        B, T, inputs = self.batch, self.tuning.step, self.inputs
        q_g = self.tuning.gyro_noise_density ** 2 * per_member(q_scale[0], B)
        q_a = self.tuning.accel_noise_density ** 2 * per_member(q_scale[1], B)
        Psi_i = self.C_s0_i @ at_epoch(inputs.Psi, k)
        Psi2_i = self.C_s0_i @ at_epoch(inputs.Psi2, k)
        G = skew(at_epoch(self._g_mid, k))
        Phi = np.zeros((B, N_STATES, N_STATES))
        Phi[:, np.arange(N_STATES), np.arange(N_STATES)] = 1.0
        Phi[:, V, PHI] = -G * T
        Phi[:, V, EPS] = G @ Psi2_i
        Phi[:, V, NABLA] = Psi_i
        Phi[:, PHI, EPS] = -Psi_i
        Q = np.zeros((B, N_STATES, N_STATES))
        Q[:, V, V] = q_a * T * _I3 + q_g * T ** 3 / 3.0 * G @ np.swapaxes(G, -1, -2)
        Q[:, V, PHI] = -q_g * T ** 2 / 2.0 * G
        Q[:, PHI, V] = Q[:, V, PHI].swapaxes(-1, -2)
        Q[:, PHI, PHI] = q_g * T * _I3
        return Transition(noise=Q, matrix=Phi)

    def observation(self, k, r_scale=1.0):
        self._Z_acc, self._Z_epoch = add_once_per_epoch(   # the specific-force integral
            self._Z_acc, self._Z_epoch, k,
            lambda: np.einsum("bij,bj->bi", self.C_s0_i, at_epoch(self.inputs.dW, k)))
        z = self._Z_acc - (at_epoch(self._V_grav, k + 1) - self._V_grav[:, 0])
        r = per_member(r_scale, self.batch)
        C_i_n = at_epoch(self._C_i_n, k + 1)
        R = r * at_epoch(self._C_n_i, k + 1) @ self._R_n @ C_i_n
        return Observation(noise=R, matrix=self._H, z=z, t=epoch_time(self.inputs.t, k + 1),
                           axes=C_i_n)

    def feedback(self, x, P, live):
        """The misalignment into this filter's C_s0^i (C_s0^i <- exp([phi x]) C_s0^i)."""
        correction = rotvec_to_dcm(np.where(live[:, None], x[:, PHI], 0.0))
        self.C_s0_i = correction @ self.C_s0_i
        x = x.copy()
        x[:, PHI] = np.where(live[:, None], 0.0, x[:, PHI])
        return x, P

    def attitude(self, k, x):
        return at_epoch(self._C_i_n, k) @ self.C_s0_i @ at_epoch(self.inputs.C_s_s0, k)

    def attitude_sigma(self, k, P):
        P_phi_n = at_epoch(self._C_i_n, k) @ P[:, PHI, PHI] @ at_epoch(self._C_n_i, k)
        return np.sqrt(np.maximum(np.diagonal(P_phi_n, axis1=-2, axis2=-1), 0.0))


def run_fine_alignment(filt: GaussianFilter, inputs: FineInputs, C_s_i_start: np.ndarray,
                       tuning: FineTuning, lat: np.ndarray | float, h: np.ndarray | float
                       ) -> FineResult:
    """Run one filter over all epochs for a batch (see InertialFineModel)."""
    return run_alignment(filt, InertialFineModel(inputs, C_s_i_start, tuning, lat, h))


@dataclass(frozen=True)
class SwaySpectrum:
    """The linear sway of the sway centre as narrow-band noise per local axis E, N, U
    (ALGORITHMS 2.12): period (s) and sigma (m/s) of each axis's velocity, damping ratio
    zeta of the shaping oscillators."""

    period: tuple[float, float, float]
    sigma: tuple[float, float, float]
    damping: float = 0.02


SWAY = slice(12, 18)
LAYOUT_SWAY = StateLayout({**LAYOUT.blocks, "sway": SWAY})
_PICK_V = np.zeros((3, 6))
_PICK_V[np.arange(3), 2 * np.arange(3)] = 1.0   # v_j of each oscillator [v_j, u_j]


class SwayAwareInertialModel(InertialFineModel):
    """The 12-state model augmented with the sway velocity as three narrow-band states
    pairs (ALGORITHMS 2.12-2.13; beyond paper 003): per local axis j, x_j = [v_j, u_j],
    x_j,k+1 = exp(-zeta w_j T) Rot(w_j T) x_j,k + w, stationary std(v_j) = sigma_j. The
    measurement sees dV^i + C_n^i(t) v_D(t) - C_n^i(t1) v_D(t1); the constant second term
    is absorbed into dV's initial covariance (anti-correlated with the oscillators' start).
    R is then the sensor-level (calm-sea) noise of ``tuning``."""

    layout = LAYOUT_SWAY

    def __init__(self, inputs: FineInputs, C_s_i_start: np.ndarray, tuning: FineTuning,
                 lat: np.ndarray | float, h: np.ndarray | float, sway: SwaySpectrum) -> None:
        super().__init__(inputs, C_s_i_start, tuning, lat, h)
        self.sway = sway
        T = tuning.step
        w = 2 * np.pi / np.asarray(sway.period, dtype=float)
        decay = np.exp(-sway.damping * w * T)
        c, s = np.cos(w * T), np.sin(w * T)
        self._A = np.zeros((6, 6))
        self._Q_sway = np.zeros((6, 6))
        sigma2 = np.square(sway.sigma)
        for j in range(3):
            block = slice(2 * j, 2 * j + 2)
            self._A[block, block] = decay[j] * np.array([[c[j], s[j]], [-s[j], c[j]]])
            self._Q_sway[block, block] = sigma2[j] * (1.0 - decay[j] ** 2) * np.eye(2)
        self._P_sway = np.diag(np.repeat(sigma2, 2))

    def initial(self):
        x12, P12 = super().initial()
        B = self.batch
        P = np.zeros((B, 18, 18))
        P[:, :12, :12] = P12
        C = self._C_n_i[:, 0]                                  # C_n^i(t1)
        sigma2 = np.square(self.sway.sigma)
        P[:, V, V] += C @ (sigma2[:, None] * np.swapaxes(C, -1, -2))
        P[:, SWAY, SWAY] = self._P_sway
        P[:, V, SWAY] = -(C * sigma2[None, None, :]) @ _PICK_V
        P[:, SWAY, V] = np.swapaxes(P[:, V, SWAY], -1, -2)
        return np.zeros((B, 18)), P

    def transition(self, k, q_scale=(1.0, 1.0)):
        base = super().transition(k, q_scale)
        B = self.batch
        Phi = np.zeros((B, 18, 18))
        Q = np.zeros((B, 18, 18))
        Phi[:, :12, :12], Q[:, :12, :12] = base.matrix, base.noise
        Phi[:, SWAY, SWAY], Q[:, SWAY, SWAY] = self._A, self._Q_sway
        return Transition(noise=Q, matrix=Phi)

    def observation(self, k, r_scale=1.0):
        base = super().observation(k, r_scale)
        H = np.zeros((self.batch, 3, 18))
        H[:, :, :12] = base.matrix
        H[:, :, SWAY] = at_epoch(self._C_n_i, k + 1) @ _PICK_V
        return Observation(noise=base.noise, matrix=H, z=base.z, t=base.t, axes=base.axes)
