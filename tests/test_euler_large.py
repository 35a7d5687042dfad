"""Seed 002's Euler-angle large-misalignment model and its static-base INS
(estimators/euler_large.py, euler_kinematics.py, euler_integrals.py; ALGORITHMS 3.1)."""
import numpy as np
import pytest

from aligngym.estimators.alignment import run_alignment
from aligngym.estimators.euler_integrals import (stack_ins_inputs, stack_integrals,
                                                 static_base_ins, static_base_integrals)
from aligngym.estimators.euler_kinematics import (C_omega, C_omega_inv, C_p_n,
                                                  continuous_dynamics, continuous_jacobian,
                                                  midpoint_jacobian, midpoint_step,
                                                  rk4_jacobian, rk4_step, small_angle_dynamics,
                                                  state_vector, true_state)
from aligngym.estimators.euler_large import (EulerLargeMisalignmentModel, Paper002Tuning,
                                             SmallAngleModel)
from aligngym.estimators.catalogue import make_filter
from aligngym.models.attitude import dcm_to_euler, euler_to_dcm, rotvec_to_dcm
from aligngym.models.earth import OMEGA_IE, normal_gravity
from aligngym.models.units import arcmin, deg, deg_per_h, ug

LAT, H, DT = 40 * deg, 0.0, 0.01
C_BN = euler_to_dcm(np.array([0.3 * deg, -0.2 * deg, 30 * deg]))  # [pitch, roll, yaw]
OMEGA = np.array([0.0, OMEGA_IE * np.cos(LAT), OMEGA_IE * np.sin(LAT)])
G = float(normal_gravity(LAT, H))
EPS = np.array([0.01, -0.008, 0.012]) * deg_per_h
NABLA = np.array([50 * ug, -40 * ug, 0.0])
ALPHA0 = np.array([0.5, -0.7, 58.5]) * deg


def static_increments(seconds, eps=EPS, nabla=NABLA, gyro_noise=0.0, rng=None):
    """Ideal increments of an IMU at rest with attitude C_BN plus constant biases and
    optional gyro white noise (rad/s/sqrt(Hz))."""
    M = int(round(seconds / DT))
    w_b = C_BN.T @ OMEGA + eps
    f_b = C_BN.T @ np.array([0.0, 0.0, G]) + nabla
    dtheta = np.tile(w_b * DT, (M, 1))
    if gyro_noise:
        dtheta += rng.normal(size=(M, 3)) * gyro_noise * np.sqrt(DT)
    return dtheta, np.tile(f_b * DT, (M, 1))


def test_euler_matrix_and_true_state_round_trip(rng):
    alpha = rng.uniform(-1.2, 1.2, size=(20, 3)) * np.array([1.0, 2.5, 2.5])
    assert np.allclose(C_p_n(alpha), euler_to_dcm(alpha), atol=1e-15)
    C_b_p = rotvec_to_dcm(rng.normal(size=(20, 3)))
    C_b_n = C_p_n(alpha) @ C_b_p
    assert np.allclose(true_state(C_b_n, C_b_p), alpha, atol=1e-12)


@pytest.mark.parametrize("alpha_fn, alpha_dot_fn", [
    (lambda t: np.array([0.3 * np.sin(t), -0.5 * np.cos(0.7 * t), 1.2 * t + 0.4]),
     lambda t: np.array([0.3 * np.cos(t), 0.35 * np.sin(0.7 * t), 1.2])),
    (lambda t: np.array([1.1 + 0.2 * t, 2.0 - t ** 2, -2.5 + np.sin(2 * t)]),
     lambda t: np.array([0.2, -2 * t, 2 * np.cos(2 * t)])),
])
def test_C_omega_is_the_rate_of_the_euler_sequence(alpha_fn, alpha_dot_fn):
    """ALGORITHMS (3.2): C_p^n_dot = C_p^n [omega_np^p x] defines omega_np^p; it equals
    C_omega alpha_dot for any smooth alpha(t), also at large angles."""
    h = 1e-5
    for t in (0.0, 0.37, 1.3):
        C = C_p_n(alpha_fn(t))
        C_dot = (C_p_n(alpha_fn(t + h)) - C_p_n(alpha_fn(t - h))) / (2 * h)
        W = C.T @ C_dot
        W = 0.5 * (W - W.T)
        omega = np.array([W[2, 1], W[0, 2], W[1, 0]])
        a, a_dot = alpha_fn(t), alpha_dot_fn(t)
        np.testing.assert_allclose(omega, C_omega(a) @ a_dot, rtol=0, atol=1e-8)
        np.testing.assert_allclose(C_omega_inv(a) @ C_omega(a), np.eye(3), atol=1e-13)


def test_small_angle_limit_is_the_classic_static_model(rng):
    """|alpha| ~ 1e-5 rad: (3.5) agrees with phi_dot = -[omega_ie x] phi - C_b^n eps,
    dv_dot = [f^n x] phi + C_b^n nabla (ALGORITHMS (0.1)-(0.2), static) up to terms of
    second order in the errors."""
    f_b = C_BN.T @ np.array([0.0, 0.0, G])
    direction = np.concatenate([rng.normal(size=3) * 1e-5, [0.0, 0.0],
                                NABLA[:2], EPS])

    def both(s):
        x = s * direction
        C_b_p = C_p_n(x[:3]).T @ C_BN      # the computed attitude of that error
        f_p = C_b_p @ (f_b + np.r_[x[5:7], 0.0])
        large = continuous_dynamics(x, C_b_p, f_p, OMEGA)
        small = small_angle_dynamics(x, C_BN, np.array([0.0, 0.0, G]), OMEGA)
        return large, small

    large, small = both(1.0)
    diff1 = np.abs(large - small)
    scale = np.abs(small)
    assert np.all(diff1[[0, 1, 2, 3, 4]] < 1e-4 * scale[[0, 1, 2, 3, 4]])
    diff_half = np.abs(np.subtract(*both(0.5)))
    ratio = diff1[:5] / diff_half[:5]
    np.testing.assert_allclose(ratio, 4.0, rtol=0.05)   # the difference is 2nd order


@pytest.mark.parametrize("step, jacobian", [(rk4_step, rk4_jacobian),
                                            (midpoint_step, midpoint_jacobian)])
def test_step_jacobian_matches_central_differences(rng, step, jacobian):
    x = rng.normal(size=(3, 10)) * np.r_[0.6, 0.6, 1.5, 0.1, 0.1, 5e-4, 5e-4, 5e-7, 5e-7, 5e-7]
    C_b_p = rotvec_to_dcm(rng.normal(size=(3, 3)))
    f_p = C_b_p @ (C_BN.T @ np.array([0.0, 0.0, G]))
    omega = np.tile(OMEGA, (3, 1))
    J = jacobian(x, 1.0, C_b_p, f_p, omega)
    steps = np.r_[[1e-5] * 3, [1e-3] * 2, [1e-5] * 5]
    J_fd = np.empty_like(J)
    for j, h in enumerate(steps):
        e = np.zeros(10)
        e[j] = h
        J_fd[..., j] = (step(x + e, 1.0, C_b_p, f_p, omega)
                        - step(x - e, 1.0, C_b_p, f_p, omega)) / (2 * h)
    np.testing.assert_allclose(J, J_fd, rtol=1e-7, atol=1e-7)
    A = continuous_jacobian(x, C_b_p, f_p, omega)
    A_fd = np.empty_like(A)
    for j, h in enumerate(steps):
        e = np.zeros(10)
        e[j] = h
        A_fd[..., j] = (continuous_dynamics(x + e, C_b_p, f_p, omega)
                        - continuous_dynamics(x - e, C_b_p, f_p, omega)) / (2 * h)
    np.testing.assert_allclose(A, A_fd, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("epoch", [1.0, 0.05])      # even / odd samples per epoch
def test_ins_attitude_at_boundaries_and_mid_epoch(epoch):
    """Constant rates: C_b^p(t) = exp(-[omega_ie x] t) C_b^p0 exp([omega_ib^b x] t)."""
    dtheta, dv = static_increments(3.0)
    C0 = C_p_n(ALPHA0).T @ C_BN
    ins = static_base_ins(dtheta, dv, DT, C0, LAT, H, epoch)
    w_b = dtheta[0] / DT

    def exact(t):
        return rotvec_to_dcm(-OMEGA * t) @ C0 @ rotvec_to_dcm(w_b * t)

    for k in (0, ins.t.size // 2, ins.t.size - 2):
        np.testing.assert_allclose(ins.C_b_p[0, k], exact(ins.t[k]), atol=1e-13)
        np.testing.assert_allclose(ins.C_b_p_mid[0, k], exact(ins.t[k] + 0.5 * epoch),
                                   atol=1e-13)
    assert ins.v_EN.shape == (1, ins.t.size, 2) and ins.f_p.shape == (1, ins.t.size - 1, 3)


def test_stack_requires_the_same_time_grid():
    dtheta, dv = static_increments(4.0)
    a = static_base_ins(dtheta, dv, DT, C_BN, LAT, H, 1.0)
    b = static_base_ins(dtheta[:200], dv[:200], DT, C_BN, LAT, H, 1.0)
    both = stack_ins_inputs([a, a])
    assert both.C_b_p.shape[0] == 2 and both.lat.shape == (2,)
    with pytest.raises(ValueError):
        stack_ins_inputs([a, b])


@pytest.mark.parametrize("step", [rk4_step, midpoint_step])
def test_model_follows_the_ins_error_over_600_s(step):
    """The strongest check: the INS started 58.5 deg off in heading, with constant gyro and
    accelerometer biases, has Euler error alpha(t) = true_state(C_b^n, C_b^p(t)) and
    velocity v(t); the model's discrete map from the true initial state reproduces both
    epoch by epoch."""
    dtheta, dv = static_increments(600.0)
    ins = static_base_ins(dtheta, dv, DT, C_p_n(ALPHA0).T @ C_BN, LAT, H, 1.0)
    alpha_ins = true_state(C_BN, ins.C_b_p[0])
    x = state_vector(ALPHA0, np.zeros(2), NABLA[:2], EPS)[None]
    xs = [x[0]]
    for k in range(ins.t.size - 1):
        x = step(x, 1.0, ins.C_b_p_mid[:, k], ins.f_p[:, k], OMEGA[None])
        xs.append(x[0])
    xs = np.array(xs)
    alpha_err = np.abs(xs[:, :3] - alpha_ins).max()
    v_err = np.abs(xs[:, 3:5] - ins.v_EN[0]).max()
    assert alpha_err < 1e-8 and v_err < 1e-5
    # not vacuous: the error angles move and the INS velocity grows to tens of m/s
    assert np.abs(alpha_ins - ALPHA0).max() > 1e-2
    assert np.abs(ins.v_EN[0, -1]).max() > 10.0

    # exact start and no biases: the INS stays at rest
    dtheta, dv = static_increments(600.0, eps=np.zeros(3), nabla=np.zeros(3))
    exact = static_base_ins(dtheta, dv, DT, C_BN, LAT, H, 1.0)
    assert np.abs(exact.v_EN).max() < 1e-3
    assert np.abs(true_state(C_BN, exact.C_b_p[0])).max() < 1e-12


def _heading_error(C_s_n):
    return np.abs(dcm_to_euler(C_s_n @ C_BN.T)[..., 2])


def test_filters_converge_from_58_5_deg_heading_error(rng):
    """EKF and SGHKF-2 on the model: from 58.5 deg to below 1 deg heading error in 600 s
    (gyro white noise 0.01 deg/h/sqrt(Hz)). With 002's literal drift prior (0.1 deg/h,
    ten times the true drift) the drift estimates wander during the transient and carry
    heading with them (ALGORITHMS 3.3); the tighter prior 0.01 deg/h is used here.
    A small-angle linear KF on the same data stalls at several degrees."""
    runs = [static_base_integrals(*static_increments(600.0, gyro_noise=0.01 * deg_per_h,
                                                     rng=rng), DT, LAT, H, 1.0)
            for _ in range(2)]
    inputs = stack_integrals(runs)
    C0 = np.broadcast_to(C_p_n(ALPHA0).T @ C_BN, (2, 3, 3))
    tuning = Paper002Tuning(gyro_bias_sigma=0.01 * deg_per_h)
    for name in ("ekf", "sghkf-2"):
        result = run_alignment(make_filter(name),
                               EulerLargeMisalignmentModel(inputs, C0, tuning))
        assert not result.diverged.any(), name
        heading = _heading_error(result.C_s_n[:, -1])
        assert np.all(heading < 1 * deg), (name, heading / arcmin)
        assert np.allclose(_heading_error(result.C_s_n[:, 0]), 58.5 * deg, atol=0.01 * deg)
    linear = run_alignment(make_filter("kf"), SmallAngleModel(inputs, C0, tuning))
    assert np.all(_heading_error(linear.C_s_n[:, -1]) > 5 * deg)


@pytest.mark.parametrize("epoch", [1.0, 0.05])
def test_integrals_reproduce_the_ins_for_any_start(epoch):
    """The filter-independent integrals give, for a start C0, exactly the INS of
    ``static_base_ins`` (attitude, mid-epoch attitude, velocity)."""
    dtheta, dv = static_increments(60.0)
    C0 = C_p_n(ALPHA0).T @ C_BN
    ins = static_base_ins(dtheta, dv, DT, C0, LAT, H, epoch)
    integrals = static_base_integrals(dtheta, dv, DT, LAT, H, epoch)
    K = integrals.t.size - 1
    att = np.stack([integrals.attitude(C0[None], k)[0] for k in range(K + 1)])
    mid = np.stack([integrals.attitude_mid(C0[None], k)[0] for k in range(K)])
    v = np.cumsum([integrals.delta_v(C0[None], k)[0] for k in range(K)], axis=0)
    np.testing.assert_allclose(att, ins.C_b_p[0], atol=1e-14)
    np.testing.assert_allclose(mid, ins.C_b_p_mid[0], atol=1e-14)
    np.testing.assert_allclose(v[:, :2], ins.v_EN[0, 1:], atol=1e-11)


def test_feedback_keeps_the_estimate_and_zeroes_the_state():
    """Closed loop: after feeding alpha_hat back, the model's attitude equals the
    open-loop estimate C_p^n(alpha_hat) C_b^p; alpha and dv are zero; the INS velocity
    drops by dv_hat; the covariance stays symmetric positive definite."""
    dtheta, dv = static_increments(10.0)
    integrals = static_base_integrals(dtheta, dv, DT, LAT, H, 1.0)
    C0 = (C_p_n(ALPHA0).T @ C_BN)[None]
    model = EulerLargeMisalignmentModel(integrals, C0, feedback_below=np.inf)
    x, P = model.initial()
    model.observation(0)
    x[0, :3] = [0.004, -0.012, 1.0]
    x[0, 3:5] = [0.02, -0.01]
    before = model.attitude(1, x)
    v_before = model.observation(0).z.copy()
    x2, P2 = model.feedback(x, P, np.array([True]))
    np.testing.assert_allclose(model.attitude(1, x2), before, atol=1e-14)
    np.testing.assert_array_equal(x2[0, :5], 0.0)
    np.testing.assert_allclose(model.observation(0).z, v_before - x[0, 3:5], atol=1e-15)
    assert np.all(np.linalg.eigvalsh(P2[0]) > 0) and np.allclose(P2, P2.transpose(0, 2, 1))


def test_process_noise_enters_as_the_biases_do():
    """Q_k = G q G^T T with G the derivative of (3.5) with respect to the accelerometer
    (x, y) and gyro biases at the linearisation point (central differences): white noise
    enters where the bias does. At a level-perturbed, 58.5 deg estimate, the accelerometer
    noise's heading dependence would show (Rx Ry C_b^p, not C_p^n C_b^p)."""
    dtheta, dv = static_increments(10.0)
    integrals = static_base_integrals(dtheta, dv, DT, LAT, H, 1.0)
    C0 = (C_p_n(ALPHA0).T @ C_BN)[None]
    tuning = Paper002Tuning()
    model = EulerLargeMisalignmentModel(integrals, C0, tuning)
    x, P = model.initial()
    x[0, :3] = [0.9 * deg, -1.3 * deg, 58.5 * deg]
    model.feedback(x, P, np.array([True]))
    noise = model.transition(3).noise[0]
    C_b_p, f_p, omega = (a[0] for a in model._args(3))
    G = np.empty((10, 5))
    for j, i in enumerate([5, 6, 7, 8, 9]):
        e = np.zeros(10)
        e[i] = 1e-6
        G[:, j] = (continuous_dynamics(x[0] + e, C_b_p, f_p, omega)
                   - continuous_dynamics(x[0] - e, C_b_p, f_p, omega)) / 2e-6
    q = np.r_[[tuning.accel_psd] * 2, [tuning.gyro_psd] * 3]
    np.testing.assert_allclose(noise, (G * q) @ G.T * model.T, rtol=1e-6, atol=1e-24)


def test_the_compiled_midpoint_step_is_the_array_one_to_the_bit():
    """The model's process map on integration points runs the compiled loop
    (``euler_kernel``): on random states, attitudes, forces, rates and steps, the same
    numbers as ``midpoint_step``, signs of zeros included, where NumPy's sine and cosine
    are the C library's (the compiled loop calls those); within 1e-13 where NumPy has its
    own (AVX-512 builds differ by an ulp)."""
    import math

    from aligngym.estimators.euler_large import _midpoint_points
    rng = np.random.default_rng(2)
    probe = rng.normal(size=20000) * 3.0
    libm = (np.array_equal(np.sin(probe), [math.sin(a) for a in probe])
            and np.array_equal(np.cos(probe), [math.cos(a) for a in probe]))
    for trial in range(60):
        B, P = rng.integers(1, 5), rng.integers(1, 30)
        x = rng.normal(size=(B, P, 10)) * rng.choice([1e-6, 1e-2, 1.0, 3.0])
        x[..., 5:7] *= 1e-3
        x[..., 7:] *= 1e-5
        if trial % 5 == 0:
            x[..., 5:] = -0.0
        C = np.linalg.qr(rng.normal(size=(B, 3, 3)))[0]
        f = rng.normal(size=(B, 3)) * [0.1, 0.1, 9.8]
        w = rng.normal(size=(B, 3)) * 7e-5
        T = float(rng.choice([0.01, 0.5, 1.0]))
        expected = midpoint_step(x, T, C[:, None], f[:, None], w[:, None])
        got = _midpoint_points(x, T, C, f, w)
        if libm:
            np.testing.assert_array_equal(got, expected)
            np.testing.assert_array_equal(np.signbit(got), np.signbit(expected))
        else:
            np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-300)


def test_the_feedback_reset_jacobian_against_scipy_rotations():
    """d alpha' / d alpha of the reset C_p^n(alpha') = C_p^n(alpha) C_p^n(alpha_hat)^T at
    alpha_hat, against the same reset written with SciPy's rotations (C_p^n =
    Rz(alpha_U) Rx(alpha_E) Ry(alpha_N): the intrinsic ZXY sequence) and differenced
    here: one batch of estimates from small to 70 deg of heading and 30 deg of tilt."""
    from scipy.spatial.transform import Rotation

    from aligngym.estimators.euler_kinematics import reset_jacobian
    rng = np.random.default_rng(6)
    alpha_hat = rng.uniform(-1, 1, (8, 3)) * np.array([30, 30, 70]) * deg
    alpha_hat[0] = [1e-5, -2e-5, 3e-5]

    def reset(alpha, at):
        R = Rotation.from_euler("ZXY", alpha[[2, 0, 1]]) * \
            Rotation.from_euler("ZXY", at[[2, 0, 1]]).inv()
        U, E, N = R.as_euler("ZXY")
        return np.array([E, N, U])

    h = 1e-5
    for b, at in enumerate(alpha_hat):
        J = np.column_stack([(reset(at + h * e, at) - reset(at - h * e, at)) / (2 * h)
                             for e in np.eye(3)])
        np.testing.assert_allclose(reset_jacobian(alpha_hat)[b], J, atol=2e-7)
