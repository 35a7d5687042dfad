"""A static marble platform with a strapdown IMU on it (paper 002, SPEC 4.4).

A granite slab (the MuJoCo body "carrier", on a free joint) rests on a concrete pier in
a laboratory; the IMU is bolted to the slab, sensor axes = body axes (no gimbal). The
slab never moves relative to the earth: its attitude is the constant PSINS Euler
``C_b_t = Rz(yaw) Rx(pitch) Ry(roll)`` (see ``models.attitude``), and the IMU's
measurement point is the body origin, at the plane origin. An ideal IMU on it senses
only the earth rate and the reaction to gravity.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.attitude import euler_to_quat
from models.units import deg
from models.world import IMU_SENSORS_MJCF, GimbalRates, PrescribedWorld, WorldSamples


@dataclass(frozen=True)
class StaticPlatformMotion(GimbalRates):
    """Constant platform attitude, rad: yaw_mean (PSINS, positive counter-clockwise),
    pitch, roll. The defaults (30, 0.3, -0.2 deg) are *assumed*: paper 002 gives no
    platform attitude. lever_arm_b: the IMU from the body origin (R, F, U), m; zero (the
    IMU is the origin), kept for code that reads a lever arm. No gimbal: both gimbal
    rates are 0 rad/s."""

    yaw_mean: float = 30 * deg
    pitch: float = 0.3 * deg
    roll: float = -0.2 * deg
    lever_arm_b: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gimbal_outer_rate: float = 0.0
    gimbal_inner_rate: float = 0.0

    @property
    def euler(self) -> np.ndarray:
        """Platform Euler angles [pitch, roll, yaw] (3,), rad."""
        return np.array([self.pitch, self.roll, self.yaw_mean])


def platform_mjcf(lever_arm_b: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> str:
    """MJCF of the marble platform: the slab (body "carrier") with the IMU case and site
    "imu" at lever_arm_b (m, body axes) on its top, on a world-fixed pier above the
    laboratory floor. All geoms are visual (no contacts); the plane origin is the body
    origin, 1 m above the floor."""
    x, y, z = lever_arm_b
    return f"""
<mujoco model="static-platform">
  <option timestep="0.005"/>
  <visual><global offwidth="640" offheight="480"/></visual>
  <asset>
    <texture name="floor" type="2d" builtin="checker" rgb1=".55 .55 .52" rgb2=".6 .6 .57"
             width="256" height="256"/>
    <material name="floor" texture="floor" texrepeat="8 8"/>
  </asset>
  <worldbody>
    <light pos="0 0 4" dir="0 0 -1" directional="true"/>
    <geom name="floor" type="plane" pos="0 0 -1.0" size="4 4 0.1" material="floor"
          contype="0" conaffinity="0"/>
    <geom name="pier" type="cylinder" size="0.35 0.3475" pos="0 0 -0.6525"
          rgba=".7 .7 .68 1" contype="0" conaffinity="0"/>
    <camera name="overview" pos="2.2 -2.2 0.9" xyaxes="1 1 0 -0.3 0.3 0.9"/>
    <body name="carrier">
      <freejoint name="platform"/>
      <geom name="slab" type="box" size="0.6 0.45 0.1" pos="{x:g} {y:g} {z - 0.2:g}"
            rgba=".2 .2 .22 1" contype="0" conaffinity="0" mass="570"/>
      <geom name="imu_case" type="box" size="0.1 0.1 0.1" pos="{x:g} {y:g} {z:g}"
            rgba=".75 .6 .2 1" contype="0" conaffinity="0" mass="8"/>
      <site name="imu" pos="{x:g} {y:g} {z:g}" size="0.03"/>
    </body>
  </worldbody>
{IMU_SENSORS_MJCF}
</mujoco>
"""


class StaticPlatformWorld(PrescribedWorld):
    """The marble platform in MuJoCo, its free joint held at the constant pose."""

    def __init__(self, motion: StaticPlatformMotion) -> None:
        if motion.has_gimbal:
            raise ValueError("the static platform has no gimbal: gimbal rates must be 0")
        self.motion = motion
        super().__init__(platform_mjcf(motion.lever_arm_b))

    def joint_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Free joint at the plane origin with the platform attitude; zero velocity and
        acceleration. (N, 7), (N, 6), (N, 6)."""
        n = np.asarray(t, dtype=float).size
        qpos = np.zeros((n, 7))
        qpos[:, 3:7] = euler_to_quat(self.motion.euler)
        return qpos, np.zeros((n, 6)), np.zeros((n, 6))

    def sample(self, t: np.ndarray) -> WorldSamples:
        """MuJoCo's sensor pass once, at t[0], copied to all times t (N,) s.

        Exact for a static world (every reading is time-invariant); it keeps a 600 s
        episode at one MuJoCo evaluation instead of 120 001."""
        t = np.asarray(t, dtype=float)
        once = super().sample(t[:1])

        def spread(x: np.ndarray) -> np.ndarray:
            return np.repeat(x, t.size, axis=0)

        return WorldSamples(t=t, r_t=spread(once.r_t), v_t=spread(once.v_t),
                            a_t=spread(once.a_t), q_s_t=spread(once.q_s_t),
                            q_b_t=spread(once.q_b_t), omega_ts_s=spread(once.omega_ts_s),
                            gimbal_angles=spread(once.gimbal_angles))
