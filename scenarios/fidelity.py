"""The truth-fidelity check of SPEC section 3: the project's strapdown, started from the
true state and fed ideal increments, must track the truth."""
from __future__ import annotations

import numpy as np

from aligngym.estimators.strapdown import StrapdownState, run_strapdown
from aligngym.models.attitude import quat_angle
from aligngym.models.earth import radii
from aligngym.scenarios.config import ScenarioConfig
from aligngym.scenarios.simulate import simulate


def fidelity_errors(config: ScenarioConfig, seed: int = 0) -> dict[str, float]:
    """Maximum attitude (rad), velocity (m/s) and position (m) error over the run of a
    strapdown on ideal sensors against the truth of the IMU sensor frame."""
    episode = simulate(config, seed=seed, ideal=True)
    tr = episode.truth
    initial = StrapdownState.from_arrays(tr.q_s_n[0], tr.v_n[0], tr.lat[0], tr.lon[0], tr.h[0])
    nav = run_strapdown(initial, episode.dtheta, episode.dv, config.imu_interval)
    R_M, R_N = radii(tr.lat)
    d_north = (nav["lat"][0] - tr.lat) * (R_M + tr.h)
    d_east = (nav["lon"][0] - tr.lon) * (R_N + tr.h) * np.cos(tr.lat)
    d_up = nav["h"][0] - tr.h
    return {
        "attitude_rad": float(quat_angle(nav["q_b_n"][0], tr.q_s_n).max()),
        "velocity_m_s": float(np.linalg.norm(nav["v_n"][0] - tr.v_n, axis=1).max()),
        "position_m": float(np.sqrt(d_north ** 2 + d_east ** 2 + d_up ** 2).max()),
    }
