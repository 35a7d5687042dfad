"""Benchmark: the strapdown's cost per IMU step, before and after it was compiled, and
the lower bound of the alternative (an associative quaternion scan).

- "numpy loop": the previous mechanization, NumPy over the batch, one Python iteration
  per IMU step (kept here as the reference);
- "compiled": ``estimators.strapdown.run_strapdown`` (numba loop over episodes and steps);
- "scan, one pass": the least a scan formulation needs per iteration: both attitude
  scans (q(-omega_in T) from the left, q(phi) from the right; ``quat_cumprod``), the
  velocity increments rotated to n and summed. Earth, transport, Coriolis and gravity
  depend on the trajectory, so it would iterate that pass several times.
Run: python benchmarks/bench_strapdown.py
"""
from __future__ import annotations

import numpy as np

from bench_simulate import best_of  # noqa: E402  (run from benchmarks/)
from aligngym.estimators.strapdown import StrapdownState, compensate, run_strapdown
from aligngym.models.attitude import cross, quat_cumprod, quat_mul, quat_rotate, rotvec_to_quat
from aligngym.models.earth import A, E2, OMEGA_IE, normal_gravity
from aligngym.scenarios.config import load_scenario
from aligngym.scenarios.simulate import simulate


def numpy_loop(s: StrapdownState, phi: np.ndarray, dv_b: np.ndarray, T: float) -> np.ndarray:
    """The previous mechanization (per step, NumPy over the batch); final q_b_n (B, 4)."""
    q, v, lat, lon, h = s.q_b_n, s.v_n, s.lat, s.lon, s.h
    a_n = np.zeros_like(v)
    for k in range(phi.shape[1]):
        v_mid = v + 0.5 * T * a_n
        sL0 = np.sin(lat)
        R_M = A * (1.0 - E2) / (1.0 - E2 * sL0 * sL0) ** 1.5
        lat_mid = lat + 0.5 * T * v_mid[:, 1] / (R_M + h)
        h_mid = h + 0.5 * T * v_mid[:, 2]
        sL, cL = np.sin(lat_mid), np.cos(lat_mid)
        w2 = 1.0 - E2 * sL * sL
        R_Mh, R_Nh = A * (1.0 - E2) / w2 ** 1.5 + h_mid, A / np.sqrt(w2) + h_mid
        omega_ie = np.stack([np.zeros_like(sL), OMEGA_IE * cL, OMEGA_IE * sL], -1)
        omega_en = np.stack([-v_mid[:, 1] / R_Mh, v_mid[:, 0] / R_Nh,
                             v_mid[:, 0] * sL / (cL * R_Nh)], -1)
        omega_in = omega_ie + omega_en
        g_n = np.stack([np.zeros_like(sL), np.zeros_like(sL),
                        -normal_gravity(lat_mid, h_mid)], -1)
        dv_n = quat_rotate(q, dv_b[:, k])
        dv_n -= 0.5 * T * cross(omega_in, dv_n)
        v_new = v + dv_n + T * (g_n - cross(omega_ie + omega_in, v_mid))
        v_avg = 0.5 * (v + v_new)
        lat, lon, h = (lat + T * v_avg[:, 1] / R_Mh, lon + T * v_avg[:, 0] / (R_Nh * cL),
                       h + T * v_avg[:, 2])
        q = quat_mul(rotvec_to_quat(-T * omega_in), quat_mul(q, rotvec_to_quat(phi[:, k])))
        q /= np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
        a_n, v = (v_new - v) / T, v_new
    return q


def scan_pass(s: StrapdownState, phi: np.ndarray, dv_b: np.ndarray, T: float,
              omega_in: np.ndarray) -> np.ndarray:
    """One pass of a scan formulation with a given omega_in (B, M, 3); velocities (B, M, 3)."""
    right = quat_cumprod(rotvec_to_quat(phi), axis=1)
    left = quat_cumprod(rotvec_to_quat(-T * omega_in[:, ::-1]), axis=1)[:, ::-1]
    q = quat_mul(left, quat_mul(s.q_b_n[:, None], right))
    return s.v_n[:, None] + np.cumsum(quat_rotate(q, dv_b), axis=1)


def main() -> None:
    config = load_scenario("ship-sway-rotary")
    episode = simulate(config.with_options(duration=60.0), seed=1, ideal=True)
    tr, T = episode.truth, config.imu_interval
    M = episode.dtheta.shape[0]
    print(f"strapdown, {M} IMU steps of the ship (us per IMU step; per episode-step)")
    for batch in (1, 50):
        init = StrapdownState.from_arrays(
            np.tile(tr.q_s_n[0], (batch, 1)), np.tile(tr.v_n[0], (batch, 1)),
            np.full(batch, tr.lat[0]), np.full(batch, tr.lon[0]), np.full(batch, tr.h[0]))
        dtheta = np.ascontiguousarray(np.broadcast_to(episode.dtheta, (batch, M, 3)))
        dv = np.ascontiguousarray(np.broadcast_to(episode.dv, (batch, M, 3)))
        phi, dv_b = compensate(dtheta, dv)
        run_strapdown(init, dtheta, dv, T)                       # compile or load the cache
        omega_in = np.broadcast_to([0.0, OMEGA_IE * np.cos(tr.lat[0]),
                                    OMEGA_IE * np.sin(tr.lat[0])], (batch, M, 3))
        rows = {"numpy loop": best_of(lambda: numpy_loop(init, phi, dv_b, T), 1),
                "compiled (with compensation)": best_of(lambda: run_strapdown(init, dtheta, dv, T)),
                "scan, one pass": best_of(lambda: scan_pass(init, phi, dv_b, T, omega_in))}
        q_ref = numpy_loop(init, phi, dv_b, T)
        q_new = run_strapdown(init, dtheta, dv, T)["q_b_n"][:, -1]
        base = rows["numpy loop"]
        for name, sec in rows.items():
            print(f"  batch {batch:3d} {name:30s} {sec / M * 1e6:9.2f} us "
                  f"{sec / M / batch * 1e6:8.3f} us  x{base / sec:7.1f}")
        print(f"  batch {batch:3d} compiled vs numpy loop: final attitude differs by "
              f"{np.abs(q_new - q_ref).max():.1e}")


if __name__ == "__main__":
    main()
