"""The integration rules' definitions against values computed here by hand (mutation
survivors of estimators/rules.py, issue 41): the defaults, the refused arguments, the
unscented points and weights for alpha != 1, which rules have negative weights, the
cross-covariance about a non-zero mean, an asymmetric user rule, the square root of a
covariance that is not positive definite, the reduced rule's point count."""
import numpy as np
import pytest

from aligngym.estimators import rules
from aligngym.estimators.model import GaussianMap
from aligngym.estimators.rules import (GaussHermiteRule, LinearizationRule,
                                       ReducedGaussHermiteRule, SigmaPointRule,
                                       SparseGridGaussHermiteRule, UnscentedRule)


def cubic(d=1):
    return GaussianMap(noise=np.zeros((1, d, d)), fn=lambda x: x ** 3)


def test_a_spread_below_one_is_a_valid_unscented_rule():
    """n + kappa in (0, 1]: points inside 1 sigma (a user's choice, valid)."""
    xi, _, _ = UnscentedRule(spread=0.5).points(4)
    np.testing.assert_allclose(np.abs(xi).max(), np.sqrt(0.5), rtol=1e-14)


def test_the_defaults():
    assert ReducedGaussHermiteRule(1).point_count(5) == 1          # order 1 is valid
    assert GaussHermiteRule().order == 3
    assert SparseGridGaussHermiteRule().level == 2
    assert ReducedGaussHermiteRule().order == 7
    assert LinearizationRule().point_count(10) == 1
    rule = UnscentedRule()
    assert (rule.alpha, rule.beta, rule.kappa, rule.spread) == (1.0, 2.0, 0.0, None)


@pytest.mark.parametrize("make, message", [
    (lambda: UnscentedRule(alpha=-0.5), "alpha must be > 0"),
    (lambda: UnscentedRule(alpha=0.0), "alpha must be > 0"),
    (lambda: UnscentedRule(spread=-1.0), "spread n \\+ kappa must be > 0"),
    (lambda: SparseGridGaussHermiteRule(level=0), "level must be >= 1"),
    (lambda: ReducedGaussHermiteRule(order=0), "order"),
    (lambda: ReducedGaussHermiteRule(order=-2), "order"),
    (lambda: rules.gauss_hermite_1d(0), "order must be >= 1"),
])
def test_bad_arguments_are_refused(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_unscented_points_and_weights_for_alpha_one_half():
    """n = 2, alpha 0.5, beta 2, kappa 1: lambda = 0.25 * 3 - 2 = -1.25, points at
    +-sqrt(0.75), W0 = -1.25 / 0.75, W0c = W0 + 1 - 0.25 + 2, Wj = 1 / 1.5."""
    xi, wm, wc = UnscentedRule(alpha=0.5, kappa=1.0).points(2)
    np.testing.assert_allclose(np.abs(xi[1:]).max(axis=1), np.sqrt(0.75), rtol=1e-14)
    np.testing.assert_allclose(wm, [-1.25 / 0.75] + [1 / 1.5] * 4, rtol=1e-14)
    np.testing.assert_allclose(wc, [-1.25 / 0.75 + 2.75] + [1 / 1.5] * 4, rtol=1e-14)


@pytest.mark.parametrize("rule, negative", [
    (UnscentedRule(), False), (UnscentedRule(kappa=1.0), False),
    (UnscentedRule(kappa=-1.0), True), (UnscentedRule(kappa=None), True),
    (UnscentedRule(alpha=0.5), True), (UnscentedRule(alpha=1.5), False),
    (UnscentedRule(spread=1.5), True), (SparseGridGaussHermiteRule(1), False),
    (SparseGridGaussHermiteRule(2), True), (SparseGridGaussHermiteRule(3), True),
    (GaussHermiteRule(3), False), (LinearizationRule(), False)])
def test_which_rules_have_negative_weights(rule, negative):
    """The flag that makes the filter floor an indefinite prediction: set where a weight
    can be negative (for the unscented rule in 10 states, the dimension of paper 002)."""
    assert rule.has_negative_weights is negative
    if isinstance(rule, SigmaPointRule) and not isinstance(rule, SparseGridGaussHermiteRule):
        _, wm, wc = rule.points(10)
        assert bool(min(wm.min(), wc.min()) < 0) == negative


def test_the_cross_covariance_about_a_non_zero_mean():
    """y = x^3, x ~ N(2, 0.5^2), the UKF (its centre's mean and covariance weights
    differ): Cov[x, y] = sum_k Wc_k (chi_k - m)(y_k - y_bar), written out."""
    m, s = 2.0, 0.5
    rule = UnscentedRule(alpha=0.5, kappa=1.0)
    xi, wm, wc = rule.points(1)
    chi = m + s * xi[:, 0]
    y = chi ** 3
    y_bar = wm @ y
    mean, cov, cross = rule.moments(cubic(), np.array([[m]]), np.array([[[s ** 2]]]))
    np.testing.assert_allclose(mean[0, 0], y_bar, rtol=1e-12)
    np.testing.assert_allclose(cov[0, 0, 0], wc @ (y - y_bar) ** 2, rtol=1e-12)
    np.testing.assert_allclose(cross[0, 0, 0], wc @ ((chi - m) * (y - y_bar)), rtol=1e-12)


class Skewed(SigmaPointRule):
    """A user's rule whose points are not symmetric: sqrt(2) (1, -1/2, -1/2), weights
    1/3 (mean 0, variance 1, third moment 1/sqrt(2))."""

    name = "skewed"

    def _points(self, n):
        return np.sqrt(2.0) * np.array([[1.0], [-0.5], [-0.5]]), np.full(3, 1 / 3)


def test_an_asymmetric_user_rule_places_its_points_where_it_says():
    """E[x^3] by the rule for x ~ N(m, s^2): m^3 + 3 m s^2 + s^3 sum w xi^3; a rule
    whose points were placed at m - s xi would give the opposite third moment."""
    m, s = 0.3, 2.0
    mean, _, _ = Skewed().moments(cubic(), np.array([[m]]), np.array([[[s ** 2]]]))
    third = np.sum(np.full(3, 1 / 3) * (np.sqrt(2.0) * np.array([1.0, -0.5, -0.5])) ** 3)
    np.testing.assert_allclose(mean[0, 0], m ** 3 + 3 * m * s ** 2 + s ** 3 * third,
                               rtol=1e-12)


def test_the_square_root_of_a_covariance_not_positive_definite():
    """A batch of 3 in 2 dimensions (B != n): episodes 0 and 1 positive definite get
    their Cholesky factor; episode 2 (eigenvalues 2 and -1; then with a NaN off the
    diagonal, read as 0) gets V sqrt(max(D, 0)): S S^T is the matrix with its negative
    eigenvalues floored at zero."""
    A = np.array([[0.5, 1.5], [1.5, 0.5]])            # eigenvalues 2, -1
    P = np.stack([np.array([[2.0, 0.3], [0.3, 1.0]]), np.eye(2) * 4.0, A])
    S = rules._sqrt_psd(P)
    np.testing.assert_allclose(S[0], np.linalg.cholesky(P[0]), rtol=1e-14)
    np.testing.assert_allclose(S[1], 2.0 * np.eye(2), rtol=1e-14)
    v = np.array([1.0, 1.0]) / np.sqrt(2.0)
    np.testing.assert_allclose(S[2] @ S[2].T, 2.0 * np.outer(v, v), atol=1e-12)
    P[2] = [[-1.0, np.nan], [np.nan, 1.0]]
    S = rules._sqrt_psd(P)[2]
    np.testing.assert_allclose(S @ S.T, np.diag([0.0, 1.0]), atol=1e-14)


def test_the_reduced_rule_counts_its_points_over_the_nonlinear_states():
    rule = ReducedGaussHermiteRule(7)
    assert rule.point_count(18) == 7                  # one nonlinear state by default
    assert rule.point_count(18, nonlinear=2) == 49
    assert rule.point_count(18, nonlinear=3) == 343


def test_the_reduced_rule_needs_both_the_conditional_form_and_the_nonlinear_states():
    n = 3
    x = np.zeros((1, n))
    P = np.eye(n)[None]

    def conditional(zeta):
        return (np.broadcast_to(np.eye(n), zeta.shape[:-1] + (n, n)),
                np.zeros(zeta.shape[:-1] + (n,)))
    for kwargs in ({"conditional": conditional}, {"nonlinear": (0,)}, {}):
        fmap = GaussianMap(noise=np.zeros((1, n, n)), fn=lambda v: v, **kwargs)
        with pytest.raises(ValueError, match="conditionally linear form"):
            ReducedGaussHermiteRule(3).moments(fmap, x, P)


def test_symmetric_is_the_mean_of_a_matrix_and_its_transpose():
    A = np.array([[[1.0, 2.0], [0.0, 3.0]], [[0.0, -1.0], [1.0, 0.0]]])
    np.testing.assert_array_equal(rules.symmetric(A), [[[1.0, 1.0], [1.0, 3.0]],
                                                       [[0.0, 0.0], [0.0, 0.0]]])


def test_the_ekfs_central_differences_default_to_a_small_step():
    """y = sin(x) at 0.3 with the default step: the Jacobian is cos(0.3) to 1e-9 (central
    differences of step h err by h^2 / 6)."""
    fmap = GaussianMap(noise=np.zeros((1, 1, 1)), fn=np.sin)
    _, cov, cross = LinearizationRule().moments(fmap, np.array([[0.3]]), np.array([[[1.0]]]))
    np.testing.assert_allclose(cross[0, 0, 0], np.cos(0.3), rtol=1e-9)


def test_a_rule_must_say_how_it_maps_a_function():
    class NoMoments(rules.IntegrationRule):
        name = "none"
    with pytest.raises(TypeError, match="abstract"):
        NoMoments()


@pytest.mark.parametrize("m, g", [(2.5, 0.1), (0.5, 0.8)])
@pytest.mark.parametrize("rule", [GaussHermiteRule(2), ReducedGaussHermiteRule(2),
                                  rules.CubatureRule()], ids=lambda r: r.name)
def test_an_angle_is_averaged_around_the_image_of_the_mean_not_of_the_state(rule, m, g):
    """y = x + g rad of an angle x ~ N(m, 1.8^2) in 1 of 3 states (rules without a point
    at the mean): mean m + g, variance 1.8^2. A reference elsewhere than the mean's
    image (the mean without its offset g, or less it, a point's image, 0) wraps a
    point by 2 pi."""
    n, s = 3, 1.8
    if isinstance(rule, rules.CubatureRule):
        s = 1.8 / np.sqrt(n)                       # its points at +-sqrt(3) sigma
    P = np.diag([s ** 2, 1e-4, 1e-4])[None]
    mean = np.array([[m, 0.0, 0.0]])
    offset = np.array([g, 0.0, 0.0])

    def conditional(zeta):
        return (np.broadcast_to(np.eye(n), zeta.shape[:-1] + (n, n)),
                np.broadcast_to(offset, zeta.shape[:-1] + (n,)))
    fmap = GaussianMap(noise=np.zeros((1, n, n)), fn=lambda x: x + offset, angles=(0,),
                       conditional=conditional, nonlinear=(0,))
    y, cov, cross = rule.moments(fmap, mean, P)
    np.testing.assert_allclose(y[0], mean[0] + offset, atol=1e-12)
    np.testing.assert_allclose(cov, P, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(cross, P, rtol=1e-9, atol=1e-15)
