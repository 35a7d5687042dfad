"""Navigation truth from MuJoCo kinematics: geodetic position, ENU velocity, attitudes,
and the exact inertial angular rate and specific force an ideal IMU senses.

Position and velocity are those of the IMU; all attitudes refer to the ENU frame at the
IMU's position (not the plane's origin: 1 km away the two differ by ~30 arcsec).
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from aligngym.models.attitude import cross, dcm_to_quat, quat_conj, quat_mul, quat_normalize, quat_rotate
from aligngym.models.earth import TangentPlane, gravity_n, normal_gravity
from aligngym.models.world import WorldSamples


@dataclass(frozen=True)
class NavigationTruth:
    """Truth at times t (N,) s.

    lat, lon (N,) rad; h (N,) m; v_n (N, 3) m/s ENU; q_b_n, q_s_n (N, 4) carrier body and
    IMU sensor frame to n; gimbal_angles (N, 2) rad (outer, inner);
    omega_is_s (N, 3) rad/s and f_s (N, 3) m/s^2: instantaneous inertial angular rate and
    specific force of the IMU in its sensor frame.
    """

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    v_n: np.ndarray
    q_b_n: np.ndarray
    q_s_n: np.ndarray
    gimbal_angles: np.ndarray
    omega_is_s: np.ndarray | None = None
    f_s: np.ndarray | None = None

    def take(self, index: np.ndarray | slice) -> "NavigationTruth":
        """Truth at a subset of its samples."""
        return NavigationTruth(**{f.name: None if getattr(self, f.name) is None
                                  else getattr(self, f.name)[index] for f in fields(self)})


def plane_truth(plane: TangentPlane, t: np.ndarray, r_t: np.ndarray, v_t: np.ndarray,
                q_b_t: np.ndarray, q_s_t: np.ndarray, gimbal_angles: np.ndarray
                ) -> NavigationTruth:
    """Geodetic position, ENU velocity and attitudes (n at the IMU) of plane-frame IMU
    position r_t (N, 3) m, velocity v_t (N, 3) m/s and attitudes q_b_t, q_s_t (N, 4)."""
    lat, lon, h = plane.to_geodetic(r_t)
    return _truth_at(t, lat, lon, h, plane.C_t_n(lat, lon), v_t, q_b_t, q_s_t,
                     gimbal_angles)


def _truth_at(t, lat, lon, h, C_t_n, v_t, q_b_t, q_s_t, gimbal_angles) -> NavigationTruth:
    """``plane_truth`` from the geodetic position and C_t_n (N, 3, 3) already known."""
    q_t_n = dcm_to_quat(C_t_n)
    return NavigationTruth(
        t=t, lat=lat, lon=lon, h=h, v_n=np.einsum("...ij,...j->...i", C_t_n, v_t),
        q_b_n=quat_normalize(quat_mul(q_t_n, q_b_t)),
        q_s_n=quat_normalize(quat_mul(q_t_n, q_s_t)), gimbal_angles=gimbal_angles)


def gravity_t(plane: TangentPlane, r_t: np.ndarray) -> np.ndarray:
    """True (normal) gravity at plane positions r_t (N, 3), in plane axes, m/s^2."""
    lat, lon, h = plane.to_geodetic(r_t)
    return np.einsum("...ji,...j->...i", plane.C_t_n(lat, lon), gravity_n(lat, h))


def navigation_truth(samples: WorldSamples, plane: TangentPlane) -> NavigationTruth:
    """Truth from plane-frame kinematics (``imu_truth`` at every sample)."""
    return imu_truth(samples, plane)[0]


def imu_truth(samples: WorldSamples, plane: TangentPlane, every: int = 1
              ) -> tuple[NavigationTruth, np.ndarray, np.ndarray]:
    """The navigation truth at samples[::every], and at every sample the IMU's inertial
    rate omega_is_s (N, 3) rad/s and specific force f_s (N, 3) m/s^2 in its sensor
    frame (what ideal increments integrate; the truth holds them at its own samples).

    The plane is earth-fixed, so omega_is = omega_ts + omega_ie and
    f = a_t + 2 omega_ie x v_t - g(position), with g the WGS-84 normal gravity (which
    includes the centrifugal term) along -U at the IMU.
    """
    lat, lon, h = plane.to_geodetic(samples.r_t)
    q_t_s = quat_conj(samples.q_s_t)
    omega_ie_t = plane.omega_ie_t
    omega_is_s = samples.omega_ts_s + quat_rotate(q_t_s, np.broadcast_to(omega_ie_t,
                                                                         samples.v_t.shape))
    g_t = -normal_gravity(lat, h)[..., None] * plane.up_t(lat, lon)
    f_t = samples.a_t + 2.0 * cross(omega_ie_t, samples.v_t) - g_t
    f_s = quat_rotate(q_t_s, f_t)
    k = slice(None, None, every)
    truth = _truth_at(samples.t[k], lat[k], lon[k], h[k], plane.C_t_n(lat[k], lon[k]),
                      samples.v_t[k], samples.q_b_t[k], samples.q_s_t[k],
                      samples.gimbal_angles[k])
    return replace(truth, omega_is_s=omega_is_s[k], f_s=f_s[k]), omega_is_s, f_s
