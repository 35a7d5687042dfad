"""A static marble platform with a strapdown IMU on it (paper 002, SPEC 4.4).

A polished marble slab (the MuJoCo body "carrier", on a free joint) rests on a concrete
pier in a laboratory; the IMU is bolted to the slab, sensor axes = body axes (no gimbal). The
slab never moves relative to the earth: its attitude is the constant PSINS Euler
``C_b_t = Rz(yaw) Rx(pitch) Ry(roll)`` (see ``models.attitude``), and the IMU's
measurement point is the body origin, at the plane origin. An ideal IMU on it senses
only the earth rate and the reaction to gravity. The scene draws the IMU's sensor axes
(x red, y green, z blue; ``models.scene``, visual only).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.models.attitude import euler_to_quat
from aligngym.models.gimbal import GimbalRates
from aligngym.models.units import deg
from aligngym.models.scene import INSTRUMENTS, geom, imu_axes
from aligngym.models.world import IMU_SENSORS_MJCF, PrescribedWorld, WorldSamples


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


MARBLE = "marble"
"""Name of the slab's texture, which ``paint_marble`` fills."""


def platform_mjcf(lever_arm_b: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> str:
    """MJCF of the marble platform: the slab (body "carrier") with the IMU case and site
    "imu" at lever_arm_b (m, body axes) on its top, on a world-fixed pier above the
    laboratory floor. All geoms are visual (no contacts); the plane origin is the body
    origin, 1 m above the floor. The dressing (materials, the case's flange and
    connector, the sensor axes: ``models.scene``) is massless; ``paint_marble`` veins the
    slab's texture."""
    x, y, z = lever_arm_b
    imu = np.array([x, y, z])
    dressing = "\n      ".join([
        geom("imu_flange", "box", (0.13, 0.13, 0.008), imu - (0, 0, 0.092),
             rgba=".55 .45 .15 1", group=INSTRUMENTS),
        geom("imu_connector", "cylinder", (0.025, 0.02), imu + (0, -0.115, 0.03),
             rgba=".15 .15 .15 1", group=INSTRUMENTS, euler="90 0 0"),
        geom("imu_label", "box", (0.06, 0.04, 0.002), imu + (0, 0.02, 0.1),
             rgba=".95 .95 .92 1", group=INSTRUMENTS),
        imu_axes(imu, 0.3, 0.012)])
    return f"""
<mujoco model="static-platform">
  <option timestep="0.005"/>
  <visual><global offwidth="640" offheight="480"/></visual>
  <asset>
    <texture name="sky" type="skybox" builtin="gradient" rgb1=".78 .8 .82" rgb2=".42 .44 .47"
             width="64" height="64"/>
    <texture name="floor" type="2d" builtin="checker" rgb1=".55 .55 .52" rgb2=".6 .6 .57"
             width="256" height="256"/>
    <material name="floor" texture="floor" texrepeat="8 8"/>
    <texture name="concrete" type="2d" builtin="flat" rgb1=".68 .68 .66" mark="random"
             markrgb=".55 .55 .53" random="0.1" width="128" height="128"/>
    <material name="concrete" texture="concrete" texrepeat="2 2"/>
    <texture name="{MARBLE}" type="2d" builtin="flat" rgb1=".92 .91 .88" width="256"
             height="256"/>
    <material name="marble" texture="{MARBLE}" texuniform="true" texrepeat="1.5 1.5"
              specular="0.5" shininess="0.9" reflectance="0.1"/>
  </asset>
  <worldbody>
    <light pos="0 0 4" dir="0 0 -1" directional="true" castshadow="false" diffuse=".3 .3 .3"/>
    <light pos="1.2 -1.6 3" dir="-0.35 0.45 -1" cutoff="45" diffuse=".45 .45 .45"/>
    <geom name="floor" type="plane" pos="0 0 -1.0" size="4 4 0.1" material="floor"
          contype="0" conaffinity="0"/>
    <geom name="pier" type="cylinder" size="0.35 0.3475" pos="0 0 -0.6525"
          material="concrete" contype="0" conaffinity="0"/>
    <camera name="overview" pos="2.2 -2.2 0.9" xyaxes="1 1 0 -0.3 0.3 0.9"/>
    <body name="carrier">
      <freejoint name="platform"/>
      <geom name="slab" type="box" size="0.6 0.45 0.1" pos="{x:g} {y:g} {z - 0.2:g}"
            material="marble" contype="0" conaffinity="0" mass="570"/>
      <geom name="imu_case" type="box" size="0.1 0.1 0.1" pos="{x:g} {y:g} {z:g}"
            rgba=".75 .6 .2 1" contype="0" conaffinity="0" mass="8"/>
      <site name="imu" pos="{x:g} {y:g} {z:g}" size="0.03"/>
      {dressing}
    </body>
  </worldbody>
{IMU_SENSORS_MJCF}
</mujoco>
"""


def paint_marble(model, seed: int = 2) -> None:
    """Veined white marble into the model's texture ``MARBLE`` (visual only): turbulent
    sine veins over a tileable noise, grey on warm white."""
    from scipy.ndimage import gaussian_filter

    tex = model.texture(MARBLE).id
    h, w, c = model.tex_height[tex], model.tex_width[tex], model.tex_nchannel[tex]
    rng = np.random.default_rng(seed)
    turb = sum(gaussian_filter(rng.standard_normal((h, w)), sigma, mode="wrap") * sigma
               for sigma in (8.0, 16.0, 32.0))
    turb /= np.abs(turb).max()
    yy, xx = np.mgrid[0:h, 0:w] / np.array([h, w])[:, None, None]
    vein = np.abs(np.sin(np.pi * (2 * xx + yy + 0.8 * turb))) ** 0.25   # 0 in a vein
    base, grey = np.array([0.88, 0.87, 0.84]), np.array([0.45, 0.46, 0.5])
    rgb = (grey + (base - grey) * (0.3 + 0.7 * vein)[..., None]) * (0.97 + 0.03 * turb)[..., None]
    adr = model.tex_adr[tex]
    model.tex_data[adr:adr + h * w * c] = np.clip(255 * rgb[..., :c], 0, 255).astype(
        np.uint8).ravel()


class StaticPlatformWorld(PrescribedWorld):
    """The marble platform in MuJoCo, its free joint held at the constant pose."""

    def __init__(self, motion: StaticPlatformMotion) -> None:
        if motion.has_gimbal:
            raise ValueError("the static platform has no gimbal: gimbal rates must be 0")
        self.motion = motion
        super().__init__(platform_mjcf(motion.lever_arm_b))
        paint_marble(self.model)

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
