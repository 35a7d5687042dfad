"""The pipelines' check of IMU data before any filter sees it: missing samples (the
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
    """(M,) True at single-sample spikes of any axis of rate (M, 3)."""
    finite = np.isfinite(rate)
    x = np.where(finite, rate, 0.0)
    second = np.zeros_like(x)
    second[1:-1] = x[1:-1] - 0.5 * (x[:-2] + x[2:])
    size = np.abs(second)
    across = np.full_like(x, np.inf)            # how far the neighbours are apart
    across[1:-1] = np.abs(x[2:] - x[:-2])
    padded = np.pad(size, ((1, 1), (0, 0)))
    peak = (size >= padded[:-2]) & (size >= padded[2:])
    # Only candidates above the floor can pass the local threshold: its median is taken
    # there alone (the median over every sample cost as much as simulating the run).
    candidate = (size > floor) & peak & (across < 0.5 * size) & finite
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
