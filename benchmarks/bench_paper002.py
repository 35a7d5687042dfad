"""Benchmark: the cost of the paper-002 campaign (static base, 58.5 deg azimuth error,
10-state Euler-angle model) per filter, and our batched UKF against filterpy's
UnscentedKalmanFilter on the same model and data.

1. Campaign cost: the episodes are prepared once (``prepare_all``, 2 worker processes,
   as ``run_campaign(..., workers=2)`` does); then per filter (ekf, ukf, sghkf-2,
   sghkf-4) alone what ``run_campaign`` runs for it (``run_filters``: the model for the
   batch of all episodes, split over worker processes as ``campaign.filtering`` plans
   it, the analysis). Printed: wall times, their total (the four filters one after
   another; a campaign runs them alongside each other, so it takes less), the filter's
   compute per epoch per episode, and the points per epoch (evaluations of the process
   map per episode).
2. Our UKF (``make_filter("ukf")``: alpha 1, beta 2, kappa 0) batched over the episodes
   versus ``filterpy.kalman.UnscentedKalmanFilter`` with ``MerweScaledSigmaPoints(10, 1,
   2, 0)`` (the same UT), episode by episode: fx is ``plain_fx``, the process map for one
   state written here in plain NumPy, hx(x) = H x, Q and R from the model each epoch, angle states 0..2 averaged
   and differenced with wrapping (x_mean_fn, residual_x, state_add), ``model.feedback``
   after each update. Both run the first ``--compare-seconds`` of the same episodes,
   each side five times, interleaved, after a warm-up; the medians are printed.
   Printed: time per episode-epoch of each, the speed-up, and the difference of the
   estimates (heading at the end and over the run, whole state, heading sigma).

Run: python benchmarks/bench_paper002.py [--episodes 100] [--filterpy-episodes 3]
     [--compare-seconds 120]
(--episodes 100 takes about 3-4 min on 2 cores, most of it sghkf-4.)
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

from aligngym.estimators.alignment import AlignmentRun
from aligngym.estimators.catalogue import make_filter
from aligngym.estimators.model import wrap_angle
from aligngym.models.units import arcmin, arcsec, deg
from aligngym.scenarios.campaign import episode_seeds, prepare_all
from aligngym.scenarios.campaign.engine import campaign_epochs
from aligngym.scenarios.campaign.filtering import plan_filter_tasks, run_filters, usable_cores
from aligngym.scenarios.experiments import experiment as make_experiment

FILTERS = ("ekf", "ukf", "sghkf-2", "sghkf-4")
START = "large-azimuth"
N = 10


def campaign_cost(experiment, episodes, workers: int) -> float:
    """Part 1: per filter what ``run_campaign`` runs (``run_filters``: model, filter over
    the planned chunks in worker processes, analysis) on all episodes; wall times."""
    B = len(episodes)
    start_error = experiment.start_errors(episodes)[START]
    total = 0.0
    print(f"{'filter':9s}{'points':>7s}{'chunks':>8s}{'wall s':>9s}"
          f"{'compute ms/epoch/episode':>26s}")
    for name in FILTERS:
        chunks = len(plan_filter_tasks([name], experiment, B, campaign_epochs(experiment),
                                       min(workers, usable_cores())))
        t0 = time.perf_counter()
        (run,) = run_filters([name], {START: start_error}, episodes, experiment, workers,
                             campaign_epochs(experiment))
        wall = time.perf_counter() - t0
        total += wall
        diverged = int(run.diverged.sum())
        print(f"{name:9s}{make_filter(name).rule.point_count(N):7d}{chunks:8d}{wall:9.2f}"
              f"{run.result.seconds_per_epoch * 1e3 / B:26.3f}"
              + (f"   ({diverged} diverged)" if diverged else ""))
    return total


def tensor_cost(workers: int, episodes: int = 5, seconds: float = 60.0) -> None:
    """The tensor-product GH filter ghkf-3 (3^10 = 59049 points) on a few short episodes,
    beside sghkf-4 on the same: the cost the sparse grid avoids."""
    experiment = make_experiment("paper002", fine_duration=seconds)
    prepared = prepare_all(experiment, episode_seeds(0, episodes), None, False, workers,
                           progress=False)
    start_error = experiment.start_errors(prepared)[START]
    for name in ("sghkf-4", "ghkf-3"):
        t0 = time.perf_counter()
        (run,) = run_filters([name], {START: start_error}, prepared, experiment, workers,
                             campaign_epochs(experiment))
        wall = time.perf_counter() - t0
        print(f"{name:9s}{make_filter(name).rule.point_count(N):7d} points: "
              f"{run.result.seconds_per_epoch * 1e3 / episodes:8.2f} ms compute per "
              f"episode-epoch ({episodes} episodes x {seconds:g} s, {wall:.1f} s wall)")


# -- filterpy side -----------------------------------------------------------------------

ANGLES = [0, 1, 2]


def x_mean(sigmas: np.ndarray, Wm: np.ndarray) -> np.ndarray:
    """Weighted mean with the angles unwrapped around sigma point 0 (the mean), as our
    rules do (estimators.rules.weighted_moments), then wrapped."""
    s = np.array(sigmas, dtype=float)
    ref = s[0, ANGLES]
    s[:, ANGLES] = ref + wrap_angle(s[:, ANGLES] - ref)
    x = Wm @ s
    x[ANGLES] = wrap_angle(x[ANGLES])
    return x


def residual_x(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = np.subtract(a, b)
    d[ANGLES] = wrap_angle(d[ANGLES])
    return d


def state_add(x: np.ndarray, dx: np.ndarray) -> np.ndarray:
    y = np.add(x, dx)
    y[ANGLES] = wrap_angle(y[ANGLES])
    return y


def _rotation(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    R = np.eye(3)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def plain_fx(x: np.ndarray, T: float, C_b_p: np.ndarray, f_p: np.ndarray,
             omega_ie: np.ndarray) -> np.ndarray:
    """Paper 002's process map for one state (10,), written here from ALGORITHMS (3.5) in
    plain NumPy, as a filterpy user would: one explicit-midpoint step of length T (s) of
    alpha_dot = C_omega^-1 [(I - C_n^p) omega_ie - C_b^p eps] and dv_dot = [f^p - Rx(alpha_E)
    Ry(alpha_N) (f^p - C_b^p [nabla_x, nabla_y, 0])]_EN, the epoch's C_b^p (3, 3), f^p (3,)
    m/s^2 and omega_ie^n (3,) rad/s held."""
    def rates(x):
        aE, aN, aU = x[0], x[1], x[2]
        level = _rotation(0, aE) @ _rotation(1, aN)              # Rx(alpha_E) Ry(alpha_N)
        C_p_n = _rotation(2, aU) @ level
        C_omega = np.array([[np.cos(aN), 0.0, -np.sin(aN) * np.cos(aE)],
                            [0.0, 1.0, np.sin(aE)],
                            [np.sin(aN), 0.0, np.cos(aN) * np.cos(aE)]])
        r = omega_ie - C_p_n.T @ omega_ie - C_b_p @ x[7:10]
        bias = C_b_p @ np.array([x[5], x[6], 0.0])
        out = np.zeros(10)
        out[0:3] = np.linalg.solve(C_omega, r)
        out[3:5] = (f_p - level @ (f_p - bias))[:2]
        return out
    return x + T * rates(x + 0.5 * T * rates(x))


def filterpy_episode(experiment, episode, start_error: np.ndarray, epochs: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """filterpy's UKF on one episode for ``epochs`` epochs, its fx ``plain_fx``: posterior
    heading per epoch (epochs,), final state (10,) and covariance (10, 10)."""
    model = experiment.model([episode], start_error[None])
    x0, P0 = model.initial()
    points = MerweScaledSigmaPoints(n=N, alpha=1.0, beta=2.0, kappa=0.0)
    ukf = UnscentedKalmanFilter(dim_x=N, dim_z=2, dt=model.T, hx=None, fx=None,
                                points=points, x_mean_fn=x_mean, residual_x=residual_x,
                                state_add=state_add)
    ukf.x, ukf.P = x0[0].copy(), P0[0].copy()
    live = np.ones(1, bool)
    heading = np.empty(epochs)
    for k in range(epochs):
        tr = model.transition(k)
        obs = model.observation(k)
        H = obs.matrix[0]
        ukf.Q = tr.noise[0]
        ukf.R = obs.noise[0]
        C_b_p, f_p, omega = (a[0] for a in model._args(k))
        ukf.predict(fx=lambda x, dt: plain_fx(x, dt, C_b_p, f_p, omega))
        ukf.update(obs.z[0], hx=lambda x: H @ x)
        x, P = model.feedback(ukf.x[None], ukf.P[None], live)
        ukf.x, ukf.P = x[0], P[0]
        heading[k] = ukf.x[2]
    return heading, ukf.x.copy(), ukf.P.copy()


def ours(experiment, episodes, start_error, epochs):
    """Our batched UKF for ``epochs`` epochs: the run (x per epoch) and wall seconds."""
    t0 = time.perf_counter()
    run = AlignmentRun(make_filter("ukf"), experiment.model(episodes, start_error))
    for _ in range(epochs):
        run.step()
    return run, time.perf_counter() - t0


def compare_filterpy(experiment, episodes, n_filterpy: int, seconds: float,
                     repeats: int = 5) -> None:
    """Part 2 (see the module docstring): each side timed ``repeats`` times, interleaved
    (ours on all, ours on the few, filterpy on the few), after one untimed warm-up of
    ours; the median of each."""
    epochs = int(round(seconds / experiment.filter_step))
    start = experiment.start_errors(episodes)[START]
    B = len(episodes)
    few = episodes[:n_filterpy]
    ours(experiment, few, start[:n_filterpy], epochs)            # warm-up (compiled paths)
    walls_all, walls_few, walls_fp = [], [], []
    for _ in range(repeats):
        run_all, wall = ours(experiment, episodes, start, epochs)
        walls_all.append(wall)
        _, wall = ours(experiment, few, start[:n_filterpy], epochs)
        walls_few.append(wall)
        fp_wall = 0.0
        rows = []
        for b, episode in enumerate(few):
            t0 = time.perf_counter()
            heading, x_fp, P_fp = filterpy_episode(experiment, episode, start[b], epochs)
            fp_wall += time.perf_counter() - t0
            rows.append(_agreement(run_all, b, episode, heading, x_fp, P_fp, epochs))
        walls_fp.append(fp_wall)
    wall_all, wall_few, fp_wall = (float(np.median(w)) for w in (walls_all, walls_few,
                                                                  walls_fp))
    _print_comparison(B, n_filterpy, epochs, seconds, wall_all, wall_few, fp_wall, rows,
                      repeats)


def _agreement(run_all, b: int, episode, heading, x_fp, P_fp, epochs: int) -> tuple:
    """One episode's agreement row (ours on all episodes - filterpy)."""
    x_ours = run_all.x[b, epochs]
    P_ours = run_all.P[b, epochs]
    d_final = wrap_angle(x_ours[2] - x_fp[2])
    d_run = np.abs(wrap_angle(run_all.x[b, 1:epochs + 1, 2] - heading)).max()
    dx = np.abs(np.r_[wrap_angle(x_ours[:3] - x_fp[:3]), x_ours[3:] - x_fp[3:]])
    dx_rel = dx / np.sqrt(np.diag(P_ours))
    d_sigma = np.sqrt(P_ours[2, 2]) - np.sqrt(P_fp[2, 2])
    dP_rel = np.abs(P_ours - P_fp).max() / np.abs(P_ours).max()
    return (episode.seed, x_ours[2], d_final, d_run, dx_rel.max(), d_sigma, dP_rel)


def _print_comparison(B: int, n_filterpy: int, epochs: int, seconds: float,
                      wall_all: float, wall_few: float, fp_wall: float, rows: list,
                      repeats: int) -> None:
    """Part 2's printout: times per episode-epoch (medians of ``repeats``), speed-ups, the
    agreement rows."""
    ours_us = wall_all * 1e6 / (B * epochs)
    few_us = wall_few * 1e6 / (n_filterpy * epochs)
    fp_us = fp_wall * 1e6 / (n_filterpy * epochs)
    print(f"our UKF, batch of {B:3d}: {ours_us:9.1f} us per episode-epoch "
          f"({wall_all:.2f} s)")
    print(f"our UKF, batch of {n_filterpy:3d}: {few_us:9.1f} us per episode-epoch "
          f"({wall_few:.2f} s)")
    print(f"filterpy UKF, loop:     {fp_us:9.1f} us per episode-epoch ({fp_wall:.2f} s)"
          f"   (medians of {repeats} interleaved runs)")
    print(f"speed-up (ours batched {B} / filterpy): {fp_us / ours_us:.1f}x   "
          f"(ours batched {n_filterpy}: {fp_us / few_us:.1f}x; issue 45 asks >= 10x at batch 3)")
    print(f"agreement after {seconds:g} s (ours - filterpy):")
    print(f"{'seed':>8s}{'heading est':>13s}{'final dh (rad)':>16s}{'max |dh| run':>14s}"
          f"{'max |dx|/sigma':>16s}{'d sigma_h (rad)':>17s}{'max |dP|/max|P|':>17s}")
    for seed, h, d_final, d_run, dx_rel, d_sigma, dP_rel in rows:
        print(f"{seed:8d}{h / deg:12.4f}d{d_final:16.2e}{d_run:14.2e}{dx_rel:16.2e}"
              f"{d_sigma:17.2e}{dP_rel:17.2e}")
    worst = max(abs(r[2]) for r in rows)
    print(f"max |final heading difference| = {worst:.2e} rad = {worst / arcsec:.2e} arcsec "
          f"({worst / arcmin:.2e} arcmin)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--filterpy-episodes", type=int, default=3)
    parser.add_argument("--compare-seconds", type=float, default=120.0)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    experiment = make_experiment("paper002")
    seeds = episode_seeds(0, args.episodes)
    print(f"paper002 campaign: {args.episodes} episodes, {experiment.fine_duration:g} s "
          f"({experiment.fine_duration / experiment.filter_step:.0f} epochs), "
          f"{args.workers} workers, {os.cpu_count()} cores")
    t0 = time.perf_counter()
    episodes = prepare_all(experiment, seeds, None, False, args.workers, progress=False)
    prep = time.perf_counter() - t0
    print(f"episode preparation (simulation + open-loop INS), {args.workers} workers: "
          f"{prep:.2f} s wall ({prep / args.episodes * 1e3:.0f} ms per episode)")
    filters = campaign_cost(experiment, episodes, args.workers)
    print(f"total: {prep + filters:.1f} s wall (preparation {prep:.1f} s + filters "
          f"{filters:.1f} s); compute = the filter's own time summed over its chunks")
    print()
    tensor_cost(args.workers)
    print()
    n_fp = min(args.filterpy_episodes, args.episodes)
    print(f"UKF: ours (batched) vs filterpy (per episode), first {args.compare_seconds:g} s "
          f"of the same episodes, same model, Q, R, P0; {n_fp} episodes for filterpy")
    compare_filterpy(experiment, episodes, n_fp, args.compare_seconds)


if __name__ == "__main__":
    main()
