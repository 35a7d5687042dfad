"""The car's scenery (visual only, ``models.scene``: massless, contact-free geoms; the
physics is bit-identical without them): the red saloon's body on the chassis (cabin,
windows, bumpers, lights, wheel arches, rims), the IMU case with its axes and gimbal
frames, the GPS antenna, and the track painted on the ground (asphalt road, dashed yellow
path, white lane edges). ``models.car.car_mjcf`` puts them in the car's MJCF."""
from __future__ import annotations

import numpy as np

from aligngym.models.car_params import WHEEL_CENTRE_Z, CarParams
from aligngym.models.car_track import TRACK_VERTICES, Track
from aligngym.models.scene import (DRESSING, INSTRUMENTS, VISUAL, fmt, geom, imu_axes, mesh_asset,
                                   quad_inset, resample_closed, ribbon, slab_mesh, torus_mesh)


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


def rim(p: CarParams, side: float) -> str:
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


def car_body(p: CarParams) -> tuple[str, str]:
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


def track_scenery(track: Track, ground, rough: bool) -> tuple[str, str]:
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
