"""Loosely coupled GPS/INS with the single-antenna GPS heading (seed 001; ALGORITHMS 5.1).

Error state in the e frame (ECEF), as in 001: x = [dr^e, dv^e, phi^e, d, b] (15), the
INS position and velocity errors (m, m/s), the misalignment (C~_b^e = (I - [phi x])
C_b^e, rad), the gyro drift (rad/s) and the accelerometer bias (m/s^2), both in the
body frame. The INS itself runs the ENU strapdown (``estimators.strapdown``) at the IMU
rate on increments corrected with the accumulated bias estimates; every epoch the
estimate is fed back into it (closed loop), so the predicted state is zero (001 eq. 8).

Error dynamics (Jekeli 2001; ALGORITHMS 5.1):
  dr' = dv;  dv' = Gamma dr - 2 [w_ie x] dv + [f^e x] phi + C_b^e b;
  phi' = -[w_ie x] phi - C_b^e d;  d' = b' = 0,
with the gravity gradient Gamma = (g / r)(3 u u^T - I) of a spherical earth.

Measurements at each GPS fix (001 eq. 12), all INS minus GPS, the antenna lever arm l^b
(from the IMU to the antenna, body frame) compensated:
  r_I + C_b^e l - r_G;  v_I + C_b^e (w_eb x l) - v_G  (e frame, m, m/s);
  psi_I - psi_G (heading clockwise from north, rad, wrapped), only in motion above the
  heading speed threshold, with 001 eqs. 2-4's sigma; its row is
  h_psi = [-tan(theta) sin(psi), -tan(theta) cos(psi), 1] R_Le, which is R_Le(3, :) on a
  level vehicle (ALGORITHMS 5.1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.model import (Epoch, FilterModel, Observation, StateLayout,
                                       Transition, at_epoch, epoch_time, per_member,
                                       set_at_epoch, wrap_angle)
from aligngym.estimators.strapdown import AidedInsInputs, body_rate_at
from aligngym.models.attitude import (cross, dcm_to_quat, quat_to_dcm, rotvec_to_dcm,
                                      skew)
from aligngym.models.earth import (C_n_e, OMEGA_IE, earth_rate_n, ecef_to_geodetic,
                          geodetic_to_ecef, normal_gravity, radii)

LAYOUT = StateLayout({"position": slice(0, 3), "velocity": slice(3, 6),
                      "misalignment": slice(6, 9), "gyro_bias": slice(9, 12),
                      "accel_bias": slice(12, 15)})
POSITION, VELOCITY, PHI = LAYOUT["position"], LAYOUT["velocity"], LAYOUT["misalignment"]
GYRO, ACCEL = LAYOUT["gyro_bias"], LAYOUT["accel_bias"]
MEASUREMENTS = ("r_x", "r_y", "r_z", "v_x", "v_y", "v_z", "heading")
HEADING = 6
OMEGA_IE_E = np.array([0.0, 0.0, OMEGA_IE])


def ins_start_at_fix(C_b_n: np.ndarray, lat: float, lon: float, h: float, v_n: np.ndarray,
                     lever_arm_b: np.ndarray, dtheta: np.ndarray, dt: float,
                     omega_bs_b: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """An INS start for one episode at the IMU, from a GNSS fix of the antenna (lat, lon
    rad; h m; v_n (3,) m/s ENU) with the attitude C_b_n (3, 3) and the lever arm
    lever_arm_b (3,) m, IMU to antenna in the IMU frame: position less C l, velocity less
    C (w_nb x l), w_nb from gyro increments dtheta (S >= 2, 3) rad of interval dt s
    (at the first boundary, ``strapdown.body_rate_at``), less the earth rate and, for an IMU turning on its carrier, its rate
    omega_bs_b (3,) rad/s relative to the carrier. Returns ``AidedInsInputs``' q_b_n0,
    v_n0, lat0, lon0, h0 as (1, ...) arrays."""
    R_M, R_N = radii(lat)
    l_n = C_b_n @ lever_arm_b
    w_b = body_rate_at(dtheta, dt, [0])[0] - C_b_n.T @ earth_rate_n(lat)
    if omega_bs_b is not None:
        w_b = w_b - omega_bs_b
    return {"q_b_n0": dcm_to_quat(C_b_n)[None],
            "v_n0": (v_n - C_b_n @ cross(w_b, lever_arm_b))[None],
            "lat0": np.array([lat - l_n[1] / (R_M + h)]),
            "lon0": np.array([lon - l_n[0] / ((R_N + h) * np.cos(lat))]),
            "h0": np.array([h - l_n[2]])}


@dataclass(frozen=True)
class LooseTuning:
    """What the filter believes, SI. P0 sigmas: position (m), velocity (m/s), attitude
    (3,) along E, N, U (rad), gyro drift (rad/s), accelerometer bias (m/s^2); process
    white noise densities: gyro (rad/sqrt(s)) and accelerometer (m/s/sqrt(s)); GPS
    sigmas: position horizontal and vertical (m), velocity (m/s, per axis); use_heading:
    use the GPS heading observation; heading_min_speed: GPS horizontal speed (m/s) from
    which it is used; motion_speed: INS horizontal speed (m/s) above which the carrier
    counts as moving (adaptive policies act only then; 001: "classic KF while static")."""

    position_sigma: float
    velocity_sigma: float
    attitude_sigma: tuple[float, float, float]
    gyro_bias_sigma: float
    accel_bias_sigma: float
    gyro_noise_density: float
    accel_noise_density: float
    gps_position_sigma_h: float
    gps_position_sigma_v: float
    gps_velocity_sigma: float
    use_heading: bool = True
    heading_min_speed: float = 5.0
    motion_speed: float = 0.5
    heading_offset_b: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """From the antenna to the body point whose velocity is along the body's forward axis
    (m, body frame): the GPS heading is that of v_G + C_b^e (w_eb x offset). Zero (001):
    the antenna's own track heading, off the body heading by the kinematic sideslip
    (distance ahead of the rear axle / turn radius)."""
    heading_sideslip_arm: float = 0.0
    """Distance (m) the heading point lies ahead of the rear axle: its track is off the
    body heading by about arm |w_z| / v (the kinematic sideslip; w_z the INS's yaw rate, v
    the GPS horizontal speed), which R's heading sigma then includes beside eq. 4's.
    0: eq. 4's sigma alone (001)."""


@dataclass
class GpsInsInputs(AidedInsInputs):
    """``AidedInsInputs`` and the GPS fixes at the epoch boundaries: gps_lat, gps_lon
    (B, K+1) rad, gps_h m, gps_v_n (B, K+1, 3) m/s ENU, gps_heading_sigma (B, K+1) rad,
    NaN where there is no fix; lever_arm_b (B, 3) m, IMU to antenna (body frame)."""

    gps_lat: np.ndarray
    gps_lon: np.ndarray
    gps_h: np.ndarray
    gps_v_n: np.ndarray
    gps_heading_sigma: np.ndarray
    lever_arm_b: np.ndarray


def heading_cw(C_b_n: np.ndarray) -> np.ndarray:
    """Heading (..., ) rad clockwise from north of the body's forward (y) axis."""
    return np.arctan2(C_b_n[..., 0, 1], C_b_n[..., 1, 1])


def heading_row(C_b_n: np.ndarray, C_e_n: np.ndarray) -> np.ndarray:
    """d(heading)/d(phi^e) (..., 3): [-tan(theta) sin(psi), -tan(theta) cos(psi), 1] R_Le
    for C~ = (I - [phi x]) C (ALGORITHMS 5.1)."""
    forward = C_b_n[..., :, 1]
    tan_pitch = forward[..., 2] / np.hypot(forward[..., 0], forward[..., 1])
    psi = heading_cw(C_b_n)
    row_n = np.stack([-tan_pitch * np.sin(psi), -tan_pitch * np.cos(psi),
                      np.ones_like(psi)], -1)
    return np.einsum("...i,...ij->...j", row_n, C_e_n)


def gravity_gradient(r_e: np.ndarray, lat: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Gamma^e (..., 3, 3) 1/s^2 of a spherical earth: (g / |r|)(3 u u^T - I)."""
    norm = np.linalg.norm(r_e, axis=-1)
    u = r_e / norm[..., None]
    g = normal_gravity(lat, h)
    return (g / norm)[..., None, None] * (3.0 * u[..., :, None] * u[..., None, :]
                                          - np.eye(3))


class LooselyCoupledModel(FilterModel):
    """The 15-state loosely coupled model (see the module docstring) on B episodes; with
    tuning.use_heading False it is the classic loosely coupled KF (position and velocity).

    The INS starts where ``GpsInsInputs`` says; P0 assumes its position is a GPS fix less
    the lever arm turned by the INS's own attitude, so the position error starts
    correlated with the misalignment (dr = -[(C_b^e l) x] phi).

    It keeps the navigation solution after each feedback (``series``): lat, lon (rad),
    h (m), v_n (m/s), C_b_n, the accumulated gyro_bias (rad/s) and accel_bias (m/s^2)
    estimates, and gps_difference (m, m/s): corrected INS (at the antenna) minus GPS,
    E, N, U position then velocity, NaN without a fix."""

    layout = LAYOUT

    def __init__(self, inputs: GpsInsInputs, tuning: LooseTuning) -> None:
        self.inputs, self.tuning = inputs, tuning
        B, K, S = inputs.dtheta.shape[:3]
        self.batch, self.epochs, self.t = B, K, inputs.t
        self.step = float(inputs.t[1] - inputs.t[0])
        self.ins = inputs.strapdown()
        self._omega_ib_b = np.zeros((B, 3))
        self._series = {"lat": np.full((B, K + 1), np.nan), "lon": np.full((B, K + 1), np.nan),
                        "h": np.full((B, K + 1), np.nan),
                        "v_n": np.full((B, K + 1, 3), np.nan),
                        "C_b_n": np.full((B, K + 1, 3, 3), np.nan),
                        "gyro_bias": np.zeros((B, K + 1, 3)),
                        "accel_bias": np.zeros((B, K + 1, 3)),
                        "gps_difference": np.full((B, K + 1, 6), np.nan)}
        self._k = np.zeros(B, int)   # each episode's boundary after its last update
        self._store(0)

    # --- navigation solution ------------------------------------------------------------
    def _navigation(self):
        """C_b^n, C_n^e, C_b^e, r^e, v^e of the current INS state."""
        s = self.ins.state
        C_b_n = quat_to_dcm(s.q_b_n)
        C_ne = C_n_e(s.lat, s.lon)
        return C_b_n, C_ne, C_ne @ C_b_n, geodetic_to_ecef(s.lat, s.lon, s.h), \
            np.einsum("bij,bj->bi", C_ne, s.v_n)

    def _w_eb(self, C_b_e: np.ndarray) -> np.ndarray:
        """The body's rate relative to the earth, w_eb^b (B, 3) rad/s: the INS's inertial
        rate less the earth's rate resolved in b."""
        return self._omega_ib_b - np.einsum("bji,j->bi", C_b_e, OMEGA_IE_E)

    def _lever(self, C_b_e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Antenna offset C_b^e l and its velocity C_b^e (w_eb^b x l), e frame."""
        l_b = self.inputs.lever_arm_b
        w_eb = self._w_eb(C_b_e)
        return (np.einsum("bij,bj->bi", C_b_e, l_b),
                np.einsum("bij,bj->bi", C_b_e, cross(w_eb, l_b)))

    def _gps(self, k: Epoch) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """GPS antenna position and velocity in e and C_n^e at the fix, boundary k."""
        inp = self.inputs
        lat, lon = at_epoch(inp.gps_lat, k), at_epoch(inp.gps_lon, k)
        C_ne = C_n_e(lat, lon)
        r = geodetic_to_ecef(lat, lon, at_epoch(inp.gps_h, k))
        return r, np.einsum("bij,bj->bi", C_ne, at_epoch(inp.gps_v_n, k)), C_ne

    def _store(self, k: Epoch) -> None:
        s, out = self.ins.state, self._series
        for name, value in (("lat", s.lat), ("lon", s.lon), ("h", s.h), ("v_n", s.v_n),
                            ("gyro_bias", self.ins.gyro_bias),
                            ("accel_bias", self.ins.accel_bias)):
            set_at_epoch(out[name], k, value)
        C_b_n, C_ne, C_b_e, r_e, v_e = self._navigation()
        set_at_epoch(out["C_b_n"], k, C_b_n)
        lever_r, lever_v = self._lever(C_b_e)
        r_g, v_g, _ = self._gps(k)
        C_en = np.swapaxes(C_ne, -1, -2)
        set_at_epoch(out["gps_difference"], k, np.concatenate([
            np.einsum("bij,bj->bi", C_en, r_e + lever_r - r_g),
            np.einsum("bij,bj->bi", C_en, v_e + lever_v - v_g)], -1))

    def series(self) -> dict[str, np.ndarray]:
        return self._series

    # --- FilterModel ----------------------------------------------------------------------
    def initial(self):
        tu, B = self.tuning, self.batch
        C_b_n, C_ne, C_b_e, *_ = self._navigation()
        P = np.zeros((B, 15, 15))
        R_pos_n = np.diag([tu.position_sigma ** 2] * 3)
        P_phi = C_ne @ np.diag(np.square(tu.attitude_sigma)) @ np.swapaxes(C_ne, -1, -2)
        L = -skew(np.einsum("bij,bj->bi", C_b_e, self.inputs.lever_arm_b))  # dr = L phi
        P[:, POSITION, POSITION] = (C_ne @ R_pos_n @ np.swapaxes(C_ne, -1, -2)
                                    + L @ P_phi @ np.swapaxes(L, -1, -2))
        P[:, POSITION, PHI] = L @ P_phi
        P[:, PHI, POSITION] = np.swapaxes(L @ P_phi, -1, -2)
        P[:, VELOCITY, VELOCITY] = np.eye(3) * tu.velocity_sigma ** 2
        P[:, PHI, PHI] = P_phi
        P[:, GYRO, GYRO] = np.eye(3) * tu.gyro_bias_sigma ** 2
        P[:, ACCEL, ACCEL] = np.eye(3) * tu.accel_bias_sigma ** 2
        return np.zeros((B, 15)), P

    def transition(self, k, q_scale=(1.0, 1.0)):
        inp, dt = self.inputs, self.inputs.imu_dt
        out, dtheta, dv = self.ins.run_compensated(at_epoch(inp.dtheta, k),
                                                   at_epoch(inp.dv, k))
        S = dtheta.shape[1]
        self._omega_ib_b = body_rate_at(dtheta, dt, [S])[:, 0]
        mid = S // 2
        C_b_n = quat_to_dcm(out["q_b_n"][:, mid])
        C_ne = C_n_e(out["lat"][:, mid], out["lon"][:, mid])
        C_b_e = C_ne @ C_b_n
        f_e = np.einsum("bij,bj->bi", C_b_e, dv.sum(1) / (S * dt))
        r_e = geodetic_to_ecef(out["lat"][:, mid], out["lon"][:, mid], out["h"][:, mid])
        B, T = self.batch, self.step
        W = skew(OMEGA_IE_E)
        F = np.zeros((B, 15, 15))
        F[:, POSITION, VELOCITY] = np.eye(3)
        F[:, VELOCITY, POSITION] = gravity_gradient(r_e, out["lat"][:, mid], out["h"][:, mid])
        F[:, VELOCITY, VELOCITY] = -2.0 * W
        F[:, VELOCITY, PHI] = skew(f_e)
        F[:, VELOCITY, ACCEL] = C_b_e
        F[:, PHI, PHI] = -W
        F[:, PHI, GYRO] = -C_b_e
        FT = F * T
        Phi = np.eye(15) + FT + 0.5 * FT @ FT
        q = np.zeros((B, 15))
        q[:, PHI] = self.tuning.gyro_noise_density ** 2 * per_member(q_scale[0], B)[:, 0]
        q[:, VELOCITY] = self.tuning.accel_noise_density ** 2 * per_member(q_scale[1], B)[:, 0]
        Qc = q[:, :, None] * np.eye(15)   # C_b^e q C_e^b = q I for isotropic white noise
        Q = 0.5 * T * (Phi @ Qc @ np.swapaxes(Phi, -1, -2) + Qc)
        return Transition(noise=Q, matrix=Phi)

    def observation(self, k, r_scale=1.0):
        tu, inp, B = self.tuning, self.inputs, self.batch
        self._k = k + 1
        C_b_n, C_ne, C_b_e, r_e, v_e = self._navigation()
        lever_r, lever_v = self._lever(C_b_e)
        r_g, v_g, C_ne_g = self._gps(k + 1)
        C_en = np.swapaxes(C_ne, -1, -2)
        z = np.full((B, 7), np.nan)
        z[:, 0:3] = r_e + lever_r - r_g
        z[:, 3:6] = v_e + lever_v - v_g
        v_track = at_epoch(inp.gps_v_n, k + 1)
        speed_gps = np.hypot(v_track[:, 0], v_track[:, 1])
        heading_sigma = at_epoch(inp.gps_heading_sigma, k + 1)
        if any(tu.heading_offset_b):
            w_eb = self._w_eb(C_b_e)
            v_track = v_track + np.einsum("bji,bj->bi", C_ne_g, np.einsum(
                "bij,bj->bi", C_b_e, cross(w_eb, np.asarray(tu.heading_offset_b))))
        psi_g = np.arctan2(v_track[:, 0], v_track[:, 1])
        use = (tu.use_heading & (speed_gps >= tu.heading_min_speed)
               & np.isfinite(heading_sigma))
        z[:, HEADING] = np.where(use, wrap_angle(heading_cw(C_b_n) - psi_g), np.nan)
        H = np.zeros((B, 7, 15))
        H[:, 0:3, POSITION] = np.eye(3)
        H[:, 0:3, PHI] = skew(lever_r)
        H[:, 3:6, VELOCITY] = np.eye(3)
        H[:, 3:6, PHI] = skew(lever_v)
        H[:, 3:6, GYRO] = -C_b_e @ skew(inp.lever_arm_b)
        H[:, HEADING, PHI] = heading_row(C_b_n, C_en)
        R = np.zeros((B, 7, 7))
        R_pos_n = np.diag([tu.gps_position_sigma_h ** 2] * 2 + [tu.gps_position_sigma_v ** 2])
        R[:, 0:3, 0:3] = C_ne @ R_pos_n @ C_en
        R[:, 3:6, 3:6] = np.eye(3) * tu.gps_velocity_sigma ** 2
        heading_var = heading_sigma ** 2
        if tu.heading_sideslip_arm:
            w_z = self._w_eb(C_b_e)[:, 2]
            slip = tu.heading_sideslip_arm * np.abs(w_z) / np.maximum(
                speed_gps, max(tu.heading_min_speed, 0.1))
            heading_var = heading_var + slip ** 2
        R[:, HEADING, HEADING] = np.where(use, heading_var, 1.0)
        directions = np.zeros((B, 7, 15))
        directions[:, np.arange(6), np.arange(6)] = 1.0
        # 001 eqs. 17-20 weigh the heading about the local vertical, R_Le(3, :), even
        # where H's heading row has tan(pitch) terms.
        directions[:, HEADING, PHI] = C_en[:, 2]
        moving = np.hypot(self.ins.state.v_n[:, 0], self.ins.state.v_n[:, 1]) >= tu.motion_speed
        return Observation(noise=R * per_member(r_scale, B), matrix=H, z=z,
                           t=epoch_time(self.t, k + 1), angles=(HEADING,), motion=moving, directions=directions)

    def feedback(self, x, P, live):
        """Correct the INS with the estimate (live episodes), accumulate the bias
        estimates, reset the state to zero (closed loop)."""
        C_b_n, C_ne, C_b_e, r_e, v_e = self._navigation()
        x = np.where(live[:, None], x, 0.0)
        r_e = r_e - x[:, POSITION]
        v_e = v_e - x[:, VELOCITY]
        C_b_e = rotvec_to_dcm(x[:, PHI]) @ C_b_e
        lat, lon, h = ecef_to_geodetic(r_e)
        C_en = np.swapaxes(C_n_e(lat, lon), -1, -2)
        s = self.ins.state
        s.q_b_n = dcm_to_quat(C_en @ C_b_e)
        s.v_n = np.einsum("bij,bj->bi", C_en, v_e)
        s.lat, s.lon, s.h = lat, lon, h
        self.ins.gyro_bias = self.ins.gyro_bias + x[:, GYRO]
        self.ins.accel_bias = self.ins.accel_bias + x[:, ACCEL]
        self._store(self._k)
        return np.where(live[:, None], 0.0, x), P

    def attitude(self, k, x):
        C_b_n = at_epoch(self._series["C_b_n"], k)
        C_en = np.swapaxes(C_n_e(at_epoch(self._series["lat"], k),
                                 at_epoch(self._series["lon"], k)), -1, -2)
        phi_n = np.einsum("bij,bj->bi", C_en, x[:, PHI])
        return rotvec_to_dcm(phi_n) @ C_b_n

    def attitude_sigma(self, k, P):
        C_en = np.swapaxes(C_n_e(at_epoch(self._series["lat"], k),
                                 at_epoch(self._series["lon"], k)), -1, -2)
        P_n = C_en @ P[:, PHI, PHI] @ np.swapaxes(C_en, -1, -2)
        return np.sqrt(np.maximum(np.diagonal(P_n, axis1=-2, axis2=-1), 0.0))
