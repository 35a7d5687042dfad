"""A single-axis azimuth indexer: the IMU turned about the hull's z axis between stops by a
position servo of finite bandwidth, simulated in MuJoCo (paper 004, SPEC 4.5).

The command is piecewise linear in time: held at each stop for the dwell, slewed to the
next stop at the slew rate, the stops visited in turn and again from the first until
the run ends (or an explicit schedule of (time, angle) breakpoints). The servo is a
rotor of inertia ``rotor_inertia`` on a hinge, driven by MuJoCo's position actuator
(kp = I w_n^2, kv = 2 zeta w_n I) and by the hull's yaw acceleration about the axis
(the reaction -I d(omega_z)/dt in the hull frame), stepped by ``mujoco.rollout``. The
servo's angle follows a ramp with the lag 2 zeta slew / w_n and settles at each stop;
the truth is the quintic spline through MuJoCo's steps, so angle, rate and acceleration
are one smooth motion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class IndexerSpec:
    """stops: command angles (rad) visited in turn, each held for dwell (s), slewed
    between at slew_rate (rad/s), the cycle repeated; schedule: instead, explicit
    (time s, angle rad) breakpoints of a piecewise-linear command (times increasing, the
    first at 0; held after the last); natural_frequency (Hz) and damping_ratio of the
    closed servo loop; rotor_inertia (kg m^2) about the axis; servo_step (s): MuJoCo's
    step of the servo."""

    stops: tuple[float, ...] = (0.0, math.pi)
    dwell: float = 300.0
    slew_rate: float = math.radians(30.0)
    schedule: tuple[tuple[float, float], ...] = ()
    natural_frequency: float = 4.0
    damping_ratio: float = 0.7
    rotor_inertia: float = 0.02
    servo_step: float = 2e-3

    def __post_init__(self) -> None:
        from aligngym.models.checks import number_rows
        object.__setattr__(self, "stops", tuple(float(s) for s in np.atleast_1d(
            np.asarray(self.stops, dtype=float))))
        object.__setattr__(self, "schedule", number_rows(self.schedule, 2, "indexer.schedule",
                                                      "(time_s, angle_deg)"))
        checks = (("dwell", 0.0, 1e6, False), ("slew_rate", 0.0, math.radians(360.0), True),
                  ("natural_frequency", 0.0, 100.0, True), ("damping_ratio", 0.0, 10.0, True),
                  ("rotor_inertia", 0.0, 1e3, True), ("servo_step", 0.0, 0.01, True))
        for name, low, high, low_open in checks:
            value = getattr(self, name)
            ok = math.isfinite(value) and (value > low if low_open else value >= low) \
                and value <= high
            if not ok:
                raise ValueError(f"indexer.{name} = {value:g} is out of range "
                                 f"{'(' if low_open else '['}{low:g}, {high:g}] (SI units)")
        if not self.stops or not all(math.isfinite(s) and abs(s) <= 4 * math.pi
                                     for s in self.stops):
            raise ValueError("indexer.stops must be 1 or more angles within +-720 deg")
        if self.schedule:
            times = np.array([row[0] for row in self.schedule])
            if times[0] != 0.0 or np.any(np.diff(times) <= 0.0):
                raise ValueError("indexer.schedule: times must increase (not monotone in "
                                 "time otherwise), the first at 0 s")
            if not all(abs(row[1]) <= 4 * math.pi for row in self.schedule):
                raise ValueError("indexer.schedule: angles must be within +-720 deg")
        if self.natural_frequency * 2 * math.pi * self.servo_step > 0.2:
            raise ValueError(f"indexer.servo_step = {self.servo_step:g} s is too long for a "
                             f"{self.natural_frequency:g} Hz servo (w_n * step <= 0.2)")

    def breakpoints(self, duration: float) -> tuple[np.ndarray, np.ndarray]:
        """Command breakpoints (times s, angles rad) covering [0, duration]."""
        if self.schedule:
            t, a = (np.array(c) for c in zip(*self.schedule))
            return t, a
        times, angles = [0.0], [self.stops[0]]
        i = 0
        while times[-1] < duration:
            times.append(times[-1] + self.dwell)
            angles.append(angles[-1])
            if len(self.stops) == 1:
                break
            i = (i + 1) % len(self.stops)
            slew = abs(self.stops[i] - angles[-1]) / self.slew_rate
            if slew > 0.0:
                times.append(times[-1] + slew)
                angles.append(self.stops[i])
        return np.array(times), np.array(angles)

    def command(self, t: np.ndarray, duration: float | None = None) -> np.ndarray:
        """Commanded angle (rad) at times t (s), held after the last breakpoint."""
        t = np.asarray(t, dtype=float)
        times, angles = self.breakpoints(float(t.max()) if duration is None else duration)
        return np.interp(t, times, angles)


def servo_mjcf(spec: IndexerSpec) -> str:
    """The servo's MJCF: the rotor on the indexer hinge, a position actuator (ctrl 0:
    commanded angle, rad) and a torque motor (ctrl 1: N m, the hull's reaction)."""
    w_n = 2 * math.pi * spec.natural_frequency
    inertia = spec.rotor_inertia
    kp, kv = inertia * w_n ** 2, 2 * spec.damping_ratio * w_n * inertia
    return f"""
<mujoco model="azimuth-indexer">
  <option timestep="{spec.servo_step!r}" integrator="implicitfast" gravity="0 0 0"/>
  <worldbody>
    <body name="rotor">
      <joint name="indexer" type="hinge" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="2" diaginertia="{inertia / 2!r} {inertia / 2!r} {inertia!r}"/>
    </body>
  </worldbody>
  <actuator>
    <position name="servo" joint="indexer" kp="{kp!r}" kv="{kv!r}"/>
    <motor name="hull_reaction" joint="indexer" gear="1"/>
  </actuator>
</mujoco>
"""


@dataclass(frozen=True)
class IndexerMotion:
    """The servo's simulated motion relative to the hull: t (n+1,) s at MuJoCo's steps,
    angle (n+1,) rad, MuJoCo's joint rate (n+1,) rad/s, the command (n+1,) rad, and the
    smooth truth through the angles (``state``)."""

    t: np.ndarray
    angle: np.ndarray
    rate: np.ndarray
    command: np.ndarray
    spline: object

    @classmethod
    def from_steps(cls, t: np.ndarray, angle: np.ndarray, rate: np.ndarray,
                   command: np.ndarray) -> "IndexerMotion":
        """The motion from MuJoCo's recorded steps (t, angle, rate, command: (n+1,)), its
        truth the quintic spline through the angles; FloatingPointError if not finite."""
        if not (np.all(np.isfinite(angle)) and np.all(np.isfinite(rate))):
            raise FloatingPointError("the indexer servo simulation produced non-finite "
                                     "angles")
        from scipy.interpolate import make_interp_spline   # lazy: reading a scenario stays light
        return cls(t=t, angle=angle, rate=rate, command=command,
                   spline=make_interp_spline(t, angle, k=5))

    def state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Angle (rad), rate (rad/s), acceleration (rad/s^2) at times t (N,) s."""
        t = np.asarray(t, dtype=float)
        return self.spline(t), self.spline(t, 1), self.spline(t, 2)

    def gimbal_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The indexer as the outer axis of the double-axis gimbal (``GimbalMotion``, the
        inner axis at rest): angles, rates, accelerations (N, 2) at times t (N,) s."""
        return tuple(np.stack([v, np.zeros_like(v)], -1) for v in self.state(t))


def simulate_indexer(spec: IndexerSpec, duration: float,
                     hull_yaw_accel: Callable[[np.ndarray], np.ndarray] | None = None
                     ) -> IndexerMotion:
    """Run the servo over [0, duration] s (``mujoco.rollout``) following the command, with
    the hull's angular acceleration about the indexer axis (rad/s^2 at times (N,) s) as
    the rotor's base excitation. The rotor starts at rest at the first command angle."""
    import mujoco
    model = mujoco.MjModel.from_xml_string(servo_mjcf(spec))
    data = mujoco.MjData(model)
    h = spec.servo_step
    n = int(math.ceil(duration / h)) + 1
    t = np.arange(n + 1) * h
    ctrl = np.zeros((n, 2))
    ctrl[:, 0] = spec.command(t[:-1], t[-1])
    if hull_yaw_accel is not None:
        ctrl[:, 1] = -spec.rotor_inertia * hull_yaw_accel(t[:-1])
    data.qpos[0] = ctrl[0, 0]
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, full))
    mujoco.mj_getState(model, data, state0, full)
    from mujoco import rollout
    states, _ = rollout.rollout(model, data, state0[None], ctrl[None])
    return IndexerMotion.from_steps(t, np.concatenate([[ctrl[0, 0]], states[0, :, 1]]),
                                    np.concatenate([[0.0], states[0, :, 2]]),
                                    np.concatenate([ctrl[:, 0], ctrl[-1:, 0]]))


SERVO_BLOCK = 60.0
"""Length step (s) of the servo runs: a 1 s episode runs 60 s of servo, not 600 s."""


@lru_cache(maxsize=4)
def cached_indexer(spec: IndexerSpec, duration: float, excitation: object = None
                   ) -> IndexerMotion:
    """``simulate_indexer`` once per process for a spec, duration and excitation (a
    hashable object with ``hull_yaw_accel(t)``, e.g. the prescribed hull motion)."""
    accel = None if excitation is None else excitation.hull_yaw_accel
    return simulate_indexer(spec, duration, accel)


def indexer_run(spec: IndexerSpec, t: np.ndarray, excitation: object = None
                ) -> IndexerMotion:
    """The cached servo run (``cached_indexer``) covering times t (s): over [0, max t]
    rounded up to whole ``SERVO_BLOCK`` s, so that calls within one block share a run.
    Runs of different lengths are the same motion: the servo is causal and its command
    does not depend on the length; only the truth spline's end condition differs, in
    the last 0.1 s of a run (a render in another block than its episode sees the same
    motion to the last bit elsewhere)."""
    horizon = SERVO_BLOCK * max(1, int(np.ceil(float(np.max(t)) / SERVO_BLOCK - 1e-9)))
    return cached_indexer(spec, horizon, excitation)
