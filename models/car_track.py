"""The car's tracks (ring and figure-8, closed polylines with arc length) and its driver
(a speed profile and a pure-pursuit steering controller), for ``models.car.CarWorld``."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aligngym.models.car_params import CarParams

G_LATERAL_MAX = 0.4 * 9.81
"""Largest steady lateral acceleration the controller is allowed to ask, m/s^2."""

RADIUS_MAX = 20000.0
"""m: the largest track (a ring's radius, a figure-8's half-width); 20 km rings stand in
for a straight road."""
TRACK_VERTICES = 20000
"""The drawn track's most samples along the path (a long track's lines get coarser)."""
ROUGH_RADIUS_MAX = 500.0
"""m: the largest track on a rough road (its 0.2 m heightfield: 5300^2 cells)."""


@dataclass(frozen=True)
class Track:
    """A closed path in the plane (E, N), m, starting at the origin heading north.
    points (N, 2); s (N,) cumulative arc length; length: total, m."""

    points: np.ndarray
    s: np.ndarray
    length: float

    @classmethod
    def from_points(cls, points: np.ndarray) -> "Track":
        seg = np.linalg.norm(np.diff(points, axis=0, append=points[:1]), axis=1)
        return cls(points, np.concatenate([[0.0], np.cumsum(seg[:-1])]), float(seg.sum()))

    def min_radius(self) -> float:
        """Smallest radius of curvature along the track, m."""
        d1 = np.gradient(self.points, self.s, axis=0)
        d2 = np.gradient(d1, self.s, axis=0)
        kappa = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(
            np.linalg.norm(d1, axis=1) ** 3, 1e-12)
        return float(1.0 / max(np.percentile(kappa, 99.5), 1e-9))


def ring_track(radius: float, clockwise: bool = True, n: int = 4000) -> Track:
    """Circle through the origin, tangent to north there."""
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    side = 1.0 if clockwise else -1.0
    pts = np.stack([side * radius * (1 - np.cos(a)), radius * np.sin(a)], -1)
    return Track.from_points(pts)


def figure8_track(size: float, n: int = 8000) -> Track:
    """Lemniscate of Bernoulli with half-width `size` (m), rotated so that it crosses the
    origin heading north; it turns both ways."""
    t = np.linspace(np.pi / 2, np.pi / 2 + 2 * np.pi, n, endpoint=False)
    den = 1 + np.sin(t) ** 2
    pts = np.stack([size * np.cos(t) / den, size * np.sin(t) * np.cos(t) / den], -1)
    d = pts[1] - pts[0]
    angle = np.arctan2(d[0], d[1])  # rotate the start tangent onto north
    c, s = np.cos(angle), np.sin(angle)
    return Track.from_points(pts @ np.array([[c, -s], [s, c]]).T)


# --- driver -------------------------------------------------------------------------------

@dataclass(frozen=True)
class DriveProfile:
    """Speed schedule: still until start_time (s), ramp at accel (m/s^2) to speed (m/s),
    drive until stop_time (s), then brake to rest."""

    speed: float
    start_time: float = 0.0
    stop_time: float = math.inf
    accel: float = 1.5

    def target_speed(self, t: float) -> float:
        if t < self.start_time:
            return 0.0
        if t >= self.stop_time:
            return max(0.0, self.speed - 2.0 * self.accel * (t - self.stop_time))
        return min(self.speed, self.accel * (t - self.start_time))


class PurePursuit:
    """Pure pursuit steering with look-ahead (m) and Ackermann wheel angles."""

    def __init__(self, track: Track, params: CarParams, lookahead: float = 6.0) -> None:
        self.track, self.p, self.lookahead = track, params, lookahead
        self._index = 0

    def steer(self, pos: np.ndarray, yaw: float) -> tuple[float, float, float]:
        """(left, right, cross-track error) for the rear-axle position (E, N) and yaw
        (rad, CCW from north)."""
        pts, n = self.track.points, len(self.track.points)
        window = (self._index + np.arange(-10, 120)) % n  # the car moves a few points per call
        d2 = (pts[window, 0] - pos[0]) ** 2 + (pts[window, 1] - pos[1]) ** 2
        best = int(np.argmin(d2))
        if best == len(window) - 1:  # lost the track: search it all
            window = np.arange(n)
            d2 = (pts[:, 0] - pos[0]) ** 2 + (pts[:, 1] - pos[1]) ** 2
            best = int(np.argmin(d2))
        self._index = int(window[best])
        s_target = (self.track.s[self._index] + self.lookahead) % self.track.length
        tx, ty = pts[int(np.searchsorted(self.track.s, s_target)) % n]
        dx, dy = tx - pos[0], ty - pos[1]
        c, s_ = math.cos(yaw), math.sin(yaw)
        # forward = (-sin yaw, cos yaw), right = (cos yaw, sin yaw); positive alpha: right
        alpha = math.atan2(dx * c + dy * s_, -dx * s_ + dy * c)
        delta = math.atan(2.0 * self.p.wheelbase * math.sin(alpha) / self.lookahead)
        delta = min(max(delta, -self.p.max_steer), self.p.max_steer)
        error = math.sqrt(float(d2[best]))
        if abs(delta) < 1e-6:
            return 0.0, 0.0, error
        R = self.p.wheelbase / math.tan(abs(delta))
        inner = math.atan(self.p.wheelbase / (R - self.p.track / 2))
        outer = math.atan(self.p.wheelbase / (R + self.p.track / 2))
        # A right turn (delta > 0) is a negative rotation about up.
        if delta > 0:
            return -outer, -inner, error
        return inner, outer, error
