"""WGS-84 earth: radii of curvature, normal gravity, earth and transport rates, and the
exact conversions between geodetic coordinates, ECEF and a local tangent plane (ENU).

Geodetic position is (lat, lon, h): rad, rad, m above the ellipsoid. n = local ENU at the
point. All functions accept a leading stack of points.
"""
from __future__ import annotations

import numpy as np

# WGS-84 defining constants (NIMA TR8350.2) and derived normal-gravity constants.
A = 6378137.0
"""Semi-major axis, m."""
F = 1.0 / 298.257223563
"""Flattening."""
OMEGA_IE = 7.2921151467e-5
"""Earth rotation rate, rad/s."""
GM = 3.986004418e14
"""Geocentric gravitational constant, m^3/s^2."""
B = A * (1.0 - F)
"""Semi-minor axis, m."""
E2 = F * (2.0 - F)
"""First eccentricity squared."""
GAMMA_EQUATOR = 9.7803253359
"""Normal gravity at the equator, m/s^2."""
GAMMA_POLE = 9.8321849378
"""Normal gravity at the poles, m/s^2."""
_K_SOMIGLIANA = B * GAMMA_POLE / (A * GAMMA_EQUATOR) - 1.0
_M = OMEGA_IE ** 2 * A ** 2 * B / GM


def radii(lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Meridian R_M and prime-vertical R_N radii of curvature (m) at geodetic latitude (rad)."""
    s2 = np.sin(lat) ** 2
    w = np.sqrt(1.0 - E2 * s2)
    return A * (1.0 - E2) / w ** 3, A / w


def metres_per_geodetic(lat: np.ndarray, h: np.ndarray | float = 0.0) -> np.ndarray:
    """(..., 3): the north, east and up metres per unit change of (lat rad, lon rad, h m):
    [R_M + h, (R_N + h) cos(lat), 1]."""
    R_M, R_N = radii(lat)
    h = np.asarray(h, dtype=float)
    return np.stack([R_M + h, (R_N + h) * np.cos(lat), np.ones_like(R_M + h)], -1)


def normal_gravity(lat: np.ndarray, h: np.ndarray | float = 0.0) -> np.ndarray:
    """Magnitude of WGS-84 normal gravity (m/s^2) at latitude (rad) and height h (m).

    Somigliana's closed formula on the ellipsoid, with the second-order height
    correction of TR8350.2 eq. (4-3). Gravity (gravitation plus centrifugal) points
    along -U of the local ENU frame.
    """
    s2 = np.sin(lat) ** 2
    gamma0 = GAMMA_EQUATOR * (1.0 + _K_SOMIGLIANA * s2) / np.sqrt(1.0 - E2 * s2)
    h = np.asarray(h, dtype=float)
    return gamma0 * (1.0 - 2.0 / A * (1.0 + F + _M - 2.0 * F * s2) * h + 3.0 * h ** 2 / A ** 2)


def _vector(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(..., 3) from three components of one shape (``np.stack(..., -1)`` without its
    per-call overhead)."""
    out = np.empty(np.shape(x) + (3,))
    out[..., 0], out[..., 1], out[..., 2] = x, y, z
    return out


def gravity_n(lat: np.ndarray, h: np.ndarray | float = 0.0) -> np.ndarray:
    """Normal gravity vector in ENU, (..., 3) m/s^2."""
    g = np.asarray(normal_gravity(lat, h))
    return _vector(np.zeros_like(g), np.zeros_like(g), -g)


def earth_rate_n(lat: np.ndarray) -> np.ndarray:
    """omega_ie^n, earth rate in ENU, (..., 3) rad/s."""
    lat = np.asarray(lat, dtype=float)
    return _vector(np.zeros_like(lat), OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat))


def transport_rate_n(lat: np.ndarray, h: np.ndarray, v_n: np.ndarray) -> np.ndarray:
    """omega_en^n, rotation rate of ENU relative to the earth, (..., 3) rad/s.

    v_n: (..., 3) velocity relative to the earth in ENU, m/s.
    """
    R_M, R_N = radii(lat)
    v_n = np.asarray(v_n, dtype=float)
    R_Mh = R_M + h
    R_Nh = R_N + h
    return _vector(-v_n[..., 1] / R_Mh, v_n[..., 0] / R_Nh, v_n[..., 0] * np.tan(lat) / R_Nh)


def C_n_e(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """DCM from local ENU to ECEF, (..., 3, 3); its columns are E, N, U in ECEF."""
    sL, cL = np.sin(lat), np.cos(lat)
    sl, cl = np.sin(lon), np.cos(lon)
    z = np.zeros_like(sL * sl)
    C = np.empty(z.shape + (3, 3), dtype=z.dtype)
    C[..., 0, 0], C[..., 0, 1], C[..., 0, 2] = -sl + z, -sL * cl, cL * cl
    C[..., 1, 0], C[..., 1, 1], C[..., 1, 2] = cl + z, -sL * sl, cL * sl
    C[..., 2, 0], C[..., 2, 1], C[..., 2, 2] = z, cL + z, sL + z
    return C


def geodetic_to_ecef(lat: np.ndarray, lon: np.ndarray, h: np.ndarray) -> np.ndarray:
    """ECEF position (..., 3) m of geodetic (lat, lon rad; h m)."""
    _, R_N = radii(lat)
    cL = np.cos(lat)
    return np.stack([(R_N + h) * cL * np.cos(lon), (R_N + h) * cL * np.sin(lon),
                     (R_N * (1.0 - E2) + h) * np.sin(lat)], -1)


def ecef_to_geodetic(r_e: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geodetic (lat rad, lon rad, h m) of ECEF position (..., 3) m.

    Bowring's parametric-latitude iteration; two passes reach rounding (3e-16 rad,
    measured over all latitudes from -500 m to 10 km; one pass leaves 1.4e-13 rad at
    10 km).
    """
    r_e = np.asarray(r_e, dtype=float)
    x, y, z = r_e[..., 0], r_e[..., 1], r_e[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    ep2 = E2 / (1.0 - E2)
    beta = np.arctan2(z, (1.0 - F) * p)
    for _ in range(2):
        lat = np.arctan2(z + ep2 * B * np.sin(beta) ** 3, p - E2 * A * np.cos(beta) ** 3)
        beta = np.arctan2((1.0 - F) * np.sin(lat), np.cos(lat))
    _, R_N = radii(lat)
    sL, cL = np.sin(lat), np.cos(lat)
    # Height along the normal, well conditioned at every latitude.
    h = p * cL + z * sL - A * A / R_N
    return lat, lon, h


class TangentPlane:
    """Exact map between a local tangent plane (ENU axes at an origin, earth-fixed) and
    geodetic coordinates. MuJoCo's world frame is this plane.

    origin: (lat rad, lon rad, h m) of the plane's origin.
    """

    def __init__(self, lat0: float, lon0: float, h0: float) -> None:
        self.lat0, self.lon0, self.h0 = float(lat0), float(lon0), float(h0)
        self.r0_e = geodetic_to_ecef(np.float64(lat0), np.float64(lon0), np.float64(h0))
        self.C_t_e = C_n_e(np.float64(lat0), np.float64(lon0))
        self.omega_ie_t = earth_rate_n(np.float64(lat0))
        """Earth rate in plane coordinates (constant: the plane is earth-fixed), rad/s."""

    def to_geodetic(self, r_t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Geodetic (lat, lon, h) of plane coordinates r_t (..., 3) m."""
        r_e = self.r0_e + np.einsum("ij,...j->...i", self.C_t_e, r_t)
        return ecef_to_geodetic(r_e)

    def from_geodetic(self, lat: np.ndarray, lon: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Plane coordinates (..., 3) m of geodetic (lat, lon, h)."""
        r_e = geodetic_to_ecef(lat, lon, h) - self.r0_e
        return np.einsum("ji,...j->...i", self.C_t_e, r_e)

    def up_t(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        """The local vertical (U axis of ENU) at (lat, lon) in plane axes, (..., 3): the
        last row of ``C_t_n``, without the full matrix."""
        cL = np.cos(lat)
        up_e = np.stack([cL * np.cos(lon), cL * np.sin(lon), np.sin(lat)], -1)
        return up_e @ self.C_t_e

    def C_t_n(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        """DCM from plane axes to the local ENU at (lat, lon), (..., 3, 3)."""
        return np.swapaxes(C_n_e(lat, lon), -1, -2) @ self.C_t_e
