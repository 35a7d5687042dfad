"""Coarse alignment: inertial-frame (i_b0) and analytic static, against physics oracles."""
from dataclasses import replace

import numpy as np
import pytest

from aligngym.estimators.inertial_frame import (attitude_from_inertial, body_frame_integrals,
                                       coarse_alignment_ib0, gravity_velocity_i, gravity_i,
                                       static_coarse_alignment)
from aligngym.estimators.metrics import misalignment
from aligngym.models.attitude import euler_to_dcm, quat_to_dcm
from aligngym.models.earth import OMEGA_IE, earth_rate_n, normal_gravity
from aligngym.models.units import deg
from aligngym.scenarios.simulate import simulate


def ib0_error(config, lever_arm=None, seed=1):
    """Coarse error phi_n (rad) at 120 s of an ideal-sensor episode."""
    ep = simulate(config.with_options(duration=121.0), seed=seed, ideal=True)
    lat, h = ep.truth.lat[0], ep.truth.h[0]
    lever = np.asarray(config.motion.lever_arm_b if lever_arm is None else lever_arm)
    ig = body_frame_integrals(ep.dtheta, ep.dv, ep.gimbal_encoder, lever, config.imu_interval)
    C = coarse_alignment_ib0(ig, lat, h, 50.0, 120.0)
    return misalignment(quat_to_dcm(ep.truth.q_s_n[12000]),
                        attitude_from_inertial(C, ig, 12000, lat))


def still(config, rotate=False):
    m = replace(config.motion, yaw_amplitude=0.0, pitch_amplitude=0.0, roll_amplitude=0.0,
                linear_amplitude=(0.0, 0.0, 0.0))
    if not rotate:
        m = replace(m, gimbal_outer_rate=0.0, gimbal_inner_rate=0.0)
    return replace(config, motion=m)


def test_gravity_velocity_derivative_has_norm_g():
    t = np.array([10.0, 100.0, 1000.0])
    h = 1e-3
    dV = (gravity_velocity_i(t + h, 0.7, 0.0) - gravity_velocity_i(t - h, 0.7, 0.0)) / (2 * h)
    np.testing.assert_allclose(np.linalg.norm(dV, axis=1), normal_gravity(0.7), rtol=1e-9)
    np.testing.assert_allclose(dV, -gravity_i(t, 0.7, 0.0), atol=1e-8)


def test_ib0_noise_free_static_and_rotating_within_1e6_rad(ship_config):
    assert np.abs(ib0_error(still(ship_config))).max() < 1e-6
    assert np.abs(ib0_error(still(ship_config, rotate=True))).max() < 1e-5


def test_ib0_lever_arm_compensation(ship_config):
    """Angular sway about a centre 33 m away: without the lever-arm term the coarse heading
    is off by degrees; with it, by arc seconds."""
    sway = replace(ship_config, motion=replace(ship_config.motion,
                                               linear_amplitude=(0.0, 0.0, 0.0)))
    with_lever = np.abs(ib0_error(sway)).max()
    without = np.abs(ib0_error(sway, lever_arm=(0.0, 0.0, 0.0))).max()
    assert with_lever < 0.01 * deg
    assert without > 1.0 * deg


def test_static_analytic_alignment_exact_and_bias_floor():
    lat = 40 * deg
    C_b_n = euler_to_dcm(np.array([2 * deg, -3 * deg, 75 * deg]))
    f_b = C_b_n.T @ [0.0, 0.0, normal_gravity(lat)]
    w_b = C_b_n.T @ earth_rate_n(lat)
    np.testing.assert_allclose(static_coarse_alignment(f_b, w_b, lat), C_b_n, atol=1e-12)
    bias_n = np.array([0.0, 1e-3, 0.0])  # 1 mg along north
    est = static_coarse_alignment(f_b + C_b_n.T @ bias_n, w_b, lat)
    phi = misalignment(C_b_n, est)
    assert phi[0] == pytest.approx(-1e-3 / normal_gravity(lat), rel=0.01)  # phi_E = -b_N/g
    # East gyro drift gives the classic heading error drift/(Omega cos L).
    drift = 0.01 * OMEGA_IE
    est = static_coarse_alignment(f_b, w_b + C_b_n.T @ [drift, 0.0, 0.0], lat)
    assert abs(misalignment(C_b_n, est)[2]) == pytest.approx(drift / (OMEGA_IE * np.cos(lat)),
                                                             rel=0.01)
