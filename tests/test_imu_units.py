"""IMU error model, piece by piece, against references independent of sensors/imu.py.

References: the paper presets as SPEC section 4 writes them, converted by hand
(deg/h = pi/648000 rad/s, deg/sqrt(h) = pi/10800 rad/sqrt(s), ug = 9.80665e-6 m/s^2,
m/s/sqrt(h) = 1/60 m/s/sqrt(s)); the Allan variance of a first-order Gauss-Markov
process from its autocorrelation by quadrature; chi-square bounds on seeded samples
(99.9 % two-sided each); exact integrals of polynomials; hand-built error matrices.
"""
import dataclasses
import math

import numpy as np
import pytest
from scipy import integrate, optimize, stats

from aligngym.sensors.imu import (FLICKER_FLOOR_FACTOR, IMU_PRESETS, ImuRealization, ImuSpec,
                                  ImuTuning, TriadRealization, TriadSpec, apply_imu_errors,
                                  gauss_markov_sigma, gm_adev_peak, ideal_increments)

DEG_H = math.pi / 648000.0          # 1 deg/h in rad/s (pi/180/3600)
DEG_SQRT_H = math.pi / 10800.0      # 1 deg/sqrt(h) in rad/sqrt(s) (pi/180/60)
UG = 9.80665e-6                     # 1 ug in m/s^2 (standard gravity 9.80665)
MG = 9.80665e-3                     # 1 mg in m/s^2
M_S_SQRT_H = 1.0 / 60.0             # 1 m/s/sqrt(h) in m/s/sqrt(s)


def zero_triad():
    return TriadRealization(bias=np.zeros(3), scale_factor=np.zeros(3),
                            misalignment=np.zeros((3, 3)))


def zero_imu():
    return ImuRealization(gyro=zero_triad(), accel=zero_triad())


def chi2_bounds(n, confidence=0.999):
    """Two-sided bounds on sum(z^2) for n standard normal z."""
    a = (1.0 - confidence) / 2.0
    return stats.chi2.ppf(a, n), stats.chi2.ppf(1.0 - a, n)


def assert_variance(samples, variance, confidence=0.999):
    """Zero-mean samples have the given variance (chi-square test, stated confidence)."""
    samples = np.ravel(samples)
    lo, hi = chi2_bounds(samples.size, confidence)
    s = np.sum(samples ** 2) / variance
    assert lo <= s <= hi, (s / samples.size, lo / samples.size, hi / samples.size)


# --- presets: SPEC section 4, unit conversions by hand ------------------------------------

PRESET_SI = {  # (gyro bias rad/s, gyro density rad/sqrt(s), accel bias m/s^2, accel density)
    # 000: 0.02 deg/h, random 0.01 deg/h (1-s average, i.e. deg/h/sqrt(Hz)); 1e-4 g, 1e-5 g
    # with g = 9.8 as the paper states.
    "paper000-fog": (0.02 * DEG_H, 0.01 * DEG_H, 9.8e-4, 9.8e-5),
    # 001: 1 deg/h, ARW 0.1 deg/sqrt(h) = 2.9089e-5 rad/sqrt(s); accel 1e-5 m/s^2, no noise.
    "paper001-van": (1.0 * DEG_H, 0.1 * DEG_SQRT_H, 1e-5, 0.0),
    # 002: 0.01 deg/h, random 0.01 deg/h; accel 50 ug, no noise.
    "paper002-static": (0.01 * DEG_H, 0.01 * DEG_H, 50 * UG, 0.0),
    # 003: 0.01 deg/h, random 0.001 deg/h; accel 100 ug, random 10 ug/sqrt(Hz).
    "paper003-rotary": (0.01 * DEG_H, 0.001 * DEG_H, 100 * UG, 10 * UG),
    # 004 (assumed in SPEC): 2 deg/h, ARW 0.1 deg/sqrt(h); 2 mg, VRW 0.03 m/s/sqrt(h).
    "paper004-mems": (2.0 * DEG_H, 0.1 * DEG_SQRT_H, 2 * MG, 0.03 * M_S_SQRT_H),
}


@pytest.mark.parametrize("name", sorted(PRESET_SI))
def test_paper_preset_values_in_si(name):
    """Every field of each preset equals SPEC 4's numbers converted by hand to SI; the rest
    stay at the no-error defaults (correlation time 100 s, README; infinite range)."""
    gb, gn, ab, an = PRESET_SI[name]
    off = dict(bias_fixed=None, bias_instability=0.0, correlation_time=100.0,
               random_walk=0.0, scale_factor_sigma=0.0, misalignment_sigma=0.0,
               quantization=0.0, measurement_range=math.inf)
    spec = IMU_PRESETS[name]
    for triad, (bias, density) in ((spec.gyro, (gb, gn)), (spec.accel, (ab, an))):
        got = dataclasses.asdict(triad)
        assert got.pop("bias_sigma") == pytest.approx(bias, rel=1e-12, abs=0.0)
        assert got.pop("white_noise_density") == pytest.approx(density, rel=1e-12, abs=0.0)
        assert got == off


def test_unit_conversions_by_hand():
    """Spot values typed from the conversions: 1 deg/h = 4.8481368e-6 rad/s,
    0.1 deg/sqrt(h) = 2.9088821e-5 rad/sqrt(s), 2 mg = 0.0196133 m/s^2."""
    p = IMU_PRESETS
    assert p["paper001-van"].gyro.bias_sigma == pytest.approx(4.8481368e-6, rel=1e-7)
    assert p["paper004-mems"].gyro.white_noise_density == pytest.approx(2.9088821e-5, rel=1e-7)
    assert p["paper004-mems"].accel.bias_sigma == pytest.approx(0.0196133, rel=1e-9)
    assert p["paper004-mems"].accel.white_noise_density == pytest.approx(5e-4, rel=1e-12)


def test_default_correlation_time_is_100_s():
    """README: Gauss-Markov correlation time defaults to 100 s."""
    assert TriadSpec().correlation_time == 100.0


@pytest.mark.parametrize("obj, attr", [
    (TriadSpec(), "bias_sigma"), (ImuSpec(), "gyro"), (zero_triad(), "bias"),
    (ImuTuning(1.0, 1.0, 1.0, 1.0), "gyro_bias_sigma")])
def test_specs_realizations_and_tunings_are_immutable(obj, attr):
    """A shared preset cannot be edited in place by one scenario (frozen dataclasses)."""
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(obj, attr, 0.0)


# --- Gauss-Markov / flicker closed forms ---------------------------------------------------

def gm_avar_by_quadrature(x):
    """Allan variance of a unit-variance GM process (autocorrelation e^-|u|, T_c = 1) at
    tau = x: (4 V(tau) - V(2 tau)) / (2 tau^2), V(tau) = 2 int_0^tau (tau - u) R(u) du the
    variance of the integral over tau."""
    def v(tau):
        return 2.0 * integrate.quad(lambda u: (tau - u) * math.exp(-u), 0.0, tau,
                                    epsabs=0, epsrel=1e-13)[0]
    return (4.0 * v(x) - v(2.0 * x)) / (2.0 * x * x)


def test_gm_adev_peak_against_quadrature_and_literature():
    """Peak Allan deviation of a unit GM process: ~0.618 at tau ~ 1.89 T_c (literature;
    0.61736 here), and to 1e-8 the maximum of the Allan variance built from the
    autocorrelation."""
    res = optimize.minimize_scalar(lambda x: -gm_avar_by_quadrature(x), bounds=(1.0, 3.0),
                                   method="bounded", options={"xatol": 1e-9})
    assert res.x == pytest.approx(1.89, abs=0.01)
    peak = math.sqrt(-res.fun)
    assert peak == pytest.approx(0.618, abs=1e-3)
    assert gm_adev_peak() == pytest.approx(peak, rel=1e-8)


def test_flicker_floor_factor():
    """IEEE Std 952: flicker (bias instability) Allan floor = sqrt(2 ln 2 / pi) B = 0.6643 B."""
    assert FLICKER_FLOOR_FACTOR == pytest.approx(0.664282, abs=1e-6)
    # The GM sigma whose Allan peak equals that floor: 0.664282 / 0.617364 B.
    assert gauss_markov_sigma(2.0) == pytest.approx(2.0 * 0.664282 / 0.617364, rel=2e-6)


def test_gauss_markov_bias_is_stationary_from_the_first_sample():
    """GM bias with sigma = 0.6643/0.6174 B: every sample, the first included, has variance
    sigma^2, and lag-k correlation e^(-k dt/T_c); 6000 independent episodes (3 axes x 2000),
    chi-square at 99.9 % per row; correlation within 4.4 standard errors."""
    B, tc, dt = 1e-3, 2.0, 1.0
    sigma = 0.664282 / 0.617364 * B
    spec = ImuSpec(gyro=TriadSpec(bias_instability=B, correlation_time=tc))
    rng = np.random.default_rng(11)
    real = zero_imu()
    zeros = np.zeros((4, 3))
    runs = np.array([apply_imu_errors(zeros, zeros, dt, spec, real, rng)[0] / dt
                     for _ in range(2000)])          # (2000, 4, 3)
    for row in (0, 3):
        assert_variance(runs[:, row, :], sigma ** 2)
    n = runs.shape[0] * 3
    for lag in (1, 3):
        r = np.sum(runs[:, 0, :] * runs[:, lag, :]) / np.sqrt(
            np.sum(runs[:, 0, :] ** 2) * np.sum(runs[:, lag, :] ** 2))
        rho = math.exp(-lag * dt / tc)
        assert abs(r - rho) < 4.4 * (1 - rho ** 2) / math.sqrt(n)


# --- white noise, constant bias, rate random walk -------------------------------------------

def test_white_noise_increment_std_is_density_times_sqrt_dt():
    """ARW N rad/sqrt(s), VRW 30 ug/sqrt(Hz): increments of std N sqrt(dt), zero mean
    (60000 samples each, chi-square 99.9 %; mean within 3.3 sigma/sqrt(n))."""
    n_arw, n_vrw, dt = 0.05 * DEG_SQRT_H, 30 * UG, 0.01
    spec = ImuSpec(gyro=TriadSpec(white_noise_density=n_arw),
                   accel=TriadSpec(white_noise_density=n_vrw))
    rng = np.random.default_rng(3)
    zeros = np.zeros((20000, 3))
    dth, dv = apply_imu_errors(zeros, zeros, dt, spec, zero_imu(), rng)
    for y, density in ((dth, n_arw), (dv, n_vrw)):
        std = density * math.sqrt(dt)
        assert_variance(y, std ** 2)
        assert np.all(np.abs(y.mean(axis=0)) < 3.3 * std / math.sqrt(y.shape[0]))


def test_constant_bias_gives_bias_times_dt_and_rotates_with_bias_rotation():
    """Constant bias b: each increment gets b dt on top of the truth; with bias_rotation C
    (90 deg about z here) the sensor sees C b."""
    b = np.array([1e-5, -2e-5, 3e-5])
    real = ImuRealization(gyro=TriadRealization(b, np.zeros(3), np.zeros((3, 3))),
                          accel=TriadRealization(-b, np.zeros(3), np.zeros((3, 3))))
    x = np.array([[1e-3, 0.0, -2e-3], [0.0, 0.0, 0.0]])
    dth, dv = apply_imu_errors(x, x, 0.02, ImuSpec(), real, np.random.default_rng(0))
    np.testing.assert_allclose(dth, x + [2e-7, -4e-7, 6e-7], rtol=0, atol=1e-20)
    np.testing.assert_allclose(dv, x - [2e-7, -4e-7, 6e-7], rtol=0, atol=1e-20)
    c = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    dth, _ = apply_imu_errors(np.zeros((2, 3)), np.zeros((2, 3)), 0.02, ImuSpec(), real,
                              np.random.default_rng(0), bias_rotation=np.stack([c, c.T]))
    np.testing.assert_allclose(dth, [[4e-7, 2e-7, 6e-7], [-4e-7, -2e-7, 6e-7]], atol=1e-20)


def test_rate_random_walk_variance_grows_linearly():
    """RRW K: the bias b_k = y_k/dt is a sum of k independent N(0, K^2 dt) steps: its steps
    (b_0 and the differences) have variance K^2 dt (chi-square 99.9 %, 30000 steps), and
    across 3 x 400 episodes Var(b_k) = K^2 k dt at k = 50."""
    K, dt = 1e-4, 0.1
    spec = ImuSpec(gyro=TriadSpec(random_walk=K))
    rng = np.random.default_rng(21)
    zeros = np.zeros((10000, 3))
    b = apply_imu_errors(zeros, zeros, dt, spec, zero_imu(), rng)[0] / dt
    assert_variance(np.diff(b, axis=0, prepend=np.zeros((1, 3))), K ** 2 * dt)
    z50 = np.zeros((50, 3))
    b50 = np.array([apply_imu_errors(z50, z50, dt, spec, zero_imu(), rng)[0][-1] / dt
                    for _ in range(400)])
    assert_variance(b50, K ** 2 * 50 * dt)


def test_draw_order_white_noise_then_rate_random_walk():
    """Only switched-on terms draw: white noise first, then the RRW steps, each one
    (M, 3) standard-normal block; y = N sqrt(dt) z1 + dt cumsum(K sqrt(dt) z2)."""
    N, K, dt, m = 2e-4, 3e-5, 0.01, 7
    zeros = np.zeros((m, 3))
    for spec_gyro, use_white in ((TriadSpec(white_noise_density=N, random_walk=K), True),
                                 (TriadSpec(random_walk=K), False)):
        y, _ = apply_imu_errors(zeros, zeros, dt, ImuSpec(gyro=spec_gyro), zero_imu(),
                                np.random.default_rng(8))
        ref = np.random.default_rng(8)
        white = N * math.sqrt(dt) * ref.standard_normal((m, 3)) if use_white else 0.0
        steps = K * math.sqrt(dt) * ref.standard_normal((m, 3))
        np.testing.assert_allclose(y, white + dt * np.cumsum(steps, axis=0), rtol=1e-13,
                                   atol=0)


def test_draw_order_gyro_then_accel():
    """The gyro triad draws first, the accelerometer triad next from the same generator; a
    switched-off gyro term (here all but white noise) draws nothing."""
    N, V, dt, m = 2e-4, 5e-4, 0.01, 5
    spec = ImuSpec(gyro=TriadSpec(white_noise_density=N), accel=TriadSpec(white_noise_density=V))
    zeros = np.zeros((m, 3))
    dth, dv = apply_imu_errors(zeros, zeros, dt, spec, zero_imu(), np.random.default_rng(4))
    ref = np.random.default_rng(4)
    np.testing.assert_allclose(dth, N * math.sqrt(dt) * ref.standard_normal((m, 3)), rtol=1e-14)
    np.testing.assert_allclose(dv, V * math.sqrt(dt) * ref.standard_normal((m, 3)), rtol=1e-14)


# --- scale factor, misalignment, saturation, quantization ----------------------------------

def test_scale_factor_and_misalignment_act_as_i_plus_s_plus_m():
    """Hand-built (I + S + M): an increment along sensor axis j reads column j of it."""
    s = np.array([1e-3, -2e-3, 3e-3])
    m = np.array([[0.0, 1e-4, -2e-4], [3e-4, 0.0, 4e-4], [-5e-4, 6e-4, 0.0]])
    real = ImuRealization(gyro=TriadRealization(np.zeros(3), s, m), accel=zero_triad())
    x = 0.01 * np.eye(3)                   # one increment along each axis
    y, _ = apply_imu_errors(x, x, 0.01, ImuSpec(), real, np.random.default_rng(0))
    expected = 0.01 * np.array([[1.001, 3e-4, -5e-4],      # column 1: (1 + s1, m21, m31)
                                [1e-4, 0.998, 6e-4],       # column 2
                                [-2e-4, 4e-4, 1.003]])     # column 3
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-17)


def test_draw_scale_and_misalignment_sigmas():
    """Per-episode draws: scale factor and off-diagonal misalignment N(0, sigma^2)
    (chi-square 99.9 % over 3000 episodes), misalignment diagonal exactly zero."""
    spec = TriadSpec(scale_factor_sigma=300e-6, misalignment_sigma=50 * math.pi / 648000)
    rng = np.random.default_rng(17)
    draws = [spec.draw(rng) for _ in range(3000)]
    scale = np.array([d.scale_factor for d in draws])
    mis = np.array([d.misalignment for d in draws])
    assert_variance(scale, 300e-6 ** 2)
    off = ~np.eye(3, dtype=bool)
    assert_variance(mis[:, off], (50 * math.pi / 648000) ** 2)
    assert np.all(mis[:, ~off] == 0.0)


def test_saturation_at_measurement_range():
    """Range 1.5 rad/s at dt = 0.4 s: increments beyond +-0.6 rad read +-0.6 rad."""
    spec = ImuSpec(gyro=TriadSpec(measurement_range=1.5))
    x = np.array([[1.0, -1.0, 0.1]])
    y, _ = apply_imu_errors(x, x, 0.4, spec, zero_imu(), np.random.default_rng(0))
    np.testing.assert_allclose(y, [[0.6, -0.6, 0.1]], rtol=1e-15)


def test_quantization_to_lsb_preserves_the_sum():
    """LSB 2^-20 rad: outputs are whole LSBs and the running sum stays within one LSB below
    the true running sum (floor of the accumulated angle)."""
    lsb = 2.0 ** -20
    spec = ImuSpec(gyro=TriadSpec(quantization=lsb))
    x = np.random.default_rng(5).normal(0.3 * lsb, 2 * lsb, (500, 3))
    y, _ = apply_imu_errors(x, x, 0.01, spec, zero_imu(), np.random.default_rng(0))
    assert np.all(y / lsb == np.round(y / lsb))
    lag = np.cumsum(x, 0) - np.cumsum(y, 0)
    assert np.all((lag >= 0.0) & (lag < lsb))


# --- argument validation: one-line errors ---------------------------------------------------

@pytest.mark.parametrize("kwargs, message", [
    ({"correlation_time": -1.0}, "correlation_time must be > 0 s"),
    ({"measurement_range": 0.0}, "measurement_range must be > 0"),
    ({"measurement_range": -0.5}, "measurement_range must be > 0"),
    ({"bias_fixed": (1.0, 2.0)}, "bias_fixed must have 3 components"),
    ({"bias_fixed": (1.0, 2.0, 3.0, 4.0)}, "bias_fixed must have 3 components"),
    ({"quantization": -1e-9}, "quantization must be finite and >= 0"),
    ({"random_walk": math.inf}, "random_walk must be finite and >= 0"),
])
def test_triad_spec_refuses(kwargs, message):
    with pytest.raises(ValueError, match=message):
        TriadSpec(**kwargs)


def test_triad_spec_accepts_short_correlation_times():
    """A 0.5 s correlation time is valid (anything > 0 s)."""
    assert TriadSpec(correlation_time=0.5, bias_fixed=(0.0, 0.0, 0.0)).correlation_time == 0.5


def test_apply_refuses_zero_interval():
    with pytest.raises(ValueError, match="dt must be > 0 s"):
        apply_imu_errors(np.zeros((1, 3)), np.zeros((1, 3)), 0.0, ImuSpec(), zero_imu(),
                         np.random.default_rng(0))


# --- ideal increments: exact integrals of cubics ---------------------------------------------

def cubic(t, t0):
    """Rate/force cubic in tau = t - t0, and its exact integral from a to b."""
    tau = t - t0
    f = np.stack([0.1 + 0.02 * tau - 0.003 * tau ** 2 + 1e-4 * tau ** 3,
                  -0.2 * tau ** 2 + 0.01 * tau ** 3, np.full(t.size, 0.3)], -1)

    def exact(a, b):
        a, b = a - t0, b - t0
        return np.stack([0.1 * (b - a) + 0.01 * (b ** 2 - a ** 2) - 0.001 * (b ** 3 - a ** 3)
                         + 2.5e-5 * (b ** 4 - a ** 4),
                         -0.2 / 3 * (b ** 3 - a ** 3) + 0.0025 * (b ** 4 - a ** 4),
                         0.3 * (b - a)], -1)
    return f, exact


@pytest.mark.parametrize("decimation", [2, 4, 6])
def test_ideal_increments_exact_on_cubics_at_any_even_decimation(decimation):
    """Composite Simpson is exact on cubics: increments over [t_k - T, t_k] of a cubic rate
    equal its integral, for truth starting at t0 = 100 s, 200 Hz truth, any even ratio."""
    t0, h, m = 100.0, 0.005, 30
    t = t0 + h * np.arange(m * decimation + 1)
    f, exact = cubic(t, t0)
    imu_t, dth, dv = ideal_increments(t, f, 2.0 * f, decimation)
    np.testing.assert_array_equal(imu_t, t[decimation::decimation])
    ref = exact(imu_t - decimation * h, imu_t)
    np.testing.assert_allclose(dth, ref, rtol=1e-11, atol=1e-15)
    np.testing.assert_allclose(dv, 2.0 * ref, rtol=1e-11, atol=1e-15)


def test_ideal_increments_simpson_error_on_a_quartic():
    """On f = tau^4 composite Simpson overshoots by (b - a) h^4 f''''/180 = (b - a) h^4 2/15
    per interval (its known error term), not more or less."""
    h, dec = 0.01, 4
    t = h * np.arange(dec + 1)
    f = np.repeat((t ** 4)[:, None], 3, axis=1)
    _, dth, _ = ideal_increments(t, f, f, dec)
    b = dec * h
    assert dth[0, 0] - b ** 5 / 5 == pytest.approx(b * h ** 4 * 2 / 15, rel=1e-6)


def test_ideal_increments_single_interval():
    """Three samples at decimation 2: one increment, Simpson's h/3 (1 + 4 + 1)."""
    t = np.array([0.0, 0.5, 1.0])
    w = np.array([[1.0, 0, 0], [2.0, 0, 0], [4.0, 0, 0]])
    imu_t, dth, _ = ideal_increments(t, w, w)
    assert imu_t.tolist() == [1.0]
    assert dth[0].tolist() == pytest.approx([(1 + 8 + 4) / 6.0, 0, 0], rel=1e-15)


@pytest.mark.parametrize("decimation", [0, 1, 3, -2])
def test_ideal_increments_refuse_odd_or_small_decimation(decimation):
    t = np.linspace(0.0, 1.0, 13)
    with pytest.raises(ValueError, match="decimation must be an even integer >= 2"):
        ideal_increments(t, np.zeros((13, 3)), np.zeros((13, 3)), decimation)


@pytest.mark.parametrize("w_shape, f_shape", [((9, 2), (9, 3)), ((9, 4), (9, 3)),
                                              ((9, 3), (9, 2)), ((9, 3), (9, 4))])
def test_ideal_increments_refuse_wrong_columns(w_shape, f_shape):
    t = np.linspace(0.0, 1.0, 9)
    with pytest.raises(ValueError, match="like t"):
        ideal_increments(t, np.zeros(w_shape), np.zeros(f_shape))


def test_ideal_increments_refuse_a_single_sample():
    with pytest.raises(ValueError, match=r"k\*2\+1 samples, got 1"):
        ideal_increments(np.zeros(1), np.zeros((1, 3)), np.zeros((1, 3)))


@pytest.mark.parametrize("steps", [
    [0.01, 0.02, 0.01, 0.01],                          # a dropped sample
    [1.0, 1.0 + 0.9e-9, 1.0 + 1.8e-9, 1.0 + 0.9e-9],   # step wander 1.8e-9 of the first step
])
def test_ideal_increments_refuse_nonuniform_grid(steps):
    """Uniformity: every step within 1e-9 (relative) of the first step."""
    t = np.concatenate([[0.0], np.cumsum(steps)])
    with pytest.raises(ValueError, match="uniformly spaced"):
        ideal_increments(t, np.zeros((5, 3)), np.zeros((5, 3)))
