"""Odometer-aided in-motion fine alignment with a large heading error (seed 000;
ALGORITHMS 4.1): 16 states x = [phi_E, phi_N, phi_U, dv (3), dp = (dL, dlambda, dh),
eps (3), nabla (3), dK_D] in ENU/RFU, phi the Euler error angles of the computed frame
n' (C_n'^n = Rz(phi_U) Rx(phi_E) Ry(phi_N)), phi_E and phi_N small, phi_U large.

With c = cos(phi_U), s = sin(phi_U) the model is conditionally linear in phi_U (4.5):
x_dot = A(phi_U) x + b(phi_U), discretised per epoch of T seconds as
x_k = (I + T A + (T A)^2 / 2) x_{k-1} + (T + T^2 A / 2) b, so the reduced-dimension
Gauss-Hermite rule integrates over phi_U only. The measurement (4.6-4.7) is the INS's
position increment over the epoch minus the odometer's, resolved with the INS attitude:
z = sum v~ T_s - sum C~_b^n dS~^b (dS~^b = [0, ds, 0] times the estimated scale, plus
the lever arm's displacement from the odometer's axle to the IMU), whose model is
z = T dv_bar - CB(phi) dS^ + dK_D Cz^T dS^ (known-quantity form), with the epoch's mean
velocity error dv_bar = dv_k - (T/2)(A x + b)_dv (ALGORITHMS takes dv_k).

The model runs its own strapdown on bias-compensated increments: open loop while the
heading sigma is above ``feedback_below`` (the large-angle model carries the full error),
then closed loop (C_b^n <- C_n'^n(phi^) C_b^n', velocity, position, biases and scale
corrected, the state reset, phi's covariance through the reset Jacobian).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.euler_kinematics import C_p_n, reset_jacobian
from aligngym.estimators.model import (FilterModel, Observation, StateLayout, Transition,
                                       at_epoch, epoch_of, epoch_time, per_member,
                                       set_at_epoch)
from aligngym.estimators.strapdown import AidedInsInputs
from aligngym.models.attitude import dcm_to_quat, quat_to_dcm, skew
from aligngym.models.earth import (OMEGA_IE, earth_rate_n, metres_per_geodetic, radii,
                          transport_rate_n)

LAYOUT = StateLayout({"misalignment": slice(0, 3), "velocity": slice(3, 6),
                      "position": slice(6, 9), "gyro_bias": slice(9, 12),
                      "accel_bias": slice(12, 15), "odometer_scale": slice(15, 16)},
                     angles=(2,))
"""000's 16 states."""
LAYOUT_MOUNTING = StateLayout({**LAYOUT.blocks, "mounting": slice(16, 18)}, angles=(2,))
"""With the odometer's residual mounting pitch and heading (rad): 18 states."""
PHI, DV, DP = LAYOUT["misalignment"], LAYOUT["velocity"], LAYOUT["position"]
EPS, NABLA, KD = LAYOUT["gyro_bias"], LAYOUT["accel_bias"], 15
MOUNT_PITCH, MOUNT_HEADING = 16, 17
N_STATES = 16
HEADING = (2,)


@dataclass(frozen=True)
class OdometerTuning:
    """The filter's belief, SI. P0 sigmas: attitude (E, N, U) rad, velocity m/s, position
    m, gyro drift rad/s, accelerometer bias m/s^2, odometer scale (relative); white-noise
    densities: gyro rad/sqrt(s), accelerometer m/s/sqrt(s); measurement_sigma: per axis of
    the position-increment difference, m; mounting_sigma: P0 of the residual mounting
    pitch and heading, rad (None: no mounting states, 000's 16-state model)."""

    attitude_sigma: tuple[float, float, float]
    velocity_sigma: float
    position_sigma: float
    gyro_bias_sigma: float
    accel_bias_sigma: float
    scale_sigma: float
    gyro_noise_density: float
    accel_noise_density: float
    measurement_sigma: float
    mounting_sigma: float | None = None
    velocity_from_attitude: bool = False
    """The INS's start velocity is the odometer's turned by the INS's own attitude, so its
    error is (C_p^n(phi)^T - I) v, up to |v| sin(phi_U) horizontally: P0's horizontal
    velocity sigma becomes sqrt(velocity_sigma^2 + (|v| sigma_U)^2). (A Gaussian with the
    first-order correlation instead misleads the filters from a 30 deg prior: the
    dependence is on a circle, not a line.)"""


@dataclass
class OdometerInputs(AidedInsInputs):
    """``AidedInsInputs`` and the odometer: distance (B, K, S) m over each IMU interval;
    C_m_b (B, 3, 3) the nominal odometer mounting (vehicle axes to IMU); lever_arm_b
    (B, 3) m, the IMU from the odometer's axle centre, in the vehicle axes turned by
    C_m_b."""

    distance: np.ndarray
    C_m_b: np.ndarray
    lever_arm_b: np.ndarray


def _matrix(like: np.ndarray, entries: dict[tuple[int, int], np.ndarray | float]
            ) -> np.ndarray:
    """(..., 3, 3) zeros shaped like ``like`` (...,), in its float type, with the given
    (row, column) entries."""
    out = np.zeros(np.shape(like) + (3, 3), dtype=np.result_type(like, np.float16))
    for (i, j), value in entries.items():
        out[..., i, j] = value
    return out


def _cz(c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Cz (..., 3, 3) = [[c, s, 0], [-s, c, 0], [0, 0, 1]]."""
    return _matrix(c, {(0, 0): c, (0, 1): s, (1, 0): -s, (1, 1): c, (2, 2): 1.0})


@dataclass
class EpochQuantities:
    """The INS at one epoch (mid-epoch, B episodes): omega_in (B, 3) rad/s, f (B, 3)
    m/s^2 in n', C_b_n (B, 3, 3), v (B, 3) m/s, lat, h (B,)."""

    omega_in: np.ndarray
    f: np.ndarray
    C_b_n: np.ndarray
    v: np.ndarray
    lat: np.ndarray
    h: np.ndarray

    def A_and_b(self, phi_U: np.ndarray, n: int = N_STATES
                ) -> tuple[np.ndarray, np.ndarray]:
        """A(phi_U) (B, P, n, n) and b(phi_U) (B, P, n) at heading errors phi_U (B, P)
        (ALGORITHMS 4.1-4.5; states beyond the 16th are constants)."""
        B, P = phi_U.shape
        c, s = np.cos(phi_U), np.sin(phi_U)
        w = self.omega_in[:, None]
        f = self.f[:, None]
        A = np.zeros((B, P, n, n))
        Cz = _cz(c, s)
        # phi rows: M1 omega (phi_E, phi_N columns) + Cz d(omega_in) - C eps
        A[..., 0, 1] = w[..., 2]
        A[..., 1, 0] = -w[..., 2]
        A[..., 2, 0] = -s * w[..., 0] + c * w[..., 1]
        A[..., 2, 1] = -w[..., 0]
        lat, h, v = self.lat, self.h, self.v
        R_M, R_N = radii(lat)
        R_Mh, R_Nh = R_M + h, R_N + h
        tL, secL = np.tan(lat), 1.0 / np.cos(lat)
        M_av = _matrix(lat, {(0, 1): -1 / R_Mh, (1, 0): 1 / R_Nh, (2, 0): tL / R_Nh})
        # d(omega_ie + omega_en)/d(dL, dlambda, dh); d(omega_ie)/d dp alone for Coriolis.
        M_ie = _matrix(lat, {(1, 0): -OMEGA_IE * np.sin(lat), (2, 0): OMEGA_IE * np.cos(lat)})
        M_en = _matrix(lat, {(0, 2): v[:, 1] / R_Mh ** 2, (1, 2): -v[:, 0] / R_Nh ** 2,
                             (2, 0): v[:, 0] * secL ** 2 / R_Nh,
                             (2, 2): -v[:, 0] * tL / R_Nh ** 2})
        A[..., PHI, DV] = Cz @ M_av[:, None]
        A[..., PHI, DP] = Cz @ (M_ie + M_en)[:, None]
        A[..., PHI, EPS] = -self.C_b_n[:, None]
        # dv rows: CB f (phi_E, phi_N columns), Cz^T C nabla, Coriolis and transport.
        A[..., 3, 0], A[..., 4, 0], A[..., 5, 0] = -s * f[..., 2], c * f[..., 2], -f[..., 1]
        A[..., 3, 1], A[..., 4, 1], A[..., 5, 1] = -c * f[..., 2], -s * f[..., 2], f[..., 0]
        omega_ie = earth_rate_n(lat)
        omega_en = self.omega_in - omega_ie
        V = skew(v)
        A[..., DV, DV] = (-skew(2 * omega_ie + omega_en) + V @ M_av)[:, None]
        A[..., DV, DP] = (V @ (2 * M_ie + M_en))[:, None]
        A[..., DV, NABLA] = np.swapaxes(Cz, -1, -2) @ self.C_b_n[:, None]
        # dp rows
        M_pv = _matrix(lat, {(0, 1): 1 / R_Mh, (1, 0): secL / R_Nh, (2, 2): 1.0})
        M_pp = _matrix(lat, {(0, 2): -v[:, 1] / R_Mh ** 2,
                             (1, 0): v[:, 0] * secL * tL / R_Nh,
                             (1, 2): -v[:, 0] * secL / R_Nh ** 2})
        A[..., DP, DV] = M_pv[:, None]
        A[..., DP, DP] = M_pp[:, None]
        b = np.zeros((B, P, n))
        b[..., 0] = (1 - c) * w[..., 0] - s * w[..., 1]
        b[..., 1] = s * w[..., 0] + (1 - c) * w[..., 1]
        b[..., 3] = (1 - c) * f[..., 0] + s * f[..., 1]
        b[..., 4] = -s * f[..., 0] + (1 - c) * f[..., 1]
        return A, b


def increment_map(phi_U: np.ndarray, dS: np.ndarray, T: float,
                  sideways: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The measurement's H(phi_U) (B, P, 3, n) and h(phi_U) (B, P, 3) for the odometer
    increment dS^ (B, 3) in n' (ALGORITHMS 4.7); sideways: (X, Z) (B, 3) m, the
    odometer's distance along the vehicle's right and up axes resolved like dS^, for the
    mounting states (n = 18; the odometer's true direction in the IMU frame is
    [psi_m, 1, -theta_m] for a residual mounting heading psi_m and pitch theta_m)."""
    B, P = phi_U.shape
    c, s = np.cos(phi_U), np.sin(phi_U)
    d = dS[:, None]
    H = np.zeros((B, P, 3, N_STATES if sideways is None else N_STATES + 2))
    H[..., 0, 0], H[..., 1, 0], H[..., 2, 0] = s * d[..., 2], -c * d[..., 2], d[..., 1]
    H[..., 0, 1], H[..., 1, 1], H[..., 2, 1] = c * d[..., 2], s * d[..., 2], -d[..., 0]
    H[..., 0, 3] = H[..., 1, 4] = H[..., 2, 5] = T
    CzT = np.swapaxes(_cz(c, s), -1, -2)
    H[..., :, KD] = np.einsum("bpij,bpj->bpi", CzT, np.broadcast_to(d, (B, P, 3)))
    h = -(d - np.einsum("bpij,bpj->bpi", CzT, np.broadcast_to(d, (B, P, 3))))
    if sideways is not None:
        X, Z = sideways
        H[..., :, MOUNT_PITCH] = -np.einsum("bpij,bj->bpi", CzT, Z)
        H[..., :, MOUNT_HEADING] = np.einsum("bpij,bj->bpi", CzT, X)
    return H, h


class OdometerLargeHeadingModel(FilterModel):
    """The 16-state model (module docstring) on B episodes; feedback_below: heading sigma
    (rad) below which an episode's estimate is fed back after each update (None: open
    loop throughout). ``series``: the accumulated gyro_bias, accel_bias, scale and
    mounting estimates (B, K+1, ...), which with x give the sensor-error estimates, and
    v_n, the velocity estimate (INS less dv), m/s ENU."""

    scratch = ("_increment", "_quantities", "_sideways")

    def __init__(self, inputs: OdometerInputs, tuning: OdometerTuning,
                 feedback_below: float | None = None) -> None:
        self.inputs, self.tuning, self.feedback_below = inputs, tuning, feedback_below
        self.mounting = tuning.mounting_sigma is not None
        self.layout = LAYOUT_MOUNTING if self.mounting else LAYOUT
        self.n = self.layout.n
        B, K, S = inputs.dtheta.shape[:3]
        self.batch, self.epochs, self.t = B, K, inputs.t
        self.T = float(inputs.t[1] - inputs.t[0])
        self.ins = inputs.strapdown()
        self.scale = np.ones(B)
        self.mount = np.zeros((B, 2))          # accumulated mounting pitch, heading (rad)
        self.feedback_count = np.zeros(B, int)
        self._C_b_n = np.empty((B, K + 1, 3, 3))
        self._C_b_n[:, 0] = quat_to_dcm(self.ins.state.q_b_n)
        self._series = {"gyro_bias": np.zeros((B, K + 1, 3)),
                        "accel_bias": np.zeros((B, K + 1, 3)), "scale": np.ones((B, K + 1)),
                        "mounting": np.zeros((B, K + 1, 2)),
                        "v_n": np.zeros((B, K + 1, 3))}
        self._series["v_n"][:, 0] = self.ins.state.v_n
        self._increment = None
        self._k = np.zeros(B, int)   # each episode's boundary after its last update

    def series(self):
        return self._series

    def initial(self):
        tu, B = self.tuning, self.batch
        sig = np.zeros((B, self.n))
        sig[:, PHI] = tu.attitude_sigma
        sig[:, DV] = tu.velocity_sigma
        sig[:, DP] = tu.position_sigma / metres_per_geodetic(self.ins.state.lat,
                                                            self.ins.state.h)
        sig[:, EPS] = tu.gyro_bias_sigma
        sig[:, NABLA] = tu.accel_bias_sigma
        sig[:, KD] = tu.scale_sigma
        if self.mounting:
            sig[:, MOUNT_PITCH:] = tu.mounting_sigma
        P = sig[:, :, None] ** 2 * np.eye(self.n)
        if tu.velocity_from_attitude:
            speed = np.linalg.norm(self.ins.state.v_n[:, :2], axis=-1)
            extra = (speed * tu.attitude_sigma[2]) ** 2
            P[:, 3, 3] += extra
            P[:, 4, 4] += extra
        return np.zeros((B, self.n)), P

    def transition(self, k, q_scale=(1.0, 1.0)):
        inp, dt, T = self.inputs, self.inputs.imu_dt, self.T
        out, dtheta, dv = self.ins.run_compensated(at_epoch(inp.dtheta, k),
                                                   at_epoch(inp.dv, k))
        S = dtheta.shape[1]
        C = quat_to_dcm(out["q_b_n"])                                  # (B, S+1, 3, 3)
        mid = S // 2
        lat, h, v = out["lat"][:, mid], out["h"][:, mid], out["v_n"][:, mid]
        omega_in = earth_rate_n(lat) + transport_rate_n(lat, h, v)
        quantities = EpochQuantities(
            omega_in=omega_in, f=np.einsum("bij,bj->bi", C[:, mid], dv.sum(1) / (S * dt)),
            C_b_n=C[:, mid], v=v, lat=lat, h=h)
        # The epoch's increments for the observation: INS displacement (trapezoid) and
        # the odometer's, resolved at mid-interval, plus the lever arm's displacement.
        v_n = out["v_n"]
        ins_displacement = 0.5 * dt * (v_n[:, 1:] + v_n[:, :-1]).sum(1)
        C_mid = 0.5 * (C[:, 1:] + C[:, :-1])
        ds = at_epoch(inp.distance, k) * self.scale[:, None]                   # (B, S)
        # The odometer's axes in the IMU frame, with the mounting estimated so far.
        mount = np.stack([self.mount[:, 1], np.ones(self.batch), -self.mount[:, 0]], -1)
        forward = np.einsum("bij,bj->bi", inp.C_m_b, mount)
        resolved = lambda axis: np.einsum(  # noqa: E731
            "bsij,bs,bj->bi", C_mid, ds, axis)
        odometer = resolved(forward)
        self._sideways = (resolved(inp.C_m_b[:, :, 0]), resolved(inp.C_m_b[:, :, 2]))
        lever = np.einsum("bij,bj->bi", C[:, -1] - C[:, 0], inp.lever_arm_b)
        self._increment = (ins_displacement, odometer + lever)
        self._quantities = quantities
        set_at_epoch(self._C_b_n, k + 1, C[:, -1])
        n = self.n
        q = np.zeros((self.batch, n))
        q[:, PHI] = self.tuning.gyro_noise_density ** 2 * per_member(q_scale[0], self.batch)[:, 0]
        q[:, DV] = self.tuning.accel_noise_density ** 2 * per_member(q_scale[1], self.batch)[:, 0]
        Q = q[:, :, None] * np.eye(n) * T

        def conditional(zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            A, b = quantities.A_and_b(zeta[..., 0], n)
            AT = A * T
            F = np.eye(n) + AT + 0.5 * AT @ AT
            g = np.einsum("bpij,bpj->bpi", np.eye(n) * T + 0.5 * T * AT, b)
            return F, g

        def fn(x: np.ndarray) -> np.ndarray:
            F, g = conditional(x[..., 2:3])
            return np.einsum("bpij,bpj->bpi", F, x) + g

        return Transition(noise=Q, fn=fn, conditional=conditional, nonlinear=HEADING,
                          angles=HEADING)

    def observation(self, k, r_scale=1.0):
        if self._increment is None:
            raise RuntimeError("observation() needs the epoch's transition() first")
        ins_displacement, odometer = self._increment
        self._k = k + 1
        z = ins_displacement - odometer
        T = self.T

        quantities, n = self._quantities, self.n
        sideways = self._sideways if self.mounting else None

        def conditional(zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            H, h = increment_map(zeta[..., 0], odometer, T, sideways)
            # T dv_bar with dv_bar = dv_k - (T / 2) dv_dot: the epoch's mean velocity
            # error, not its end value (open loop with a large heading error, dv grows
            # by tenths of m/s per second).
            A, b = quantities.A_and_b(zeta[..., 0], n)
            return H - 0.5 * T * T * A[..., DV, :], h - 0.5 * T * T * b[..., DV]

        def fn(x: np.ndarray) -> np.ndarray:
            H, h = conditional(x[..., 2:3])
            return np.einsum("bpij,bpj->bpi", H, x) + h

        R = np.eye(3) * self.tuning.measurement_sigma ** 2 * per_member(r_scale, self.batch)
        speed = np.linalg.norm(odometer, axis=-1) / T
        return Observation(noise=R, fn=fn, conditional=conditional,
                           nonlinear=HEADING, z=z, t=epoch_time(self.t, k + 1),
                           motion=speed > 0.5)

    def feedback(self, x, P, live):
        k = self._k
        if self.feedback_below is not None:
            ready = live & (np.sqrt(np.maximum(P[:, 2, 2], 0.0)) < self.feedback_below)
            if ready.any():
                x, P = x.copy(), P.copy()
                b = np.flatnonzero(ready)
                s = self.ins.state
                C_fix = C_p_n(x[b, PHI])
                C_b_n = C_fix @ quat_to_dcm(s.q_b_n[b])
                s.q_b_n[b] = dcm_to_quat(C_b_n)
                s.v_n[b] -= x[b, DV]
                s.lat[b] -= x[b, 6]
                s.lon[b] -= x[b, 7]
                s.h[b] -= x[b, 8]
                self.ins.gyro_bias[b] += x[b, EPS]
                self.ins.accel_bias[b] += x[b, NABLA]
                self.scale[b] *= 1.0 + x[b, KD]
                if self.mounting:
                    self.mount[b] += x[b, MOUNT_PITCH:]
                self._C_b_n[b, epoch_of(k, b)] = C_b_n
                J = np.broadcast_to(np.eye(self.n), (b.size, self.n, self.n)).copy()
                J[:, PHI, PHI] = reset_jacobian(x[b, PHI])
                P[b] = J @ P[b] @ np.swapaxes(J, -1, -2)
                x[b] = 0.0
                self.feedback_count[b] += 1
        for name, value in (("gyro_bias", self.ins.gyro_bias),
                            ("accel_bias", self.ins.accel_bias), ("scale", self.scale),
                            ("mounting", self.mount),
                            ("v_n", self.ins.state.v_n - x[:, DV])):     # v_n: the estimate
            set_at_epoch(self._series[name], k, value)
        return x, P

    def attitude(self, k, x):
        """C_b^n = C_n'^n(phi^) C_b^n' (B, 3, 3) at boundary k."""
        return C_p_n(x[:, PHI]) @ at_epoch(self._C_b_n, k)

    def attitude_sigma(self, k, P):
        return np.sqrt(np.maximum(np.diagonal(P[:, PHI, PHI], axis1=-2, axis2=-1), 0.0))
