"""Paper 001's robust-adaptive and selective-weight policies (estimators/robust_adaptive.py),
and the fading-factor machinery (estimators/fading_factors.py), against values computed
by hand from ALGORITHMS
section 5 ((5.3)-(5.9)), 003 eq. (50) and the chi-square quantiles: IGG-III weights and
the adaptive factor in each branch and at the thresholds, the equivalent noise, whole
``adapt`` calls on hand-built batches, the rejection streak, argument checks."""
import dataclasses

import numpy as np
import pytest

from aligngym.estimators.adaptation import AdaptationContext, NoAdaptation
from aligngym.estimators.fading_factors import (MeasurementFadingFactor, MultipleFadingFactors,
                                                SingleFadingFactor)
from aligngym.estimators.robust_adaptive import (RobustAdaptive, SelectiveWeights,
                                                 adaptive_factor, equivalent_noise,
                                                 igg3_weights)


def context(innovation, S, R, PhiPPhi, Q, H, valid=None, motion=None, directions=None,
            **kw):
    """An update's context from plain lists (B leading); valid defaults to all present."""
    e = np.asarray(innovation, float)
    H = np.asarray(H, float)
    J = np.asarray(PhiPPhi, float) + np.asarray(Q, float)
    return AdaptationContext(
        innovation=e, valid=np.ones(e.shape, bool) if valid is None else np.asarray(valid),
        S=np.asarray(S, float), P_xz=J @ np.swapaxes(H, -1, -2),
        PhiPPhi=np.asarray(PhiPPhi, float), Q=np.asarray(Q, float),
        R=np.asarray(R, float), H=H,
        motion=None if motion is None else np.asarray(motion, bool),
        directions=None if directions is None else np.asarray(directions, float), **kw)


def batch(a, b):
    """a (...) repeated over b episodes."""
    return np.repeat(np.asarray(a, float)[None], b, axis=0)


# ---------------------------------------------------------------- IGG-III, (5.6) ------

def test_igg3_weights_in_each_branch_with_psins_defaults():
    """(5.6) with k0 = 2, k1 = 6 (PSINS igg3's defaults): 1 up to and at k0;
    (k0/|v|)((k1 - |v|)/(k1 - k0))^2 between: 3 -> (2/3)(3/4)^2 = 0.375,
    4 -> (1/2)(1/2)^2 = 0.125, 5 -> (2/5)(1/4)^2 = 0.025; 0 at k1 and beyond; even in v."""
    v = np.array([0.0, 1.0, 2.0, -2.0, 3.0, -3.0, 4.0, 5.0, 6.0, 6.5, 100.0, np.inf])
    expected = [1, 1, 1, 1, 0.375, 0.375, 0.125, 0.025, 0, 0, 0, 0]
    np.testing.assert_allclose(igg3_weights(v, 2.0, 6.0), expected, rtol=1e-12, atol=0)


def test_igg3_weights_are_continuous_at_k0_and_k1_and_keep_the_shape():
    """The middle branch meets 1 at k0 and 0 at k1 (a continuous, decreasing weight), here
    for k0 = 1.5, k1 = 2.5 (ALGORITHMS' range): 2 -> (1.5/2)(0.5/1)^2 = 0.1875; a (B, m)
    array keeps its shape."""
    eps = 1e-9
    v = np.array([[1.5 + eps, 2.0], [2.5 - eps, -2.0]])
    w = igg3_weights(v, 1.5, 2.5)
    assert w.shape == (2, 2)
    np.testing.assert_allclose(w, [[1.0, 0.1875], [0.0, 0.1875]], atol=1e-8)
    grid = np.linspace(0.0, 3.0, 301)
    assert np.all(np.diff(igg3_weights(grid, 1.5, 2.5)) <= 0.0)


# ------------------------------------------------------- adaptive factor, (5.5) -------

def test_adaptive_factor_three_segments_with_the_default_thresholds():
    """(5.5), c0 = 1, c1 = 3: 1 up to and at c0; Delta = 2 -> (1/2)(1/2)^2 = 0.125,
    2.5 -> (1/2.5)(0.5/2)^2 = 0.025; 0 from c1 on, clamped at 1e-3 (ALGORITHMS 5.2)."""
    d = np.array([0.0, 0.5, 1.0, 2.0, 2.5, 3.0, 4.0, 1e6])
    np.testing.assert_allclose(adaptive_factor(d, 1.0, 3.0),
                               [1, 1, 1, 0.125, 0.025, 1e-3, 1e-3, 1e-3], rtol=1e-12)
    np.testing.assert_allclose(adaptive_factor(d, 1.0, 3.0, smallest=0.0),
                               [1, 1, 1, 0.125, 0.025, 0, 0, 0], rtol=1e-12, atol=0)


def test_adaptive_factor_with_other_thresholds():
    """c0 = 1.5, c1 = 4.5: Delta = 3 -> (1.5/3)(1.5/3)^2 = 0.125; a list is taken."""
    np.testing.assert_allclose(adaptive_factor([1.5, 3.0, 4.5], 1.5, 4.5, smallest=0.0),
                               [1.0, 0.125, 0.0], rtol=1e-12, atol=0)


# ------------------------------------------------------------ equivalent noise --------

def test_equivalent_noise_divides_the_variance_by_the_weight():
    """Sigma_bar_ii = Sigma_ii / w_i (5.6); the correlation coefficients of R are kept
    (R_bar = D R D); w = 0 keeps R (the component is rejected instead)."""
    R = batch([[4.0, 1.0], [1.0, 9.0]], 3)
    w = np.array([[0.25, 1.0], [1.0, 1.0], [0.0, 0.5]])
    R_bar = equivalent_noise(R, w)
    np.testing.assert_allclose(R_bar[0], [[16.0, 2.0], [2.0, 9.0]], rtol=1e-12)
    np.testing.assert_allclose(R_bar[1], R[1], rtol=1e-12)
    np.testing.assert_allclose(np.diagonal(R_bar[2]), [4.0, 18.0], rtol=1e-12)
    corr = lambda A: A[..., 0, 1] / np.sqrt(A[..., 0, 0] * A[..., 1, 1])  # noqa: E731
    np.testing.assert_allclose(corr(R_bar), corr(R), rtol=1e-12)


# ------------------------------------------------------- robust adaptive KF (5.2) -----

# n = 3, m = 2, H = [I 0]: J = PhiPPhi + Q, S = H J H^T + R = [[4, 0.7], [0.7, 9]].
RA_PP = [[2.0, 0.5, 0.3], [0.5, 7.0, 0.2], [0.3, 0.2, 4.0]]
RA_Q = np.diag([1.0, 1.0, 0.5])
RA_H = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
RA_R = [[1.0, 0.2], [0.2, 1.0]]
RA_S = [[4.0, 0.7], [0.7, 9.0]]


def test_robust_adaptive_step_by_hand():
    """RobustAdaptive() (c0 = 1, c1 = 3, k0 = 2, k1 = 6), six episodes, S_ii = 4, 9:
    0: e = (1, 1.5): residuals 0.5 sigma, Delta = sqrt(3.25/13) = 0.5: the KF.
    1: e = (6, 4): standardised (3, 4/3) -> w = (0.375, 1); Delta = sqrt(52/13) = 2 ->
       alpha = 0.125 (5.4-5.5): P_pred = J / alpha (5.3), R_bar = D R D, D = diag(w^-1/2).
    2: e = (14, 6): 7 sigma -> w_1 = 0, rejected; Delta from the kept one, sqrt(36/9) = 2.
    3: as 2 but still: the classic KF (001).
    4: second component missing, e_1 = 5: w_1 = (2/2.5)(3.5/4)^2 = 0.6125,
       Delta = sqrt(25/4) = 2.5 -> alpha = 0.025.
    5: nothing measured: the KF."""
    B = 6
    e = [[1.0, 1.5], [6.0, 4.0], [14.0, 6.0], [14.0, 6.0], [5.0, 0.0], [0.0, 0.0]]
    valid = [[True, True]] * 4 + [[True, False], [False, False]]
    motion = [True, True, True, False, True, True]
    ctx = context(e, batch(RA_S, B), batch(RA_R, B), batch(RA_PP, B), batch(RA_Q, B),
                  batch(RA_H, B), valid=valid, motion=motion)
    policy = RobustAdaptive()
    policy.reset(B)
    adj = policy.adapt(ctx)
    alpha = [1.0, 0.125, 0.125, 1.0, 0.025, 1.0]
    w = [[1, 1], [0.375, 1], [0, 1], [1, 1], [0.6125, 1], [1, 1]]
    np.testing.assert_allclose(adj.factors, np.column_stack([alpha, w]), rtol=1e-12)
    assert policy.n_factors == adj.factors.shape[1] == 3
    np.testing.assert_array_equal(adj.rejected, [[False, False], [False, False],
                                                 [True, False]] + [[False, False]] * 3)
    J = np.asarray(RA_PP) + RA_Q
    np.testing.assert_allclose(adj.P_pred, J / np.array(alpha)[:, None, None], rtol=1e-12)
    R = np.asarray(RA_R)
    d = 1.0 / np.sqrt(0.375)
    np.testing.assert_allclose(adj.R[1], [[d * d, 0.2 * d], [0.2 * d, 1.0]], rtol=1e-12)
    for b in (0, 2, 3, 5):          # weight 1 or rejected: R as modelled
        np.testing.assert_allclose(adj.R[b], R, rtol=1e-12)
    assert adj.R[4, 0, 0] == pytest.approx(1.0 / 0.6125)


def test_robust_adaptive_without_a_motion_flag_acts():
    """No motion flag: the policy acts (an episode is taken as moving): e = (6, 4) as in
    episode 1 above -> alpha = 0.125."""
    ctx = context([[6.0, 4.0]], [RA_S], [RA_R], [RA_PP], [RA_Q], [RA_H])
    adj = RobustAdaptive().adapt(ctx)
    np.testing.assert_allclose(adj.factors, [[0.125, 0.375, 1.0]], rtol=1e-12)


def rejection_run(policy, innovations, valid=None):
    """Observation weights of component 0 over epochs of one episode (S = I, m = 2)."""
    out = []
    for k, e0 in enumerate(innovations):
        ok = [[True, True]] if valid is None else [valid[k]]
        n = 2
        ctx = context([[e0, 0.5]], [np.eye(2)], [np.eye(2)], [np.eye(n)], [np.zeros((n, n))],
                      [np.eye(2)], valid=ok, motion=[True],
                      directions=[np.eye(2)])
        f = policy.adapt(ctx).factors
        out.append(float(f[0, -2]))
        assert f[0, -1] == 1.0           # the quiet component is never touched
    return out


@pytest.mark.parametrize("make", [RobustAdaptive, SelectiveWeights])
def test_a_persistent_misclosure_is_rejected_three_epochs_then_accepted(make):
    """max_rejections = 3 (default): a 10-sigma residual (IGG-III weight 0) is rejected at
    epochs 1-3, accepted with weight 1 at the 4th (the state's, not an outlier), and a new
    run starts after it; a missing epoch neither counts nor breaks the run; a quiet epoch
    breaks it."""
    policy = make()
    policy.reset(1)
    assert rejection_run(policy, [10.0] * 5) == [0, 0, 0, 1, 0]
    policy.reset(1)
    assert rejection_run(policy, [10.0, 10.0, 10.0, 10.0, 10.0],
                         valid=[[True, True], [True, True], [False, True], [True, True],
                                [True, True]]) == [0, 0, 1, 0, 1]
    policy.reset(1)
    assert rejection_run(policy, [10.0, 10.0, 0.1, 10.0, 10.0, 10.0, 10.0]) == \
        [0, 0, 1, 0, 0, 0, 1]


def test_rejection_limits_zero_and_one_and_a_change_of_measurement_size():
    """max_rejections = 0 never rejects; 1 alternates; a change of m restarts the count
    (both ways) without an error."""
    assert rejection_run(RobustAdaptive(max_rejections=0), [10.0] * 3) == [1, 1, 1]
    assert rejection_run(RobustAdaptive(max_rejections=1), [10.0] * 4) == [0, 1, 0, 1]
    policy = RobustAdaptive(max_rejections=2)
    assert rejection_run(policy, [10.0]) == [0]
    for m in (3, 1):
        ctx = context([[10.0] * m], [np.eye(m)], [np.eye(m)], [np.eye(3)],
                      [np.zeros((3, 3))], [np.eye(m, 3)], motion=[True])
        assert policy.adapt(ctx).factors[0, 1] == 0.0
    assert rejection_run(policy, [10.0] * 3) == [0, 0, 1]


# ----------------------------------------------------- selective weights (5.7-5.9) ----

# n = 4: a position state (measured by z_0) and a 2-D attitude block whose direction
# u = (0.6, 0.8) a heading measures (z_1). u^T J u = 0.64: sigma_u = 0.8; J_00 = 4.
SW_J = np.array([[4.0, 0.4, 0.2, -0.1], [0.4, 1.0, 0.1, 0.3],
                 [0.2, 0.1, 0.64, 0.0], [-0.1, 0.3, 0.0, 0.64]])
SW_Q = 0.1 * np.eye(4)
SW_U = np.array([[1.0, 0, 0, 0], [0, 0, 0.6, 0.8]])


def selective_context(e, R, valid=None, motion=None, directions=None):
    B = len(e)
    U = batch(SW_U, B) if directions is None else np.asarray(directions)
    H = batch(SW_U, B)
    S = H @ SW_J @ np.swapaxes(H, -1, -2) + np.asarray(R)
    return context(e, S, R, batch(SW_J - SW_Q, B), batch(SW_Q, B), H, valid=valid,
                   motion=motion, directions=U)


def test_selective_weights_step_by_hand():
    """m = 2.5 (001), thresholds m sigma = 5 (position) and 2 (heading), robust=False:
    0: |L_0| = 10 = 2 m sigma -> w_0 = 0.5: row and column 0 of J doubled (5.7-5.8).
    1: |L_1| = 4 -> w = 0.5 along u: W^-1 = R_u^T diag(1, 2) R_u on the attitude block
       (5.9, rows of R_u = (0.8, -0.6), u); the inflated sigma along u is |L|/m = 1.6.
    2: still: W = I (001).  3: z_0 missing: its misclosure is not read.
    4: (4.8, 1.9) just inside m sigma: W = I.
    5: z_1 without a state direction (zero row): no state weight however large."""
    e = [[10.0, 1.0], [1.0, -4.0], [10.0, -4.0], [10.0, 1.0], [4.8, 1.9], [1.0, 50.0]]
    valid = [[True, True]] * 3 + [[False, True]] + [[True, True]] * 2
    motion = [True, True, False, True, True, True]
    U = batch(SW_U, 6)
    U[5, 1] = 0.0
    policy = SelectiveWeights(robust=False)
    policy.reset(6)
    adj = policy.adapt(selective_context(e, batch(np.eye(2), 6), valid, motion, U))
    assert adj.R is None and not adj.rejected.any()
    w = [[0.5, 1], [1, 0.5], [1, 1], [1, 1], [1, 1], [1, 1]]
    np.testing.assert_allclose(adj.factors, np.hstack([w, np.ones((6, 2))]), rtol=1e-12)
    assert policy.n_factors == 4
    D = np.diag([2.0, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(adj.P_pred[0], D @ SW_J @ D, rtol=1e-12)
    Ru = np.array([[0.8, -0.6], [0.6, 0.8]])
    W_inv = np.eye(4)
    W_inv[2:, 2:] = Ru.T @ np.diag([1.0, 2.0]) @ Ru
    np.testing.assert_allclose(adj.P_pred[1], W_inv @ SW_J @ W_inv, rtol=1e-12)
    u = SW_U[1]
    assert 2.5 * np.sqrt(u @ adj.P_pred[1] @ u) == pytest.approx(4.0)
    for b in (2, 3, 4, 5):
        np.testing.assert_allclose(adj.P_pred[b], SW_J, rtol=1e-12)


def test_selective_weights_with_robust_observations_by_default():
    """SelectiveWeights() (m = 2.5, robust, k0 = 2, k1 = 6), R = diag(5, 0.36): S_ii = 9, 1.
    0: e = (9, 1): observation weights (0.375, 1) at 3 sigma (5.6), R_bar_00 = 5/0.375;
       state weight w_0 = 5/9 (5.8).
    1: e = (30, 1): 10 sigma, observation rejected, and it forms no state weight (001:
       the robust model's), P_pred = J.
    robust=False on the same: R as modelled, nothing rejected, w_0 = 5/30 in episode 1."""
    R = batch(np.diag([5.0, 0.36]), 2)
    ctx = selective_context([[9.0, 1.0], [30.0, 1.0]], R, motion=[True, True])
    adj = SelectiveWeights().adapt(ctx)
    np.testing.assert_allclose(adj.factors, [[5 / 9, 1, 0.375, 1], [1, 1, 0, 1]],
                               rtol=1e-12)
    np.testing.assert_array_equal(adj.rejected, [[False, False], [True, False]])
    np.testing.assert_allclose(adj.R[0], np.diag([5.0 / 0.375, 0.36]), rtol=1e-12)
    np.testing.assert_allclose(adj.R[1], R[1], rtol=1e-12)
    D = np.diag([9 / 5, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(adj.P_pred[0], D @ SW_J @ D, rtol=1e-12)
    np.testing.assert_allclose(adj.P_pred[1], SW_J, rtol=1e-12)
    plain = SelectiveWeights(robust=False).adapt(ctx)
    assert plain.R is None and not plain.rejected.any()
    np.testing.assert_allclose(plain.factors[1], [1 / 6, 1, 1, 1], rtol=1e-12)


def test_selective_weight_of_a_state_with_zero_variance_stays_finite():
    """A state known exactly (J_00 = 0) measured with misclosure 1: P_pred finite and the
    unmeasured state's variance (J_11 = 1) untouched. A chosen convention, not the limit:
    the direction keeps weight 1 (its variance stays 0), where sigma -> 0 would tend to
    (|L| / m)^2 = 0.16; before, 1 / w = inf made every state NaN."""
    U = np.array([[[1.0, 0.0]]])
    ctx = context([[1.0]], [[[1.0]]], [[[1.0]]], [np.diag([0.0, 1.0])], [np.zeros((2, 2))],
                  U, motion=[True], directions=U)
    adjusted = SelectiveWeights(robust=False).adapt(ctx)
    P = adjusted.P_pred
    assert np.all(np.isfinite(P)) and P[0, 1, 1] == 1.0
    assert adjusted.factors[0, 0] == 1.0


def test_selective_weights_need_directions():
    ctx = selective_context([[1.0, 1.0]], batch(np.eye(2), 1))
    ctx = dataclasses.replace(ctx, directions=None)
    with pytest.raises(ValueError, match="state directions"):
        SelectiveWeights().adapt(ctx)
    assert SelectiveWeights().needs == frozenset({"directions"})


# ------------------------------------------------------------- argument checks --------

@pytest.mark.parametrize("make, match", [
    (lambda: RobustAdaptive(k0=0.0), "0 < k0 < k1"),
    (lambda: RobustAdaptive(k0=-0.5, k1=1.0), "0 < k0 < k1"),
    (lambda: RobustAdaptive(k0=3.0, k1=3.0), "0 < k0 < k1"),
    (lambda: RobustAdaptive(k0=4.0, k1=3.0), "0 < k0 < k1"),
    (lambda: SelectiveWeights(k0=6.0, k1=2.0), "0 < k0 < k1"),
    (lambda: RobustAdaptive(max_rejections=-1), "max_rejections must be an integer >= 0"),
    (lambda: RobustAdaptive(c0=0.0), "0 < c0 < c1"),
    (lambda: RobustAdaptive(c0=-0.5, c1=3.0), "0 < c0 < c1"),
    (lambda: RobustAdaptive(c0=3.0, c1=3.0), "0 < c0 < c1"),
    (lambda: RobustAdaptive(c0=4.0, c1=3.0), "0 < c0 < c1"),
    (lambda: SelectiveWeights(m=0.0), "threshold m must be > 0"),
    (lambda: SelectiveWeights(m=-0.5), "threshold m must be > 0"),
    (lambda: SelectiveWeights(m=np.inf), "threshold m must be > 0"),
    (lambda: SelectiveWeights(m=np.nan), "threshold m must be > 0"),
    (lambda: SingleFadingFactor(rho=0.0), "rho must be in"),
    (lambda: SingleFadingFactor(rho=-0.5), "rho must be in"),
    (lambda: SingleFadingFactor(rho=1.5), "rho must be in"),
    (lambda: SingleFadingFactor(floor=0.0), "0 < floor <= cap"),
    (lambda: SingleFadingFactor(floor=-0.5), "0 < floor <= cap"),
    (lambda: SingleFadingFactor(floor=2.0, cap=1.5), "0 < floor <= cap"),
    (lambda: SingleFadingFactor(warm_up=-0.5), "warm_up must be >= 0"),
    (lambda: SingleFadingFactor(warm_up=np.inf), "warm_up must be >= 0"),
    (lambda: SingleFadingFactor(warm_up=np.nan), "warm_up must be >= 0"),
    (lambda: SingleFadingFactor(outlier_probability=0.5), "outlier_probability"),
    (lambda: SingleFadingFactor(outlier_probability=0.3), "outlier_probability"),
    (lambda: SingleFadingFactor(outlier_probability=1.2), "outlier_probability"),
    (lambda: SingleFadingFactor(outlier_run=0), "outlier_run must be an integer >= 1"),
    (lambda: MultipleFadingFactors(axes="body"), "valid: measurement, local-level"),
])
def test_bad_arguments_raise_one_line_errors(make, match):
    with pytest.raises(ValueError, match=match) as info:
        make()
    assert "\n" not in str(info.value)


def test_edge_arguments_are_accepted():
    """The open bounds: small positive thresholds, rho = 1, cap = floor, no warm-up or a
    long one, outlier_run = 1, max_rejections = 0."""
    RobustAdaptive(c0=0.5, c1=0.6, k0=0.5, k1=0.6, max_rejections=0)
    SelectiveWeights(m=0.5, k0=0.5, k1=0.6)
    SingleFadingFactor(rho=1.0, floor=0.5, cap=0.5, warm_up=0.0, outlier_run=1)
    SingleFadingFactor(warm_up=5.0, outlier_probability=0.51)


# ----------------------------------------------- single fading factor (SAKF, 2.x) -----
# The hand example of test_adaptation.py: n = 2, m = 1, H = [1 0]; e = 3 -> C_1 = 9,
# N = 9 - 0.1 - 0.5 = 8.4, M = H PhiPPhi H^T = 2, lambda = 4.2.
PP = [[2.0, 0.5], [0.5, 1.0]]
QQ = [[0.1, 0.0], [0.0, 0.2]]
HH = [[1.0, 0.0]]
RR = [[0.5]]
SS = [[2.6]]      # H (PhiPPhi + Q) H^T + R


def sakf_step(policy, e, B=1, S=SS, **kw):
    ctx = context(np.reshape(e, (B, 1)), batch(S, B), batch(RR, B), batch(PP, B),
                  batch(QQ, B), batch(HH, B), **kw)
    return policy.adapt(ctx)


def test_warm_up_holds_lambda_at_one_and_leaves_c_unstarted():
    """warm_up = 1 s: at t = 0.5 s a 10-sigma innovation gives lambda = 1 and is not
    taken into C; at t = ten steps of 0.1 s (1 s to rounding) the filter is warmed up and
    C starts at e e^T = 9: lambda = 4.2. The default t (0 s) is before any warm-up."""
    policy = SingleFadingFactor(warm_up=1.0)
    policy.reset(1)
    assert sakf_step(policy, 30.0, t=0.5).factors[0, 0] == 1.0
    adj = sakf_step(policy, 3.0, t=sum([0.1] * 10))
    assert adj.factors[0, 0] == pytest.approx(4.2)
    np.testing.assert_allclose(adj.P_pred[0], [[8.5, 2.1], [2.1, 4.4]])
    assert sakf_step(SingleFadingFactor(warm_up=0.5), 30.0).factors[0, 0] == 1.0


def test_in_motion_only_skips_a_still_carrier():
    """in_motion_only: a still episode keeps lambda = 1 and P_pred = PhiPPhi + Q, and its C
    does not start; the moving one fades (4.2). Next epoch, e = 2 in both: the first starts
    C = 4 (lambda = (4 - 0.6)/2 = 1.7), the second recurses C = (0.95 9 + 4)/1.95 (003
    eq. 50). Without in_motion_only, or with no motion flag, both fade."""
    policy = SingleFadingFactor(in_motion_only=True)
    policy.reset(2)
    adj = sakf_step(policy, [3.0, 3.0], B=2, motion=[False, True])
    np.testing.assert_allclose(adj.factors[:, 0], [1.0, 4.2])
    np.testing.assert_allclose(adj.P_pred[0], np.add(PP, QQ))
    adj = sakf_step(policy, [2.0, 2.0], B=2, motion=[True, True])
    C2 = (0.95 * 9.0 + 4.0) / 1.95
    np.testing.assert_allclose(adj.factors[:, 0], [1.7, (C2 - 0.6) / 2.0])
    adj = sakf_step(SingleFadingFactor(), [3.0, 3.0], B=2, motion=[False, True])
    np.testing.assert_allclose(adj.factors[:, 0], [4.2, 4.2])
    adj = sakf_step(SingleFadingFactor(in_motion_only=True), [3.0, 3.0], B=2)
    np.testing.assert_allclose(adj.factors[:, 0], [4.2, 4.2])


def test_beta_and_the_derivative_free_denominator():
    """beta = 2: N = 9 - 0.1 - 2 * 0.5 = 7.9, lambda = 3.95. derivative_free with a
    predicted measurement covariance wider than the linearised one (S = 3.6 instead of
    2.6): M = S - R - H Q H^T = 3 (ALGORITHMS 4.3, 000 eq. 58), lambda = 2.8; on the
    linear S it equals the linear lambda."""
    assert sakf_step(SingleFadingFactor(beta=2.0), 3.0).factors[0, 0] == pytest.approx(3.95)
    df = SingleFadingFactor(derivative_free=True)
    assert sakf_step(df, 3.0, S=[[3.6]]).factors[0, 0] == pytest.approx(2.8)
    assert sakf_step(SingleFadingFactor(derivative_free=True), 3.0).factors[0, 0] == \
        pytest.approx(4.2)


def test_outlier_test_counts_only_the_present_components():
    """p = 0.999: chi2 quantiles 10.83 (1 dof), 13.82 (2 dof); S = [[2, 1], [1, 2]].
    0: z_1 missing, e_0^2 / 2 = 12: flagged at 1 dof (not at 2).
    1: z_1 missing (a large value in its slot), e_0^2 / 2 = 10: not flagged (its missing
       slot and the correlation with it would push the NIS over 10.83).
    2: both present, NIS = 2 a^2 / 3 = 13: not flagged at 2 dof.
    Without a reset first (the batch size is new)."""
    policy = SingleFadingFactor(outlier_probability=0.999)
    S = batch([[2.0, 1.0], [1.0, 2.0]], 3)
    e = np.array([[np.sqrt(24.0), 50.0], [np.sqrt(20.0), 50.0],
                  [np.sqrt(19.5), np.sqrt(19.5)]])
    valid = np.array([[True, False], [True, False], [True, True]])
    z = np.zeros((3, 2, 2))
    ctx = AdaptationContext(innovation=e, valid=valid, S=S, P_xz=z, PhiPPhi=z, Q=z,
                            R=z, H=z)
    np.testing.assert_array_equal(policy._outliers(ctx, valid), [True, False, False])


def test_outlier_run_of_one_and_a_broken_run():
    """outlier_run = 1: the first 10-sigma innovation is gated, the second in a row fades
    (a change of state); a quiet epoch between two outliers restarts the run, so both are
    gated. A batch of two (the gate's mask is per episode)."""
    big = 10.0 * np.sqrt(2.6)
    policy = SingleFadingFactor(outlier_probability=0.999, outlier_run=1)
    policy.reset(2)
    first = sakf_step(policy, [big, 0.1], B=2).factors[:, 0]
    second = sakf_step(policy, [big, 0.1], B=2).factors[:, 0]
    assert first[0] == 1.0 and second[0] > 10.0
    policy = SingleFadingFactor(outlier_probability=0.999, outlier_run=1)
    policy.reset(2)
    gated = [sakf_step(policy, [x, 0.1], B=2).factors[0, 0] for x in (big, 0.1, big)]
    assert gated == [1.0, 1.0, 1.0]


# --------------------------------------------------- innovation covariance (003 50) ---

def test_innovation_covariance_recursion_restart_and_no_mask():
    """C_1 = e e^T, C_2 = (rho C_1 + e_2 e_2^T)/(1 + rho) with rho = 0.5, a (B, m) = (3, 2)
    batch without a valid mask; a change of m restarts C at e e^T (both ways)."""
    policy = SingleFadingFactor(rho=0.5)
    e1 = np.array([[1.0, 2.0], [0.0, 1.0], [3.0, -1.0]])
    e2 = np.array([[2.0, 0.0], [1.0, 1.0], [0.0, 0.0]])
    outer = lambda e: e[:, :, None] * e[:, None, :]  # noqa: E731
    np.testing.assert_allclose(policy.innovation_covariance(e1), outer(e1))
    np.testing.assert_allclose(policy.innovation_covariance(e2),
                               (0.5 * outer(e1) + outer(e2)) / 1.5)
    e3 = np.array([[1.0, 2.0, 3.0]] * 3)
    np.testing.assert_allclose(policy.innovation_covariance(e3), outer(e3))
    np.testing.assert_allclose(policy.innovation_covariance(e1), outer(e1))


# ----------------------------------------------- floors and per-axis factors ----------

def per_axis_step(policy, e, J_diag=(1.0, 1.0, 1.0, 1.0), H=None):
    """MAKF with Q = R = 0, J = diag: first-epoch factors lambda_i = |e_i| / sqrt(J_ii)
    (003 eq. 37: N = C_1 = e e^T), floored."""
    e = np.asarray(e, float)
    B, m = e.shape
    H = np.hstack([np.eye(m), np.zeros((m, 1))]) if H is None else np.asarray(H, float)
    n = H.shape[-1]
    ctx = context(e, batch(np.eye(m), B), batch(np.zeros((m, m)), B),
                  batch(np.diag(J_diag[:n]), B), batch(np.zeros((n, n)), B), batch(H, B))
    return policy.adapt(ctx)


def test_per_episode_floors_and_caps_over_per_axis_factors():
    """Factors (B, m) = (2, 3) of |e| = (2, 0.5, 1.5): floor 1 -> (2, 1, 1.5). An agent's
    per-episode floor (1, 3) lifts episode 1 to (3, 3, 3); a floor below 1 (0.25) lets a
    factor under 1 through (0.5); a cap of 1.8 is raised to a larger floor."""
    e = [[2.0, 0.5, 1.5]] * 2
    policy = MultipleFadingFactors()
    adj = per_axis_step(policy, e)
    np.testing.assert_allclose(adj.factors, [[2, 1, 1.5]] * 2)
    assert policy.n_factors == 3
    policy = MultipleFadingFactors()
    policy.retune([1.0, 3.0])
    np.testing.assert_allclose(per_axis_step(policy, e).factors, [[2, 1, 1.5], [3, 3, 3]])
    policy = MultipleFadingFactors()
    policy.retune(np.array([0.25, 1.0]))
    np.testing.assert_allclose(per_axis_step(policy, e).factors, [[2, 0.5, 1.5], [2, 1, 1.5]])
    policy = MultipleFadingFactors(cap=1.8)
    policy.retune([1.0, 3.0])
    np.testing.assert_allclose(per_axis_step(policy, e).factors, [[1.8, 1, 1.5], [3, 3, 3]])


def test_a_scalar_floor_and_a_floor_below_one_on_the_single_factor():
    """retune(0.5): tr N / tr M = (1.8 - 0.6)/2 = 0.6 stands (an agent may go below 1);
    retune(5) on cap 3 raises the cap: lambda = 5 (not 3)."""
    policy = SingleFadingFactor()
    policy.retune(0.5)
    assert sakf_step(policy, np.sqrt(1.8)).factors[0, 0] == pytest.approx(0.6)
    policy = SingleFadingFactor(cap=3.0)
    policy.retune(5)
    assert sakf_step(policy, 3.0).factors[0, 0] == 5.0


@pytest.mark.parametrize("floor", [0.0, -1.0, np.nan, np.inf, [1.0, 0.0],
                                   [[1.0, 2.0]]])
def test_retune_rejects_a_bad_floor(floor):
    with pytest.raises(ValueError, match="floor must be > 0"):
        SingleFadingFactor().retune(floor)


def test_per_axis_factor_edge_cases():
    """A state of zero predicted variance gets the floor (not NaN); a small N_ii below
    J_ii gives sqrt(N/J) < 1 with a low floor (0.5^2 / 1 -> 0.5); a scaled selection
    H = [-2 0 ...]: lambda = sqrt(N / (s^2 J)) (003 eq. 37) = 3 / 2; B = 2 != m = 1."""
    policy = MultipleFadingFactors(floor=0.1)
    adj = per_axis_step(policy, [[0.5, 3.0, 1.0]], J_diag=(1.0, 0.0, 1.0, 1.0))
    np.testing.assert_allclose(adj.factors, [[0.5, 0.1, 1.0]])
    assert np.all(np.isfinite(adj.P_pred))
    policy = MultipleFadingFactors()
    adj = per_axis_step(policy, [[3.0], [3.0]], H=[[-2.0, 0.0]])
    np.testing.assert_allclose(adj.factors, [[1.5], [1.5]])
    assert policy.n_factors == 1


def test_per_axis_factors_reject_repeated_states_and_local_level_misuse():
    """Two measurements of one state is no selection H; local-level factors need the axes
    and an unscaled H = [I 0] (scale 2 or 0.5 refused)."""
    with pytest.raises(ValueError, match="H = \\[diag"):
        per_axis_step(MultipleFadingFactors(), [[1.0, 1.0]], H=[[1.0, 0.0], [1.0, 0.0]])
    with pytest.raises(ValueError, match="need the observation's axes"):
        per_axis_step(MultipleFadingFactors(axes="local-level"), [[1.0]])
    for s in (2.0, 0.5):
        ctx = context([[1.0]], [[[1.0]]], [[[0.0]]], [np.eye(2)], [np.zeros((2, 2))],
                      [[[s, 0.0]]], axes=np.eye(1)[None])
        with pytest.raises(ValueError, match="H = \\[I 0\\]"):
            MultipleFadingFactors(axes="local-level").adapt(ctx)
    assert MultipleFadingFactors().needs == frozenset({"selection-H"})
    assert MultipleFadingFactors(axes="local-level").needs == frozenset(
        {"selection-H", "unit-selection-H", "axes"})


# -------------------------------------------------------------- the contract ----------

@pytest.mark.parametrize("make, width", [(NoAdaptation, 0), (SingleFadingFactor, 1),
                                         (MeasurementFadingFactor, 1)])
def test_a_fixed_width_policy_announces_its_width_before_the_first_update(make, width):
    """The filter sizes its factor record from n_factors at reset (filters.py), before any
    update: a policy with a fixed number of factors must announce it (SAKF and the R
    factor: one lambda; the KF: none)."""
    policy = make()
    assert policy.n_factors == width
    assert sakf_step(policy, [3.0, 1.0], B=2).factors.shape == (2, width)


def test_no_adaptation_reports_no_factors_and_the_context_is_frozen():
    """The KF: no factors, (B, 0) for B = 3 with m = 1, n = 2; a policy cannot write into
    the context it is given."""
    adj = sakf_step(NoAdaptation(), [1.0, 2.0, 3.0], B=3)
    assert adj.P_pred is None and adj.R is None and adj.factors.shape == (3, 0)
    assert NoAdaptation().n_factors == 0
    with pytest.raises(dataclasses.FrozenInstanceError):
        adj.factors = None
    ctx = context([[1.0]], [SS], [RR], [PP], [QQ], [HH])
    with pytest.raises(dataclasses.FrozenInstanceError):
        ctx.t = 1.0
