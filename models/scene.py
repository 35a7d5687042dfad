"""Visual scene dressing for the MuJoCo worlds (issue 15): MJCF snippets and meshes made in
code, no downloaded assets.

Every geom made here is visual only: ``VISUAL`` (no contacts, mass 0: MuJoCo adds no mass
or inertia for it), so the bodies' mass properties, the joints, sensors and sites, and
hence the physics, are unchanged. Groups: 1 for the carrier's dressing and the scenery,
2 for the instruments (IMU case and axes, gimbal frames, antenna); MuJoCo shows groups
0-2 by default, and hiding 0 and 1 leaves the instruments alone (an x-ray view).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

VISUAL = 'contype="0" conaffinity="0" mass="0"'
"""Attributes of a visual-only geom."""

DRESSING, INSTRUMENTS = 1, 2
"""Geom groups of the scenery and carrier dressing, and of the instruments."""

AXIS_RGBA = {"x": ".9 .1 .1 1", "y": ".1 .8 .1 1", "z": ".15 .3 1 1"}


def fmt(values, digits: int = 5) -> str:
    """Numbers as an MJCF attribute string."""
    return " ".join(f"{float(v):.{digits}g}" for v in np.ravel(values))


def geom(name: str | None, kind: str, size, pos=(0.0, 0.0, 0.0), rgba: str | None = None,
         group: int = DRESSING, **attrs) -> str:
    """A visual-only geom; attrs are further MJCF attributes (euler, material, ...)."""
    parts = [f'<geom type="{kind}"' + (f' name="{name}"' if name else ""),
             f'size="{fmt(size)}"', f'pos="{fmt(pos)}"', f'group="{group}"', VISUAL]
    if rgba:
        parts.append(f'rgba="{rgba}"')
    parts += [f'{k}="{v}"' for k, v in attrs.items()]
    return " ".join(parts) + "/>"


def imu_axes(pos, length: float = 0.3, radius: float = 0.012) -> str:
    """The sensor axes from pos (body frame): capsules imu_axis_x (red), _y (green),
    _z (blue), length m."""
    pos = np.asarray(pos, dtype=float)
    out = []
    for i, axis in enumerate("xyz"):
        tip = pos.copy()
        tip[i] += length
        out.append(f'<geom name="imu_axis_{axis}" type="capsule" size="{radius:g}" '
                   f'fromto="{fmt(pos)} {fmt(tip)}" rgba="{AXIS_RGBA[axis]}" '
                   f'group="{INSTRUMENTS}" {VISUAL}/>')
    return "\n".join(out)


def mesh_asset(name: str, vertices: np.ndarray, faces: np.ndarray | None = None,
               digits: int = 7) -> str:
    """An inline mesh asset; without faces MuJoCo takes the convex hull. Open surfaces
    get the shell inertia (they have no volume; the geoms are massless anyway)."""
    face = "" if faces is None else f' face="{" ".join(map(str, np.ravel(faces)))}"'
    shell = "" if faces is None else ' inertia="shell"'
    return f'<mesh name="{name}" vertex="{fmt(vertices, digits)}"{face}{shell}/>'


def slab_mesh(corners: np.ndarray, outward: np.ndarray, thickness: float) -> np.ndarray:
    """Vertices (8, 3) of a thin plate on the planar polygon corners (4, 3), from the
    polygon out along the unit normal outward by thickness (a convex mesh)."""
    return np.concatenate([corners, corners + thickness * np.asarray(outward)])


def quad_inset(quad: np.ndarray, u: tuple[float, float], v: tuple[float, float]) -> np.ndarray:
    """The sub-quad (4, 3) of quad (4, 3; corners p00, p10, p11, p01) between the bilinear
    parameters u (along p00-p10) and v (along p00-p01)."""
    p00, p10, p11, p01 = quad

    def at(a, b):
        return (1 - a) * (1 - b) * p00 + a * (1 - b) * p10 + a * b * p11 + (1 - a) * b * p01

    return np.array([at(u[0], v[0]), at(u[1], v[0]), at(u[1], v[1]), at(u[0], v[1])])


def torus_mesh(major: float, minor: float, n: int = 32, m: int = 8
               ) -> tuple[np.ndarray, np.ndarray]:
    """A ring about the z axis: vertices (n m, 3) and faces (2 n m, 3)."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)[:, None]
    b = np.linspace(0, 2 * np.pi, m, endpoint=False)[None, :]
    r = major + minor * np.cos(b)
    v = np.stack([r * np.cos(a), r * np.sin(a), minor * np.sin(b) + 0 * a], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    q00, q10 = i * m + j, (i + 1) % n * m + j
    q01, q11 = i * m + (j + 1) % m, (i + 1) % n * m + (j + 1) % m
    f = np.concatenate([np.stack([q00, q10, q11], -1).reshape(-1, 3),
                        np.stack([q00, q11, q01], -1).reshape(-1, 3)])
    return v, f


def resample_closed(points: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray,
                                                               np.ndarray]:
    """Points (N, 2) of a closed path resampled every ~step m: (M, 2) points, (M,) arc
    lengths and (M, 2) unit left normals."""
    closed = np.vstack([points, points[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    count = max(8, int(np.ceil(s[-1] / step)))
    s_new = np.linspace(0.0, s[-1], count, endpoint=False)
    pts = np.stack([np.interp(s_new, s, closed[:, 0]), np.interp(s_new, s, closed[:, 1])], -1)
    tangent = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return pts, s_new, np.stack([-tangent[:, 1], tangent[:, 0]], -1)


def ribbon(pts: np.ndarray, s: np.ndarray, normal: np.ndarray, offset: float, width: float,
           ground: Callable[[np.ndarray, np.ndarray], np.ndarray], lift: float,
           across: int = 2, dash: tuple[float, float] | None = None
           ) -> tuple[np.ndarray, np.ndarray]:
    """A painted strip along a closed path (points pts (M, 2), arc lengths s, left normals
    normal): centred offset m to the left, width m wide, lift m above ground(x, y) at each
    vertex, across vertices over its width; dash (length, period) m paints only the
    segments starting within length of each period. Upward-facing triangles; returns
    vertices (K, 3) and faces (L, 3)."""
    m = len(pts)
    w = np.linspace(-width / 2, width / 2, across) + offset
    xy = pts[:, None, :] + w[None, :, None] * normal[:, None, :]           # (M, across, 2)
    z = ground(xy[..., 0], xy[..., 1]) + lift
    vertices = np.concatenate([xy, z[..., None]], -1).reshape(-1, 3)
    seg = np.arange(m)
    if dash is not None:
        seg = seg[np.mod(s, dash[1]) < dash[0]]
    nxt = (seg + 1) % m
    k = np.arange(across - 1)
    # (i, k) right of (i, k+1); forward i -> i+1: right, forward, left is counter-clockwise
    r0, l0 = seg[:, None] * across + k, seg[:, None] * across + k + 1
    r1, l1 = nxt[:, None] * across + k, nxt[:, None] * across + k + 1
    faces = np.concatenate([np.stack([r0, r1, l1], -1).reshape(-1, 3),
                            np.stack([r0, l1, l0], -1).reshape(-1, 3)])
    used, faces = np.unique(faces, return_inverse=True)
    return vertices[used], faces.reshape(-1, 3)
