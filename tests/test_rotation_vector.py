"""Paper 004's rotation-vector large-misalignment model and its state transformation
(ALGORITHMS 6): J_r^-1, the dv <-> dv_ST round trip, the STEKF and classic Jacobians
against the exact derivatives, the static case, and the exact model against two
simulated INSs."""
from dataclasses import replace

import numpy as np
import pytest

from aligngym.estimators.rotation_vector_dynamics import (DV, DP, N_STATES, PHI, InsQuantities,
                                                          J_r_inv, classic_derivative,
                                                          classic_matrix, classic_to_st,
                                                          st_derivative, st_to_classic,
                                                          stekf_matrix)
from aligngym.estimators.strapdown import StrapdownState, run_strapdown
from aligngym.models.attitude import dcm_to_quat, dcm_to_rotvec, quat_to_dcm, rotvec_to_dcm
from aligngym.models.earth import gravity_n
from aligngym.scenarios.config import load_scenario
from aligngym.scenarios.simulate import simulate


@pytest.mark.parametrize("phi", [[1e-6, -2e-6, 3e-6], [0.1, -0.2, 0.3], [1.2, -0.8, 2.0]])
def test_inverse_right_jacobian_against_finite_differences(phi):
    phi = np.array(phi)
    omega = np.array([0.3, -0.7, 0.5])
    h = 1e-6
    C = rotvec_to_dcm(phi)
    rate = (dcm_to_rotvec(C @ rotvec_to_dcm(omega * h))
            - dcm_to_rotvec(C @ rotvec_to_dcm(-omega * h))) / (2 * h)
    np.testing.assert_allclose(J_r_inv(phi) @ omega, rate, atol=1e-8)


def _moving_quantities(rng) -> InsQuantities:
    C = rotvec_to_dcm(rng.standard_normal(3))
    return InsQuantities(C_b_p=C, f_b=C.T @ np.array([0.8, -1.5, 9.9]),
                         v=np.array([12.0, -7.0, 0.4]), lat=np.array(0.6),
                         lon=np.array(2.0), h=np.array(150.0))


def test_velocity_transformation_round_trip():
    rng = np.random.default_rng(2)
    q = _moving_quantities(rng)
    x = rng.standard_normal((5, N_STATES))
    x[:, PHI] *= 1.5                                     # large angles included
    np.testing.assert_allclose(st_to_classic(classic_to_st(x, q.v), q.v), x, atol=1e-12)
    small = x * 1e-4
    # Small angle: dv = dv_ST + [v x] phi, to second order in phi (|phi|^2 |v| / 2).
    np.testing.assert_allclose(st_to_classic(small, q.v)[:, DV],
                               small[:, DV] + np.cross(q.v, small[:, PHI]), atol=1e-6)


def _numeric_jacobian(derivative, q: InsQuantities) -> np.ndarray:
    steps = np.array([1e-7] * 6 + [1e-9, 1e-9, 1e-3] + [1e-7] * 6)
    J = np.empty((N_STATES, N_STATES))
    for j in range(N_STATES):
        d = np.zeros(N_STATES)
        d[j] = steps[j]
        J[:, j] = (derivative(d, q) - derivative(-d, q)) / (2 * steps[j])
    return J


def _gravity_jacobian(q: InsQuantities) -> np.ndarray:
    """d(g^ - g_true)/d(dL, dlambda, dh): the dg terms ALGORITHMS 6.7 leaves out."""
    J = np.zeros((3, 3))
    for j, step in ((0, 1e-9), (2, 1e-3)):
        d = np.zeros(3)
        d[j] = step
        g = lambda s: gravity_n(q.lat - s * d[0], q.h - s * d[2])  # noqa: E731
        J[:, j] = -(g(1.0) - g(-1.0)) / (2 * step)
    return J


@pytest.mark.parametrize("model", ["st", "classic"])
def test_linearised_matrices_are_the_exact_models_jacobians_at_zero(model):
    """ALGORITHMS 6 oracle 1 (and its classic counterpart): the Jacobian of the exact
    derivative at phi = 0 equals the (6.7) / (0.1)-(0.3) blocks, but for the gravity
    gradient both leave out and the radii's latitude dependence (relative 1e-5 of each
    row's and column's largest entry)."""
    q = _moving_quantities(np.random.default_rng(4))
    derivative, matrix = ((st_derivative, stekf_matrix) if model == "st"
                          else (classic_derivative, classic_matrix))
    J = _numeric_jacobian(derivative, q)
    F = matrix(q)
    J[DV, DP] -= _gravity_jacobian(q)
    # The radii's latitude dependence (d R_M / dL) that M_pp leaves out: ~1e-8 1/s.
    assert np.abs(J[DP, DP] - F[DP, DP]).max() < 3e-8
    J[DP, DP] = F[DP, DP]
    scale = np.maximum(np.abs(F).max(axis=1)[:, None], np.abs(F).max(axis=0)[None])
    bad = np.abs(J - F) > 1e-5 * scale + 1e-14
    assert not bad.any(), np.argwhere(bad)


def test_static_base_stekf_equals_the_classic_model():
    """ALGORITHMS 6 oracle 2: v = 0 and f^n = -g^n make the two F matrices equal."""
    q = _moving_quantities(np.random.default_rng(6))
    g = gravity_n(q.lat, q.h)
    q = replace(q, v=np.zeros(3), f_b=q.C_b_p.T @ -g)
    np.testing.assert_allclose(stekf_matrix(q), classic_matrix(q), atol=1e-15)


@pytest.fixture(scope="module")
def driving():
    """40 s of the figure-8 car on ideal sensors, moving from 5 s."""
    config = load_scenario("figure8-gps").with_options(duration=40.0)
    config = replace(config, motion=replace(config.motion, start_time=5.0))
    return simulate(config, seed=1, ideal=True)


def _ins(episode, start, stop, q0, v0, lat0, lon0, h0, gyro=0.0, accel=0.0):
    dt = episode.config.imu_interval
    sl = slice(int(round(start / dt)), int(round(stop / dt)))
    dtheta = episode.dtheta[sl] + gyro * dt
    dv = episode.dv[sl] + accel * dt
    state = StrapdownState.from_arrays(q0, v0, lat0, lon0, h0)
    return run_strapdown(state, dtheta, dv, dt), dv / dt


@pytest.mark.parametrize("model", ["st", "classic"])
def test_exact_model_follows_two_simulated_inss(driving, model):
    """ALGORITHMS 6 oracle 4: an INS started 70 deg off (rotation vector [0.3, -0.4, 1.2]
    rad) with drift and bias, against one started on the truth, over 10 s of driving: the
    model integrated (RK4 at the IMU rate, with the erroneous INS's own quantities) ends
    where the two INSs' difference is: measured 2e-9 rad and 2e-8 m/s on velocity errors
    of 36 m/s (1e-9 relative; the strapdown's own discretisation), asserted 1e-8 rad and
    1e-7 m/s; the classic model needs the specific force between IMU samples (1.3e-6 m/s
    with the samples' means, asserted 1e-5), the transformed one does not (6.4)."""
    tr, dt = driving.truth, driving.config.imu_interval
    i0 = int(round(20.0 / dt))
    phi0 = np.array([0.3, -0.4, 1.2])
    eps, nabla = np.array([2e-5, -1e-5, 3e-5]), np.array([0.02, -0.01, 0.015])
    C_true = quat_to_dcm(tr.q_s_n[i0])
    ref, _ = _ins(driving, 20.0, 30.0, tr.q_s_n[i0], tr.v_n[i0], tr.lat[i0], tr.lon[i0],
                  tr.h[i0])
    dv0, dp0 = np.array([0.3, -0.2, 0.05]), np.array([2e-7, -1e-7, 3.0])
    C_p = rotvec_to_dcm(-phi0) @ C_true                                # C_b^p
    v_ins0 = tr.v_n[i0] + dv0
    err, f_b = _ins(driving, 20.0, 30.0, dcm_to_quat(C_p), v_ins0, tr.lat[i0] + dp0[0],
                    tr.lon[i0] + dp0[1], tr.h[i0] + dp0[2], gyro=eps, accel=nabla)

    def quantities(k: float) -> InsQuantities:
        """The erroneous INS at boundary k (half-integers interpolate)."""
        lo, hi = int(np.floor(k)), int(np.ceil(k))
        mix = lambda a: 0.5 * (a[0, lo] + a[0, hi])  # noqa: E731
        C = quat_to_dcm(dcm_to_quat(0.5 * (quat_to_dcm(err["q_b_n"][0, lo])
                                           + quat_to_dcm(err["q_b_n"][0, hi]))))
        # Specific force: the interval's mean at its middle, the neighbours' mean at a
        # boundary.
        n = f_b.shape[0] - 1
        f = (f_b[lo] if lo != hi else 0.5 * (f_b[max(lo - 1, 0)] + f_b[min(lo, n)]))
        return InsQuantities(C_b_p=C, f_b=f, v=mix(err["v_n"]),
                             lat=mix(err["lat"]), lon=mix(err["lon"]), h=mix(err["h"]))

    def state(k: int) -> np.ndarray:
        C_ins = quat_to_dcm(err["q_b_n"][0, k])
        C_ref = quat_to_dcm(ref["q_b_n"][0, k])
        x = np.zeros(N_STATES)
        x[PHI] = dcm_to_rotvec(C_ref @ C_ins.T)
        x[DV] = err["v_n"][0, k] - ref["v_n"][0, k]
        x[DP] = [err["lat"][0, k] - ref["lat"][0, k], err["lon"][0, k] - ref["lon"][0, k],
                 err["h"][0, k] - ref["h"][0, k]]
        x[9:12], x[12:15] = eps, nabla
        return classic_to_st(x, err["v_n"][0, k]) if model == "st" else x

    derivative = st_derivative if model == "st" else classic_derivative
    x = state(0)
    M = err["v_n"].shape[1] - 1
    for k in range(M):
        a = derivative(x, quantities(k))
        b = derivative(x + 0.5 * dt * a, quantities(k + 0.5))
        c = derivative(x + 0.5 * dt * b, quantities(k + 0.5))
        d = derivative(x + dt * c, quantities(k + 1))
        x = x + dt / 6.0 * (a + 2 * b + 2 * c + d)
    truth = state(M)
    assert np.abs(x[PHI] - truth[PHI]).max() < 1e-8
    assert np.abs(x[DV] - truth[DV]).max() < (1e-7 if model == "st" else 1e-5)
    assert np.abs(x[6:8] - truth[6:8]).max() < 1e-10 and abs(x[8] - truth[8]) < 1e-5


@pytest.fixture(scope="module")
def figure8_inputs(tmp_path_factory):
    """Two short figure-8 episodes (RTK GPS, moving from 40 s; paper 001's preparation) as
    GNSS-aided INS inputs started 10, -10, 60 deg off (rotation vector)."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from test_paper001 import short_scenario
    from aligngym.scenarios.experiments.paper001 import Paper001Experiment, model_inputs
    from aligngym.models.units import deg
    exp = Paper001Experiment(scenario=short_scenario(tmp_path_factory.mktemp("p004")),
                             coarse_duration=30.0)
    episodes = [exp.prepare_episode(s) for s in (1, 2)]
    start = np.broadcast_to(np.array([10.0, -10.0, 60.0]) * deg, (2, 3))
    return episodes, lambda: model_inputs(episodes, start)


def _tuning():
    from aligngym.estimators.rotation_vector import RotationVectorTuning
    from aligngym.models.units import deg, deg_per_h
    return RotationVectorTuning(
        attitude_sigma=(45 * deg, 45 * deg, 60 * deg), velocity_sigma=0.1, position_sigma=1.0,
        gyro_bias_sigma=1 * deg_per_h, accel_bias_sigma=1e-4, gyro_noise_density=0.1 * deg / 60,
        accel_noise_density=1e-4, gyro_bias_walk=1e-8, accel_bias_walk=1e-6,
        gnss_position_sigma_h=0.02, gnss_position_sigma_v=0.03, gnss_velocity_sigma=0.02)


def test_nonlinear_and_linear_transformed_models_agree_near_zero(figure8_inputs):
    """The STUKF's map (RK4 of 6.1/6.4/6.5) and the STEKF's Phi (6.7) agree on a small
    error state, and so do the measurement maps (the (6.6) h and (6.7) H)."""
    from aligngym.estimators.rotation_vector import RotationVectorGnssModel
    _, inputs = figure8_inputs
    nonlinear = RotationVectorGnssModel(inputs(), _tuning(), "st")
    linear = RotationVectorGnssModel(inputs(), _tuning(), "st-linear")
    x = np.broadcast_to(np.concatenate([[1e-5, -2e-5, 3e-5], [1e-3, -2e-3, 5e-4],
                                        [1e-9, -2e-9, 0.01], [1e-7, 2e-7, -1e-7],
                                        [1e-4, -2e-4, 1e-4]]), (2, 15))
    for k in range(80):                                    # into the motion phase
        f, Phi = nonlinear.transition(k), linear.transition(k).matrix
        h, H = nonlinear.observation(k), linear.observation(k).matrix
    step = f.fn(x[:, None])[:, 0]
    np.testing.assert_allclose(step, np.einsum("bij,bj->bi", Phi, x), rtol=0,
                               atol=2e-3 * np.abs(step - x).max() + 1e-15)
    np.testing.assert_allclose(h.fn(x[:, None])[:, 0], np.einsum("bij,bj->bi", H, x),
                               rtol=1e-3, atol=1e-9)


@pytest.mark.parametrize("variant", ["st", "classic"])
def test_the_models_compiled_map_is_the_numpy_derivatives(figure8_inputs, variant):
    """The model's process map, compiled, against the same model integrating the NumPy
    derivative (``derivative=``): the INS's quantities at each step's start, middle and
    end handed to the right stages, on the figure-8 drive into its motion, at points up to
    1 rad of attitude error (the same within 4e-12 of the increments); a replaced
    derivative is the one integrated (a drift of the accelerometer biases added to it
    comes out as T times the drift); no derivative replaces the linear variant's matrix."""
    from aligngym.estimators.rotation_vector import RotationVectorGnssModel
    _, inputs = figure8_inputs
    reference = st_derivative if variant == "st" else classic_derivative
    drift = np.r_[np.zeros(12), 1e-3, -2e-3, 3e-3]       # an accelerometer bias drift
    models = [RotationVectorGnssModel(inputs(), _tuning(), variant, derivative=derivative)
              for derivative in (None, reference, lambda x, q: reference(x, q) + drift)]
    x = np.random.default_rng(3).normal(size=(2, 7, N_STATES)) * np.r_[
        [0.5] * 3, [0.5] * 3, 1e-6, 1e-6, 3.0, [1e-5] * 3, [1e-3] * 3]
    for k in range(80):
        maps = [model.transition(k) for model in models]
        if k % 20 == 19:
            got, expected, drifted = (m.fn(x) for m in maps)
            scale = np.abs(expected - x).reshape(-1, N_STATES).max(0)
            assert np.all(np.abs(got - expected) <= 4e-12 * scale + 4e-15 * np.abs(x)), k
            np.testing.assert_allclose(drifted[..., 12:] - expected[..., 12:],
                                       np.broadcast_to(models[0].T * drift[12:], (2, 7, 3)),
                                       rtol=1e-9)
    with pytest.raises(ValueError, match="st-linear"):
        RotationVectorGnssModel(inputs(), _tuning(), "st-linear", derivative=reference)


def test_stekf_aligns_the_moving_car_from_60_degrees(figure8_inputs):
    """Velocity-aided alignment in motion with the transformed EKF, closed loop from the
    start: from 10, -10, 60 deg to 0.1 deg in 170 s of driving (measured 0.015 deg
    level, 0.014 deg heading), within 4 of its own sigmas (the level errors sit at 3)."""
    from aligngym.estimators.alignment import run_alignment
    from aligngym.estimators.filters import GaussianFilter
    from aligngym.estimators.adaptation import NoAdaptation
    from aligngym.estimators.metrics import misalignment
    from aligngym.estimators.rotation_vector import RotationVectorGnssModel
    from aligngym.estimators.rules import LinearizationRule
    from aligngym.models.units import deg
    episodes, inputs = figure8_inputs
    result = run_alignment(GaussianFilter("stekf", LinearizationRule(), NoAdaptation()),
                           RotationVectorGnssModel(inputs(), _tuning(), "st-linear"))
    K = result.t.size
    error = misalignment(np.stack([e.C_s_n_true[:K] for e in episodes]), result.C_s_n)
    assert not result.diverged.any()
    assert np.abs(error[:, -1]).max() < 0.1 * deg
    assert np.all(np.abs(error[:, -1]) < 4 * result.sigma_n[:, -1])


def test_stukf_aligns_the_moving_car_from_60_degrees(figure8_inputs):
    """The registry's stukf (n + kappa = 1.5: points at 1.22 sigma; with kappa = 0 they
    sit at sqrt(15) x 45-60 deg, past pi, and it fails) on the transformed model, closed
    loop: from (10, -10, 60) deg to 0.05 deg in 170 s (measured 0.004-0.011 deg)."""
    from aligngym.estimators.alignment import run_alignment
    from aligngym.estimators.catalogue import filter_entry, make_filter
    from aligngym.estimators.metrics import misalignment
    from aligngym.estimators.rotation_vector import RotationVectorGnssModel
    from aligngym.models.units import deg
    episodes, inputs = figure8_inputs
    assert filter_entry("stukf").model == "st" and filter_entry("stekf").model == "st-linear"
    result = run_alignment(make_filter("stukf"),
                           RotationVectorGnssModel(inputs(), _tuning(), "st"))
    K = result.t.size
    error = misalignment(np.stack([e.C_s_n_true[:K] for e in episodes]), result.C_s_n)
    assert not result.diverged.any()
    assert np.abs(error[:, -1]).max() < 0.05 * deg


def _reset_by_definition(x, x_hat, v_ins, variant):
    """The error state after (6.8)'s feedback of x_hat, from the definitions alone (scipy
    for the rotation's log): the truth the pre-reset error x implies (INS attitude I,
    velocity v_ins), the INS corrected as ``feedback`` corrects it, the error between
    them expressed in the variant's states."""
    from scipy.spatial.transform import Rotation
    from aligngym.estimators.rotation_vector_dynamics import classic_to_st, st_to_classic
    classic = variant == "classic"
    v_true = v_ins - (x[DV] if classic else st_to_classic(x, v_ins)[DV])
    if variant == "st":
        dv_hat = st_to_classic(x_hat, v_ins)[DV]
    elif variant == "st-linear":                        # (6.8)'s small-angle form
        dv_hat = x_hat[DV] + np.cross(v_ins, x_hat[PHI])
    else:
        dv_hat = x_hat[DV]
    v_plus = v_ins - dv_hat
    after = x - x_hat
    after[PHI] = Rotation.from_matrix(Rotation.from_rotvec(x[PHI]).as_matrix()
                                      @ Rotation.from_rotvec(x_hat[PHI]).as_matrix().T
                                      ).as_rotvec()
    after[DV] = v_plus - v_true
    if not classic:
        after[DV] = classic_to_st(after, v_plus)[DV]
    return after


@pytest.mark.parametrize("variant", ["st", "st-linear", "classic"])
def test_the_reset_jacobian_is_the_derivative_of_the_reset(variant):
    """P <- G P G^T at feedback (ALGORITHMS 6.8, corrected): G against central
    differences of the reset itself at a large estimate (52 deg of heading, 0.5 m/s)."""
    from aligngym.estimators.rotation_vector_dynamics import reset_jacobian
    rng = np.random.default_rng(3)
    x_hat = np.concatenate([[0.1, -0.15, 0.9], [0.4, -0.3, 0.1], rng.normal(size=9) * 1e-3])
    v_ins = np.array([3.0, -2.0, 0.5])
    h = 1e-6
    G = np.stack([(_reset_by_definition(x_hat + h * e, x_hat, v_ins, variant)
                   - _reset_by_definition(x_hat - h * e, x_hat, v_ins, variant)) / (2 * h)
                  for e in np.eye(N_STATES)], -1)
    np.testing.assert_allclose(reset_jacobian(x_hat, variant), G, atol=1e-8)
    assert not np.allclose(G, np.eye(N_STATES), atol=1e-2)      # the reset is not P kept


@pytest.mark.parametrize("transformed", [True, False], ids=["st", "classic"])
def test_the_compiled_runge_kutta_step_is_the_numpy_one(transformed):
    """The filters' process map runs compiled (``rotation_vector_kernel``): on random error
    states (rotation vectors from zero to about 12 rad), attitudes, forces, velocities,
    latitudes to 75 deg, heights and steps, its Runge-Kutta step is the one of the NumPy
    derivatives (``st_derivative``, ``classic_derivative``) within 4e-12 of the
    component's largest increment and 4e-15 of its value (NumPy's AVX-512 tangent and
    power differ from the C library's by an ulp; the classic velocity's terms cancel),
    keeps the points' shape, and refuses points of another batch than its stages'."""
    from aligngym.estimators.rotation_vector import (_stages, numpy_runge_kutta_step,
                                                     runge_kutta_step)
    derivative = st_derivative if transformed else classic_derivative
    rng = np.random.default_rng(4)
    for trial in range(40):
        B, P = rng.integers(1, 5), rng.integers(1, 33)
        x = rng.normal(size=(B, P, N_STATES)) * np.r_[[rng.choice([1e-6, 1e-3, 0.1, 1.0, 3.0])]
                                                      * 3, [0.5] * 3, 1e-6, 1e-6, 3.0,
                                                      [1e-5] * 3, [1e-3] * 3]
        if trial % 7 == 0:
            x[..., PHI] = 0.0
        stages = [InsQuantities(C_b_p=rotvec_to_dcm(rng.normal(size=(B, 1, 3))),
                                f_b=rng.normal(size=(B, 1, 3)) * [0.3, 0.3, 9.8],
                                v=rng.normal(size=(B, 1, 3)) * 5.0,
                                lat=rng.uniform(-1.3, 1.3, (B, 1)),
                                lon=rng.uniform(-3.0, 3.0, (B, 1)),
                                h=rng.normal(size=(B, 1)) * 100.0) for _ in range(3)]
        T = float(rng.choice([0.01, 0.1, 1.0]))
        expected = numpy_runge_kutta_step(derivative, x, T, stages)
        got = runge_kutta_step(x, T, transformed, _stages(stages))
        scale = np.abs(expected - x).reshape(-1, N_STATES).max(0)
        assert np.all(np.abs(got - expected) <= 4e-12 * scale + 4e-15 * np.abs(x)), trial
        assert runge_kutta_step(x[:, 0], T, transformed, _stages(stages)).shape == (B, N_STATES)
    with pytest.raises(ValueError, match="stages of"):
        runge_kutta_step(np.zeros((B + 1, 2, N_STATES)), T, transformed, _stages(stages))
