"""WGS-84 earth model against published references and exact conversions."""
import numpy as np
import pytest

from aligngym.models import earth
from aligngym.models.units import arcsec, deg


def test_normal_gravity_references():
    # WGS-84 (NIMA TR8350.2 table 3.4) on the ellipsoid.
    assert earth.normal_gravity(0.0) == pytest.approx(9.7803253359, rel=1e-9)
    assert earth.normal_gravity(np.pi / 2) == pytest.approx(9.8321849378, rel=1e-9)
    # 45 deg: the GRS-80 series of GJB 6304 (independent formula) agrees to 2e-7.
    s2 = 0.5
    series = 9.7803267715 * (1 + 5.2790414e-3 * s2 + 2.32718e-5 * s2 * s2)
    assert earth.normal_gravity(45 * deg) == pytest.approx(series, rel=1e-6)
    assert earth.normal_gravity(45 * deg) == pytest.approx(9.80619777, rel=1e-8)


def test_normal_gravity_free_air_gradient():
    g0 = earth.normal_gravity(40 * deg, 0.0)
    g1 = earth.normal_gravity(40 * deg, 1000.0)
    assert (g1 - g0) / 1000.0 == pytest.approx(-3.086e-6, rel=5e-3)


def test_radii_references():
    R_M, R_N = earth.radii(np.array([0.0, np.pi / 2, 45 * deg]))
    assert R_M[0] == pytest.approx(6335439.327, rel=1e-9)      # a (1 - e^2)
    assert R_N[0] == pytest.approx(6378137.0, rel=1e-12)        # a
    assert R_M[1] == pytest.approx(6399593.626, rel=1e-9)       # a^2 / b
    assert R_N[1] == pytest.approx(6399593.626, rel=1e-9)
    assert R_N[2] == pytest.approx(6388838.290, rel=1e-9)
    assert R_M[2] == pytest.approx(6367381.816, rel=1e-9)


def test_ecef_geodetic_round_trip():
    rng = np.random.default_rng(3)
    lat = rng.uniform(-89.9, 89.9, 1000) * deg
    lon = rng.uniform(-180, 180, 1000) * deg
    h = rng.uniform(-400, 9000, 1000)
    lat2, lon2, h2 = earth.ecef_to_geodetic(earth.geodetic_to_ecef(lat, lon, h))
    np.testing.assert_allclose(lat2, lat, atol=1e-14)
    np.testing.assert_allclose(lon2, lon, atol=1e-14)
    np.testing.assert_allclose(h2, h, atol=1e-8)


def test_tangent_plane_exact_and_tilt():
    plane = earth.TangentPlane(40 * deg, 118 * deg, 0.0)
    r_t = np.array([[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [0.0, 1000.0, 5.0],
                    [123.4, -567.8, 9.0]])
    lat, lon, h = plane.to_geodetic(r_t)
    np.testing.assert_allclose(plane.from_geodetic(lat, lon, h), r_t, atol=1e-8)
    assert lat[0] == pytest.approx(40 * deg, abs=1e-15) and h[0] == pytest.approx(0, abs=1e-8)
    # 1 km north the local level frame is tilted by ~1 km / R_M about east: ~32 arcsec.
    C = plane.C_t_n(lat[2], lon[2])
    tilt = np.arccos(np.clip(C[2, 2], -1, 1))
    R_M, _ = earth.radii(40 * deg)
    assert tilt / arcsec == pytest.approx(1000.0 / R_M / arcsec, rel=2e-3)
    # A point 1 km away along the plane lies ~8 cm above the plane (h > 0 ... curvature).
    assert h[1] == pytest.approx(1000.0 ** 2 / (2 * earth.radii(40 * deg)[1]), rel=1e-2)


def test_earth_and_transport_rate():
    w = earth.earth_rate_n(np.array([0.0, 40 * deg]))
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), earth.OMEGA_IE)
    v = np.array([10.0, 20.0, 0.0])
    lat = 40 * deg
    R_M, R_N = earth.radii(lat)
    np.testing.assert_allclose(earth.transport_rate_n(lat, 0.0, v),
                               [-20 / R_M, 10 / R_N, 10 * np.tan(lat) / R_N])
