"""How a world's run becomes an episode's truth (``WorldTruth``), through the truth cache:
a prescribed world sampled at TRUTH_OVERSAMPLING x the IMU rate with Simpson's
increments, or a dynamic world's MuJoCo steps with the exact discrete IMU; a run every
seed shares is kept per process and a shorter one is its start. The worlds themselves
(``scenarios.worlds``) choose which."""
from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from aligngym.models.earth import TangentPlane
from aligngym.models.truth import NavigationTruth, imu_truth
from aligngym.models.world import PrescribedWorld
from aligngym.scenarios.truth_cache import cached_arrays
from aligngym.sensors.imu import ideal_increments

Scenario = Any
"""A ``scenarios.config.ScenarioConfig`` (that module imports the worlds, which import
this one)."""

TRUTH_OVERSAMPLING = 2
"""Prescribed worlds' truth is sampled at twice the IMU rate, so that Simpson's rule
integrates the increments."""


@dataclass(frozen=True)
class WorldTruth:
    """What a world's run gives an episode (arrays may be shared by episodes: read-only):
    truth at the IMU interval boundaries (M+1 samples); imu_t (M,) s, the intervals' end
    times; dtheta, dv (M, 3) the ideal increments of the IMU case (rad, m/s); antenna: the
    GNSS antenna's (t (G,) s, position (G, 3) m, velocity (G, 3) m/s in the plane) at the
    fixes of the scenario's receiver, or None; rear_wheels: the car's driven wheels'
    angles (M+1, 2) rad, or None; cross_track: the car's distance from its track (M+1,) m,
    or None."""

    truth: NavigationTruth
    imu_t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    antenna: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    rear_wheels: np.ndarray | None = None
    cross_track: np.ndarray | None = None


def run_gimbal(run, motion):
    """The gimbal's motion (``GimbalMotion``) of a dynamic world's run: the one MuJoCo
    simulated (an indexer's servo), else the motion's constant rates, with their stalls;
    None without a gimbal."""
    if run.gimbal is not None:
        return run.gimbal
    return motion.gimbal_state if motion.has_gimbal else None


@lru_cache(maxsize=4)
def prescribed_world_truth(world: type, motion, latitude: float, longitude: float,
                           height: float, duration: float, imu_samples: int):
    """``_prescribed_truth`` of a prescribed world's motion (world: its class, whose
    ``scene(motion)`` is its MuJoCo world), cached per process by its motion (a motion
    without random phases has one truth for every seed) and on disk (``truth_cache``,
    kind: the world's name); read-only arrays."""
    key = (motion, latitude, longitude, height, duration, imu_samples)
    return _prescribed_cached(world.cache_kind(world.name), key, lambda: _prescribed_truth(
        world().scene(motion), latitude, longitude, height, duration, imu_samples))


def _prescribed_truth(world: PrescribedWorld, latitude: float, longitude: float,
                      height: float, duration: float, imu_samples: int):
    """Truth at the IMU interval boundaries, the ideal increments (imu_t, dtheta, dv) and
    the GNSS antenna's plane position and velocity at the boundaries ((M+1, 3) each, or
    None) of a prescribed world whose plane origin is at latitude, longitude (rad),
    height (m), over duration (s) in imu_samples intervals; MuJoCo is sampled at
    TRUTH_OVERSAMPLING x the IMU rate."""
    plane = TangentPlane(latitude, longitude, height)
    n_fine = imu_samples * TRUTH_OVERSAMPLING
    t_fine = np.arange(n_fine + 1) * (duration / n_fine)
    samples = world.sample(t_fine)
    truth, omega_is_s, f_s = imu_truth(samples, plane, TRUTH_OVERSAMPLING)
    imu_t, dtheta, dv = ideal_increments(t_fine, omega_is_s, f_s, TRUTH_OVERSAMPLING)
    every = slice(None, None, TRUTH_OVERSAMPLING)
    antenna = ((samples.antenna_r_t[every], samples.antenna_v_t[every])
               if samples.antenna_r_t is not None else (None, None))
    return truth, imu_t, dtheta, dv, antenna


def _prescribed_cached(kind: str, key: tuple, compute):
    """A prescribed world's (truth, imu_t, dtheta, dv, (antenna r, v)) through the truth
    cache, its arrays made read-only."""
    def arrays():
        truth, imu_t, dtheta, dv, (r, v) = compute()
        out = _truth_arrays(truth) | {"imu_t": imu_t, "dtheta": dtheta, "dv": dv}
        return out | ({} if r is None else {"antenna_r": r, "antenna_v": v})
    a = _read_only(cached_arrays(kind, key, arrays))
    return (_truth_from(a), a["imu_t"], a["dtheta"], a["dv"],
            (a.get("antenna_r"), a.get("antenna_v")))


def _truth_arrays(truth: NavigationTruth) -> dict[str, np.ndarray]:
    return {f"truth.{name}": value for name, value in vars(truth).items()
            if value is not None}


def _truth_from(arrays: dict[str, np.ndarray]) -> NavigationTruth:
    return NavigationTruth(**{name[6:]: value for name, value in arrays.items()
                              if name.startswith("truth.")})


def _read_only(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """arrays with each made read-only (shared between episodes: nobody may modify them)."""
    for value in arrays.values():
        value.setflags(write=False)
    return arrays


def dynamic_motion(config: Scenario, world) -> WorldTruth:
    """A dynamic MuJoCo world's run (world: built from the episode's motion stream):
    MuJoCo's discrete steps and the exact discrete IMU of the case (on its gimbal, turned
    by the odometer's mounting)."""
    from aligngym.models.attitude import euler_to_quat, quat_mul, quat_to_dcm
    from aligngym.models.truth import gravity_t, plane_truth
    from aligngym.models.discrete_run import SmoothRun

    motion = config.motion
    run = world.run(config.duration)
    if world.smooth_truth:
        run = SmoothRun(run)
    plane = TangentPlane(config.latitude, config.longitude, config.height)
    site, v_site = run.imu_trajectory()
    gimbal_motion = run_gimbal(run, motion)
    dtheta, dv = run.imu_increments(plane.omega_ie_t,
                                    gravity_t(plane, 0.5 * (site[:-1] + site[1:])),
                                    gimbal_motion)
    gimbal = (np.zeros((run.t.size, 2)) if gimbal_motion is None
              else gimbal_motion(run.t)[0])
    # C_s_b = Rz(outer) Rx(inner): the PSINS Euler DCM with pitch = inner, yaw = outer.
    q_s_b = euler_to_quat(np.stack([gimbal[:, 1], np.zeros(run.t.size), gimbal[:, 0]], -1))
    k = int(round(1.0 / (config.imu_rate * run.dt)))
    m = config.imu_samples
    dtheta = dtheta[: m * k].reshape(m, k, 3).sum(1)
    dv = dv[: m * k].reshape(m, k, 3).sum(1)
    if config.odometer is not None:
        # The IMU case sits on the chassis (on the gimbal, if any) turned by the odometer's
        # mounting angles: C_s^b = C_gimbal Rz(heading) Rx(pitch), so the error a filter
        # must absorb is in the data. Constant: the increments turn with it exactly.
        odo = config.odometer
        q_mount = euler_to_quat(np.array([odo.mounting_pitch, 0.0, odo.mounting_heading]))
        q_s_b = quat_mul(q_s_b, q_mount)
        C_mount = quat_to_dcm(q_mount)
        dtheta, dv = dtheta @ C_mount, dv @ C_mount
    q_s_t = quat_mul(run.quat, q_s_b)
    idx = np.arange(m + 1) * k
    truth = plane_truth(plane, run.t[idx], site[idx], v_site[idx], run.quat[idx],
                        q_s_t[idx], gimbal[idx])
    antenna = None
    if config.gps is not None:
        g_idx = np.arange(0, run.t.size, int(round(1.0 / (config.gps.rate * run.dt))))
        antenna = (run.t[g_idx], *run.point_kinematics(motion.gps_antenna_b, g_idx))
    cross_track = None if run.cross_track is None else run.cross_track[idx]
    wheels = None if run.wheel_angles is None else run.wheel_angles[idx][:, 2:4]
    return WorldTruth(truth=truth, imu_t=truth.t[1:], dtheta=dtheta, dv=dv,
                      cross_track=cross_track, rear_wheels=wheels, antenna=antenna)


SHARED_RUNS = 4
"""Runs every seed shares kept per process (``shared_motion``): 12.6 MB each for a
600 s smooth-road car run at 100 Hz."""
_shared_runs: OrderedDict[tuple, WorldTruth] = OrderedDict()


def motion_key(config: Scenario, any_duration: bool = False) -> tuple:
    """Everything a dynamic world's run (``dynamic_motion``) reads of config but the
    episode's random streams (any_duration: "any" in place of the duration), with the
    schedule's changes of the motion where it has any."""
    odo, gps = config.odometer, config.gps
    key = (config.world, config.motion, config.latitude, config.longitude, config.height,
           "any" if any_duration else config.duration, config.imu_rate,
           None if odo is None else (odo.mounting_pitch, odo.mounting_heading),
           None if gps is None else gps.rate)
    changes = tuple(e for e in config.schedule.entries if e.section == "motion")
    return key + (changes,) if changes else key


def cached_motion(kind: str, key: tuple, compute, usable=None) -> WorldTruth:
    """A dynamic world's run through the truth cache, its arrays made read-only (usable:
    ``truth_cache.cached_arrays``'s)."""
    def arrays():
        shared = compute()
        out = _truth_arrays(shared.truth) | {"dtheta": shared.dtheta, "dv": shared.dv}
        for name in ("cross_track", "rear_wheels"):
            if getattr(shared, name) is not None:
                out[name] = getattr(shared, name)
        if shared.antenna is not None:
            out.update(zip(("antenna_t", "antenna_r", "antenna_v"), shared.antenna))
        return out
    a = _read_only(cached_arrays(kind, key, arrays, usable))
    antenna = ((a["antenna_t"], a["antenna_r"], a["antenna_v"]) if "antenna_t" in a
               else None)
    truth = _truth_from(a)
    return WorldTruth(truth=truth, imu_t=truth.t[1:], dtheta=a["dtheta"], dv=a["dv"],
                      cross_track=a.get("cross_track"), rear_wheels=a.get("rear_wheels"),
                      antenna=antenna)


def _prefix(shared: WorldTruth, config: Scenario, dt: float) -> WorldTruth:
    """The first config.duration of a longer run (dt: its physics step, s): the run of
    that duration bit for bit (MuJoCo steps and the driver do not look ahead, and the
    IMU and truth pipeline works sample by sample)."""
    m = config.imu_samples
    if shared.dtheta.shape[0] == m:
        return shared
    cut = slice(0, m + 1)
    antenna = shared.antenna
    if antenna is not None:      # the fixes at the physics steps the shorter run makes
        last = np.arange(int(round(config.duration / dt)) + 1)[-1:] * dt
        antenna = tuple(a[: int(np.searchsorted(antenna[0], last[0], "right"))]
                        for a in antenna)
    truth = shared.truth.take(cut)
    return WorldTruth(truth=truth, imu_t=truth.t[1:], dtheta=shared.dtheta[:m],
                      dv=shared.dv[:m], antenna=antenna,
                      cross_track=None if shared.cross_track is None
                      else shared.cross_track[cut],
                      rear_wheels=None if shared.rear_wheels is None
                      else shared.rear_wheels[cut])


def shared_motion(kind: str, config: Scenario, build: Callable[[], Any], dt: float
                  ) -> WorldTruth:
    """``dynamic_motion`` of a run every seed shares (the car on a smooth road: with no
    road heightfield the run does not depend on the episode, so every seed, ideal or not,
    has the same truth; build: its MuJoCo world; dt: its physics step, s), cached per
    process and on disk (``truth_cache``, kind), and a
    shorter run is the start of a longer one (``_prefix``): one run per motion, the
    longest asked for. Its arrays are read-only, so a caller that would modify them
    fails instead of changing the next episode."""
    key = motion_key(config, any_duration=True)
    m = config.imu_samples
    held = _shared_runs.get(key)
    if held is None or held.dtheta.shape[0] < m:
        held = cached_motion(kind, key, lambda: dynamic_motion(config, build()),
                              usable=lambda arrays: arrays["dtheta"].shape[0] >= m)
        _shared_runs[key] = held
    _shared_runs.move_to_end(key)
    while len(_shared_runs) > SHARED_RUNS:
        _shared_runs.popitem(last=False)
    return _prefix(held, config, dt)
