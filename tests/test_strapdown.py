"""Strapdown: analytic single-interval cases, batch = loop, and the SPEC section 3
fidelity requirement on the ship scenario."""
import numpy as np
import pytest

from aligngym.estimators.strapdown import (StrapdownState, Strapdown, body_velocity_increment,
                                  run_strapdown)
from aligngym.models.attitude import rotvec_to_dcm, skew
from aligngym.models.units import arcsec
from aligngym.scenarios.fidelity import fidelity_errors
from aligngym.scenarios.simulate import simulate


def exact_constant_rate(omega, f_b, T):
    """Exact integral over [0, T] of C_b(tau)^b(0) f for a constant body rate."""
    w = np.linalg.norm(omega)
    K = skew(omega / w)
    return (T * np.eye(3) + (1 - np.cos(w * T)) / w * K + (T - np.sin(w * T) / w) * K @ K) @ f_b


@pytest.mark.parametrize("T", [0.01, 0.002])
def test_velocity_increment_constant_rate_constant_body_force(T):
    omega = np.array([0.3, -0.1, 0.2])
    f_b = np.array([1.0, 2.0, 9.8])
    dtheta, dv = omega * T, f_b * T
    got = body_velocity_increment(dtheta, dv, dtheta, dv)
    exact = exact_constant_rate(omega, f_b, T)
    plain = dv + 0.5 * np.cross(dtheta, dv)  # first-order rotation compensation only
    wT = np.linalg.norm(omega) * T
    assert np.linalg.norm(got - exact) < 0.1 * wT ** 3 * np.linalg.norm(dv)
    assert np.linalg.norm(plain - exact) > 0.1 * wT ** 2 * np.linalg.norm(dv)


def test_velocity_increment_rotating_body_in_constant_navigation_force():
    # The gravity case: f constant in n, body rotating at constant rate: dv_b = f_0 T.
    omega = np.array([0.314, 0.0, 0.105])
    f0 = np.array([0.0, 0.0, 9.8])
    T = 0.01
    tau = np.linspace(-T, T, 20001)
    f_b = np.einsum("nij,j->ni", rotvec_to_dcm(-tau[:, None] * omega), f0)
    # Increments by fine quadrature over the previous and current interval.
    dv_prev = np.trapezoid(f_b[:10001], tau[:10001], axis=0)
    dv = np.trapezoid(f_b[10000:], tau[10000:], axis=0)
    dtheta = omega * T
    got = body_velocity_increment(dtheta, dv, dtheta, dv_prev)
    # Residual is third order, (omega T)^3 |dv| ~ 3e-9 m/s; 3 ng at 100 Hz.
    np.testing.assert_allclose(got, f0 * T, atol=1e-9)
    # The classical rotation + two-sample sculling terms alone leave ~(omega T)^2 |dv| / 6.
    classical = (dv + 0.5 * np.cross(dtheta, dv)
                 + (np.cross(dtheta, dv) + np.cross(dv_prev, dtheta)) / 12.0)
    assert np.linalg.norm(classical - f0 * T) > 30 * np.linalg.norm(got - f0 * T)


def test_batch_equals_loop(ship_config):
    config = ship_config.with_options(duration=5.0)
    episodes = [simulate(config, seed=s) for s in (1, 2, 3)]
    states = [StrapdownState.from_arrays(e.truth.q_s_n[0], e.truth.v_n[0], e.truth.lat[0],
                                         e.truth.lon[0], e.truth.h[0]) for e in episodes]
    batch_initial = StrapdownState(*(np.concatenate([getattr(s, f) for s in states])
                                     for f in ("q_b_n", "v_n", "lat", "lon", "h")))
    dtheta = np.stack([e.dtheta for e in episodes])
    dv = np.stack([e.dv for e in episodes])
    batch = run_strapdown(batch_initial, dtheta, dv, config.imu_interval)
    for b, (state, e) in enumerate(zip(states, episodes)):
        one = run_strapdown(state, e.dtheta, e.dv, config.imu_interval)
        for key in one:
            np.testing.assert_array_equal(batch[key][b], one[key][0])
    # Streaming with raw increments equals the precompensated run.
    mech = Strapdown(states[0], config.imu_interval)
    for k in range(e.dtheta.shape[0]):
        s = mech.update(episodes[0].dtheta[None, k], episodes[0].dv[None, k])
    np.testing.assert_allclose(s.q_b_n[0], batch["q_b_n"][0, -1], atol=1e-15)
    np.testing.assert_allclose(s.v_n[0], batch["v_n"][0, -1], atol=1e-12)


def test_fidelity_ship_sway_rotary_600s(ship_config):
    """SPEC section 3: 1 arcsec, 5 mm/s, 1 m over 600 s. We assert 10x better."""
    err = fidelity_errors(ship_config.with_options(duration=600.0), seed=11)
    assert err["attitude_rad"] < 0.1 * arcsec
    assert err["velocity_m_s"] < 0.5e-3
    assert err["position_m"] < 0.1


def test_stationary_navigation_stays_put():
    """Exact stationary increments at 40 N: the navigation solution does not move."""
    from aligngym.models.earth import earth_rate_n, normal_gravity
    lat, T, M = np.deg2rad(40.0), 0.01, 6000
    dtheta = np.tile(earth_rate_n(lat) * T, (M, 1))       # body = ENU
    dv = np.tile([0.0, 0.0, normal_gravity(lat) * T], (M, 1))
    out = run_strapdown(StrapdownState.from_arrays([1.0, 0, 0, 0], np.zeros(3), lat, 0.3, 0.0),
                        dtheta, dv, T)
    assert np.abs(out["v_n"]).max() < 1e-9
    assert np.abs(out["q_b_n"][0, -1] - [1, 0, 0, 0]).max() < 1e-12


def test_body_rate_at_boundaries_is_exact_for_a_linear_rate():
    """Increments of the rate a + b t: the rate at every boundary, the two ends (linear
    extrapolation) included, without the half-interval lag of an interval's mean."""
    from aligngym.estimators.strapdown import body_rate_at
    dt, S = 0.01, 10
    a, b = np.array([0.1, -0.2, 0.3]), np.array([2.0, 1.0, -3.0])
    t = np.arange(S + 1) * dt
    dtheta = a * dt + 0.5 * b * (t[1:, None] ** 2 - t[:-1, None] ** 2)
    k = np.arange(S + 1)
    np.testing.assert_allclose(body_rate_at(dtheta, dt, k), a + b * t[:, None], atol=1e-12)
    batch = np.stack([dtheta, 2 * dtheta])
    np.testing.assert_allclose(body_rate_at(batch, dt, [S])[:, 0],
                               [a + b * t[-1], 2 * (a + b * t[-1])], atol=1e-12)

    with pytest.raises(ValueError, match="boundaries"):
        body_rate_at(dtheta, dt, [S + 1])


def _coning_drift(half_angle, rate, T, duration, compensated=True):
    """Attitude error (3,) rad after ``duration`` s of classical coning (the rotation vector
    half_angle [cos rate t, sin rate t, 0], rad, rad/s), integrated from exact increments
    over intervals of T s, with the two-sample coning term or without it. Truth,
    increments (10-point Gauss-Legendre quadrature of the body rate) and composition are
    SciPy's rotations, independent of the project's attitude code."""
    from scipy.spatial.transform import Rotation

    from aligngym.estimators.strapdown import coning_rotation_vector

    def truth(t):
        t = np.asarray(t, float)
        return Rotation.from_rotvec(half_angle * np.stack(
            [np.cos(rate * t), np.sin(rate * t), np.zeros_like(t)], -1))
    n = int(round(duration / T))
    nodes, weights = np.polynomial.legendre.leggauss(10)
    t = ((np.arange(-1, n)[:, None] + 0.5 + 0.5 * nodes) * T).ravel()
    h = 1e-5                                   # body rate: R^T dR/dt, central difference
    body_rate = (truth(t - h).inv() * truth(t + h)).as_rotvec() / (2 * h)
    dtheta = (body_rate.reshape(n + 1, 10, 3) * (0.5 * T * weights)[None, :, None]).sum(1)
    phi = (coning_rotation_vector(dtheta[1:], dtheta[:-1]) if compensated else dtheta[1:])
    attitude = truth(0.0)
    for step in phi:
        attitude = attitude * Rotation.from_rotvec(step)
    return (truth(n * T).inv() * attitude).as_rotvec()


@pytest.mark.parametrize("T", [0.01, 0.005])
def test_coning_drift_is_the_closed_form_with_and_without_the_coning_term(T):
    """Classical coning at 1 deg, 2 Hz for 10 s: without the coning term the attitude
    drifts about the cone axis at Omega a^2 (Omega T)^2 / 12 (5.0e-5 rad at T = 10 ms);
    with it at Omega a^2 (Omega T)^4 / 60, the two-sample algorithm's residual (Savage's
    Omega a^2 (Omega 2T)^4 / 960 for an update of two T intervals), 300x smaller."""
    a, rate, duration = np.radians(1.0), 2 * np.pi * 2.0, 10.0
    plain = _coning_drift(a, rate, T, duration, compensated=False)
    coned = _coning_drift(a, rate, T, duration)
    first_order = rate * a ** 2 * (rate * T) ** 2 / 12 * duration
    two_sample = rate * a ** 2 * (rate * T) ** 4 / 60 * duration
    assert abs(plain[2]) == pytest.approx(first_order, rel=0.01)
    assert abs(coned[2]) == pytest.approx(two_sample, rel=0.03)
    assert np.hypot(*coned[:2]) < 0.05 * abs(coned[2])       # about the cone axis
