"""Ship swaying on waves with a rotary IMU on a double-axis gimbal (paper 003, prescribed).

Hull attitude (PSINS Euler angles, ``C_b_t = Rz(yaw) Rx(pitch) Ry(roll)``, see
``models.attitude``) follows 003 section 4.1:
yaw = 30 deg + 5 deg cos(2 pi t/7 + pi/3), pitch = 7 deg cos(2 pi t/5 + pi/4),
roll = 10 deg cos(2 pi t/6 + pi/7). The sway centre moves with plane-frame (E, N, U)
velocity V_i = A_i w_i cos(w_i t + phi_i). The IMU sits at a body-frame lever arm from
the sway centre on a gimbal: outer axis body z, inner axis (rotated) x, so
``C_s_b = Rz(outer) Rx(inner)`` with outer = w2 t, inner = w1 t.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from aligngym.models.attitude import euler_to_quat
from aligngym.models.gimbal import GimbalRates, smoothstep, stalled
from aligngym.models.indexer import IndexerSpec, indexer_run
from aligngym.models.units import deg
from aligngym.models.scene import INSTRUMENTS, VISUAL, fmt, imu_axes, mesh_asset, torus_mesh
from aligngym.models.world import ANTENNA_SENSORS_MJCF, IMU_SENSORS_MJCF, PrescribedWorld


@dataclass(frozen=True)
class ShipSwayMotion(GimbalRates):
    """Prescribed ship motion. Angles rad, periods s, lengths m, rates rad/s.

    Each attitude channel is ``mean + k(t) amplitude cos(2 pi t / period + phase)``.
    Linear sway amplitudes, periods and phases are per plane axis (E, N, U), each
    displacement ``k(t) A sin(2 pi t / T + phase)``. k(t) is the sway scale (the sea state
    relative to the amplitudes given): sway_scale, changed within the episode by
    sway_scale_changes ((time s, ramp s > 0, value), a [[schedule]]'s), each reached by a
    septic smoothstep over its ramp (``models.gimbal.smoothstep``), so that angles,
    positions and their first three derivatives stay continuous.
    indexer: a single-axis azimuth indexer (``models.indexer``) on the outer gimbal axis
    instead of the constant-rate double-axis rotation (both rates 0 then);
    antenna_b: the GNSS antenna from the sway centre (R, F, U), m (None: at the IMU);
    hull_size: the hull's beam, length and depth, m (visual only); gimbal_stalls:
    injected stalls (start s, duration s) of the gimbal (``models.gimbal.stalled``).
    """

    yaw_mean: float = 30 * deg
    yaw_amplitude: float = 5 * deg
    yaw_period: float = 7.0
    yaw_phase: float = np.pi / 3
    pitch_amplitude: float = 7 * deg
    pitch_period: float = 5.0
    pitch_phase: float = np.pi / 4
    roll_amplitude: float = 10 * deg
    roll_period: float = 6.0
    roll_phase: float = np.pi / 7
    linear_amplitude: tuple[float, float, float] = (0.02, 0.03, 0.3)
    linear_period: tuple[float, float, float] = (7.0, 6.0, 8.0)
    linear_phase: tuple[float, float, float] = (0.0, 0.0, 0.0)
    lever_arm_b: tuple[float, float, float] = (10.0, 30.0, 10.0)
    gimbal_outer_rate: float = 6 * deg
    gimbal_inner_rate: float = 18 * deg
    indexer: IndexerSpec | None = None
    antenna_b: tuple[float, float, float] | None = None
    hull_size: tuple[float, float, float] = (18.0, 90.0, 8.0)
    gimbal_stalls: tuple[tuple[float, float], ...] = ()
    sway_scale: float = 1.0
    sway_scale_changes: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self) -> None:
        self.check_indexer()

    def sway_scale_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The sway scale k(t) (N,), its first and second derivatives (1/s, 1/s^2)."""
        k = np.full(t.shape, float(self.sway_scale))
        dk, ddk = np.zeros(t.shape), np.zeros(t.shape)
        before = float(self.sway_scale)
        for time, ramp, target in self.sway_scale_changes:
            value, slope, curvature, _ = smoothstep((t - time) / ramp)
            step = target - before
            k += step * value
            dk += step * slope / ramp
            ddk += step * curvature / (ramp * ramp)
            before = target
        return k, dk, ddk

    def hull_yaw_accel(self, t: np.ndarray) -> np.ndarray:
        """The hull's angular acceleration about its z axis (N,) rad/s^2 (what a rotor on
        the indexer axis is excited by)."""
        return self.hull_angular_rate(np.asarray(t, dtype=float))[1][:, 2]

    def gimbal_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Gimbal angles (rad), rates (rad/s) and accelerations (rad/s^2), (N, 2) each
        (outer, inner), at times t (N,) s: the indexer servo's simulated motion
        (``indexer_run``) or the constant rates."""
        if self.indexer is None:
            return super().gimbal_state(t)
        # The servo is excited by the hull's turning only: one run serves every linear phase.
        hull = replace(self, linear_phase=(0.0, 0.0, 0.0))
        return stalled(indexer_run(self.indexer, t, hull).gimbal_state,
                       self.gimbal_stalls)(t)

    def euler(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Hull Euler angles [pitch, roll, yaw], their first and second derivatives; (N, 3)."""
        channels = [(0.0, self.pitch_amplitude, self.pitch_period, self.pitch_phase),
                    (0.0, self.roll_amplitude, self.roll_period, self.roll_phase),
                    (self.yaw_mean, self.yaw_amplitude, self.yaw_period, self.yaw_phase)]
        angle, rate, accel = [], [], []
        changing = bool(self.sway_scale_changes)
        if changing:
            k, dk, ddk = self.sway_scale_at(t)
        for mean, amplitude, period, phase in channels:
            w = 2 * np.pi / period
            c, s = np.cos(w * t + phase), np.sin(w * t + phase)
            if changing:   # d/dt (k A c), d2/dt2 (k A c); k = 1, dk = ddk = 0: as below
                kA, dkA, ddkA = k * amplitude, dk * amplitude, ddk * amplitude
                angle.append(mean + kA * c)
                rate.append(-kA * w * s + dkA * c)
                accel.append(-kA * w * w * c - 2.0 * dkA * w * s + ddkA * c)
                continue
            amplitude = self.sway_scale * amplitude
            angle.append(mean + amplitude * c)
            rate.append(-amplitude * w * s)
            accel.append(-amplitude * w * w * c)
        return np.stack(angle, -1), np.stack(rate, -1), np.stack(accel, -1)

    def hull_angular_rate(self, t: np.ndarray, euler: tuple | None = None
                          ) -> tuple[np.ndarray, np.ndarray]:
        """omega_tb^b (N, 3) rad/s and its time derivative (N, 3) rad/s^2 (euler: the
        ``euler(t)`` already computed, or None).

        From C_b_t = Rz(psi) Rx(theta) Ry(gamma):
        omega = Ry^T (Rx^T psi_dot e_z + theta_dot e_x) + gamma_dot e_y.
        """
        (th, ga, _), (dth, dga, dps), (ddth, ddga, ddps) = (
            a.T for a in (self.euler(t) if euler is None else euler))
        sth, cth, sga, cga = np.sin(th), np.cos(th), np.sin(ga), np.cos(ga)
        omega = np.stack([cga * dth - sga * cth * dps,
                          sth * dps + dga,
                          sga * dth + cga * cth * dps], -1)
        omega_dot = np.stack([
            -sga * dga * dth + cga * ddth
            - (cga * dga * cth * dps - sga * sth * dth * dps + sga * cth * ddps),
            cth * dth * dps + sth * ddps + ddga,
            cga * dga * dth + sga * ddth
            + (-sga * dga * cth * dps - cga * sth * dth * dps + cga * cth * ddps),
        ], -1)
        return omega, omega_dot

    def sway_centre(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sway-centre position (m), velocity (m/s), acceleration (m/s^2) in t; (N, 3)."""
        A = self.sway_scale * np.asarray(self.linear_amplitude)
        w = 2 * np.pi / np.asarray(self.linear_period)
        arg = w * t[:, None] + np.asarray(self.linear_phase)
        sine = np.sin(arg)
        if not self.sway_scale_changes:
            return A * sine, A * w * np.cos(arg), -A * w * w * sine
        k, dk, ddk = (x[:, None] * np.asarray(self.linear_amplitude)
                      for x in self.sway_scale_at(t))            # k A, k' A, k'' A
        cosine = np.cos(arg)
        return (k * sine, k * w * cosine + dk * sine,
                -k * w * w * sine + 2.0 * dk * w * cosine + ddk * sine)


HULL_SIZE_RANGE = (0.5, 500.0)
"""Allowed beam, length and depth of a hull, m (prescribed or wave-driven)."""

REFERENCE_HULL = ((18.0, 90.0, 8.0), 5.01e6, (3.41e9, 1.62e8, 3.52e9))
"""Paper 003's ship: beam, length, depth (m), mass (kg) and principal inertia about its
centre of mass (kg m^2, R, F, U). Other hulls scale it as boxes of the same density."""


def hull_mass_properties(hull_size: tuple[float, float, float]
                         ) -> tuple[float, tuple[float, float, float]]:
    """Mass (kg) and principal inertia (kg m^2, about R, F, U) of a hull of size (beam,
    length, depth, m): the reference hull's scaled by the volume and, per axis, by the
    box's sum of squared dimensions across it (exact for the reference)."""
    (b0, l0, d0), mass0, inertia0 = REFERENCE_HULL
    b, l, d = hull_size
    mass = mass0 * (b * l * d) / (b0 * l0 * d0)
    ratio = ((l * l + d * d) / (l0 * l0 + d0 * d0), (b * b + d * d) / (b0 * b0 + d0 * d0),
             (b * b + l * l) / (b0 * b0 + l0 * l0))
    return mass, tuple(i * mass / mass0 * r for i, r in zip(inertia0, ratio))


SEA_GRID = 161
"""Rows and columns of a rendered sea patch's heightfield."""


def hullfmt(beam: float, length: float, depth: float, top: float
                  ) -> tuple[list, list]:
    """Visual hull and deck outlines (half beam, half length, depth, m; R, F, U from the
    sway centre, the deck at height top, m): the hull's convex outline with a raked bow
    and a narrower keel, and the deck's outline 0.3 % of the length thick on it."""
    bow, stern = length, -length
    hull, deck = [], []
    for y, half, keel in ((stern, 0.85, 0.7), (-0.5 * length, 1.0, 0.75), (0.3 * length, 1.0, 0.7),
                          (0.7 * length, 0.7, 0.45)):
        hull += [(sx * half * beam, y, top) for sx in (-1, 1)]
        hull += [(sx * keel * half * beam, y, top - depth * (0.6 if y == stern else 1.0))
                 for sx in (-1, 1)]
        deck += [(sx * 0.97 * half * beam, y, top + z) for sx in (-1, 1)
                 for z in (0.0, 0.006 * length)]
    hull += [(0.0, bow, top), (0.0, 0.85 * length, top - 0.8 * depth)]
    deck += [(0.0, 0.98 * bow, top + z) for z in (0.0, 0.006 * length)]
    return hull, deck


def ship_mjcf(lever_arm_b: tuple[float, float, float], floating: bool = False,
              antenna_b: tuple[float, float, float] | None = None,
              hull_size: tuple[float, float, float] = REFERENCE_HULL[0],
              indexer: IndexerSpec | None = None,
              sea_patch: tuple[float, float] | None = None) -> str:
    """MJCF of the hull (body "carrier"), the double-axis gimbal, the IMU site and the
    GNSS antenna site "antenna" (at antenna_b, m; None: at the IMU) with its position and
    velocity sensors.

    The hull origin is the sway centre. A floating hull (``floating``) has its centre of
    mass there, about which a free body turns (``hull_mass_properties`` of hull_size:
    beam, length, depth, m); the prescribed hull's mass properties play no part. With
    ``indexer`` on a floating hull the outer gimbal axis is the indexer: a rotor of the
    spec's inertia driven by a position actuator "indexer" (kp = I w_n^2, kv = 2 zeta w_n
    I; ctrl: the commanded angle, rad), the inner axis nearly massless.

    The scene (visual geoms only, massless and without contacts): the hull with its deck,
    bridge, funnel and mast; a pedestal under the gimbal; the gimbal's outer frame (a
    ring through the inner axis' bearings, orange, geom "gimbal_outer_frame"), its inner
    frame (green, "gimbal_inner_frame"), the IMU case ("imu_case") with its sensor axes
    x, y, z drawn red, green, blue ("imu_axis_x/y/z"), drawn at a visible size (the
    gimbal's drawing is at least 3 % of the hull's length); sky and sea. sea_patch
    (half size m, largest elevation m): a heightfield "sea" of that size around the
    origin, which a renderer fills with the waves (``scenarios.render``).
    """
    x, y, z = lever_arm_b
    ax, ay, az = lever_arm_b if antenna_b is None else antenna_b
    beam, length, depth = (0.5 * v for v in hull_size)
    top = 0.8 * depth                                  # the deck above the sway centre, m
    hull, deck = hullfmt(beam, length, 2.0 * depth, top)
    scale = min(1.0, beam / 9.0)
    g = max(0.6 * scale, 0.03 * hull_size[1])          # the gimbal's drawn radius, m
    bridge = (min(7.0, 0.6 * beam), min(6.0, 0.1 * length), min(5.0, 0.6 * depth))
    # The masses the hull's model has always had (the prescribed hull's play no part in
    # its motion; kept so that its rounding stays bit for bit), drawn in group 3 (hidden).
    mass_box = (min(7.0, 0.4 * beam), min(6.0, 0.15 * length), min(5.0, 0.6 * depth))
    by = -0.45 * length
    inertial = actuator = ""
    outer_mass = inner_mass = ""
    if floating:
        mass, inertia = hull_mass_properties(hull_size)
        inertial = (f'<inertial pos="0 0 0" mass="{mass!r}" '
                    f'diaginertia="{inertia[0]!r} {inertia[1]!r} {inertia[2]!r}"/>')
        if indexer is not None:
            rotor = indexer.rotor_inertia
            outer_mass = (f'<inertial pos="0 0 0" mass="1" '
                          f'diaginertia="{rotor / 2!r} {rotor / 2!r} {rotor!r}"/>')
            inner_mass = '<inertial pos="0 0 0" mass="1e-3" diaginertia="1e-7 1e-7 1e-7"/>'
            w_n = 2 * np.pi * indexer.natural_frequency
            total = rotor + 1e-7
            actuator = (f'<actuator><position name="indexer" joint="gimbal_outer" '
                        f'kp="{total * w_n ** 2!r}" '
                        f'kv="{2 * indexer.damping_ratio * w_n * total!r}"/></actuator>')
    visual = VISUAL
    sea_asset = sea_geom = ""
    if sea_patch is not None:
        half, crest = sea_patch
        sea_asset = (f'<hfield name="sea" nrow="{SEA_GRID}" ncol="{SEA_GRID}" '
                     f'size="{half:g} {half:g} {2 * crest:g} {0.05 * crest:g}"/>')
        sea_geom = (f'<geom name="sea_waves" type="hfield" hfield="sea" pos="0 0 {-crest:g}" '
                    f'material="sea" group="1" {visual}/>')
    foot = (float(np.clip(x, -0.5 * beam, 0.5 * beam)), y, top)   # on the deck
    base = (x, y, z - 1.3 * g)                                     # under the gimbal
    antenna_mast = ""
    if az > top + 0.05 * g:
        antenna_mast = (f'<geom name="antenna_mast" type="capsule" size="{0.03 * g:.4g}" '
                        f'fromto="{ax:g} {ay:g} {top:g} {ax:g} {ay:g} {az:g}" '
                        f'rgba=".8 .8 .8 1" group="1" {visual}/>')
    pedestal = ""
    if np.linalg.norm(np.subtract(base, foot)) > 0.05 * g:
        pedestal = (f'<geom name="pedestal" type="cylinder" fromto="{fmt([foot, base])}" '
                    f'size="{0.15 * g:.4g}" rgba=".5 .5 .55 1" group="1" {visual}/>')

    # The gimbal's frames: rings about the inner axis' bearings (the outer one, its axis
    # along x) and about the IMU's z axis (the inner one).
    rings = {name: mesh_asset(name, *torus_mesh(radius, 0.06 * radius))
             for name, radius in (("gimbal_outer_ring", g), ("gimbal_inner_ring", 0.75 * g))}

    return f"""
<mujoco model="ship-sway-rotary">
  <option timestep="0.005" integrator="implicitfast"/>
  <statistic extent="{2.0 * max(hull_size):g}" center="0 0 0"/>
  <visual><global offwidth="1280" offheight="960"/><quality shadowsize="4096"/>
    <map znear="0.01" zfar="50000"/><headlight ambient=".3 .3 .3" diffuse=".25 .25 .25"/></visual>
  <asset>
    <texture name="sky" type="skybox" builtin="gradient" rgb1=".55 .72 .9" rgb2=".95 .97 1"
             width="512" height="512"/>
    <texture name="sea" type="2d" builtin="flat" rgb1=".07 .24 .40" width="64" height="64"/>
    <material name="sea" texture="sea" reflectance="0" specular=".8" shininess=".3"/>
    <material name="hull" rgba=".22 .27 .36 1" specular=".3"/>
    <material name="deck" rgba=".62 .58 .50 1"/>
    <material name="white" rgba=".93 .93 .95 1" specular=".4"/>
    <mesh name="hull" vertex="{fmt(hull)}"/>
    <mesh name="deck" vertex="{fmt(deck)}"/>
    {rings["gimbal_outer_ring"]}
    {rings["gimbal_inner_ring"]}
    {sea_asset}
  </asset>
  <worldbody>
    <light pos="0 0 2000" dir="-.3 .2 -1" directional="true" diffuse=".45 .45 .45"
           castshadow="false"/>
    <light pos="0 0 2000" dir=".85 .35 -.4" directional="true" diffuse=".5 .5 .5"
           specular=".4 .4 .4" castshadow="false"/>
    <geom name="sea" type="plane" size="3000 3000 1" material="sea" contype="0" conaffinity="0"
          pos="0 0 {-(sea_patch[1] if sea_patch else 0.0):g}"/>
    {sea_geom}
    <body name="carrier">
      <freejoint name="hull"/>
      {inertial}
      <geom name="hull_mass" type="box" size="{beam:g} {length:g} {depth:g}" pos="0 0 {-depth / 2:g}"
            contype="0" conaffinity="0" mass="5e6" group="3"/>
      <geom name="hull" type="mesh" mesh="hull" material="hull" {visual}/>
      <geom name="deck" type="mesh" mesh="deck" material="deck" {visual}/>
      <geom name="bridge_mass" type="box" size="{mass_box[0]:g} {mass_box[1]:g} {mass_box[2]:g}"
            pos="{x:g} {y:g} {z / 2:g}" contype="0" conaffinity="0" mass="1e4" group="3"/>
      <geom name="bridge" type="box" size="{bridge[0]:g} {bridge[1]:g} {bridge[2]:g}"
            pos="0 {by:g} {top + bridge[2]:g}" material="white" {visual}/>
      <geom name="bridge_windows" type="box" size="{0.9 * bridge[0]:g} {0.02 * bridge[1]:g} {0.12 * bridge[2]:g}"
            pos="0 {by + bridge[1]:g} {top + 1.6 * bridge[2]:g}" rgba=".1 .12 .16 1" group="1" {visual}/>
      <geom name="bridge_top" type="box" size="{0.7 * bridge[0]:g} {0.8 * bridge[1]:g} {0.35 * bridge[2]:g}"
            pos="0 {by:g} {top + 2.35 * bridge[2]:g}" material="white" group="1" {visual}/>
      <geom name="funnel" type="cylinder" size="{0.25 * bridge[0]:g} {0.6 * bridge[2]:g}"
            pos="0 {by - 1.6 * bridge[1]:g} {top + 1.6 * bridge[2]:g}" rgba=".75 .2 .15 1" group="1" {visual}/>
      <geom name="mast" type="capsule" size="{0.03 * bridge[0]:g}"
            fromto="0 {by + 0.3 * bridge[1]:g} {top + 2.7 * bridge[2]:g} 0 {by + 0.3 * bridge[1]:g} {top + 4.2 * bridge[2]:g}"
            rgba=".85 .85 .85 1" group="1" {visual}/>
      {pedestal}
      {antenna_mast}
      <geom name="antenna" type="cylinder" size="{0.15 * g:.4g} {0.03 * g:.4g}"
            pos="{ax:g} {ay:g} {az:g}" rgba=".95 .95 .95 1" group="1" {visual}/>
      <site name="antenna" pos="{ax:g} {ay:g} {az:g}" size="{0.1 * scale:g}"/>
      <body name="gimbal_outer" pos="{x:g} {y:g} {z:g}">
        <joint name="gimbal_outer" type="hinge" axis="0 0 1"/>
        {outer_mass}
        <geom type="cylinder" size="{0.6 * scale:g} {0.05 * scale:g}" rgba=".9 .5 .1 1"
              contype="0" conaffinity="0" mass="20" group="3"/>
        <geom name="gimbal_outer_base" type="cylinder" size="{0.35 * g:.4g} {0.05 * g:.4g}"
              pos="0 0 {-1.25 * g:.4g}" rgba=".95 .55 .1 1" group="1" {visual}/>
        <geom name="gimbal_outer_stem" type="capsule" size="{0.05 * g:.4g}"
              fromto="0 0 {-1.25 * g:.4g} 0 0 {-g:.4g}" rgba=".95 .55 .1 1" group="1" {visual}/>
        <geom name="gimbal_outer_frame" type="mesh" mesh="gimbal_outer_ring" euler="0 90 0"
              rgba=".95 .55 .1 1" group="{INSTRUMENTS}" {visual}/>
        <body name="gimbal_inner">
          <joint name="gimbal_inner" type="hinge" axis="1 0 0"/>
          {inner_mass}
          <geom type="box" size="{0.25 * scale:g} {0.25 * scale:g} {0.25 * scale:g}"
                rgba=".2 .8 .3 1" contype="0" conaffinity="0" mass="10" group="3"/>
          <geom name="gimbal_inner_frame" type="mesh" mesh="gimbal_inner_ring"
                rgba=".2 .75 .3 1" group="{INSTRUMENTS}" {visual}/>
          <geom name="gimbal_inner_axle" type="capsule" size="{0.04 * g:.4g}"
                fromto="{-g:.4g} 0 0 {g:.4g} 0 0" rgba=".6 .6 .6 1" group="1" {visual}/>
          <geom name="imu_case" type="box" size="{0.3 * g:.4g} {0.3 * g:.4g} {0.22 * g:.4g}"
                rgba=".25 .25 .28 1" group="1" {visual}/>
          {imu_axes((0.0, 0.0, 0.0), 1.1 * g, 0.045 * g)}
          <site name="imu" size="0.05"/>
        </body>
      </body>
    </body>
  </worldbody>
  {actuator}
{IMU_SENSORS_MJCF}
{ANTENNA_SENSORS_MJCF}
</mujoco>
"""


class ShipWorld(PrescribedWorld):
    """The 003 ship in MuJoCo, hull and gimbal following ShipSwayMotion exactly."""

    gimbal_joints = ("gimbal_outer", "gimbal_inner")

    def __init__(self, motion: ShipSwayMotion) -> None:
        self.motion = motion
        super().__init__(ship_mjcf(motion.lever_arm_b, antenna_b=motion.antenna_b,
                                   hull_size=motion.hull_size))

    def joint_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Free-joint hull (world position, quaternion; world linear and body angular
        velocity and acceleration) and the two gimbal hinges."""
        t = np.asarray(t, dtype=float)
        motion = self.motion
        n = t.size
        pos, vel, acc = motion.sway_centre(t)
        euler = motion.euler(t)
        omega, omega_dot = motion.hull_angular_rate(t, euler)
        qpos = np.empty((n, 9))
        qvel = np.empty((n, 8))
        qacc = np.empty((n, 8))
        qpos[:, 0:3] = pos
        qpos[:, 3:7] = euler_to_quat(euler[0])
        gimbal, gimbal_rate, gimbal_accel = motion.gimbal_state(t)
        qpos[:, 7:9] = gimbal
        qvel[:, 0:3] = vel
        qvel[:, 3:6] = omega
        qvel[:, 6:8] = gimbal_rate
        qacc[:, 0:3] = acc
        qacc[:, 3:6] = omega_dot
        qacc[:, 6:8] = gimbal_accel
        return qpos, qvel, qacc
