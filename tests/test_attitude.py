"""Attitude math: round trips, agreement with scipy's Rotation, batched equals looped."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from aligngym.models import attitude as att


@pytest.fixture
def rng():
    return np.random.default_rng(7)


def random_quats(rng, n):
    return att.quat_normalize(rng.standard_normal((n, 4)))


def test_quat_dcm_round_trip_and_scipy(rng):
    q = random_quats(rng, 500)
    C = att.quat_to_dcm(q)
    np.testing.assert_allclose(att.dcm_to_quat(C), q, atol=1e-12)
    scipy_C = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()
    np.testing.assert_allclose(C, scipy_C, atol=1e-12)


def test_dcm_to_quat_near_180_deg():
    for axis in np.eye(3):
        C = att.rotvec_to_dcm((np.pi - 1e-9) * axis)
        np.testing.assert_allclose(att.quat_to_dcm(att.dcm_to_quat(C)), C, atol=1e-12)


def test_rotvec_round_trip_small_and_large(rng):
    axes = rng.standard_normal((300, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([10.0 ** rng.uniform(-14, -3, 150), rng.uniform(1e-3, 3.1, 150)])
    phi = axes * angles[:, None]
    np.testing.assert_allclose(att.quat_to_rotvec(att.rotvec_to_quat(phi)), phi,
                               rtol=1e-12, atol=1e-15)
    scipy_q = Rotation.from_rotvec(phi).as_quat()[:, [3, 0, 1, 2]]
    np.testing.assert_allclose(att.rotvec_to_quat(phi), scipy_q, atol=1e-15)


def test_euler_convention_is_psins_zxy(rng):
    euler = np.column_stack([rng.uniform(-1.5, 1.5, 200), rng.uniform(-3, 3, 200),
                             rng.uniform(-3, 3, 200)])
    C = att.euler_to_dcm(euler)
    expected = Rotation.from_euler("ZXY", euler[:, [2, 0, 1]]).as_matrix()
    np.testing.assert_allclose(C, expected, atol=1e-12)
    np.testing.assert_allclose(att.dcm_to_euler(C), euler, atol=1e-12)
    np.testing.assert_allclose(att.quat_to_euler(att.euler_to_quat(euler)), euler, atol=1e-12)


def test_yaw_positive_counter_clockwise():
    # Yaw +90 deg: body forward (y) points west (-E).
    C = att.euler_to_dcm(np.array([0.0, 0.0, np.pi / 2]))
    np.testing.assert_allclose(C @ [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], atol=1e-15)


def test_quat_mul_matches_dcm_product_and_rotate(rng):
    p, q = random_quats(rng, 100), random_quats(rng, 100)
    np.testing.assert_allclose(att.quat_to_dcm(att.quat_mul(p, q)),
                               att.quat_to_dcm(p) @ att.quat_to_dcm(q), atol=1e-12)
    v = rng.standard_normal((100, 3))
    np.testing.assert_allclose(att.quat_rotate(p, v),
                               np.einsum("nij,nj->ni", att.quat_to_dcm(p), v), atol=1e-12)
    np.testing.assert_allclose(att.cross(v, v[::-1]), np.cross(v, v[::-1]), atol=1e-15)
    np.testing.assert_allclose(att.skew(v[0]) @ v[1], np.cross(v[0], v[1]), atol=1e-15)


def test_batched_equals_looped(rng):
    q = random_quats(rng, 24).reshape(2, 3, 4, 4)
    phi = rng.standard_normal((2, 3, 4, 3))
    batched = [att.quat_to_dcm(q), att.quat_to_euler(q), att.rotvec_to_quat(phi),
               att.quat_to_rotvec(q)]
    for idx in np.ndindex(2, 3, 4):
        looped = [att.quat_to_dcm(q[idx]), att.quat_to_euler(q[idx]),
                  att.rotvec_to_quat(phi[idx]), att.quat_to_rotvec(q[idx])]
        for b, one in zip(batched, looped):
            np.testing.assert_array_equal(b[idx], one)


def test_quat_angle_small():
    q = att.rotvec_to_quat(np.array([1e-9, 0.0, 0.0]))
    assert att.quat_angle(np.array([1.0, 0, 0, 0]), q) == pytest.approx(1e-9, rel=1e-9)


def _numpy_scan(q: np.ndarray, axis: int = 0) -> np.ndarray:
    """The running products as NumPy passes: the scan quat_cumprod compiles."""
    out = np.moveaxis(np.array(q, dtype=float), axis, 0)
    step = 1
    while step < out.shape[0]:
        out[step:] = att.quat_mul(out[:-step], out[step:])
        out[step:] /= np.sqrt(np.sum(out[step:] ** 2, axis=-1, keepdims=True))
        step *= 2
    return np.moveaxis(out, 0, axis)


@pytest.mark.parametrize("shape, axis", [((1, 3), 0), ((2, 3), 0), ((37, 3), 0),
                                         ((5000, 3), 0), ((3, 257, 3), 1), ((6, 2, 3), 0)])
def test_quat_cumprod_is_the_numpy_scan_to_the_bit_and_the_closed_form(rng, shape, axis):
    """The compiled scan equals the NumPy passes bit for bit (any length, batch axis
    before or after), and n equal steps compose to one rotation of n times the angle
    (one axis: the closed form)."""
    q = att.rotvec_to_quat(rng.normal(scale=0.02, size=shape))
    np.testing.assert_array_equal(att.quat_cumprod(q, axis=axis), _numpy_scan(q, axis))
    step = np.array([0.003, -0.001, 0.002])
    n = shape[axis]
    runs = att.quat_cumprod(np.broadcast_to(att.rotvec_to_quat(step), (n, 4)))
    expected = att.rotvec_to_quat(np.arange(1, n + 1)[:, None] * step)
    assert np.max(np.abs(runs - expected)) < 1e-12 * max(n, 10)


def test_quat_cumprod_of_a_zero_norm_is_numpy_s_and_wrong_shapes_are_refused():
    """A zero (or underflowing) norm gives what the NumPy passes give (inf, NaN), not an
    error; an array whose last axis is not 4 is refused."""
    q = np.zeros((3, 4))
    q[:, 0] = [1.0, 1e-200, 1.0]
    with np.errstate(all="ignore"):
        np.testing.assert_array_equal(att.quat_cumprod(q), _numpy_scan(q))
    assert not np.isfinite(att.quat_cumprod(q)[1:]).any()
    with pytest.raises(ValueError, match=r"\(\.\.\., 4\)"):
        att.quat_cumprod(np.ones((5, 8)))
