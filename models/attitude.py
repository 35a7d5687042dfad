"""Attitude math on one value or a stack with leading axes (like scipy's Rotation).

The one place where conventions are written down:

- Quaternions are scalar-first unit quaternions ``q = [w, x, y, z]``. ``q_b_n`` maps
  b-coordinates into n-coordinates: ``v_n = q_b_n * v_b * conj(q_b_n)``; its DCM is
  ``C_b_n``. Composition: ``q_b_n = q_m_n * q_b_m``, like ``C_b_n = C_m_n @ C_b_m``.
- Euler angles ``[pitch, roll, yaw]`` (rad) follow PSINS:
  ``C_b_n = Rz(yaw) @ Rx(pitch) @ Ry(roll)`` with n = ENU and b = Right-Forward-Up.
  Yaw is positive counter-clockwise (toward west); heading clockwise from north is
  ``-yaw``.
- Rotation vectors ``phi`` (rad) map through the exponential:
  ``C = exp([phi x])``.
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "cross", "skew", "quat_mul", "quat_conj", "quat_normalize", "quat_rotate",
    "quat_to_dcm", "dcm_to_quat", "rotvec_to_quat", "quat_to_rotvec",
    "rotvec_to_dcm", "dcm_to_rotvec", "euler_to_dcm", "dcm_to_euler",
    "euler_to_quat", "quat_to_euler", "rot_x", "rot_y", "rot_z", "quat_angle", "quat_cumprod",
]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product a x b of (..., 3) arrays; several times faster than np.cross on
    small stacks."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def skew(v: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrix [v x]; v: (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -w, y
    out[..., 1, 0], out[..., 1, 2] = w, -x
    out[..., 2, 0], out[..., 2, 1] = -y, x
    return out


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p * q of scalar-first quaternions (..., 4)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[..., 0] = pw * qw - px * qx - py * qy - pz * qz
    out[..., 1] = pw * qx + px * qw + py * qz - pz * qy
    out[..., 2] = pw * qy - px * qz + py * qw + pz * qx
    out[..., 3] = pw * qz + px * qy - py * qx + pz * qw
    return out


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate (inverse of a unit quaternion), (..., 4)."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion with non-negative scalar part, (..., 4)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate v (..., 3) by unit quaternion q (..., 4): C(q) @ v."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * cross(u, v)
    return v + w * t + cross(u, t)


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """DCM (..., 3, 3) of unit quaternion (..., 4)."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    C = np.empty(q.shape[:-1] + (3, 3))
    C[..., 0, 0] = 1 - 2 * (y * y + z * z)
    C[..., 0, 1] = 2 * (x * y - w * z)
    C[..., 0, 2] = 2 * (x * z + w * y)
    C[..., 1, 0] = 2 * (x * y + w * z)
    C[..., 1, 1] = 1 - 2 * (x * x + z * z)
    C[..., 1, 2] = 2 * (y * z - w * x)
    C[..., 2, 0] = 2 * (x * z - w * y)
    C[..., 2, 1] = 2 * (y * z + w * x)
    C[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return C


def dcm_to_quat(C: np.ndarray) -> np.ndarray:
    """Unit quaternion (..., 4), scalar part >= 0, of a rotation matrix (..., 3, 3).

    Uses the largest of the four squared components (Shepperd's method), so it is
    accurate for every rotation.
    """
    C = np.asarray(C, dtype=float)
    tr = C[..., 0, 0] + C[..., 1, 1] + C[..., 2, 2]
    cands = np.stack([
        np.stack([1 + tr, C[..., 2, 1] - C[..., 1, 2], C[..., 0, 2] - C[..., 2, 0],
                  C[..., 1, 0] - C[..., 0, 1]], -1),
        np.stack([C[..., 2, 1] - C[..., 1, 2], 1 + 2 * C[..., 0, 0] - tr,
                  C[..., 0, 1] + C[..., 1, 0], C[..., 0, 2] + C[..., 2, 0]], -1),
        np.stack([C[..., 0, 2] - C[..., 2, 0], C[..., 0, 1] + C[..., 1, 0],
                  1 + 2 * C[..., 1, 1] - tr, C[..., 1, 2] + C[..., 2, 1]], -1),
        np.stack([C[..., 1, 0] - C[..., 0, 1], C[..., 0, 2] + C[..., 2, 0],
                  C[..., 1, 2] + C[..., 2, 1], 1 + 2 * C[..., 2, 2] - tr], -1),
    ], -2)
    diag = np.stack([tr, C[..., 0, 0], C[..., 1, 1], C[..., 2, 2]], -1)
    best = np.argmax(diag, axis=-1)
    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    return quat_normalize(q)


def rotvec_to_quat(phi: np.ndarray) -> np.ndarray:
    """Quaternion exp of rotation vector phi (..., 3) rad -> (..., 4); exact for all angles."""
    phi = np.asarray(phi, dtype=float)
    angle = np.sqrt(np.sum(phi * phi, axis=-1))
    out = np.empty(phi.shape[:-1] + (4,))
    out[..., 0] = np.cos(0.5 * angle)
    # sin(angle/2)/angle = sinc(angle / 2pi) / 2, well defined at zero.
    out[..., 1:] = (0.5 * np.sinc(angle / (2.0 * np.pi)))[..., None] * phi
    return out


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector (..., 3) rad, angle in [0, pi], of unit quaternion (..., 4)."""
    q = quat_normalize(q)
    w = q[..., :1]
    u = q[..., 1:]
    s = np.linalg.norm(u, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, w)
    small = s < 1e-8
    scale = np.where(small, 2.0 / w * (1.0 - s * s / (3.0 * w * w)),
                     angle / np.where(small, 1.0, s))
    return scale * u


def rotvec_to_dcm(phi: np.ndarray) -> np.ndarray:
    """DCM exp([phi x]) of rotation vector (..., 3) rad."""
    return quat_to_dcm(rotvec_to_quat(phi))


def dcm_to_rotvec(C: np.ndarray) -> np.ndarray:
    """Rotation vector log(C) (..., 3) rad of a DCM (..., 3, 3).

    Directly from the skew part, sin(a) axis = vee(C - C^T)/2, and a = atan2(sin, cos):
    accurate down to zero angle; rotations beyond ~150 deg, where the skew part loses
    the axis, go through the quaternion.
    """
    C = np.asarray(C, dtype=float)
    w = 0.5 * np.stack([C[..., 2, 1] - C[..., 1, 2], C[..., 0, 2] - C[..., 2, 0],
                        C[..., 1, 0] - C[..., 0, 1]], -1)
    s = np.sqrt(np.sum(w * w, axis=-1))
    c = 0.5 * (C[..., 0, 0] + C[..., 1, 1] + C[..., 2, 2] - 1.0)
    angle = np.arctan2(s, c)
    small = s < 1e-6
    scale = np.where(small, 1.0 + s * s / 6.0, angle / np.where(small, 1.0, s))
    out = scale[..., None] * w
    large = c < -0.85
    if np.any(large):
        out[large] = quat_to_rotvec(dcm_to_quat(C[large]))
    return out


def rot_x(angle: np.ndarray) -> np.ndarray:
    """Rotation matrix about x by angle (...) rad, (..., 3, 3)."""
    return rotvec_to_dcm(np.asarray(angle, dtype=float)[..., None] * np.array([1.0, 0.0, 0.0]))


def rot_y(angle: np.ndarray) -> np.ndarray:
    """Rotation matrix about y by angle (...) rad, (..., 3, 3)."""
    return rotvec_to_dcm(np.asarray(angle, dtype=float)[..., None] * np.array([0.0, 1.0, 0.0]))


def rot_z(angle: np.ndarray) -> np.ndarray:
    """Rotation matrix about z by angle (...) rad, (..., 3, 3)."""
    return rotvec_to_dcm(np.asarray(angle, dtype=float)[..., None] * np.array([0.0, 0.0, 1.0]))


def euler_to_quat(euler: np.ndarray) -> np.ndarray:
    """q_b_n (..., 4) from Euler angles [pitch, roll, yaw] (..., 3) rad (PSINS order)."""
    euler = np.asarray(euler, dtype=float)
    half = 0.5 * euler
    sx, sy, sz = np.sin(half[..., 0]), np.sin(half[..., 1]), np.sin(half[..., 2])
    cx, cy, cz = np.cos(half[..., 0]), np.cos(half[..., 1]), np.cos(half[..., 2])
    # q_z(yaw) * q_x(pitch) * q_y(roll), expanded.
    return quat_normalize(np.stack([cz * cx * cy - sz * sx * sy, cz * sx * cy - sz * cx * sy,
                                    cz * cx * sy + sz * sx * cy, sz * cx * cy + cz * sx * sy],
                                   -1))


def euler_to_dcm(euler: np.ndarray) -> np.ndarray:
    """C_b_n (..., 3, 3) = Rz(yaw) Rx(pitch) Ry(roll) from [pitch, roll, yaw] (..., 3) rad."""
    return quat_to_dcm(euler_to_quat(euler))


def dcm_to_euler(C: np.ndarray) -> np.ndarray:
    """[pitch, roll, yaw] (..., 3) rad of C_b_n (..., 3, 3); pitch in [-pi/2, pi/2]."""
    C = np.asarray(C, dtype=float)
    pitch = np.arcsin(np.clip(C[..., 2, 1], -1.0, 1.0))
    roll = np.arctan2(-C[..., 2, 0], C[..., 2, 2])
    yaw = np.arctan2(-C[..., 0, 1], C[..., 1, 1])
    return np.stack([pitch, roll, yaw], -1)


def quat_to_euler(q: np.ndarray) -> np.ndarray:
    """[pitch, roll, yaw] (..., 3) rad of q_b_n (..., 4)."""
    return dcm_to_euler(quat_to_dcm(q))


def quat_angle(q_a: np.ndarray, q_b: np.ndarray) -> np.ndarray:
    """Rotation angle (...) rad between two attitudes; robust for tiny angles."""
    d = quat_mul(quat_conj(q_a), q_b)
    s = np.linalg.norm(d[..., 1:], axis=-1)
    return 2.0 * np.arctan2(s, np.abs(d[..., 0]))


def quat_cumprod(q: np.ndarray, axis: int = 0) -> np.ndarray:
    """Running products q_0, q_0 q_1, q_0 q_1 q_2, ... along an axis of (..., 4).

    A Hillis-Steele scan: log2(n) passes, each product normalised
    (``attitude_kernel.quat_scan``, compiled: 5x the NumPy passes on 120 000 samples, the
    same numbers to the bit).
    """
    from aligngym.models.attitude_kernel import quat_scan   # Numba: loaded when run

    out = np.moveaxis(np.array(q, dtype=float), axis, 0)
    if out.shape[-1] != 4:
        raise ValueError(f"quaternions must be (..., 4), got {np.shape(q)}")
    n = out.shape[0]
    if n < 2 or out.size == 0:
        return np.moveaxis(out, 0, axis)
    flat = np.ascontiguousarray(out.reshape(n, -1, 4))
    quat_scan(flat)
    return np.moveaxis(flat.reshape(out.shape), 0, axis)
