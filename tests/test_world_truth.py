"""MuJoCo ship world and navigation truth: sensors agree with the prescribed motion, and
the truth is self-consistent with the earth model."""

import numpy as np
import pytest

from aligngym.models.attitude import (quat_conj, quat_mul, quat_rotate, quat_to_dcm, quat_to_euler,
                             rot_x, rot_z)
from aligngym.models.earth import earth_rate_n, normal_gravity, radii
from aligngym.models.ship import ShipSwayMotion, ShipWorld
from aligngym.models.truth import navigation_truth
from aligngym.models.units import deg

MOTION = ShipSwayMotion(linear_phase=(0.3, 1.7, 4.0))


@pytest.fixture(scope="module")
def samples():
    t = np.linspace(0.0, 20.0, 2001)
    return ShipWorld(MOTION).sample(t)


def test_hull_attitude_and_lever_arm(samples):
    euler = quat_to_euler(samples.q_b_t)
    expected, _, _ = MOTION.euler(samples.t)
    np.testing.assert_allclose(euler, expected, atol=1e-12)
    centre, _, _ = MOTION.sway_centre(samples.t)
    lever_t = quat_rotate(samples.q_b_t, np.array(MOTION.lever_arm_b))
    np.testing.assert_allclose(samples.r_t, centre + lever_t, atol=1e-10)


def test_gimbal_gives_C_s_b_equal_Rz_outer_Rx_inner(samples):
    C_s_b = quat_to_dcm(quat_mul(quat_conj(samples.q_b_t), samples.q_s_t))
    outer, inner = samples.gimbal_angles.T
    np.testing.assert_allclose(C_s_b, rot_z(outer) @ rot_x(inner), atol=1e-12)
    np.testing.assert_allclose(outer, 6 * deg * samples.t)
    np.testing.assert_allclose(inner, 18 * deg * samples.t)


def test_mujoco_gyro_equals_analytic_rate(samples):
    omega_tb_b, _ = MOTION.hull_angular_rate(samples.t)
    C_s_b = quat_to_dcm(quat_mul(quat_conj(samples.q_b_t), samples.q_s_t))
    inner = samples.gimbal_angles[:, 1]
    omega_bs_s = (np.swapaxes(rot_x(inner), -1, -2) @ [0.0, 0.0, MOTION.gimbal_outer_rate]
                  + [MOTION.gimbal_inner_rate, 0.0, 0.0])
    expected = np.einsum("nji,nj->ni", C_s_b, omega_tb_b) + omega_bs_s
    np.testing.assert_allclose(samples.omega_ts_s, expected, atol=1e-12)


def test_hull_rate_is_derivative_of_attitude():
    # Independent of the closed form: finite difference of the attitude.
    t = np.array([3.3, 11.0]); h = 1e-5
    q = [MOTION.euler(t + k * h)[0] for k in (-1, 1)]
    from aligngym.models.attitude import euler_to_quat, quat_to_rotvec
    dq = quat_mul(quat_conj(euler_to_quat(q[0])), euler_to_quat(q[1]))
    omega, omega_dot = MOTION.hull_angular_rate(t)
    np.testing.assert_allclose(quat_to_rotvec(dq) / (2 * h), omega, atol=1e-9)
    w = [MOTION.hull_angular_rate(t + k * h)[0] for k in (-1, 1)]
    np.testing.assert_allclose((w[1] - w[0]) / (2 * h), omega_dot, atol=1e-8)


def deriv(x, h):
    """Fourth-order central difference at samples 2..N-3."""
    return (x[:-4] - 8 * x[1:-3] + 8 * x[3:-1] - x[4:]) / (12 * h)


def test_velocity_and_acceleration_are_derivatives(samples):
    h = samples.t[1] - samples.t[0]
    np.testing.assert_allclose(deriv(samples.r_t, h), samples.v_t[2:-2], atol=1e-7)
    np.testing.assert_allclose(deriv(samples.v_t, h), samples.a_t[2:-2], atol=1e-6)


def test_static_truth_senses_earth_rate_and_gravity(plane):
    still = ShipSwayMotion(yaw_mean=20 * deg, yaw_amplitude=0.0, pitch_amplitude=0.0,
                           roll_amplitude=0.0, linear_amplitude=(0.0, 0.0, 0.0),
                           gimbal_outer_rate=0.0, gimbal_inner_rate=0.0)
    world = ShipWorld(still)
    truth = navigation_truth(world.sample(np.array([0.0, 1.0])), plane)
    q_n_s = quat_conj(truth.q_s_n)
    np.testing.assert_allclose(truth.v_n, 0.0, atol=1e-15)
    np.testing.assert_allclose(truth.omega_is_s, quat_rotate(q_n_s, earth_rate_n(truth.lat)),
                               atol=1e-18)
    up = np.stack([np.zeros(2), np.zeros(2), normal_gravity(truth.lat, truth.h)], -1)
    np.testing.assert_allclose(truth.f_s, quat_rotate(q_n_s, up), atol=1e-13)
    assert truth.h[0] == pytest.approx(10.0, abs=1e-4)  # the IMU is 10 m above the origin


def test_truth_position_rate_matches_velocity(samples, plane):
    truth = navigation_truth(samples, plane)
    h = samples.t[1] - samples.t[0]
    R_M, R_N = radii(truth.lat)
    k = slice(2, -2)
    v_north = deriv(truth.lat, h) * (R_M[k] + truth.h[k])
    v_east = deriv(truth.lon, h) * (R_N[k] + truth.h[k]) * np.cos(truth.lat[k])
    v_up = deriv(truth.h, h)
    np.testing.assert_allclose(np.stack([v_east, v_north, v_up], -1), truth.v_n[k], atol=1e-6)


@pytest.mark.parametrize("scenario, start", [("ship-sway-rotary", 0.0),
                                             ("usv-mems-swing", 299.5)])
def test_kinematic_rollout_equals_mujocos_sensor_path_at_every_state(scenario, start):
    """The batched sensor pass (one forward step of the kinematic twin per state) reads
    what MuJoCo's own sensor path (mj_inverse on the real model, the prescribed qacc
    given) reads: every sensor, with the hull accelerating, and the boat's indexer
    starting its slew at 300 s (gimbal acceleration)."""
    import mujoco
    from aligngym.scenarios.config import load_scenario
    world = ShipWorld(load_scenario(scenario).motion)
    t = np.linspace(start, start + 37.0, 301)
    samples = world.sample(t)
    qpos, qvel, qacc = world.joint_state(t)
    m, d = world.model, world.data
    reference = np.empty((t.size, m.nsensordata))
    for k in range(t.size):
        d.qpos[:], d.qvel[:], d.qacc[:] = qpos[k], qvel[k], qacc[k]
        mujoco.mj_inverse(m, d)
        reference[k] = d.sensordata

    def read(name):
        adr, dim = world._adr[name]
        return reference[:, adr:adr + dim]

    np.testing.assert_allclose(samples.omega_ts_s, read("imu_gyro"), atol=1e-14)
    np.testing.assert_allclose(samples.r_t, read("imu_pos"), atol=1e-12)
    np.testing.assert_allclose(samples.v_t, read("imu_linvel"), atol=1e-13)
    np.testing.assert_allclose(samples.q_s_t, read("imu_quat"), atol=1e-15)
    a_t = quat_rotate(read("imu_quat"), read("imu_accel")) + m.opt.gravity
    np.testing.assert_allclose(samples.a_t, a_t, atol=1e-12)     # m/s^2
    assert np.abs(a_t).max() > 0.3                                # it does accelerate
    assert np.abs(qacc[:, 6:8]).max() > 1.0 or start == 0.0        # the indexer too
