"""A MuJoCo car driven around ring and figure-8 tracks (papers 000 and 001).

The car: a chassis (body "carrier", free joint) on four slide-joint suspensions; front
wheels steered by position servos about their kingpins (Ackermann angles from the
controller); rear wheels driven through a fixed-tendon differential by one velocity
servo; ellipsoid tyres with friction on a ground plane, or on a heightfield with road
roughness. A pure-pursuit controller (6 m look-ahead) with a speed ramp follows the
track; the car starts at the plane origin heading north.

Physics runs at 2 ms with the implicitfast integrator. For it MuJoCo updates the
velocity first and then moves the free joint with the new velocity: over step k the
body rotates at the constant body rate omega_{k+1} and its origin moves at the constant
world velocity v_{k+1}. ``CarWorld.run`` records exactly these, so the IMU increments
can be made consistent with the discrete motion to rounding (``discrete_imu``).

The scene (visual only, ``models.scene``: massless, contact-free geoms; the physics is
bit-identical without them): the chassis box is the lower body of a red saloon with a
cabin, windows, bumpers, lights, wheel arches and rims; the IMU case with its sensor axes
(x red, y green, z blue) and, with a gimbal, its two frames; the GPS antenna on a mast;
the track painted on the ground (asphalt road, dashed yellow path, white lane edges).
The IMU sits inside the body: hide geom groups 0 and 1 to see the instruments.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aligngym.models.scene import (DRESSING, INSTRUMENTS, VISUAL, fmt, geom, imu_axes, mesh_asset,
                          quad_inset, resample_closed, ribbon, slab_mesh, torus_mesh)
from aligngym.models.world import IMU_SENSORS_MJCF, DiscreteRun, GimbalRates, skip_sensors

G_LATERAL_MAX = 0.4 * 9.81
"""Largest steady lateral acceleration the controller is allowed to ask, m/s^2."""


WHEEL_CENTRE_Z = -0.25
"""Wheel centres below the chassis origin at rest, m."""


@dataclass(frozen=True)
class CarParams:
    """Car geometry (m), masses (kg), suspension and tyres. imu_offset_b: IMU site from the
    chassis origin in the body frame (R, F, U), m."""

    wheelbase: float = 2.7
    track: float = 1.6
    wheel_radius: float = 0.33
    wheel_width: float = 0.22
    chassis_mass: float = 1400.0
    wheel_mass: float = 20.0
    suspension_stiffness: float = 7.0e4
    suspension_damping: float = 4.0e3
    tyre_friction: float = 1.0
    max_steer: float = math.radians(35.0)
    imu_offset_b: tuple[float, float, float] = (0.0, 0.3, 0.2)
    gps_antenna_b: tuple[float, float, float] = (0.0, -0.5, 1.2)
    roughness_rms: float = 0.0
    """Road roughness (heightfield) RMS height, m; 0 for a smooth plane."""
    gimbal: bool = False
    """The IMU rides a double-axis gimbal (drawn only: its motion is analytic)."""

    @property
    def rear_axle_b(self) -> tuple[float, float, float]:
        """Centre of the rear axle from the chassis origin (R, F, U), m, at rest: the
        point of the body whose velocity is along the body's forward axis when the
        rear tyres do not slip."""
        return (0.0, -self.wheelbase / 2, WHEEL_CENTRE_Z)


def car_mjcf(p: CarParams, roughness_seed: int = 0, extent: float = 600.0,
             track: Track | None = None, dressed: bool = True) -> tuple[str, dict]:
    """MJCF of the car and the ground, with the track painted on it if given; returns
    (xml, assets) (the heightfield data). The car body, the instruments and the track are
    visual only (``models.scene``): the physics does not depend on them, and dressed=False
    leaves them out (with the horizon and the rims: the model to simulate, not to draw)."""
    hw, hl = p.track / 2, p.wheelbase / 2
    z_wheel = WHEEL_CENTRE_Z
    spring_ref = 0.0
    wheels = []
    for name, x, y, steer in (("fl", -hw, hl, True), ("fr", hw, hl, True),
                              ("rl", -hw, -hl, False), ("rr", hw, -hl, False)):
        steer_joint = (f'<joint name="{name}_steer" type="hinge" axis="0 0 1" '
                       f'range="{-p.max_steer:.5f} {p.max_steer:.5f}" damping="50"/>'
                       if steer else "")
        wheels.append(f"""
      <body name="{name}_susp" pos="{x:g} {y:g} {z_wheel:g}">
        <joint name="{name}_susp" type="slide" axis="0 0 1" range="-0.12 0.12"
               stiffness="{p.suspension_stiffness:g}" springref="{spring_ref:g}"
               damping="{p.suspension_damping:g}"/>
        <geom type="sphere" size="0.05" mass="15" contype="0" conaffinity="0"/>
        <body name="{name}_hub">
          {steer_joint}
          <geom type="sphere" size="0.04" mass="5" contype="0" conaffinity="0"/>
          <body name="{name}_wheel">
            <joint name="{name}_spin" type="hinge" axis="-1 0 0" damping="0.5"/>
            <geom name="{name}_tyre" type="ellipsoid"
                  size="{p.wheel_width / 2:g} {p.wheel_radius:g} {p.wheel_radius:g}"
                  mass="{p.wheel_mass:g}" friction="{p.tyre_friction:g} 0.02 0.001"
                  condim="3" rgba=".1 .1 .1 1"/>
            {_rim(p, -1.0 if x < 0 else 1.0) if dressed else ""}
          </body>
        </body>
      </body>""")
    # Ground: a plane, or a heightfield whose RMS height is the road roughness.
    assets = {}
    if p.roughness_rms > 0.0:
        from scipy.ndimage import gaussian_filter
        cell = 0.2  # m; correlation length ~0.4 m: wheel-hop band at road speeds
        n = int(math.ceil(2 * extent / cell)) + 1
        rng = np.random.default_rng(roughness_seed)
        f = gaussian_filter(rng.standard_normal((n, n)), sigma=2.0, mode="wrap")
        heights = p.roughness_rms * (f - f.mean()) / f.std()
        low, high = float(heights.min()), float(heights.max())
        ground = (f'<geom name="ground" type="hfield" hfield="road" pos="0 0 {low:.6f}" '
                  f'friction="{p.tyre_friction:g} 0.02 0.001" material="ground"/>')
        spacing = 2 * extent / (n - 1)
        ring = np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1]), -1).reshape(-1, 2)

        def ground_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            """Highest grid height around (x, y) (rows along y, columns along x), m."""
            col = np.rint((x + extent) / spacing).astype(int)[..., None] + ring[:, 0]
            row = np.rint((y + extent) / spacing).astype(int)[..., None] + ring[:, 1]
            return heights[np.clip(row, 0, n - 1), np.clip(col, 0, n - 1)].max(-1)
        hfield = (f'<hfield name="road" nrow="{n}" ncol="{n}" '
                  f'size="{extent:g} {extent:g} {high - low:.6f} 0.1"/>')
        assets["road"] = ((heights - low) / (high - low)).astype(np.float32)
    else:
        ground = (f'<geom name="ground" type="plane" size="{extent:g} {extent:g} 1" '
                  f'friction="{p.tyre_friction:g} 0.02 0.001" material="ground"/>')
        hfield = ""

        def ground_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            return np.zeros(np.shape(x))
    ix, iy, iz = p.imu_offset_b
    track_assets, track_geoms = _track_scenery(track, ground_height, p.roughness_rms > 0.0) if track else ("", "")
    body_assets, body_geoms = _car_body(p) if dressed else ("", "")
    # The renderer's scale (its near clipping plane is 0.01 extent): the plane's own
    # statistic (0.2 x its size), which the track would widen; the heightfield's
    # (its diagonal) would clip views closer than ~6 m. Visual only.
    statistic = f'<statistic extent="{0.2 * extent!r}" center="0 0 0"/>'
    # Grass beyond the ground's edge, just below it, out to the far clipping plane.
    low = min(0.0, float(heights.min())) if hfield else 0.0
    horizon = geom("horizon", "plane", (20 * extent, 20 * extent, 1), (0, 0, low - 0.05),
                   material="ground") if dressed else ""
    xml = f"""
<mujoco model="car">
  <option timestep="0.002" integrator="implicitfast" iterations="20" ls_iterations="10"/>
  <visual><global offwidth="640" offheight="480"/></visual>
  {statistic}
  <asset>{hfield}
    {CAR_MATERIALS}
    {track_assets}
    {body_assets}
  </asset>
  <worldbody>
    <light pos="0 0 100" dir="0 0 -1" directional="true" castshadow="false" diffuse=".6 .6 .6"/>
    <light name="sun" mode="trackcom" pos="6 -8 30" dir="-0.2 0.27 -1" cutoff="50"
           diffuse=".4 .4 .4" castshadow="true"/>
    {ground}
    {horizon}
    {track_geoms}
    <body name="carrier" pos="0 0 {p.wheel_radius - z_wheel:g}">
      <freejoint name="chassis"/>
      <geom name="chassis" type="box" size="0.85 2.2 0.3" mass="{p.chassis_mass:g}"
            rgba=".7 .1 .1 1" contype="0" conaffinity="0"/>
      <site name="imu" pos="{ix:g} {iy:g} {iz:g}" size="0.05"/>
      {body_geoms}
      {''.join(wheels)}
    </body>
  </worldbody>
  <tendon>
    <fixed name="rear_diff">
      <joint joint="rl_spin" coef="0.5"/>
      <joint joint="rr_spin" coef="0.5"/>
    </fixed>
  </tendon>
  <actuator>
    <position name="steer_fl" joint="fl_steer" kp="4000" ctrlrange="{-p.max_steer:.5f} {p.max_steer:.5f}"/>
    <position name="steer_fr" joint="fr_steer" kp="4000" ctrlrange="{-p.max_steer:.5f} {p.max_steer:.5f}"/>
    <velocity name="drive" tendon="rear_diff" kv="2000" forcerange="-4000 4000"/>
  </actuator>
{IMU_SENSORS_MJCF}
</mujoco>
"""
    return xml, assets


# --- scenery (visual only) -----------------------------------------------------------------

CAR_MATERIALS = """
    <texture name="sky" type="skybox" builtin="gradient" rgb1=".55 .7 .9" rgb2=".92 .95 1"
             width="64" height="64"/>
    <texture name="ground" type="2d" builtin="checker" rgb1=".34 .45 .26" rgb2=".31 .42 .24"
             mark="random" markrgb=".4 .5 .3" random="0.05" width="512" height="512"/>
    <material name="ground" texture="ground" texrepeat="200 200" texuniform="true"/>
    <texture name="asphalt" type="2d" builtin="flat" rgb1=".24 .24 .25" mark="random"
             markrgb=".38 .38 .4" random="0.08" width="256" height="256"/>
    <material name="asphalt" texture="asphalt" texrepeat="2 2" texuniform="true"
              specular="0.1"/>
    <material name="paint" rgba=".72 .08 .08 1" specular="0.6" shininess="0.8"/>
    <material name="roof" rgba=".52 .05 .06 1" specular="0.6" shininess="0.8"/>
    <material name="glass" rgba=".07 .09 .12 .85" specular="0.9" shininess="0.95"/>
    <material name="trim" rgba=".12 .12 .13 1" specular="0.2"/>
    <material name="chrome" rgba=".78 .78 .8 1" specular="1" shininess="1"/>
    <material name="headlight" rgba="1 .97 .8 1" emission="0.8"/>
    <material name="taillight" rgba=".85 .03 .03 1" emission="0.5"/>"""
"""Car-world textures and materials (visual only)."""

LANE_LIFT, ROAD_LIFT = 0.04, 0.02
"""Painted lines and road surface above the ground, m (clear of depth-buffer fighting)."""


def _rim(p: CarParams, side: float) -> str:
    """Wheel rim, hub and spokes on the outer face (side: +1 right wheels, -1 left)."""
    x = side * (p.wheel_width / 2 + 0.004)
    r = 0.62 * p.wheel_radius
    return "\n".join([
        geom(None, "cylinder", (r, 0.005), (x, 0, 0), material="chrome", euler="0 90 0"),
        geom(None, "cylinder", (0.07, 0.012), (x + side * 0.006, 0, 0), material="trim",
             euler="0 90 0"),
        geom(None, "box", (0.006, r * 0.95, 0.025), (x + side * 0.004, 0, 0), material="trim"),
        geom(None, "box", (0.006, 0.025, r * 0.95), (x + side * 0.004, 0, 0), material="trim")])


# The car body (chassis origin, R F U, m): the chassis box (the physics geom) is the lower
# body, 0.85 x 2.2 x 0.3 half; the cabin's base and roof rectangles (x half, y back, y front,
# z).
_CABIN_BASE = (0.80, -1.55, 0.85, 0.30)
_CABIN_ROOF = (0.66, -1.05, 0.15, 0.80)


def _cabin_faces() -> dict[str, np.ndarray]:
    """The cabin's window faces, each (4, 3) corners (p00, p10, p11, p01)."""
    bx, by0, by1, bz = _CABIN_BASE
    rx, ry0, ry1, rz = _CABIN_ROOF
    faces = {"windshield": [(-bx, by1, bz), (bx, by1, bz), (rx, ry1, rz), (-rx, ry1, rz)],
             "rear_window": [(bx, by0, bz), (-bx, by0, bz), (-rx, ry0, rz), (rx, ry0, rz)]}
    for name, s in (("left", -1.0), ("right", 1.0)):
        faces[name] = [(s * bx, by0, bz), (s * bx, by1, bz), (s * rx, ry1, rz),
                       (s * rx, ry0, rz)]
    return {k: np.array(v, dtype=float) for k, v in faces.items()}


def _pane(name: str, quad: np.ndarray, u, v) -> tuple[str, str]:
    """A dark window pane on the cabin face quad, between the bilinear parameters u, v."""
    centre = np.array([0.0, (_CABIN_BASE[1] + _CABIN_BASE[2]) / 2, 0.5])
    n = np.cross(quad[1] - quad[0], quad[3] - quad[0])
    n /= np.linalg.norm(n)
    if n @ (quad.mean(0) - centre) < 0:
        n = -n
    corners = quad_inset(quad, u, v) + 0.004 * n
    return (mesh_asset(name, slab_mesh(corners, n, 0.008)),
            f'<geom name="{name}" type="mesh" mesh="{name}" material="glass" '
            f'group="{DRESSING}" {VISUAL}/>')


def _car_body(p: CarParams) -> tuple[str, str]:
    """(assets, geoms) of the car's visual body on the chassis: cabin, windows, bumpers,
    lights, arches, mirrors; the IMU case and its axes at the IMU site, the gimbal frames
    if any, and the GPS antenna (mast and disc) at its offset."""
    bx, by0, by1, bz = _CABIN_BASE
    rx, ry0, ry1, rz = _CABIN_ROOF
    cabin = np.array([(sx * bx, y, bz) for sx in (-1, 1) for y in (by0, by1)]
                     + [(sx * rx, y, rz) for sx in (-1, 1) for y in (ry0, ry1)])
    assets = [mesh_asset("cabin", cabin)]
    geoms = ['<geom name="cabin" type="mesh" mesh="cabin" material="roof" '
             f'group="{DRESSING}" {VISUAL}/>']
    faces = _cabin_faces()
    panes = [("windshield", faces["windshield"], (0.06, 0.94), (0.08, 0.92)),
             ("rear_window", faces["rear_window"], (0.08, 0.92), (0.12, 0.9))]
    for side in ("left", "right"):
        panes += [(f"window_{side}_front", faces[side], (0.5, 0.9), (0.12, 0.9)),
                  (f"window_{side}_rear", faces[side], (0.1, 0.46), (0.12, 0.9))]
    for name, quad, u, v in panes:
        a, g = _pane(name, quad, u, v)
        assets.append(a)
        geoms.append(g)
    hw, hl = p.track / 2, p.wheelbase / 2
    geoms += [
        geom("bumper_front", "box", (0.87, 0.08, 0.09), (0, 2.22, -0.18), material="trim"),
        geom("bumper_rear", "box", (0.87, 0.08, 0.09), (0, -2.22, -0.18), material="trim"),
        geom("grille", "box", (0.42, 0.01, 0.07), (0, 2.205, 0.05), material="trim"),
        geom("plate_front", "box", (0.24, 0.005, 0.055), (0, 2.305, -0.18), rgba=".95 .95 .92 1"),
        geom("plate_rear", "box", (0.24, 0.005, 0.055), (0, -2.305, -0.18), rgba=".95 .95 .92 1"),
    ]
    for s in (-1.0, 1.0):
        geoms += [
            geom(None, "box", (0.17, 0.012, 0.055), (s * 0.6, 2.205, 0.13),
                 material="headlight"),
            geom(None, "box", (0.15, 0.012, 0.05), (s * 0.62, -2.205, 0.15),
                 material="taillight"),
            geom(None, "box", (0.05, 0.09, 0.045), (s * 0.9, 0.72, 0.38), material="paint"),
            geom(None, "box", (0.003, 0.9, 0.004), (s * 0.852, -0.35, 0.05), material="trim"),
        ]
        for y in (-hl, hl):   # wheel arches: the circle above the sill, on the body side
            a = np.linspace(-0.05, np.pi + 0.05, 24)
            r = p.wheel_radius + 0.07
            arch = np.stack([np.zeros_like(a), r * np.cos(a), r * np.sin(a)], -1)
            arch = np.concatenate([arch + (s * (hw + 0.053), y, WHEEL_CENTRE_Z),
                                   arch + (s * (hw + 0.047), y, WHEEL_CENTRE_Z)])
            arch[:, 2] = np.maximum(arch[:, 2], -0.3)
            name = f"arch_{'r' if s > 0 else 'l'}{'f' if y > 0 else 'r'}"
            assets.append(mesh_asset(name, arch))
            geoms.append(f'<geom name="{name}" type="mesh" mesh="{name}" material="trim" '
                         f'group="{DRESSING}" {VISUAL}/>')
    # The instruments: IMU case and axes (gimbal frames round it), the GPS antenna.
    imu = np.asarray(p.imu_offset_b, dtype=float)
    geoms += [geom("imu_case", "box", (0.07, 0.09, 0.05), imu, rgba=".85 .65 .2 1",
                   group=INSTRUMENTS), imu_axes(imu, 0.3, 0.015)]
    if p.gimbal:
        for name, major, euler in (("gimbal_outer", 0.19, "0 0 0"),
                                   ("gimbal_inner", 0.15, "0 90 0")):
            v, f = torus_mesh(major, 0.012)
            assets.append(mesh_asset(name, v, f))
            geoms.append(f'<geom name="{name}" type="mesh" mesh="{name}" pos="{fmt(imu)}" '
                         f'euler="{euler}" rgba=".85 .45 .1 1" group="{INSTRUMENTS}" '
                         f'{VISUAL}/>')
        geoms += [geom(None, "capsule", (0.01,), group=INSTRUMENTS, rgba=".3 .3 .3 1",
                       fromto=fmt(np.concatenate([imu + (s * 0.07, 0, 0),
                                                  imu + (s * 0.19, 0, 0)])))
                  for s in (-1.0, 1.0)]
        geoms.append(geom(None, "capsule", (0.012,), group=INSTRUMENTS, rgba=".3 .3 .3 1",
                          fromto=fmt(np.concatenate([imu - (0, 0, 0.19),
                                                     imu - (0, 0, 0.3)]))))
    ant = np.asarray(p.gps_antenna_b, dtype=float)
    on_roof = abs(ant[0]) < rx and ry0 < ant[1] < ry1
    base = rz if on_roof else 0.3 if abs(ant[0]) < 0.85 and abs(ant[1]) < 2.2 else ant[2] - 0.3
    if ant[2] - base > 0.02:
        geoms.append(geom("antenna_mast", "cylinder", (0.012, (ant[2] - base) / 2),
                          (ant[0], ant[1], (ant[2] + base) / 2), rgba=".2 .2 .2 1",
                          group=INSTRUMENTS))
    geoms.append(geom("antenna", "cylinder", (0.09, 0.015), ant, rgba=".92 .92 .9 1",
                      group=INSTRUMENTS))
    return "\n    ".join(assets), "\n      ".join(geoms)


def _track_scenery(track: Track, ground, rough: bool) -> tuple[str, str]:
    """(assets, geoms) of the track on the ground: a 6 m asphalt road along the path, the
    path itself as a dashed yellow line (1.5 m dashes every 3 m, 0.3 m wide) and solid
    white lane edges 2 m either side; meshes lifted above ground(x, y), m (on a rough
    road sampled every 0.25 m along and 0.5 m across, else every 0.5 m)."""
    length = float(np.sum(np.linalg.norm(np.diff(track.points, axis=0), axis=1)))
    pts, s, normal = resample_closed(track.points, max(0.25 if rough else 0.5,
                                                       length / TRACK_VERTICES))
    s_end = s[-1] + np.linalg.norm(pts[0] - pts[-1])
    rise = 0.015 * (1 - np.cos(2 * np.pi * s / s_end))[:, None]

    def raised(x, y):
        """The ground, up to 3 cm higher half way round: where a figure-8 crosses itself
        the later branch lies above the first (coplanar roads would flicker)."""
        return ground(x, y) + rise

    out = []
    for name, offset, width, dash, lift, across in (
            ("track_road", 0.0, 6.0, None, ROAD_LIFT, 13 if rough else 2),
            ("track_path", 0.0, 0.3, (1.5, 3.0), LANE_LIFT, 2),
            ("track_edge_left", 2.0, 0.15, None, LANE_LIFT, 2),
            ("track_edge_right", -2.0, 0.15, None, LANE_LIFT, 2)):
        out.append((name, *ribbon(pts, s, normal, offset, width, raised, lift, across, dash)))
    assets = "\n    ".join(mesh_asset(name, v, f) for name, v, f in out)
    colour = {"track_road": 'material="asphalt"', "track_path": 'rgba=".95 .78 .1 1"',
              "track_edge_left": 'rgba=".95 .95 .95 1"', "track_edge_right": 'rgba=".95 .95 .95 1"'}
    geoms = "\n    ".join(f'<geom name="{name}" type="mesh" mesh="{name}" {colour[name]} '
                          f'group="{DRESSING}" {VISUAL}/>' for name, _, _ in out)
    return assets, geoms


# --- tracks ------------------------------------------------------------------------------

RADIUS_MAX = 20000.0
"""m: the largest track (a ring's radius, a figure-8's half-width); 20 km rings stand in
for a straight road."""
TRACK_VERTICES = 20000
"""The drawn track's most samples along the path (a long track's lines get coarser)."""
ROUGH_RADIUS_MAX = 500.0
"""m: the largest track on a rough road (its 0.2 m heightfield: 5300^2 cells)."""


@dataclass(frozen=True)
class Track:
    """A closed path in the plane (E, N), m, starting at the origin heading north.
    points (N, 2); s (N,) cumulative arc length; length: total, m."""

    points: np.ndarray
    s: np.ndarray
    length: float

    @classmethod
    def from_points(cls, points: np.ndarray) -> "Track":
        seg = np.linalg.norm(np.diff(points, axis=0, append=points[:1]), axis=1)
        return cls(points, np.concatenate([[0.0], np.cumsum(seg[:-1])]), float(seg.sum()))

    def min_radius(self) -> float:
        """Smallest radius of curvature along the track, m."""
        d1 = np.gradient(self.points, self.s, axis=0)
        d2 = np.gradient(d1, self.s, axis=0)
        kappa = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(
            np.linalg.norm(d1, axis=1) ** 3, 1e-12)
        return float(1.0 / max(np.percentile(kappa, 99.5), 1e-9))


def ring_track(radius: float, clockwise: bool = True, n: int = 4000) -> Track:
    """Circle through the origin, tangent to north there."""
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    side = 1.0 if clockwise else -1.0
    pts = np.stack([side * radius * (1 - np.cos(a)), radius * np.sin(a)], -1)
    return Track.from_points(pts)


def figure8_track(size: float, n: int = 8000) -> Track:
    """Lemniscate of Bernoulli with half-width `size` (m), rotated so that it crosses the
    origin heading north; it turns both ways."""
    t = np.linspace(np.pi / 2, np.pi / 2 + 2 * np.pi, n, endpoint=False)
    den = 1 + np.sin(t) ** 2
    pts = np.stack([size * np.cos(t) / den, size * np.sin(t) * np.cos(t) / den], -1)
    d = pts[1] - pts[0]
    angle = np.arctan2(d[0], d[1])  # rotate the start tangent onto north
    c, s = np.cos(angle), np.sin(angle)
    return Track.from_points(pts @ np.array([[c, -s], [s, c]]).T)


# --- driver -------------------------------------------------------------------------------

@dataclass(frozen=True)
class DriveProfile:
    """Speed schedule: still until start_time (s), ramp at accel (m/s^2) to speed (m/s),
    drive until stop_time (s), then brake to rest."""

    speed: float
    start_time: float = 0.0
    stop_time: float = math.inf
    accel: float = 1.5

    def target_speed(self, t: float) -> float:
        if t < self.start_time:
            return 0.0
        if t >= self.stop_time:
            return max(0.0, self.speed - 2.0 * self.accel * (t - self.stop_time))
        return min(self.speed, self.accel * (t - self.start_time))


class PurePursuit:
    """Pure pursuit steering with look-ahead (m) and Ackermann wheel angles."""

    def __init__(self, track: Track, params: CarParams, lookahead: float = 6.0) -> None:
        self.track, self.p, self.lookahead = track, params, lookahead
        self._index = 0

    def steer(self, pos: np.ndarray, yaw: float) -> tuple[float, float, float]:
        """(left, right, cross-track error) for the rear-axle position (E, N) and yaw
        (rad, CCW from north)."""
        pts, n = self.track.points, len(self.track.points)
        window = (self._index + np.arange(-10, 120)) % n  # the car moves a few points per call
        d2 = (pts[window, 0] - pos[0]) ** 2 + (pts[window, 1] - pos[1]) ** 2
        best = int(np.argmin(d2))
        if best == len(window) - 1:  # lost the track: search it all
            window = np.arange(n)
            d2 = (pts[:, 0] - pos[0]) ** 2 + (pts[:, 1] - pos[1]) ** 2
            best = int(np.argmin(d2))
        self._index = int(window[best])
        s_target = (self.track.s[self._index] + self.lookahead) % self.track.length
        tx, ty = pts[int(np.searchsorted(self.track.s, s_target)) % n]
        dx, dy = tx - pos[0], ty - pos[1]
        c, s_ = math.cos(yaw), math.sin(yaw)
        # forward = (-sin yaw, cos yaw), right = (cos yaw, sin yaw); positive alpha: right
        alpha = math.atan2(dx * c + dy * s_, -dx * s_ + dy * c)
        delta = math.atan(2.0 * self.p.wheelbase * math.sin(alpha) / self.lookahead)
        delta = min(max(delta, -self.p.max_steer), self.p.max_steer)
        error = math.sqrt(float(d2[best]))
        if abs(delta) < 1e-6:
            return 0.0, 0.0, error
        R = self.p.wheelbase / math.tan(abs(delta))
        inner = math.atan(self.p.wheelbase / (R - self.p.track / 2))
        outer = math.atan(self.p.wheelbase / (R + self.p.track / 2))
        # A right turn (delta > 0) is a negative rotation about up.
        if delta > 0:
            return -outer, -inner, error
        return inner, outer, error


# --- the world ------------------------------------------------------------------------------

class CarWorld:
    """The car and its driver in MuJoCo."""

    smooth_truth = False
    """The truth is MuJoCo's discrete motion itself (``models.world.discrete_imu``): wheel
    contacts on a rough road change the rates within a step."""

    def __init__(self, params: CarParams, track: Track, profile: DriveProfile,
                 roughness_seed: int = 0, control_period: int = 25,
                 pictures: bool = False) -> None:
        """pictures: dress the model to be drawn (the car's body, the instruments, the
        road and its lanes: visual geoms only). Without them the simulation is bit for bit
        the same, and 10 % cheaper per step (``mj_step`` computes every geom's pose)."""
        import mujoco
        self.params, self.track, self.profile = params, track, profile
        reach = np.abs(track.points).max() + 30.0
        xml, assets = car_mjcf(params, roughness_seed, extent=float(reach),
                               track=track if pictures else None, dressed=pictures)
        self.model = mujoco.MjModel.from_xml_string(xml)
        if "road" in assets:
            self.model.hfield_data[:] = assets["road"].ravel()
        skip_sensors(self.model)
        self.data = mujoco.MjData(self.model)
        self.control_period = control_period
        m = self.model
        self._spin_qpos = [m.joint(f"{w}_spin").qposadr[0] for w in ("fl", "fr", "rl", "rr")]
        self._settle()

    def _settle(self, seconds: float = 2.0) -> None:
        """Let the suspension settle at rest before time zero (brakes on)."""
        import mujoco
        m, d = self.model, self.data
        for _ in range(int(seconds / m.opt.timestep)):
            d.ctrl[:] = 0.0
            mujoco.mj_step(m, d)
        d.qvel[:] = 0.0
        d.time = 0.0
        # Re-centre at the origin heading north after settling.
        d.qpos[0:2] = 0.0
        mujoco.mj_forward(m, d)

    def run(self, duration: float) -> DiscreteRun:
        """Drive for duration (s), recording every physics step."""
        import mujoco
        m, d, p = self.model, self.data, self.params
        dt = m.opt.timestep
        n = int(round(duration / dt))
        qpos_hist = np.empty((n + 1, m.nq))
        qvel_hist = np.empty((n + 2, m.nv))
        control_steps = np.arange(0, n + 1, self.control_period)
        xtrack = np.empty(control_steps.size)
        driver = PurePursuit(self.track, p)
        qpos, qvel, ctrl = d.qpos, d.qvel, d.ctrl
        rear_offset = np.array([0.0, -p.wheelbase / 2])
        period = self.control_period
        for k in range(n + 1):
            qpos_hist[k] = qpos
            qvel_hist[k] = qvel
            if k % period == 0:
                w, x, y, z = qpos[3], qpos[4], qpos[5], qpos[6]
                # yaw from C = quat_to_dcm(q): atan2(-C[0, 1], C[1, 1])
                yaw = math.atan2(-2 * (x * y - w * z), 1 - 2 * (x * x + z * z))
                fx, fy = 2 * (x * y - w * z), 1 - 2 * (x * x + z * z)  # C[0, 1], C[1, 1]
                rear = (qpos[0] + fx * rear_offset[1], qpos[1] + fy * rear_offset[1])
                left, right, xtrack[k // period] = driver.steer(rear, yaw)
                ctrl[0], ctrl[1] = left, right
                ctrl[2] = self.profile.target_speed(k * dt) / p.wheel_radius
            mujoco.mj_step(m, d)
        qvel_hist[n + 1] = qvel
        wheels = qpos_hist[:, self._spin_qpos]
        return DiscreteRun(dt=dt, t=np.arange(n + 1) * dt, pos=qpos_hist[:, 0:3],
                      quat=qpos_hist[:, 3:7], vel=qvel_hist[:, 0:3], omega=qvel_hist[:, 3:6],
                      wheel_angles=np.unwrap(wheels, axis=0),
                      cross_track=np.repeat(xtrack, period)[: n + 1],
                           imu_offset_b=np.asarray(p.imu_offset_b), qpos=qpos_hist)


@dataclass(frozen=True)
class VehicleMotion(GimbalRates):
    """What the car does: track "ring" (radius = circle radius, m) or "figure8"
    (radius = half-width of the lemniscate, m); speed, m/s; still until start_time, s;
    brake at stop_time, s; accel, m/s^2; road roughness RMS, m; IMU and GPS-antenna
    offsets from the chassis origin (R, F, U), m."""

    track: str = "ring"
    radius: float = 100.0
    speed: float = 8.0
    start_time: float = 0.0
    stop_time: float = math.inf
    accel: float = 1.5
    roughness_rms: float = 0.0
    imu_offset_b: tuple[float, float, float] = (0.0, 0.3, 0.2)
    gps_antenna_b: tuple[float, float, float] = (0.0, -0.5, 1.2)
    gimbal_outer_rate: float = 0.0
    """Optional double-axis gimbal under the IMU (``GimbalRates``), rad/s; both 0 for a
    strapdown IMU."""
    gimbal_inner_rate: float = 0.0
    gimbal_stalls: tuple[tuple[float, float], ...] = ()
    """Injected stalls (start s, duration s) of that gimbal (``models.world.stalled``)."""

    def make_track(self) -> Track:
        if self.track == "ring":
            return ring_track(self.radius)
        if self.track == "figure8":
            return figure8_track(self.radius)
        raise ValueError(f"motion.track = {self.track!r}; valid choices: figure8, ring")

    def car_params(self) -> CarParams:
        return CarParams(imu_offset_b=self.imu_offset_b, gps_antenna_b=self.gps_antenna_b,
                         roughness_rms=self.roughness_rms, gimbal=self.has_gimbal)

    def profile(self) -> DriveProfile:
        return DriveProfile(speed=self.speed, start_time=self.start_time,
                            stop_time=self.stop_time, accel=self.accel)

    def check(self) -> None:
        """Raise ValueError naming the field if the car cannot drive this."""
        if self.track not in ("ring", "figure8"):
            raise ValueError(f"motion.track = {self.track!r}; valid choices: figure8, ring")
        if not 0.0 < self.radius <= RADIUS_MAX:
            raise ValueError(f"motion.radius = {self.radius:g} m is out of range "
                             f"(0, {RADIUS_MAX:g}]")
        if self.roughness_rms > 0.0 and self.radius > ROUGH_RADIUS_MAX:
            raise ValueError(f"motion.radius = {self.radius:g} m with a rough road: at most "
                             f"{ROUGH_RADIUS_MAX:g} m (the road's heightfield grows with the "
                             "track's square)")
        if not 0.0 <= self.speed <= 40.0:
            raise ValueError(f"motion.speed = {self.speed:g} m/s is out of range [0, 40]")
        p = self.car_params()
        turning = p.wheelbase / math.tan(p.max_steer)
        r_min = self.make_track().min_radius()
        if r_min < turning + p.track:
            raise ValueError(f"motion.radius = {self.radius:g} m gives curves of {r_min:.1f} m"
                             f" radius, tighter than the car can steer ({turning + p.track:.1f} m)")
        lateral = self.speed ** 2 / r_min
        if lateral > G_LATERAL_MAX:
            raise ValueError(
                f"motion.speed = {self.speed:g} m/s on curves of {r_min:.1f} m radius needs "
                f"{lateral:.2f} m/s^2 lateral acceleration; the car holds at most "
                f"{G_LATERAL_MAX:.2f} (speed <= {math.sqrt(G_LATERAL_MAX * r_min):.1f} m/s)")
        if not self.accel > 0.0:
            raise ValueError(f"motion.accel = {self.accel:g} m/s^2 must be > 0")
        for name, reach in (("imu_offset_b", 5.0), ("gps_antenna_b", 10.0)):
            offset = getattr(self, name)
            if not all(math.isfinite(v) and abs(v) <= reach for v in offset):
                raise ValueError(f"motion.{name} = {list(offset)} m: each component must be "
                                 f"within +-{reach:g} m of the chassis origin (on the car)")
