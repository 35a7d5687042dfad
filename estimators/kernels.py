"""The Numba-compiled kernels loaded ahead of need (``load_compiled_kernels``)."""
from __future__ import annotations

import numpy as np


def load_compiled_kernels() -> None:
    """Every compiled kernel (the IMU screen's spike candidates, the attitude scan, the
    strapdown's compensation and mechanization, paper 002's Euler map, paper 004's
    Runge-Kutta step) loaded into this process from Numba's on-disk cache, by one call
    each on a few samples. About 0.4-0.5 s, most of it Numba's own start-up: a campaign
    on more than one worker pays it once in its parent before it forks, and its
    preparation and filter workers inherit the kernels instead of each paying it in its
    first episode or filter (paper 001, two workers: 0.5 s of each filter worker's
    1.6-3.8 s)."""
    from aligngym.estimators.euler_kernel import midpoint_points
    from aligngym.estimators.rotation_vector_kernel import runge_kutta_points
    from aligngym.estimators.screen_kernel import spike_candidates
    from aligngym.estimators.strapdown_kernel import compensate_increments, mechanize
    from aligngym.models.attitude_kernel import quat_scan

    rate = np.zeros((3, 3))
    spike_candidates(rate, 0.01, np.empty_like(rate), np.empty(rate.shape, dtype=np.bool_))
    quat_scan(np.tile([1.0, 0.0, 0.0, 0.0], (2, 1, 1)))

    one = np.zeros((1, 1, 3))
    compensate_increments(one, one, one[:, 0], one[:, 0], np.empty_like(one),
                          np.empty_like(one))
    q0 = np.array([[1.0, 0.0, 0.0, 0.0]])
    column = np.zeros(1)
    mechanize(q0, np.zeros((1, 3)), column, column, column, np.zeros((1, 3)), one, one, 0.01,
              np.empty((1, 2, 4)), np.empty((1, 2, 3)), np.empty((1, 2)), np.empty((1, 2)),
              np.empty((1, 2)), np.empty((1, 3)))
    x = np.zeros((1, 1, 10))
    midpoint_points(x, 0.01, np.eye(3)[None], np.zeros((1, 3)), np.zeros((1, 3)),
                    np.empty_like(x))
    x = np.zeros((1, 1, 15))
    vectors = np.zeros((3, 1, 3))
    runge_kutta_points(x, 0.01, True, np.zeros((3, 1, 3, 3)), *[vectors] * 6,
                       np.zeros((3, 1)), np.zeros((3, 1)), np.empty_like(x))
