"""The adaptation policies at the places the mutation run (issue 41) found untested: hand
values from ALGORITHMS 2.2, 2.10-2.11 and 5.2-5.3 in inputs the two other test files did
not reach (a factor ratio that is not an integer, a direction with no zero component, a
batch size other than the measurement size, a chi-square NIS exactly at its quantile,
the warm-up's rounding edge, a variance rounded below zero), and the policies' contract
(what an agent's retune is, what a policy needs, which width it announces). Innovations
and their standard deviations are in the measurement's units, variances in its units
squared; the factors and weights have none."""
import dataclasses
import warnings

import numpy as np
import pytest
from scipy.special import gammaincinv

from aligngym.estimators.adaptation import (AdaptationContext, AdaptationPolicy, NoAdaptation,
                                            PolicyTuning)
from aligngym.estimators.fading_factors import (
    ImprovedMultipleFadingFactors, MeasurementAxisFading, MeasurementFadingFactor,
    MultipleFadingFactors, SingleFadingFactor)
from aligngym.estimators.robust_adaptive import RobustAdaptive, SelectiveWeights, adaptive_factor


def context(e, PhiPPhi, Q, H, R, S=None, valid=None, **kw):
    """An update's context (B leading) from arrays; S defaults to H (PhiPPhi + Q) H^T + R
    and valid to all present."""
    e, PhiPPhi, Q, H, R = (np.asarray(a, float) for a in (e, PhiPPhi, Q, H, R))
    J = PhiPPhi + Q
    S = H @ J @ np.swapaxes(H, -1, -2) + R if S is None else np.asarray(S, float)
    return AdaptationContext(innovation=e, valid=np.ones(e.shape, bool) if valid is None
                             else np.asarray(valid, bool), S=S,
                             P_xz=J @ np.swapaxes(H, -1, -2), PhiPPhi=PhiPPhi, Q=Q, R=R,
                             H=H, **kw)


def batch(a, b):
    """a repeated over b episodes."""
    return np.repeat(np.asarray(a, float)[None], b, axis=0)


# ------------------------------------------------- fading factors on R (2.10-2.11) ----

def test_single_factor_on_r_by_hand_in_a_batch_of_two():
    """(2.10), first epoch (C_1 = e e^T), H = I, m = n = B = 2, episodes unlike each other:
    0: e = (3, 1), J = diag(1, 0.5), R = diag(0.5, 0.25): (10 - 1.5) / 0.75 = 34/3.
    1: e = (2, 2), J = diag(2, 1), R = I: (8 - 3) / 2 = 2.5.
    R_k = lambda R, P_pred not faded. Each trace is over an episode's own m x m matrix."""
    PhiPPhi = [np.diag([0.8, 0.4]), np.diag([1.5, 0.5])]
    Q = [np.diag([0.2, 0.1]), np.diag([0.5, 0.5])]
    R = np.array([np.diag([0.5, 0.25]), np.eye(2)])
    ctx = context([[3.0, 1.0], [2.0, 2.0]], PhiPPhi, Q, batch(np.eye(2), 2), R)
    adj = MeasurementFadingFactor().adapt(ctx)
    np.testing.assert_allclose(adj.factors, [[34 / 3], [2.5]], rtol=1e-12)
    np.testing.assert_allclose(adj.R, np.array([34 / 3, 2.5])[:, None, None] * R,
                               rtol=1e-12)
    assert adj.P_pred is None


def test_per_axis_factors_on_r_by_hand_along_rotated_axes():
    """(2.11), first epoch, H = I (n = m = 3), U a quarter turn about Up (the measurement's
    x axis points South: U e = (e_1, -e_0, e_2)), J = diag(1, 2, 0.5), R = diag(0.5, 2, 1),
    e = (3, 1, 2.5): along E, N, U, C^n_jj = (1, 9, 6.25), (H J H^T)^n_jj = (2, 1, 0.5),
    R^n_jj = (2, 0.5, 1) -> lambda = (1 (N_EE < 0), 16, 5.75): the measurement's R is
    scaled by 16 on its x axis (0.5 -> 8) and by 5.75 on its z axis. B = 2 episodes (not
    3): the policy then reports three factors per episode."""
    U = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    R = np.diag([0.5, 2.0, 1.0])
    ctx = context(batch([3.0, 1.0, 2.5], 2), batch(np.diag([0.8, 1.5, 0.4]), 2),
                  batch(np.diag([0.2, 0.5, 0.1]), 2), batch(np.eye(3), 2), batch(R, 2),
                  axes=batch(U, 2))
    policy = MeasurementAxisFading()
    adj = policy.adapt(ctx)
    np.testing.assert_allclose(adj.factors, [[1.0, 16.0, 5.75]] * 2, rtol=1e-12)
    np.testing.assert_allclose(adj.R, batch(np.diag([8.0, 2.0, 5.75]), 2), rtol=1e-12,
                               atol=1e-15)
    assert adj.P_pred is None
    assert policy.n_factors == 3


def test_the_policies_along_e_n_u_announce_three_factors_before_the_first_update():
    """Factors along local E, N, U are three whatever the batch: the measurement-axis R
    factors and the local-level per-axis factors of the MAKF and the IMAKF announce 3
    before any update (as the fixed-width policies of test_adaptation_001 do)."""
    assert MeasurementAxisFading().n_factors == 3
    assert MultipleFadingFactors(axes="local-level").n_factors == 3
    assert ImprovedMultipleFadingFactors(axes="local-level").n_factors == 3


# ------------------------------------------------------- per-axis fading (2.8-2.9) ----

def test_a_negative_n_with_a_variance_rounded_below_zero_gives_the_floor():
    """ALGORITHMS 2.2: N_ii < 0 => lambda_i = 1, also where J_ii is a variance rounded
    below zero (-1e-17, as a sigma-point rule's Phi P Phi^T of a state known exactly may
    give): C_1 = 0.25, R = 1: N = -0.75 -> lambda = 1 and P_pred = Phi P Phi^T + Q (not
    sqrt(-0.75 / -1e-17) ~ 3e8)."""
    PhiPPhi = [np.diag([-1e-17, 1.0])]
    adj = MultipleFadingFactors().adapt(context([[0.5]], PhiPPhi, np.zeros((1, 2, 2)),
                                                [[[1.0, 0.0]]], [[[1.0]]]))
    np.testing.assert_array_equal(adj.factors, [[1.0]])
    np.testing.assert_array_equal(adj.P_pred, PhiPPhi)


def test_a_zero_row_of_h_is_no_selection():
    """A measurement that measures no state (a zero row of H) is not H = [diag(s) 0] up to
    a selection: refused (with the row first and with another row on state 0)."""
    for H in ([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]):
        ctx = context([[1.0, 1.0]], [np.eye(3)], [np.zeros((3, 3))], [H], [np.eye(2)])
        with pytest.raises(ValueError, match="H = \\[diag"):
            MultipleFadingFactors().adapt(ctx)


def test_per_axis_factors_of_a_large_measurement():
    """m = 300 measurements of 300 states (H = I, J = I, Q = R = 0), e = 2 on each: C_1 =
    e e^T, N_ii = 4 -> every lambda_i = sqrt(4 / 1) = 2 and P_pred = L J L = 4 I. (More
    than 256: the selection check must compare its counts by value, not by identity.)"""
    m = 300
    ctx = context(np.full((1, m), 2.0), [np.eye(m)], np.zeros((1, m, m)), [np.eye(m)],
                  np.zeros((1, m, m)))
    adj = MultipleFadingFactors().adapt(ctx)
    np.testing.assert_allclose(adj.factors, np.full((1, m), 2.0), rtol=1e-15)
    np.testing.assert_allclose(adj.P_pred[0], 4.0 * np.eye(m), rtol=1e-15)


# ------------------------------------------- single fading factor: gate and warm-up ---

def test_a_nis_exactly_at_the_chi_square_quantile_is_no_outlier():
    """The gate flags a NIS above the chi-square quantile (p = 0.999, 1 dof: q = 10.83,
    from scipy's gammaincinv): e = 1 with S = 1/q gives a NIS of q to the last bit (not
    flagged); the next float above e is (flagged)."""
    q = 2.0 * gammaincinv(0.5, 0.999)
    S = np.array([[[1.0 / q]]] * 2)
    e = np.array([[1.0], [np.nextafter(1.0, 2.0)]])
    assert e[0, 0] * np.linalg.solve(S[0], e[0])[0] == q      # the NIS is q exactly
    z = np.zeros((2, 1, 1))
    ctx = AdaptationContext(innovation=e, valid=np.ones((2, 1), bool), S=S, P_xz=z,
                            PhiPPhi=z, Q=z, R=z, H=z)
    policy = SingleFadingFactor(outlier_probability=0.999)
    policy.reset(2)
    np.testing.assert_array_equal(policy._outliers(ctx, ctx.valid), [False, True])


def test_the_outlier_gate_does_not_read_the_missing_components_of_s():
    """A missing component's row and column of S (NaN here, as a sensor without a fix may
    report) are not read: z_1 missing, S_00 = 2, e_0^2 / 2 = 12 > 10.83 (1 dof, p =
    0.999): flagged, as with S = diag(2, anything)."""
    S = np.array([[[2.0, np.nan], [np.nan, np.nan]]])
    e = np.array([[np.sqrt(24.0), 0.0]])
    z = np.zeros((1, 2, 2))
    valid = np.array([[True, False]])
    ctx = AdaptationContext(innovation=e, valid=valid, S=S, P_xz=z, PhiPPhi=z, Q=z, R=z,
                            H=z)
    policy = SingleFadingFactor(outlier_probability=0.999)
    policy.reset(1)
    np.testing.assert_array_equal(policy._outliers(ctx, valid), [True])


def test_the_outlier_run_restarts_when_the_batch_shrinks():
    """After reset(3), a batch of two without a new reset (the filter's batch changed):
    the gate's run counter restarts at the new size; a 10-sigma innovation (NIS 100,
    S = 1) is gated in episode 0, a quiet one not in episode 1."""
    policy = SingleFadingFactor(outlier_probability=0.999)
    policy.reset(3)
    z = np.zeros((2, 1, 1))
    ctx = AdaptationContext(innovation=np.array([[10.0], [0.1]]),
                            valid=np.ones((2, 1), bool), S=np.ones((2, 1, 1)), P_xz=z,
                            PhiPPhi=z, Q=z, R=z, H=z)
    np.testing.assert_array_equal(policy._outliers(ctx, ctx.valid), [True, False])


def test_the_warm_up_ends_within_its_rounding_tolerance():
    """warm_up = 1 s counts as over from t = 1 s - 1e-9 s (the tolerance for a time summed
    in steps): there the hand example of test_adaptation fades (C_1 = 9, lambda = 8.4 / 2
    = 4.2); 1e-6 s earlier it does not (lambda = 1)."""
    def factor(t):
        policy = SingleFadingFactor(warm_up=1.0)
        policy.reset(1)
        ctx = context([[3.0]], [[[2.0, 0.5], [0.5, 1.0]]], [np.diag([0.1, 0.2])],
                      [[[1.0, 0.0]]], [[[0.5]]], t=t)
        return policy.adapt(ctx).factors[0, 0]
    assert factor(1.0 - 1e-9) == pytest.approx(4.2)
    assert factor(1.0 - 1e-6) == 1.0


# ----------------------------------------------------------- Yang's factors (5.5) -----

def test_adaptive_factor_below_half_of_c1():
    """(5.5), c0 = 1, c1 = 6, Delta = 2 (less than c1 / 2): (1/2)((6 - 2)/(6 - 1))^2 =
    0.32; Delta = 1.5: (1/1.5)(4.5/5)^2 = 0.54."""
    np.testing.assert_allclose(adaptive_factor([2.0, 1.5], 1.0, 6.0), [0.32, 0.54],
                               rtol=1e-12)


def test_adaptive_factor_is_zero_beyond_c1_before_its_clamp():
    """(5.5): alpha = 0 beyond c1; the clamp only raises it (to ``smallest``): with a clamp
    below zero alpha stays 0."""
    np.testing.assert_array_equal(adaptive_factor([4.0, 100.0], 1.0, 3.0, smallest=-1.0),
                                  [0.0, 0.0])


# ------------------------------------------------------------- IGG-III streak ---------

def rejection_run(policy, innovations):
    """Observation weights of component 0 over epochs of one moving episode (S = R = I,
    J = I, m = n = 2; component 1 quiet)."""
    out = []
    for e0 in innovations:
        ctx = context([[e0, 0.5]], [np.eye(2) - 0.5 * np.eye(2)], [0.5 * np.eye(2)],
                      [np.eye(2)], [np.eye(2)], S=[np.eye(2)], motion=np.array([True]),
                      directions=np.eye(2)[None])
        out.append(float(policy.adapt(ctx).factors[0, -2]))
    return out


@pytest.mark.parametrize("make", [RobustAdaptive, SelectiveWeights])
def test_a_streak_at_its_limit_restores_only_a_zero_weight(make):
    """(5.6) k0 = 2, k1 = 6: a 3-sigma residual has weight (2/3)(3/4)^2 = 0.375. The
    streak limit turns only a rejection (weight 0) into 1: max_rejections = 0 keeps 0.375
    at every epoch, and max_rejections = 1 keeps it after a rejection (10 sigma)."""
    assert rejection_run(make(max_rejections=0), [3.0, 3.0]) == [0.375, 0.375]
    assert rejection_run(make(max_rejections=0), [10.0, 3.0]) == [1.0, 0.375]
    assert rejection_run(make(max_rejections=1), [10.0, 3.0, 10.0, 10.0]) == \
        [0.0, 0.375, 0.0, 1.0]


# ------------------------------------------------------ selective weights (5.7-5.9) ---

def test_selective_weight_along_directions_without_a_zero_component():
    """(5.7)-(5.9), robust=False, n = 2, J = I: a measurement along u = (0.6, 0.8) (and
    along -u), misclosure 5 > m sigma = 2.5 -> w = 0.5, W^-1 = I + u u^T, P_pred =
    (I + u u^T)^2 = I + 3 u u^T = [[2.08, 1.44], [1.44, 2.92]]: variance 4 = (|L|/m)^2
    along u, 1 across it."""
    U = np.array([[[0.6, 0.8]], [[-0.6, -0.8]]])
    ctx = context([[5.0], [-5.0]], batch(0.9 * np.eye(2), 2), batch(0.1 * np.eye(2), 2),
                  U, batch([[0.01]], 2), motion=np.array([True, True]), directions=U)
    adj = SelectiveWeights(robust=False).adapt(ctx)
    np.testing.assert_allclose(adj.factors, [[0.5, 1.0]] * 2, rtol=1e-12)
    np.testing.assert_allclose(adj.P_pred, batch([[2.08, 1.44], [1.44, 2.92]], 2),
                               rtol=1e-12)
    u = U[:, 0]
    np.testing.assert_allclose(np.einsum("bi,bij,bj->b", u, adj.P_pred, u), 4.0,
                               rtol=1e-12)


def test_selective_weight_of_a_single_state_just_outside_m_sigma():
    """n = m = 1, J = 4 (sigma 2, m sigma = 5), direction +1 and -1: |L| = 6 -> w = 5/6,
    P_pred = 4 (6/5)^2 = 5.76 = (|L|/m)^2; |L| = 4.9 is inside: P_pred = 4."""
    U = np.array([[[1.0]], [[-1.0]], [[1.0]]])
    ctx = context([[6.0], [6.0], [4.9]], batch([[3.0]], 3), batch([[1.0]], 3), U,
                  batch([[0.01]], 3), motion=np.array([True] * 3), directions=U)
    adj = SelectiveWeights(robust=False).adapt(ctx)
    np.testing.assert_allclose(adj.factors[:, 0], [5 / 6, 5 / 6, 1.0], rtol=1e-12)
    np.testing.assert_allclose(adj.P_pred[:, 0, 0], [5.76, 5.76, 4.0], rtol=1e-12)


def test_selective_weights_of_three_measurements_report_six_factors():
    """m = 3 (n = 3, U = I, J = I, R = diag(16/9, 1, 1)), e = (5, 1, 0): state weight
    w_0 = 2.5 / 5 = 0.5; observation weights (5.6): e_0 / sqrt(S_00) = 5 / (5/3) = 3 ->
    0.375, the others 1. Factors: 3 state weights, then 3 observation weights."""
    U = np.eye(3)[None]
    policy = SelectiveWeights()
    policy.reset(1)
    adj = policy.adapt(context([[5.0, 1.0, 0.0]], [0.5 * np.eye(3)], [0.5 * np.eye(3)], U,
                               [np.diag([16 / 9, 1.0, 1.0])], motion=np.array([True]),
                               directions=U))
    np.testing.assert_allclose(adj.factors, [[0.5, 1, 1, 0.375, 1, 1]], rtol=1e-12)
    assert policy.n_factors == adj.factors.shape[1] == 6


def test_a_direction_variance_rounded_below_zero_keeps_weight_one_quietly():
    """u^T J u = -1e-17 (a zero variance rounded below zero): sigma is 0, the direction
    keeps weight 1 (the convention of test_adaptation_001) and P_pred = J, with no
    floating-point warning (a NaN sigma would raise one)."""
    J = np.diag([-1e-17, 1.0])
    U = np.array([[[1.0, 0.0]]])
    ctx = context([[1.0]], [J], [np.zeros((2, 2))], U, [[[1.0]]], motion=np.array([True]),
                  directions=U)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        adj = SelectiveWeights(robust=False).adapt(ctx)
    np.testing.assert_array_equal(adj.factors, [[1.0, 1.0]])
    np.testing.assert_array_equal(adj.P_pred, [J])


# ---------------------------------------------------------------- the contract --------

def test_an_agents_retune_is_an_immutable_record_taken_by_tune():
    """PolicyTuning(floor) is a frozen record: tune() raises the SAKF's floor to it (the
    hand example's lambda 4.2 becomes 5); a policy without fading factors refuses it."""
    tuning = PolicyTuning(floor=5.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        tuning.floor = 2.0
    policy = SingleFadingFactor()
    policy.tune(tuning)
    ctx = context([[3.0]], [[[2.0, 0.5], [0.5, 1.0]]], [np.diag([0.1, 0.2])],
                  [[[1.0, 0.0]]], [[[0.5]]])
    assert policy.adapt(ctx).factors[0, 0] == 5.0
    with pytest.raises(ValueError, match="no fading factors"):
        NoAdaptation().tune(tuning)


def test_a_scalar_floor_is_kept_as_a_number_and_a_per_episode_one_as_an_array():
    """retune(2) stores the floor as a Python float (as the constructor's); retune of one
    floor per episode stores a (B,) array."""
    policy = SingleFadingFactor()
    policy.retune(2)
    assert type(policy.floor) is float and policy.floor == 2.0
    policy.retune([1.0, 3.0])
    assert isinstance(policy.floor, np.ndarray) and policy.floor.shape == (2,)


def test_policies_without_model_needs_need_nothing():
    """``needs`` is a property: the policies that need nothing of the observation give the
    empty set (not a method)."""
    for policy in (NoAdaptation(), SingleFadingFactor(), MeasurementFadingFactor(),
                   RobustAdaptive()):
        assert policy.needs == frozenset()


def test_a_policy_must_define_adapt():
    """AdaptationPolicy is abstract in adapt: neither it nor a subclass without adapt can
    be made."""
    class Incomplete(AdaptationPolicy):
        pass
    for cls in (AdaptationPolicy, Incomplete):
        with pytest.raises(TypeError, match="abstract"):
            cls()


@pytest.mark.parametrize("make, message", [
    (lambda: RobustAdaptive(c0=1.0, c1=np.inf), "need 0 < c0 < c1 < inf"),
    (lambda: SelectiveWeights(k0=1.0, k1=np.inf), "need 0 < k0 < k1 < inf"),
    (lambda: SelectiveWeights(max_rejections=2.5), "max_rejections must be an integer"),
])
def test_thresholds_that_would_give_nan_weights_are_refused(make, message):
    """An infinite upper threshold made the IGG-III weights and the adaptive factor
    NaN (inf - x over inf - k0), silently; a fractional rejection count let one more
    rejection through than it says."""
    with pytest.raises(ValueError, match=message):
        make()
