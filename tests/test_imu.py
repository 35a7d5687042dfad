"""IMU: exact ideal increments, the error model's statistics, and the paper presets."""
import math

import allantools
import numpy as np
import pytest

from aligngym.models.truth import NavigationTruth
from aligngym.models.units import deg_per_h, deg_per_sqrt_h, ug
from aligngym.sensors.encoder import GimbalEncoderSpec
from aligngym.sensors.imu import (IMU_PRESETS, FLICKER_FLOOR_FACTOR, ImuSpec, ImuTuning, TriadSpec,
                         apply_imu_errors, ideal_increments)


def polynomial_truth(t):
    """Truth whose rate and specific force are cubic in time (Simpson is exact on cubics)."""
    n = t.size
    omega = np.stack([0.1 + 0.02 * t - 0.003 * t ** 2 + 1e-4 * t ** 3,
                      -0.2 * t ** 2 + 0.01 * t ** 3, np.full(n, 0.3)], -1)
    f = np.stack([1.0 + t ** 3, 2.0 - t, 9.8 + 0.5 * t ** 2], -1)
    zeros = np.zeros(n)
    return NavigationTruth(t=t, lat=zeros, lon=zeros, h=zeros, v_n=np.zeros((n, 3)),
                           q_b_n=np.tile([1.0, 0, 0, 0], (n, 1)),
                           q_s_n=np.tile([1.0, 0, 0, 0], (n, 1)),
                           gimbal_angles=np.zeros((n, 2)), omega_is_s=omega, f_s=f)


def test_ideal_increments_integrate_exactly():
    t = np.linspace(0.0, 2.0, 401)  # IMU at 100 Hz, truth at 200 Hz
    truth = polynomial_truth(t)
    imu_t, dtheta, dv = ideal_increments(t, truth.omega_is_s, truth.f_s)
    assert imu_t.shape == (200,)
    np.testing.assert_array_equal(imu_t, t[2::2])
    a, b = imu_t - 0.01, imu_t
    exact_x = (0.1 * (b - a) + 0.01 * (b ** 2 - a ** 2) - 0.001 * (b ** 3 - a ** 3)
               + 2.5e-5 * (b ** 4 - a ** 4))
    np.testing.assert_allclose(dtheta[:, 0], exact_x, rtol=1e-12, atol=1e-16)
    np.testing.assert_allclose(dv[:, 2], 9.8 * 0.01 + 0.5 / 3 * (b ** 3 - a ** 3), rtol=1e-12)


def test_ideal_increments_reject_arrays_not_of_the_grid():
    truth = polynomial_truth(np.linspace(0.0, 2.0, 401))
    with pytest.raises(ValueError, match="like t"):
        ideal_increments(truth.t[::2], truth.omega_is_s, truth.f_s)


def test_ideal_increments_reject_bad_grid():
    with pytest.raises(ValueError, match="k\\*2\\+1"):
        truth = polynomial_truth(np.linspace(0, 1, 10))
        ideal_increments(truth.t, truth.omega_is_s, truth.f_s)


def error_rates(spec, dt, n, seed):
    """Synthesized error of a still IMU as rate samples (n, 3): gyro rad/s, accel m/s^2."""
    rng = np.random.default_rng(seed)
    zeros = np.zeros((n, 3))
    dtheta, dv = apply_imu_errors(zeros, zeros, dt, spec, spec.draw(rng), rng)
    return dtheta / dt, dv / dt


def adev(y, rate, taus):
    t2, ad, _, _ = allantools.oadev(y, rate=rate, data_type="freq", taus=taus)
    return t2, ad


def test_allan_white_noise_level():
    N = 0.05 * deg_per_sqrt_h
    spec = ImuSpec(gyro=TriadSpec(white_noise_density=N),
                   accel=TriadSpec(white_noise_density=30 * ug))
    gyro, accel = error_rates(spec, 0.01, 360_000, seed=1)
    taus = np.array([0.1, 1.0, 10.0])
    for axis in range(3):
        t2, ad = adev(gyro[:, axis], 100.0, taus)
        np.testing.assert_allclose(ad * np.sqrt(t2), N, rtol=0.1)
        t2, ad = adev(accel[:, axis], 100.0, taus)
        np.testing.assert_allclose(ad * np.sqrt(t2), 30 * ug, rtol=0.1)


def test_allan_bias_instability_floor():
    B = 0.5 * deg_per_h
    spec = ImuSpec(gyro=TriadSpec(bias_instability=B, correlation_time=20.0))
    gyro, _ = error_rates(spec, 0.1, 400_000, seed=2)  # 11 h at 10 Hz
    taus = np.logspace(0, 3, 40)
    for axis in range(3):
        _, ad = adev(gyro[:, axis], 10.0, taus)
        assert ad.max() == pytest.approx(FLICKER_FLOOR_FACTOR * B, rel=0.1)


def test_random_constant_bias_sigma_across_episodes():
    spec = IMU_PRESETS["paper003-rotary"]
    rng = np.random.default_rng(5)
    draws = [spec.draw(rng) for _ in range(4000)]
    gyro = np.array([d.gyro.bias for d in draws])
    accel = np.array([d.accel.bias for d in draws])
    np.testing.assert_allclose(gyro.std(axis=0), 0.01 * deg_per_h, rtol=0.05)
    np.testing.assert_allclose(accel.std(axis=0), 100 * ug, rtol=0.05)
    assert np.all(np.abs(gyro.mean(axis=0)) < 4 * 0.01 * deg_per_h / np.sqrt(4000))


def test_fixed_bias_scale_factor_and_misalignment_are_applied_exactly():
    spec = ImuSpec(gyro=TriadSpec(bias_fixed=(1e-5, -2e-5, 3e-5), scale_factor_sigma=1e-3,
                                  misalignment_sigma=1e-4))
    rng = np.random.default_rng(9)
    real = spec.draw(rng)
    x = rng.standard_normal((50, 3)) * 1e-3
    y, _ = apply_imu_errors(x, x, 0.01, spec, real, rng)
    np.testing.assert_allclose(y, x @ real.gyro.error_matrix.T + real.gyro.bias * 0.01,
                               rtol=1e-15, atol=1e-18)
    np.testing.assert_array_equal(real.gyro.bias, [1e-5, -2e-5, 3e-5])
    assert np.all(np.diag(real.gyro.misalignment) == 0)


def test_quantization_carries_residual_and_saturation_clips():
    lsb = 1e-6
    spec = ImuSpec(gyro=TriadSpec(quantization=lsb, measurement_range=1.0))
    rng = np.random.default_rng(1)
    x = np.full((1000, 3), 0.37e-6)
    x[10] = [0.02, -0.02, 0.0]  # 2 rad/s for one 10 ms sample: beyond the 1 rad/s range
    y, _ = apply_imu_errors(x, x, 0.01, spec, spec.draw(rng), rng)
    assert np.all(np.isclose(y / lsb, np.round(y / lsb)))
    clipped = np.clip(x, -0.01, 0.01)
    # The running sum never drifts more than one LSB from the (clipped) truth.
    assert np.abs(np.cumsum(y, 0) - np.cumsum(clipped, 0)).max() <= lsb * (1 + 1e-9)


def test_paper_presets_contain_exactly_the_stated_terms():
    expected = {  # SPEC section 4: constant (random-constant) bias and white noise only
        "paper000-fog": ({"bias_sigma", "white_noise_density"}, {"bias_sigma",
                                                                 "white_noise_density"}),
        "paper001-van": ({"bias_sigma", "white_noise_density"}, {"bias_sigma"}),
        "paper002-static": ({"bias_sigma", "white_noise_density"}, {"bias_sigma"}),
        "paper003-rotary": ({"bias_sigma", "white_noise_density"}, {"bias_sigma",
                                                                    "white_noise_density"}),
        "paper004-mems": ({"bias_sigma", "white_noise_density"}, {"bias_sigma",
                                                                  "white_noise_density"}),
    }
    assert set(IMU_PRESETS) == set(expected)
    for name, (gyro_terms, accel_terms) in expected.items():
        assert IMU_PRESETS[name].gyro.error_terms() == gyro_terms, name
        assert IMU_PRESETS[name].accel.error_terms() == accel_terms, name
    p3 = IMU_PRESETS["paper003-rotary"]
    assert p3.gyro.bias_sigma == pytest.approx(4.8481e-8, rel=1e-4)          # 0.01 deg/h
    assert p3.gyro.white_noise_density == pytest.approx(4.8481e-9, rel=1e-4)  # 0.001 deg/h/rtHz
    assert IMU_PRESETS["paper001-van"].gyro.white_noise_density == pytest.approx(
        0.1 * math.pi / 180 / 60, rel=1e-12)                                  # 0.1 deg/sqrt(h)


def test_tuning_is_separate_from_spec():
    spec = IMU_PRESETS["paper003-rotary"]
    tuning = ImuTuning.from_spec(spec)
    assert tuning.gyro_bias_sigma == spec.gyro.bias_sigma
    assert tuning.scaled(gyro_bias_sigma=10.0).gyro_bias_sigma == 10 * spec.gyro.bias_sigma
    assert spec.gyro.bias_sigma == IMU_PRESETS["paper003-rotary"].gyro.bias_sigma


@pytest.mark.parametrize("kwargs, field", [({"bias_sigma": -1.0}, "bias_sigma"),
                                           ({"correlation_time": 0.0}, "correlation_time"),
                                           ({"white_noise_density": float("nan")},
                                            "white_noise_density")])
def test_spec_rejects_bad_values(kwargs, field):
    with pytest.raises(ValueError, match=field):
        TriadSpec(**kwargs)


def test_gimbal_encoder_resolution_and_offset():
    spec = GimbalEncoderSpec(resolution=1e-5, offset_sigma=1e-3)
    rng = np.random.default_rng(4)
    offsets = spec.draw_offsets(rng)
    angles = rng.uniform(0, 100, (1000, 2))
    reading = spec.measure(angles, offsets)
    assert np.abs(reading - angles - offsets).max() <= 0.5e-5 * (1 + 1e-6)
    assert np.all(np.isclose(reading / 1e-5, np.round(reading / 1e-5)))
