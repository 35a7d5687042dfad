"""The pipelines' checks of their data before any filter sees it: the IMU
(``screen_imu``, below), the gimbal encoders against the commands (``screen_gimbal``),
the GNSS fixes (``screen_gnss``) and the odometer against the IMU (``screen_odometer``).

The IMU check: missing samples (the
timestamps say so), non-finite samples, samples at a triad's rail (saturation) and
single-sample spikes are detected, flagged with their time and kind, and repaired by a
cubic spline through the good samples' rates, onto the run's uniform grid (what a
missing stretch held cannot be recovered: the spline bounds the loss for smooth motion).

A spike is a sample whose rate departs from its neighbours' mean (the second difference)
by more than ``SPIKE_MADS`` robust standard deviations of the second differences around
it (1.4826 x their median over +-``SPIKE_WINDOW`` samples) and at least a floor
(``SPIKE_FLOOR``), more than its neighbours do (a one-sample spike shows half as large in
theirs), while the neighbours agree with each other (their difference under half the
departure): a kink in the motion, such as a servo starting a slew, is not a spike.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SPIKE_MADS = 50.0
SPIKE_WINDOW = 25
"""Samples either side of the local median of the second differences."""
SPIKE_FLOOR = (0.01, 0.5)
"""Least spike, (gyro rad/s, accelerometer m/s^2) of rate departure."""


@dataclass(frozen=True)
class ScreenedImu:
    """Increments on the uniform grid: imu_t (M,) s, dtheta (M, 3) rad, dv (M, 3) m/s,
    repaired; the flags: kind (F,) str ("gap", "nan", "saturation", "spike"), start and
    end (F,) s (interval end times of the first and last sample flagged)."""

    imu_t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    kind: np.ndarray
    start: np.ndarray
    end: np.ndarray


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in mask."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > 1)
    return list(zip(idx[np.r_[0, breaks + 1]], idx[np.r_[breaks, idx.size - 1]]))


def _spikes(rate: np.ndarray, floor: float) -> np.ndarray:
    """(M,) True at single-sample spikes of any axis of rate (M, 3): the second difference's
    size, and the candidates (a finite sample above the floor, at least its neighbours,
    which agree with each other: ``screen_kernel.spike_candidates``, compiled), then the
    local median at the candidates alone (the median over every sample cost as much as
    simulating the run)."""
    from aligngym.estimators.screen_kernel import spike_candidates   # Numba: when run

    rate = np.ascontiguousarray(rate, dtype=float)
    size = np.empty_like(rate)
    candidate = np.empty(rate.shape, dtype=np.bool_)
    spike_candidates(rate, float(floor), size, candidate)
    k, axis = np.nonzero(candidate)
    edge = np.pad(size, ((SPIKE_WINDOW, SPIKE_WINDOW), (0, 0)), mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(edge, 2 * SPIKE_WINDOW + 1, axis=0)
    local = np.median(windows[k, axis], axis=-1)
    spike = np.zeros_like(candidate)
    spike[k, axis] = size[k, axis] > SPIKE_MADS * 1.4826 * local
    return np.any(spike, axis=1)


def screen_imu(imu_t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, dt: float,
               samples: int, gyro_rail: float, accel_rail: float) -> ScreenedImu:
    """Check and repair increments (M', 3) stamped at interval end times imu_t (M',) s
    against the run's grid of ``samples`` intervals of dt s, the rails (full scales,
    rad/s and m/s^2) marking saturation. See the module docstring."""
    index = np.rint(np.asarray(imu_t) / dt).astype(int) - 1
    if np.any(np.abs(imu_t - (index + 1) * dt) > 1e-6 * dt) or np.any(np.diff(index) <= 0) \
            or index.min(initial=0) < 0 or index.max(initial=0) >= samples:
        raise ValueError("IMU timestamps must lie on the run's grid, increasing")
    increments = np.full((samples, 6), np.nan)      # the good samples pass exactly as given
    increments[index] = np.concatenate([dtheta, dv], axis=1)
    rate = increments / dt                           # gyro 0:3, accelerometer 3:6
    present = np.zeros(samples, bool)
    present[index] = True
    bad = {"gap": ~present, "nan": present & ~np.all(np.isfinite(rate), axis=1)}
    with np.errstate(invalid="ignore"):
        bad["saturation"] = present & (np.any(np.abs(rate[:, :3]) >= 0.999 * gyro_rail, axis=1)
                                       | np.any(np.abs(rate[:, 3:]) >= 0.999 * accel_rail,
                                                axis=1))
    clean = np.where((bad["nan"] | bad["saturation"])[:, None], np.nan, rate)
    bad["spike"] = (_spikes(clean[:, :3], SPIKE_FLOOR[0]) | _spikes(clean[:, 3:], SPIKE_FLOOR[1]))
    t = (np.arange(samples) + 1) * dt
    kinds, starts, ends = [], [], []
    for kind in ("gap", "nan", "saturation", "spike"):
        for first, last in _runs(bad[kind]):
            kinds.append(kind)
            starts.append(t[first])
            ends.append(t[last])
    flagged = np.any(np.stack(list(bad.values())), axis=0)
    good = ~flagged
    if not good.any():
        raise ValueError("no good IMU sample in the run")
    if flagged.any():
        # A cubic spline through the good samples' rates: a swaying hull's rate is far
        # from linear over half a second (linear interpolation of a 0.5 s rail cost 13'
        # of attitude on the ship, the spline 6.7 arcsec).
        if good.sum() >= 4:
            from scipy.interpolate import make_interp_spline
            bridged = make_interp_spline(t[good], rate[good], k=3)(t[flagged])
        else:
            bridged = np.stack([np.interp(t[flagged], t[good], rate[good, c])
                                for c in range(6)], -1)
        increments[flagged] = bridged * dt
    order = np.argsort(starts, kind="stable")
    return ScreenedImu(imu_t=t, dtheta=increments[:, :3], dv=increments[:, 3:],
                       kind=np.array(kinds, dtype=str)[order],
                       start=np.array(starts)[order], end=np.array(ends)[order])


STALL_TOLERANCE = 2e-3
"""rad: a gimbal axis this far from the angle its commands give (both counted from the
run's start) is stalled. Quantisation and the hull's excitation of an indexer's rotor
keep it within 4e-4 rad; an axis stalling at 6 deg/s is this far off within 0.13 s."""
OUTLIER_MADS = 6.0
"""A GNSS fix is an outlier when its position is off the velocities' path by more than
this many robust standard deviations of the scenario's path residuals, both ways."""


def _flags(kind: str, times) -> tuple[np.ndarray, np.ndarray]:
    """Flags of one kind at times (s): kind (F,) str and time (F,) s."""
    return np.array([kind] * len(times), dtype=str), np.array(times, dtype=float)


def screen_gimbal(t: np.ndarray, encoder: np.ndarray, expected: np.ndarray,
                  resolution: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Stalls of a gimbal: encoder readings and the angles the commands give (both
    (M+1, 2) rad at times t (M+1,) s), each counted from the first (the encoders'
    constant offsets cancel; their quantisation, one count of resolution rad, adds to
    the tolerance). Returns the flags' kind (F,) ("gimbal_stall") and time (F,) s: the
    first sample of each stretch in which some axis is more than ``STALL_TOLERANCE``
    off (the stall and its catch-up are one stretch)."""
    deviation = (encoder - encoder[0]) - (expected - expected[0])
    stretches = _runs(np.any(np.abs(deviation) > STALL_TOLERANCE + resolution, axis=1))
    return _flags("gimbal_stall", [t[first] for first, _ in stretches])


def screen_gnss(t: np.ndarray, lat: np.ndarray, lon: np.ndarray, h: np.ndarray,
                v_n: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outages and position outliers of GNSS fixes stamped t (N,) s (lat, lon rad, h m,
    v_n (N, 3) ENU m/s, valid (N,) bool). An outage is a run of invalid fixes (flagged at
    its first); an outlier is a fix whose position jumps off the path the velocities
    give (trapezoid) by more than ``OUTLIER_MADS`` robust sigmas, and back at the next
    fix, on some axis. Flags only: the filters meet the outliers (paper 001 compares how
    they do). Returns the flags' kind (F,) ("gnss_outage", "gnss_outlier") and time
    (F,) s, in time order."""
    from aligngym.models.earth import radii
    kinds = ["gnss_outage"] * len(_runs(~valid))
    times = [t[first] for first, _ in _runs(~valid)]
    both = valid[1:] & valid[:-1]
    if both.sum() >= 8:
        R_M, R_N = radii(lat[:-1])
        dt = np.diff(t)[:, None]
        step = np.stack([np.diff(lon) * (R_N + h[:-1]) * np.cos(lat[:-1]),
                         np.diff(lat) * (R_M + h[:-1]), np.diff(h)], -1)
        residual = step - 0.5 * (v_n[1:] + v_n[:-1]) * dt        # (N-1, 3), m
        good = residual[both]
        sigma = 1.4826 * np.median(np.abs(good - np.median(good, 0)), 0)
        limit = OUTLIER_MADS * np.maximum(sigma, 1e-3)
        with np.errstate(invalid="ignore"):
            off = np.abs(residual) > limit
            back = np.sign(residual[1:]) == -np.sign(residual[:-1])
            jump = np.any(off[:-1] & off[1:] & back, axis=1) & both[:-1] & both[1:]
        for k in np.flatnonzero(jump):
            kinds.append("gnss_outlier")
            times.append(t[k + 1])
    order = np.argsort(times, kind="stable")
    return np.array(kinds, dtype=str)[order], np.array(times, dtype=float)[order]


SLIP_WINDOW = 0.2
"""s: the odometer's speed is taken over windows this long."""
SLIP_FLOOR = 0.5
"""m/s: the least slip flagged. Between two windows, the odometer's speed change less
the IMU's forward velocity change is a slip above this and 12 robust sigmas of the run's
(measured on the ring road: sigma 0.01 m/s, largest 0.07 m/s, 0.19 on the rough road;
a 0.5 m burst over 0.3 s shows 1.7 m/s)."""
SLIP_MERGE = 5.0
"""s: odometer flags within this of the previous flagged window are one burst (its start
and its end show as opposite jumps of the speed, with none between)."""


def screen_odometer(dt: float, distance: np.ndarray, dv_forward: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Slip bursts of an odometer: its cumulative distance (M+1,) m at the IMU boundaries
    (every dt s from 0) against the IMU's velocity increments along the carrier's forward
    axis (M,) m/s. Two consecutive windows of ``SLIP_WINDOW`` give a speed change; the
    IMU's increments between the windows' centres give the carrier's, plus gravity along
    the forward axis (nearly constant: the run's median residual is taken off). Returns
    the flags' kind (F,) ("odometer_slip") and time (F,) s: the first window end off by more than
    ``SLIP_FLOOR`` (flags within ``SLIP_MERGE`` are one burst)."""
    n = max(2, 2 * int(round(SLIP_WINDOW / dt / 2)))      # even: the centres on boundaries
    if distance.size < 3 * n:
        return _flags("odometer_slip", [])
    speed = (distance[n:] - distance[:-n]) / (n * dt)    # windows ending at n .. M
    change = speed[n:] - speed[:-n]                       # ends j = 2n .. M
    cumulative = np.r_[0.0, np.cumsum(dv_forward)]
    j = np.arange(2 * n, distance.size)
    residual = change - (cumulative[j - n // 2] - cumulative[j - 3 * n // 2])
    residual -= np.median(residual)          # gravity along a tilted forward axis
    sigma = 1.4826 * np.median(np.abs(residual))
    slipped = np.abs(residual) > max(SLIP_FLOOR, 12.0 * sigma)
    times: list[float] = []
    last_end = -np.inf
    for first, last in _runs(slipped):
        if j[first] * dt - last_end > SLIP_MERGE:
            times.append(float(j[first] * dt))
        last_end = j[last] * dt
    return _flags("odometer_slip", times)
