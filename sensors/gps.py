"""GPS receiver: antenna position and velocity with white errors, rate, latency, outages,
and the single-antenna heading from the velocity with its sigma (001 eqs. 1-4)."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from aligngym.sensors import number_rows
from aligngym.sensors.base import (Sensor, SensorRecord, SensorTruth, outside_windows,
                                   register_sensor, window_faults)


@dataclass(frozen=True)
class GpsSpec:
    """rate: Hz; position sigmas horizontal / vertical, m; velocity_sigma per axis, m/s;
    heading_min_speed: below this horizontal speed the heading is flagged invalid, m/s;
    latency: age of each fix when it is stamped, s; outages: (start, end) windows, s;
    outliers: faults (time s, east m, north m, up m), the position of the fix stamped
    nearest that time is offset by (east, north, up); multipath_dof: 0 for Gaussian fix
    errors, else the degrees of freedom (> 2) of Student-t errors of the same sigma (a
    multipath burst's heavy tails: the lower, the heavier)."""

    rate: float = 1.0
    position_sigma_h: float = 0.02
    position_sigma_v: float = 0.03
    velocity_sigma: float = 0.02
    heading_min_speed: float = 5.0
    latency: float = 0.0
    outages: tuple[tuple[float, float], ...] = ()
    outliers: tuple[tuple[float, float, float, float], ...] = ()
    multipath_dof: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "outages", number_rows(self.outages, 2, "gps.outages",
                                                     "(start_s, end_s)"))
        object.__setattr__(self, "outliers", number_rows(self.outliers, 4, "gps.outliers",
                                                      "(time_s, east_m, north_m, up_m)"))
        if not 0.0 < self.rate <= 100.0:
            raise ValueError(f"gps.rate = {self.rate} Hz is out of range (0, 100]")
        for name in ("position_sigma_h", "position_sigma_v", "velocity_sigma", "latency",
                     "heading_min_speed"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"gps.{name} must be finite and >= 0, got {value}")
        for start, end in self.outages:
            if not end > start:
                raise ValueError(f"gps.outages: window ({start}, {end}) must have end > start")
        if not (self.multipath_dof == 0.0 or 2.0 < self.multipath_dof <= 1000.0):
            raise ValueError(f"gps.multipath_dof = {self.multipath_dof:g} must be 0 "
                             "(Gaussian) or in (2, 1000]")


def heading_from_velocity(v_n: np.ndarray, velocity_sigma: float
                          ) -> tuple[np.ndarray, np.ndarray]:
    """Yaw (rad, the truth's convention: CCW from north, = -atan2(v_E, v_N)) and its
    sigma (rad) from ENU velocity (N, 3) with isotropic horizontal sigma (001 eqs. 2-4:
    sigma = sqrt(A Sigma A^T), A = [v_N, -v_E] / |v_h|^2 -> sigma_v / |v_h|)."""
    v_h = np.hypot(v_n[:, 0], v_n[:, 1])
    yaw = -np.arctan2(v_n[:, 0], v_n[:, 1])
    with np.errstate(divide="ignore"):
        sigma = np.where(v_h > 0.0, velocity_sigma / v_h, np.inf)
    return yaw, sigma


def nearest_fix(stamps: np.ndarray, when: float) -> int:
    """Index of the fix stamped (stamps (N,) s) nearest time when (s), the earlier on a
    tie: the fix an outlier at that time is put on."""
    return int(np.argmin(np.abs(stamps - when)))


def measure(spec: GpsSpec, t: np.ndarray, lat: np.ndarray, lon: np.ndarray, h: np.ndarray,
            v_n: np.ndarray, rng: np.random.Generator,
            profile: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Fixes from the antenna truth (lat, lon rad; h m; v_n (N, 3) m/s ENU) at the times
    t (N,) s the fixes describe. Stamps are t + latency; fixes inside an outage are NaN
    and invalid. profile: the sigmas and multipath_dof per fix (N,) where a schedule
    changes them (None: the spec's, constant)."""
    from aligngym.models.earth import radii

    n = t.size
    R_M, R_N = radii(lat)
    if profile is None:
        profile = {name: np.full(n, getattr(spec, name)) for name in GnssReceiver.schedulable}
    d_north = profile["position_sigma_h"] * rng.standard_normal(n)
    d_east = profile["position_sigma_h"] * rng.standard_normal(n)
    d_up = profile["position_sigma_v"] * rng.standard_normal(n)
    d_v = profile["velocity_sigma"][:, None] * rng.standard_normal((n, 3))
    dof = profile["multipath_dof"]
    if np.any(dof > 0.0):
        # Student-t of the same sigma: a Gaussian over sqrt(chi2_dof / (dof - 2)), one
        # draw per fix (its position and velocity share the multipath).
        tails = dof > 0.0
        chi2 = rng.chisquare(np.where(tails, dof, 3.0))
        scale = np.where(tails, np.sqrt(np.where(tails, dof - 2.0, 1.0) / chi2), 1.0)
        d_north, d_east, d_up, d_v = (d_north * scale, d_east * scale, d_up * scale,
                                      d_v * scale[:, None])
    v_meas = v_n + d_v
    for when, east, north, up in spec.outliers:
        i = nearest_fix(t + spec.latency, when)
        d_east[i] += east
        d_north[i] += north
        d_up[i] += up
    yaw, sigma = heading_from_velocity(v_meas, spec.velocity_sigma)
    stamp = t + spec.latency
    valid = outside_windows(stamp, spec.outages)
    out = {"gps_t": stamp,
           "gps_lat": lat + d_north / (R_M + h),
           "gps_lon": lon + d_east / ((R_N + h) * np.cos(lat)),
           "gps_h": h + d_up, "gps_v_n": v_meas, "gps_heading": yaw,
           "gps_heading_sigma": sigma, "gps_valid": valid,
           "gps_heading_valid": valid & (np.hypot(v_meas[:, 0], v_meas[:, 1])
                                         >= spec.heading_min_speed)}
    for key in ("gps_lat", "gps_lon", "gps_h", "gps_heading", "gps_heading_sigma"):
        out[key] = np.where(valid, out[key], np.nan)
    out["gps_v_n"] = np.where(valid[:, None], out["gps_v_n"], np.nan)
    return out


GPS_PRESETS = {
    "rtk": GpsSpec(position_sigma_h=0.02, position_sigma_v=0.03, velocity_sigma=0.02),
    "single-point": GpsSpec(position_sigma_h=2.5, position_sigma_v=5.0, velocity_sigma=0.05),
}
"""001: RTK, cm / cm/s (values within that level assumed); 004: 2.5 m, 0.05 m/s
(vertical 5 m assumed)."""


@dataclass(frozen=True)
class GnssFixes(SensorRecord):
    """The receiver's fixes (G,): stamps t s; antenna lat, lon rad, h m; v_n (G, 3) m/s
    ENU; the velocity's heading and its sigma, rad; valid (False inside an outage, where
    the values are NaN) and heading_valid (valid and fast enough)."""

    PREFIX = "gps_"
    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    v_n: np.ndarray
    heading: np.ndarray
    heading_sigma: np.ndarray
    valid: np.ndarray
    heading_valid: np.ndarray


@register_sensor
class GnssReceiver(Sensor):
    """A single-antenna GNSS receiver ([gps]) at the carrier's antenna."""

    section = "gps"
    spec_type = GpsSpec
    units = {"rate": "_hz", "position_sigma_h": "_m", "position_sigma_v": "_m",
             "velocity_sigma": "", "heading_min_speed": "", "latency": "_s",
             "outages": "_s", "outliers": "", "multipath_dof": ""}
    schedulable = ("position_sigma_h", "position_sigma_v", "velocity_sigma", "multipath_dof")
    presets = GPS_PRESETS
    needs = frozenset({"antenna"})
    stream = "gps"

    def check(self, duration: float, imu_rate: float, world: str) -> None:
        for when, *_ in self.spec.outliers:
            if not 0.0 <= when <= duration:
                raise ValueError(f"gps.outliers time = {when:g} s is out of range "
                                 f"[0, {duration:g}]")

    def measure(self, truth: SensorTruth, rng: np.random.Generator, ideal: bool
                ) -> GnssFixes:
        t, r_t, v_t = truth.antenna
        plane = truth.plane
        lat, lon, h = plane.to_geodetic(r_t)
        v_n = np.einsum("...ij,...j->...i", plane.C_t_n(lat, lon), v_t)
        spec, profile = self.spec, None
        if ideal:
            spec = replace(spec, position_sigma_h=0.0, position_sigma_v=0.0,
                           velocity_sigma=0.0, multipath_dof=0.0)
        else:
            profile = {name: self.profile(name, t) for name in self.schedulable}
        fixes = measure(spec, t, lat, lon, h, v_n, rng, profile)
        return GnssFixes(**{name.removeprefix("gps_"): value
                            for name, value in fixes.items()})

    def faults(self, record: SensorRecord, duration: float
               ) -> list[tuple[str, float, float]]:
        outliers = [("gnss_outlier", record.t[k], record.t[k]) for k in
                    (nearest_fix(record.t, when) for when, *_ in self.spec.outliers)]
        return window_faults("gnss_outage", self.spec.outages, duration) + outliers
