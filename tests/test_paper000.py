"""Paper 000's pieces: the IMU case's mounting in the physics and the odometer-aided
coarse alignment while driving."""
from dataclasses import replace

import numpy as np
import pytest

from estimators.inertial_frame import odometer_aided_alignment
from estimators.metrics import misalignment
from models.attitude import euler_to_dcm, quat_conj, quat_mul, quat_to_dcm
from models.units import arcmin, deg
from scenarios.config import ConfigError, load_scenario
from scenarios.simulate import simulate


@pytest.fixture(scope="module")
def ring():
    """150 s of the ring road (driving from 5 s), ideal sensors."""
    config = load_scenario("ring-road-odometer").with_options(duration=150.0)
    return simulate(config, seed=2, ideal=True)


def test_imu_case_is_turned_by_the_mounting_angles(ring):
    """The truth's C_s^b is the odometer spec's mounting, and the accelerometers see it:
    at rest the specific force leans forward by the mounting pitch against an unmounted
    IMU on the same car."""
    odo = ring.config.odometer
    mount = euler_to_dcm(np.array([odo.mounting_pitch, 0.0, odo.mounting_heading]))
    q_s_b = quat_mul(quat_conj(ring.truth.q_b_n), ring.truth.q_s_n)
    np.testing.assert_allclose(quat_to_dcm(q_s_b[::1000]), np.broadcast_to(mount, (16, 3, 3)),
                               atol=1e-12)
    flat = replace(ring.config, odometer=replace(odo, mounting_pitch=0.0,
                                                 mounting_heading=0.0))
    level = simulate(flat.with_options(duration=5.0), seed=2, ideal=True)
    still = slice(0, 400)                                  # the first 4 s: parked
    lean = lambda e: np.arctan2(e.dv[still, 1].sum(), e.dv[still, 2].sum())  # noqa: E731
    assert lean(ring) - lean(level) == pytest.approx(odo.mounting_pitch, abs=1e-9)


def test_mounting_angles_out_of_range_are_rejected(tmp_path):
    text = (load_scenario.__globals__["DATA_DIR"] / "ring-road-odometer.toml").read_text()
    path = tmp_path / "bad.toml"
    path.write_text(text + "mounting_heading_deg = 12.0\n")
    with pytest.raises(ConfigError, match=r"odometer.mounting_heading must be within \+-10 "
                                          r"deg, got 12 deg"):
        load_scenario(str(path))


def test_odometer_aided_alignment_while_driving(ring):
    """ALGORITHMS 1.13 over 120 s of the ring, ideal sensors, the true mounting: level to
    arcseconds, heading to the earth-rate information's limit (measured 19'); the IMU's
    lever arm from the rear axle (1.65 m: 0.13 m/s sideways on the ring) must be
    compensated (without: 5.5 deg of heading)."""
    config, dt = ring.config, ring.config.imu_interval
    odo, motion = config.odometer, config.motion
    C_m_b = euler_to_dcm(np.array([odo.mounting_pitch, 0.0, odo.mounting_heading])).T
    lever = C_m_b @ np.subtract(motion.imu_offset_b, motion.car_params().rear_axle_b)
    i0, i1 = int(round(20.0 / dt)), int(round(140.0 / dt))
    C_true = quat_to_dcm(ring.truth.q_s_n[i1])
    errors, residuals = {}, {}
    for name, arm in (("lever", lever), ("none", None)):
        C, residuals[name] = odometer_aided_alignment(
            ring.dtheta[i0:i1], ring.dv[i0:i1], dt, ring.extra["odo_distance"][i0:i1 + 1],
            config.latitude, config.height, C_m_b, arm)
        np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-12)
        errors[name] = np.abs(misalignment(C_true, C))
    assert errors["lever"][:2].max() < 0.5 * arcmin
    assert errors["lever"][2] < 0.5 * deg
    assert errors["none"][2] > 2.0 * deg
    assert residuals["none"] > 5 * residuals["lever"]
