"""Strapdown building blocks against independent references: the classical rotation and
sculling terms (Savage 1998), the exact velocity increment of a body turning about a
fixed axis (Rodrigues), interval-mean rates of a quadratic rate (hand integrals), bias
compensation, a stationary INS on WGS-84 (Somigliana gravity and the earth rate typed in
from TR8350.2), call splitting, and the argument checks."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from aligngym.estimators.strapdown import (AidedInsInputs, AidedStrapdown, Strapdown,
                                           StrapdownState, body_rate_at,
                                           body_velocity_increment, compensate,
                                           run_strapdown)

# --------------------------------------------------------------------------------------
# Velocity increment: rotation, sculling and second-order terms
# --------------------------------------------------------------------------------------

# The linear models on the previous and current interval, tau in [-1, 1] (time in units
# of the interval): omega = a + b tau (rad per interval), f = c + d tau (m/s per interval).
# The increments are their integrals over [-1, 0] and [0, 1].
C_F = np.array([0.31, -0.52, 9.79])
D_F = np.array([1.7, 0.9, -1.3])


def _increments(a, b, c, d):
    """(dtheta, dv, dtheta_prev, dv_prev) of the linear models."""
    return a + b / 2, c + d / 2, a - b / 2, c - d / 2


def _parts(a, b, c=C_F, d=D_F):
    """body_velocity_increment split by the parity in the rotation: the part odd in
    (dtheta, dtheta_prev) (first order: rotation and sculling) and the even part less dv
    (second order); exact, since the formula has no terms above second order."""
    dth, dv, dthp, dvp = _increments(a, b, c, d)
    plus = body_velocity_increment(dth, dv, dthp, dvp)
    minus = body_velocity_increment(-dth, dv, -dthp, dvp)
    return (plus - minus) / 2, (plus + minus) / 2 - dv


def _exact_fixed_axis(a, b, c=C_F, d=D_F, nodes=24):
    """Exact integral over tau in [0, 1] of C_b(tau)^b(0) f(tau) for a rate along a fixed
    axis (a, b parallel): C = Rodrigues(theta(tau)), theta = a tau + b tau^2 / 2;
    Gauss-Legendre quadrature of a smooth integrand (converged to rounding)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    tau, w = 0.5 * (x + 1), 0.5 * w
    theta = a * tau[:, None] + b * tau[:, None] ** 2 / 2
    f = c + d * tau[:, None]
    return np.einsum("n,nij,nj->i", w, Rotation.from_rotvec(theta).as_matrix(), f)


def _exact_general(a, b, c=C_F, d=D_F):
    """Exact integral over [0, 1] of C f for any linear rate: Cdot = C [omega x],
    vdot = C f integrated by DOP853 at 1e-13."""
    def rhs(t, y):
        C = y[:9].reshape(3, 3)
        wx, wy, wz = a + b * t
        W = np.array([[0.0, -wz, wy], [wz, 0.0, -wx], [-wy, wx, 0.0]])
        return np.concatenate([(C @ W).ravel(), C @ (c + d * t)])
    y0 = np.concatenate([np.eye(3).ravel(), np.zeros(3)])
    return solve_ivp(rhs, (0.0, 1.0), y0, method="DOP853", rtol=1e-13, atol=1e-15).y[9:, -1]


def _even_part(exact, a, b, c=C_F, d=D_F):
    """Second-order part of an exact integral: its part even in the rotation, less dv."""
    return (exact(a, b, c, d) + exact(-a, -b, c, d)) / 2 - (c + d / 2)


U = np.array([2.0, -1.0, 2.0]) / 3.0           # a fixed rate axis
W = np.array([1.0, 2.0, 0.0]) / np.sqrt(5.0)   # perpendicular to U


@pytest.mark.parametrize("a, b", [
    (3e-3 * U, 0.0 * U),            # constant rate
    (3e-3 * U, 4e-3 * U),           # rate ramp
    (0.0 * U, 5e-3 * U),            # rate reversal (sway at its turning point)
    (2e-3 * U + 1e-3 * W, 3e-3 * W - 2e-3 * U),   # coning and sculling
])
def test_first_order_part_is_classical_rotation_and_sculling(a, b):
    """The part first order in the rotation is the rotation term plus the two-sample
    sculling term with one previous sample, 1/2 dtheta x dv + 1/12 (dtheta_prev x dv +
    dv_prev x dtheta) (Savage 1998, JGCD 21(2); PSINS cnscl with one previous sample)."""
    dth, dv, dthp, dvp = _increments(a, b, C_F, D_F)
    first, _ = _parts(a, b)
    classical = 0.5 * np.cross(dth, dv) + (np.cross(dthp, dv) + np.cross(dvp, dth)) / 12
    np.testing.assert_allclose(first, classical, rtol=0, atol=1e-14 * np.linalg.norm(dv))


@pytest.mark.parametrize("a, b", [
    (1e-2 * U, 0.0 * U),            # constant rate
    (1e-2 * U, 1.6e-2 * U),         # rate ramp
    (0.0 * U, 2e-2 * U),            # rate reversal
    (1e-2 * U, -3e-2 * U),          # rate through zero within the interval
])
def test_second_order_part_is_the_exact_fixed_axis_rotation(a, b):
    """About a fixed axis (the body rate's direction constant, its magnitude linear)
    the rotation vector is the integral of the rate, so the second-order part must be
    the exact one: the part even in the rotation of the Rodrigues integral, here to its
    relative fourth-order residue ~ theta^2 / 12 < 1e-4."""
    _, second = _parts(a, b)
    exact = _even_part(_exact_fixed_axis, a, b)
    np.testing.assert_allclose(second, exact, rtol=0, atol=3e-4 * np.linalg.norm(exact))


def test_velocity_increment_error_is_third_order_about_a_fixed_axis():
    """Whole increment against the exact fixed-axis integral: within the exponential
    series' third-order remainder, theta^3 / 6 e^theta max |f| (theta = max rotation
    in the interval)."""
    a, b = 2e-3 * U, 3e-3 * U
    dth, dv, dthp, dvp = _increments(a, b, C_F, D_F)
    got = body_velocity_increment(dth, dv, dthp, dvp)
    theta = np.linalg.norm(a) + np.linalg.norm(b) / 2
    bound = theta ** 3 / 6 * np.exp(theta) * (np.linalg.norm(C_F) + np.linalg.norm(D_F))
    assert np.linalg.norm(got - _exact_fixed_axis(a, b)) < bound
    plain = dv + 0.5 * np.cross(dth, dv) + (np.cross(dthp, dv) + np.cross(dvp, dth)) / 12
    assert np.linalg.norm(plain - _exact_fixed_axis(a, b)) > 100 * bound


def test_velocity_increment_batched_equals_one_by_one():
    """(B, M, 3) stacks give the per-vector results."""
    rng = np.random.default_rng(7)
    args = [rng.normal(scale=s, size=(2, 4, 3)) for s in (1e-2, 1.0, 1e-2, 1.0)]
    got = body_velocity_increment(*args)
    for i in range(2):
        for j in range(4):
            np.testing.assert_array_equal(
                got[i, j], body_velocity_increment(*(x[i, j] for x in args)))


def test_second_order_part_is_exact_when_the_rate_turns():
    """Module docstring: dv_b to second order in the rotation from the linear rate and
    force models. With the rate direction turning (coning plus sculling), the second
    order part against the exact integral of Cdot = C [omega x] (ODE solution)."""
    a, b = 1e-2 * U, 2e-2 * W
    _, second = _parts(a, b)
    exact = _even_part(_exact_general, a, b)
    np.testing.assert_allclose(second, exact, rtol=0, atol=3e-4 * np.linalg.norm(exact))


def test_compensate_first_interval_uses_the_given_previous_increments():
    """Two-sample coning phi = dtheta + 1/12 dtheta_prev x dtheta (Bortz 1971; Savage
    1998, JGCD 21(1)) and the velocity increment of each interval with its predecessor, the
    first interval's predecessor being the one given or, without it, the first interval
    itself (constant rate and force)."""
    dth = np.array([[[1e-3, 2e-3, -1e-3], [3e-3, -1e-3, 2e-3], [-2e-3, 1e-3, 1e-3]]])
    dv = np.array([[[0.01, -0.02, 0.098], [0.03, 0.01, 0.097], [-0.01, 0.02, 0.099]]])
    dth0, dv0 = np.array([[2e-3, 1e-3, 3e-3]]), np.array([[0.02, 0.03, 0.096]])
    phi, dv_b = compensate(dth, dv, dth0, dv0)
    prev = np.concatenate([dth0[:, None], dth[:, :-1]], 1)
    prev_v = np.concatenate([dv0[:, None], dv[:, :-1]], 1)
    np.testing.assert_allclose(phi, dth + np.cross(prev, dth) / 12, rtol=0, atol=1e-18)
    np.testing.assert_array_equal(dv_b[0], [body_velocity_increment(dth[0, j], dv[0, j],
                                                                    prev[0, j], prev_v[0, j])
                                            for j in range(3)])
    phi_default, dv_default = compensate(dth, dv)
    np.testing.assert_allclose(phi_default[:, 0], dth[:, 0], rtol=0, atol=1e-18)
    np.testing.assert_array_equal(dv_default[0, 0], body_velocity_increment(
        dth[0, 0], dv[0, 0], dth[0, 0], dv[0, 0]))
    np.testing.assert_array_equal(dv_default[:, 1:], dv_b[:, 1:])


# --------------------------------------------------------------------------------------
# Body rate at increment boundaries
# --------------------------------------------------------------------------------------

def _quadratic_rate_increments(S, dt, a, b, c):
    """Increments (S, 3) of the rate a + b t + c t^2 over [k dt, (k+1) dt]."""
    t = np.arange(S + 1)[:, None] * dt
    return a * dt + b * np.diff(t ** 2, axis=0) / 2 + c * np.diff(t ** 3, axis=0) / 3


@pytest.mark.parametrize("S", [2, 3, 10])
def test_body_rate_at_a_quadratic_rate_has_the_hand_integrated_errors(S):
    """Rate a + b t + c t^2 at boundary t_k: the mean of the two adjacent intervals'
    mean rates is omega(t_k) + c dt^2 / 3 inside; the ends' linear extrapolation
    1.5 r[0] - 0.5 r[1] (or r[S-1], r[S-2]) gives omega(t_k) - 2 c dt^2 / 3
    (from the means c dt^2 / 3 and 7 c dt^2 / 3 of s^2 over the two intervals)."""
    dt = 0.01
    a, b = np.array([0.1, -0.2, 0.3]), np.array([2.0, 1.0, -3.0])
    c = np.array([30.0, -20.0, 10.0])
    dtheta = _quadratic_rate_increments(S, dt, a, b, c)
    k = np.arange(S + 1)
    t = k[:, None] * dt
    offset = np.where((k == 0) | (k == S), -2.0, 1.0)[:, None] * c * dt ** 2 / 3
    expected = a + b * t + c * t ** 2 + offset
    np.testing.assert_allclose(body_rate_at(dtheta, dt, k), expected, rtol=0, atol=1e-11)
    np.testing.assert_allclose(body_rate_at(dtheta, dt, 1)[0], expected[1], rtol=0, atol=1e-11)
    batch = np.stack([dtheta, -dtheta])
    np.testing.assert_allclose(body_rate_at(batch, dt, k[::-1]), [expected[::-1],
                               -expected[::-1]], rtol=0, atol=1e-11)


@pytest.mark.parametrize("S, k", [(1, [0]), (1, [1]), (0, [0]), (10, [-1]), (10, [11]),
                                  (10, [3, 11]), (10, [-1, 4])])
def test_body_rate_at_refuses_too_few_increments_or_boundaries_outside(S, k):
    """One line: at least 2 increments, boundaries in [0, S]."""
    dtheta = np.ones((S, 3)) * 1e-3
    with pytest.raises(ValueError, match=r"^boundaries must lie in \[0, %d\] of %d >= 2 "
                                         r"increments, got -?\d+\.\.-?\d+$" % (S, S)):
        body_rate_at(dtheta, 0.01, k)


# --------------------------------------------------------------------------------------
# Mechanization: stationary on WGS-84, call splitting, streaming, bias compensation
# --------------------------------------------------------------------------------------

GAMMA_E = 9.7803253359                # TR8350.2 Table 3.4
K_SOMIGLIANA = 0.00193185265241      # TR8350.2 Table 3.4, Somigliana's k
E2_WGS84 = 0.00669437999013          # TR8350.2 Table 3.3
OMEGA_E = 7.2921151467e-5            # rad/s, TR8350.2 sec. 3.2.4, omega prime


def _somigliana(lat):
    s2 = np.sin(lat) ** 2
    return GAMMA_E * (1 + K_SOMIGLIANA * s2) / np.sqrt(1 - E2_WGS84 * s2)


def test_stationary_ins_in_any_attitude_stays_put():
    """A body at rest on the ellipsoid in two attitudes and latitudes, 10 s at 100 Hz:
    constant increments C_n^b omega_ie^n T, C_n^b [0, 0, gamma] T are exact; with gamma
    from Somigliana's formula and omega_ie^n = Omega [0, cos L, sin L] the velocity
    stays below 1e-9 m/s, the attitude and position unchanged."""
    T, M = 0.01, 1000
    lat = np.radians([40.0, -63.0])
    rot = Rotation.from_euler("zxy", [[30.0, 5.0, -12.0], [-140.0, -20.0, 60.0]], degrees=True)
    q = rot.as_quat(scalar_first=True)                     # q_b_n
    w_n = OMEGA_E * np.stack([0 * lat, np.cos(lat), np.sin(lat)], -1)
    f_n = np.stack([0 * lat, 0 * lat, _somigliana(lat)], -1)
    dtheta = np.repeat(rot.inv().apply(w_n)[:, None] * T, M, 1)
    dv = np.repeat(rot.inv().apply(f_n)[:, None] * T, M, 1)
    start = StrapdownState.from_arrays(q, np.zeros((2, 3)), lat, [0.3, -2.0], [0.0, 0.0])
    out = run_strapdown(start, dtheta, dv, T)
    assert out["v_n"].shape == (2, M + 1, 3) and out["q_b_n"].shape == (2, M + 1, 4)
    assert np.abs(out["v_n"]).max() < 1e-9
    assert np.abs(out["q_b_n"][:, -1] - q).max() < 1e-12
    np.testing.assert_allclose(out["lat"][:, -1], lat, rtol=0, atol=1e-15)
    np.testing.assert_allclose(out["h"][:, -1], 0.0, rtol=0, atol=1e-8)
    one = run_strapdown(StrapdownState.from_arrays(q[1], np.zeros(3), lat[1], -2.0, 0.0),
                        dtheta[1], dv[1], T)                # (M, 3): one episode
    for key in out:
        np.testing.assert_array_equal(one[key][0], out[key][1])


def _moving(B=2, M=40, seed=3):
    """A state moving at ~10 m/s and varying increments (B, M, 3) at 100 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(M)[None, :, None] * 0.01
    dtheta = 0.01 * (rng.normal(scale=0.2, size=(B, 1, 3)) * np.cos(3 * t)
                     + rng.normal(scale=0.1, size=(B, 1, 3)))
    dv = 0.01 * (np.array([0.0, 0.0, 9.8]) + rng.normal(scale=2.0, size=(B, 1, 3))
                 * np.sin(2 * t + rng.normal(size=(B, 1, 3))))
    q = Rotation.from_rotvec(rng.normal(scale=0.5, size=(B, 3))).as_quat(scalar_first=True)
    state = StrapdownState.from_arrays(q, [[10.0, -4.0, 0.5], [-7.0, 9.0, -1.0]][:B],
                                       np.radians([35.0, -20.0][:B]), [1.0, -0.5][:B],
                                       [100.0, 20.0][:B])
    return state, dtheta, dv


def _copy(state):
    return StrapdownState(*(np.array(getattr(state, f)) for f in
                            ("q_b_n", "v_n", "lat", "lon", "h")))


def test_run_in_pieces_equals_one_run():
    """Strapdown.run across calls: the compensation uses the previous call's last
    increments and the mechanization its last state and acceleration, so 13 + 1 + 26
    intervals give the 40-interval run bit for bit; the first call is run_strapdown's."""
    state, dtheta, dv = _moving()
    whole = run_strapdown(_copy(state), dtheta, dv, 0.01)
    mech = Strapdown(_copy(state), 0.01)
    pieces = [mech.run(dtheta[:, i:j], dv[:, i:j]) for i, j in ((0, 13), (13, 14), (14, 40))]
    for key in whole:
        joined = np.concatenate([pieces[0][key]] + [p[key][:, 1:] for p in pieces[1:]], 1)
        np.testing.assert_array_equal(joined, whole[key])
        np.testing.assert_array_equal(getattr(mech.state, key), whole[key][:, -1])


def test_update_one_interval_at_a_time_equals_run_strapdown():
    """Strapdown.update streams raw increments: every field of every state, position
    included, equals run_strapdown's trajectory."""
    state, dtheta, dv = _moving(M=12)
    whole = run_strapdown(_copy(state), dtheta, dv, 0.01)
    assert np.ptp(whole["lat"], 1).min() > 1e-8 and np.ptp(whole["lon"], 1).min() > 1e-8
    mech = Strapdown(_copy(state), 0.01)
    for k in range(dtheta.shape[1]):
        s = mech.update(dtheta[:, k], dv[:, k])
        for key in whole:
            np.testing.assert_allclose(getattr(s, key), whole[key][:, k + 1], rtol=1e-15,
                                       atol=1e-15)


def test_run_compensated_subtracts_bias_times_interval():
    """Increments less bias x dt, by hand: gyro 2e-3 rad/s and accel 0.05 m/s^2 over
    dt = 0.02 s take 4e-5 rad and 1e-3 m/s off; the trajectory is run_strapdown's on the
    compensated increments."""
    state, dtheta, dv = _moving(M=6)
    ins = AidedStrapdown(state.q_b_n, state.v_n, state.lat, state.lon, state.h, 0.02)
    assert ins.gyro_bias.shape == (2, 3) and ins.accel_bias.shape == (2, 3)
    assert not ins.gyro_bias.any() and not ins.accel_bias.any()
    ins.gyro_bias[:] = [[2e-3, -2e-3, 0.0], [0.0, 1e-3, 3e-3]]
    ins.accel_bias[:] = [[0.05, 0.0, -0.05], [0.1, 0.02, 0.0]]
    out, dth_c, dv_c = ins.run_compensated(dtheta, dv)
    by_hand_gyro = np.array([[4e-5, -4e-5, 0.0], [0.0, 2e-5, 6e-5]])
    by_hand_accel = np.array([[1e-3, 0.0, -1e-3], [2e-3, 4e-4, 0.0]])
    np.testing.assert_allclose(dth_c, dtheta - by_hand_gyro[:, None], rtol=0, atol=1e-18)
    np.testing.assert_allclose(dv_c, dv - by_hand_accel[:, None], rtol=0, atol=1e-17)
    reference = run_strapdown(_copy(state), dth_c, dv_c, 0.02)
    for key in reference:
        np.testing.assert_allclose(out[key], reference[key], rtol=1e-15, atol=1e-15)


def test_run_compensated_with_zero_biases_is_run():
    """Three episodes (B != 3, 4): the zero biases broadcast and change nothing."""
    state, dtheta, dv = _moving(B=2, M=5)
    state3 = StrapdownState(*(np.concatenate([getattr(state, f), getattr(state, f)[:1]])
                              for f in ("q_b_n", "v_n", "lat", "lon", "h")))
    dtheta3, dv3 = np.concatenate([dtheta, dtheta[:1]]), np.concatenate([dv, dv[:1]])
    ins = AidedStrapdown(state3.q_b_n, state3.v_n, state3.lat, state3.lon, state3.h, 0.01)
    out, dth_c, dv_c = ins.run_compensated(dtheta3, dv3)
    np.testing.assert_array_equal(dth_c, dtheta3)
    reference = run_strapdown(_copy(state3), dtheta3, dv3, 0.01)
    for key in reference:
        np.testing.assert_array_equal(out[key], reference[key])


def test_aided_ins_inputs_start_their_strapdown():
    """AidedInsInputs(...).strapdown() starts at q_b_n0, v_n0, lat0, lon0, h0 with the
    IMU interval."""
    inputs = AidedInsInputs(t=np.array([0.0, 1.0]), imu_dt=0.005,
                            dtheta=np.zeros((1, 1, 200, 3)), dv=np.zeros((1, 1, 200, 3)),
                            q_b_n0=np.array([[0.5, 0.5, 0.5, 0.5]]),
                            v_n0=np.array([[1.0, 2.0, 3.0]]), lat0=np.array([0.7]),
                            lon0=np.array([2.0]), h0=np.array([12.0]))
    ins = inputs.strapdown()
    assert isinstance(ins, AidedStrapdown) and ins.dt == 0.005
    np.testing.assert_array_equal(ins.state.q_b_n, [[0.5, 0.5, 0.5, 0.5]])
    np.testing.assert_array_equal(ins.state.v_n, [[1.0, 2.0, 3.0]])
    assert (ins.state.lat, ins.state.lon, ins.state.h) == ([0.7], [2.0], [12.0])


@pytest.mark.parametrize("dt", [0.0, -0.01, -1.0, -2.0, float("nan")])
def test_interval_must_be_positive(dt):
    """Strapdown and run_strapdown refuse a non-positive (or NaN) interval, in one line."""
    state, dtheta, dv = _moving(B=1, M=2)
    with pytest.raises(ValueError, match=r"^dt must be > 0 s, got "):
        Strapdown(state, dt)
    with pytest.raises(ValueError, match=r"^dt must be > 0 s, got "):
        run_strapdown(state, dtheta, dv, dt)


def test_the_compiled_compensation_is_the_formulas_to_the_bit():
    """``compensate`` runs a compiled loop (``strapdown_kernel.compensate_increments``):
    on random increments, with and without the increments before the first, the same
    numbers as ``coning_rotation_vector`` and ``body_velocity_increment`` of each
    interval and the one before it (checked above against closed forms)."""
    from aligngym.estimators.strapdown import (body_velocity_increment, compensate,
                                               coning_rotation_vector)
    rng = np.random.default_rng(4)
    for trial in range(40):
        B, M = rng.integers(1, 4), rng.integers(1, 40)
        dtheta = rng.normal(size=(B, M, 3)) * rng.choice([1e-6, 1e-3, 0.1])
        dv = rng.normal(size=(B, M, 3)) * rng.choice([1e-4, 0.1, 1.0])
        given = trial % 2 == 0
        first = rng.normal(size=(B, 3)) * 1e-3 if given else None
        first_dv = rng.normal(size=(B, 3)) * 1e-2 if given else None
        prev = np.concatenate([dtheta[:, :1] if first is None else first[:, None],
                               dtheta[:, :-1]], 1)
        prev_dv = np.concatenate([dv[:, :1] if first_dv is None else first_dv[:, None],
                                  dv[:, :-1]], 1)
        phi, dv_b = compensate(dtheta, dv, first, first_dv)
        np.testing.assert_array_equal(phi, coning_rotation_vector(dtheta, prev))
        np.testing.assert_array_equal(dv_b, body_velocity_increment(dtheta, dv, prev, prev_dv))


def test_the_compensation_refuses_mismatched_increments_and_takes_none():
    """Increments of different shapes, or a first-previous increment of another batch,
    are refused in one line (the compiled loop reads no bounds); no increments give none."""
    from aligngym.estimators.strapdown import compensate
    with pytest.raises(ValueError, match=r"dtheta and dv must both be \(B, M, 3\), got "
                                         r"\(4, 50, 3\) and \(4, 10, 3\)"):
        compensate(np.zeros((4, 50, 3)), np.zeros((4, 10, 3)))
    with pytest.raises(ValueError, match=r"before the first must be \(B, 3\) = \(2, 3\), "
                                         r"got \(1, 3\)"):
        compensate(np.zeros((2, 5, 3)), np.zeros((2, 5, 3)), np.zeros((1, 3)), np.zeros((1, 3)))
    phi, dv_b = compensate(np.zeros((2, 0, 3)), np.zeros((2, 0, 3)))
    assert phi.shape == dv_b.shape == (2, 0, 3)
