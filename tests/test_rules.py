"""Integration rules against the ALGORITHMS 3.2 oracles: points and weights, and the
moments of nonlinear maps against closed forms."""
import numpy as np
import pytest

from aligngym.estimators.model import GaussianMap
from aligngym.estimators.rules import (CubatureRule, GaussHermiteRule, LinearizationRule,
                              ReducedGaussHermiteRule, SparseGridGaussHermiteRule,
                              UnscentedRule, gauss_hermite_1d)

RULES = [UnscentedRule(), UnscentedRule(kappa=None), UnscentedRule(spread=1.5), CubatureRule(), GaussHermiteRule(3),
         SparseGridGaussHermiteRule(2), SparseGridGaussHermiteRule(3),
         SparseGridGaussHermiteRule(3, "linear"), SparseGridGaussHermiteRule(4)]


@pytest.mark.parametrize("rule", RULES, ids=lambda r: r.name)
@pytest.mark.parametrize("n", [2, 3, 5])
def test_weights_and_first_two_moments(rule, n):
    xi, wm, wc = rule.points(n)
    assert wm.sum() == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(wm @ xi, 0.0, atol=1e-12)
    np.testing.assert_allclose((wm[:, None] * xi).T @ xi, np.eye(n), atol=1e-11)


def test_gauss_hermite_1d_points_and_exactness():
    p, w = gauss_hermite_1d(3)
    np.testing.assert_allclose(p, [-np.sqrt(3), 0.0, np.sqrt(3)], atol=1e-14)
    np.testing.assert_allclose(w, [1 / 6, 2 / 3, 1 / 6], atol=1e-14)
    p, w = gauss_hermite_1d(5)
    np.testing.assert_allclose(np.sort(np.abs(p))[::2], [0.0, 1.355626, 2.856970], atol=1e-6)
    # Exact for x^k, k <= 2m - 1; wrong at 2m (N(0,1) moments: (k-1)!!).
    for m in (2, 3, 4):
        p, w = gauss_hermite_1d(m)
        moments = [w @ p ** k for k in range(2 * m + 1)]
        exact = [0.0 if k % 2 else float(np.prod(np.arange(k - 1, 0, -2))) for k in
                 range(2 * m + 1)]
        np.testing.assert_allclose(moments[: 2 * m], exact[: 2 * m], atol=1e-10)
        assert abs(moments[2 * m] - exact[2 * m]) > 1e-3


@pytest.mark.parametrize("n", [2, 3, 5, 10])
def test_sparse_grid_point_counts(n):
    # L = 2: 2n + 1, except n = 3 where the origin weight 1 - n/3 is exactly 0 (pruned).
    assert len(SparseGridGaussHermiteRule(2).points(n)[0]) == 2 * n + (n != 3)
    assert len(SparseGridGaussHermiteRule(3, "linear").points(n)[0]) == 2 * n * n + 2 * n + 1
    expected_odd = 2 * n * n + 4 * n + 1
    assert len(SparseGridGaussHermiteRule(3).points(n)[0]) == expected_odd


def test_sparse_grid_exact_for_total_degree_2L_minus_1():
    xi, w, _ = SparseGridGaussHermiteRule(3).points(4)  # exact to total degree 5
    assert w @ (xi[:, 0] ** 2 * xi[:, 1] ** 2) == pytest.approx(1.0, abs=1e-10)
    assert w @ xi[:, 2] ** 4 == pytest.approx(3.0, abs=1e-10)
    assert w @ (xi[:, 0] ** 3 * xi[:, 1] ** 2) == pytest.approx(0.0, abs=1e-10)
    xi, w, _ = SparseGridGaussHermiteRule(2).points(4)  # total degree 3 only
    assert abs(w @ (xi[:, 0] ** 2 * xi[:, 1] ** 2) - 1.0) > 0.1


def test_sparse_grid_level_2_is_the_ukf_with_kappa_3_minus_n():
    n = 6
    xs, ws, _ = SparseGridGaussHermiteRule(2).points(n)
    xu, wu, _ = UnscentedRule(alpha=1.0, beta=0.0, kappa=None).points(n)
    order_s = np.lexsort(xs.T)
    order_u = np.lexsort(xu.T)
    np.testing.assert_allclose(xs[order_s], xu[order_u], atol=1e-12)
    np.testing.assert_allclose(ws[order_s], wu[order_u], atol=1e-12)
    # n = 3: the origin weight is exactly zero and pruned: 2n points remain.
    assert len(SparseGridGaussHermiteRule(2).points(3)[0]) == 6


def test_unscented_covariance_weights_sum():
    for alpha, beta in ((1.0, 2.0), (0.5, 2.0), (1.0, 0.0)):
        _, _, wc = UnscentedRule(alpha, beta, 0.0).points(7)
        assert wc.sum() == pytest.approx(2 - alpha ** 2 + beta)


def test_tensor_gauss_hermite_refuses_infeasible_dimension():
    with pytest.raises(ValueError, match="sparse-grid"):
        GaussHermiteRule(3).points(16)




def nonlinear(fn, d, angles=()):
    return GaussianMap(noise=np.zeros((1, d, d)), fn=fn, angles=angles)


@pytest.mark.parametrize("rule", RULES + [LinearizationRule()], ids=lambda r: r.name)
def test_linear_map_given_as_a_function_is_exact_under_every_rule(rule):
    rng = np.random.default_rng(4)
    n, d = 5, 3
    M = rng.standard_normal((1, d, n))
    A = rng.standard_normal((1, n, n))
    P = A @ A.transpose(0, 2, 1) + np.eye(n)
    m = rng.standard_normal((1, n))
    fmap = nonlinear(lambda x: np.einsum("bij,bpj->bpi", M, x), d)
    y, Pyy, Pxy = rule.moments(fmap, m, P)
    np.testing.assert_allclose(y, np.einsum("bij,bj->bi", M, m), atol=1e-10)
    np.testing.assert_allclose(Pyy, M @ P @ M.transpose(0, 2, 1), atol=1e-10)
    np.testing.assert_allclose(Pxy, P @ M.transpose(0, 2, 1), atol=1e-10)


def sin_cos_moments(mu, s2):
    """Closed-form mean, covariance of [sin x, cos x] and Cov(x, .) for x ~ N(mu, s2)."""
    e1, e2 = np.exp(-s2 / 2), np.exp(-2 * s2)
    mean = e1 * np.array([np.sin(mu), np.cos(mu)])
    E_ss = 0.5 * (1 - e2 * np.cos(2 * mu))
    E_cc = 0.5 * (1 + e2 * np.cos(2 * mu))
    E_sc = 0.5 * e2 * np.sin(2 * mu)
    cov = np.array([[E_ss, E_sc], [E_sc, E_cc]]) - np.outer(mean, mean)
    cross = s2 * e1 * np.array([np.cos(mu), -np.sin(mu)])
    return mean, cov, cross


@pytest.mark.parametrize("rule", [GaussHermiteRule(20), SparseGridGaussHermiteRule(6)],
                         ids=lambda r: r.name)
def test_moments_of_sin_and_cos_of_a_gaussian_angle(rule):
    mu, s2 = 0.7, 0.8 ** 2
    fmap = nonlinear(lambda x: np.concatenate([np.sin(x), np.cos(x)], -1), 2)
    y, Pyy, Pxy = rule.moments(fmap, np.array([[mu]]), np.array([[[s2]]]))
    mean, cov, cross = sin_cos_moments(mu, s2)
    np.testing.assert_allclose(y[0], mean, atol=1e-9)
    np.testing.assert_allclose(Pyy[0], cov, atol=1e-9)
    np.testing.assert_allclose(Pxy[0, 0], cross, atol=1e-9)
    # The unscented transform is only approximate at this spread.
    y_ut, _, _ = UnscentedRule().moments(fmap, np.array([[mu]]), np.array([[[s2]]]))
    assert np.max(np.abs(y_ut[0] - mean)) > 1e-3


def test_moments_of_the_polar_to_cartesian_map():
    r0, th0, sr2, st2 = 10.0, 0.6, 0.5 ** 2, 0.3 ** 2
    fmap = nonlinear(lambda x: np.stack([x[..., 0] * np.cos(x[..., 1]),
                                         x[..., 0] * np.sin(x[..., 1])], -1), 2)
    y, Pyy, _ = GaussHermiteRule(12).moments(fmap, np.array([[r0, th0]]),
                                             np.diag([sr2, st2])[None])
    e1, e2 = np.exp(-st2 / 2), np.exp(-2 * st2)
    np.testing.assert_allclose(y[0], r0 * e1 * np.array([np.cos(th0), np.sin(th0)]),
                               rtol=1e-10)
    var_x = (r0 ** 2 + sr2) * 0.5 * (1 + e2 * np.cos(2 * th0)) - (r0 * e1 * np.cos(th0)) ** 2
    var_y = (r0 ** 2 + sr2) * 0.5 * (1 - e2 * np.cos(2 * th0)) - (r0 * e1 * np.sin(th0)) ** 2
    np.testing.assert_allclose(np.diag(Pyy[0]), [var_x, var_y], rtol=1e-10)


@pytest.mark.parametrize("m", [2, 3, 4])
def test_tensor_gauss_hermite_map_exact_to_degree_2m_minus_1_per_variable(m):
    """E[x1^a x2^b] for x ~ N(0, I): exact while a, b <= 2m - 1, wrong at 2m."""
    rule = GaussHermiteRule(m)
    k = 2 * m - 1 if (2 * m - 1) % 2 == 0 else 2 * m - 2  # largest even exponent <= 2m-1
    fmap = nonlinear(lambda x: (x[..., :1] ** k) * (x[..., 1:] ** k), 1)
    y, _, _ = rule.moments(fmap, np.zeros((1, 2)), np.eye(2)[None])
    double_factorial = float(np.prod(np.arange(k - 1, 0, -2)))
    assert y[0, 0] == pytest.approx(double_factorial ** 2, rel=1e-10)
    fmap = nonlinear(lambda x: x[..., :1] ** (2 * m), 1)
    y, _, _ = rule.moments(fmap, np.zeros((1, 2)), np.eye(2)[None])
    assert abs(y[0, 0] - float(np.prod(np.arange(2 * m - 1, 0, -2)))) > 1e-3


def test_sparse_grid_level_2_moments_equal_the_ukf_with_kappa_3_minus_n():
    rng = np.random.default_rng(9)
    n = 4
    A = rng.standard_normal((1, n, n))
    P = 0.1 * A @ A.transpose(0, 2, 1) + 0.1 * np.eye(n)
    fmap = nonlinear(lambda x: np.stack([np.sin(x[..., 0]) * x[..., 1],
                                         np.exp(0.3 * x[..., 2]) + x[..., 3] ** 3], -1), 2)
    m = rng.standard_normal((1, n))
    a = SparseGridGaussHermiteRule(2).moments(fmap, m, P)
    b = UnscentedRule(alpha=1.0, beta=0.0, kappa=None).moments(fmap, m, P)
    for u, v in zip(a, b):
        np.testing.assert_allclose(u, v, atol=1e-12)


def test_ekf_differs_from_the_ukf_by_the_second_order_term():
    """y = sin x, x ~ N(mu, s^2): E[y] - sin(mu) = -s^2/2 sin(mu) + O(s^4); the EKF mean
    is sin(mu), a sigma-point mean carries the second-order term."""
    mu, s = 1.1, 0.02
    fmap = nonlinear(np.sin, 1)
    args = (np.array([[mu]]), np.array([[[s * s]]]))
    ekf, _, _ = LinearizationRule().moments(fmap, *args)
    ukf, _, _ = UnscentedRule().moments(fmap, *args)
    assert ekf[0, 0] == pytest.approx(np.sin(mu), abs=1e-15)
    assert ukf[0, 0] - ekf[0, 0] == pytest.approx(-0.5 * s * s * np.sin(mu), rel=1e-3)


def test_angle_outputs_average_across_plus_minus_pi():
    """A heading near pi: points on both sides of the cut average to pi, not to 0."""
    fmap = nonlinear(lambda x: np.pi - np.mod(np.pi - x, 2 * np.pi), 1, angles=(0,))
    y, Pyy, _ = CubatureRule().moments(fmap, np.array([[np.pi - 0.01]]),
                                       np.array([[[0.05 ** 2]]]))
    assert abs(abs(y[0, 0]) - (np.pi - 0.01)) < 1e-12
    assert Pyy[0, 0, 0] == pytest.approx(0.05 ** 2, rel=1e-9)


def test_reduced_gauss_hermite_equals_the_full_tensor_rule():
    """ALGORITHMS 4.2 oracle: quadrature on zeta only, exact conditional moments of the
    rest, equals tensor GH with the same order in every dimension (exact in the
    conditionally linear states; zeta ordered first, as in both rules' Cholesky
    factor)."""
    rng = np.random.default_rng(11)
    n = 3

    def conditional(zeta):
        c, s = np.cos(zeta[..., 0]), np.sin(zeta[..., 0])
        F = np.zeros(zeta.shape[:-1] + (2, n))
        F[..., 0, 1], F[..., 0, 2], F[..., 1, 1], F[..., 1, 2] = c, s, -s, c
        F[..., 1, 0] = 0.5
        g = np.stack([1 - c, s], -1)
        return F, g

    def fn(x):
        F, g = conditional(x[..., :1])
        return np.einsum("bpij,bpj->bpi", F, x) + g

    fmap = GaussianMap(noise=np.zeros((1, 2, 2)), fn=fn, conditional=conditional,
                       nonlinear=(0,))
    A = rng.standard_normal((1, n, n))
    P = 0.3 * A @ A.transpose(0, 2, 1) + 0.2 * np.eye(n)
    m = rng.standard_normal((1, n))
    reduced = ReducedGaussHermiteRule(7).moments(fmap, m, P)
    full = GaussHermiteRule(7).moments(fmap, m, P)
    for u, v in zip(reduced, full):
        np.testing.assert_allclose(u, v, atol=1e-12)
    assert ReducedGaussHermiteRule(7).point_count(n, nonlinear=1) == 7
    assert GaussHermiteRule(7).point_count(n) == 7 ** 3


def test_unscented_spread_places_the_points_and_equals_its_kappa():
    """spread = n + kappa: the points at +-sqrt(spread) whatever n; for 004's 15 states
    spread 1.5 is kappa -13.5 exactly."""
    xi, wm, wc = UnscentedRule(spread=1.5).points(15)
    assert np.abs(xi).max() == pytest.approx(np.sqrt(1.5), rel=1e-14)
    xk, wmk, wck = UnscentedRule(kappa=-13.5).points(15)
    np.testing.assert_allclose(xi, xk, rtol=1e-14)
    np.testing.assert_allclose(wm, wmk, rtol=1e-14)
    np.testing.assert_allclose(wc, wck, rtol=1e-14)
    with pytest.raises(ValueError, match="spread n \\+ kappa must be > 0"):
        UnscentedRule(spread=0.0)


@pytest.mark.parametrize("rule", [CubatureRule(), GaussHermiteRule(2), UnscentedRule(),
                                  ReducedGaussHermiteRule(2), ReducedGaussHermiteRule(3)],
                         ids=lambda r: r.name)
def test_a_wide_angle_is_averaged_around_the_image_of_the_mean(rule):
    """An angle state with a wide prior (sigma 0.8 rad: the cubature points of 10 states
    reach +-2.5 rad, paper 002's large starts) under the identity map, a linear map on
    which every rule is exact: the mean is the prior's and the variance its sigma^2. A
    reference at an outer point (the cubature rule and even Gauss-Hermite orders have
    none at the mean) would wrap the opposite points by 2 pi: mean 1.2 rad off."""
    n = 10
    P = np.diag([0.8 ** 2] + [1e-4] * (n - 1))[None]
    m = np.zeros((1, n))
    m[0, 0] = 0.3

    def conditional(zeta):
        return np.broadcast_to(np.eye(n), zeta.shape[:-1] + (n, n)), np.zeros(
            zeta.shape[:-1] + (n,))

    fmap = GaussianMap(noise=np.zeros((1, n, n)), fn=lambda x: x.copy(), angles=(0,),
                       conditional=conditional, nonlinear=(0,))
    mean, cov, cross = rule.moments(fmap, m, P)
    np.testing.assert_allclose(mean, m, atol=1e-12)
    np.testing.assert_allclose(cov, P, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(cross, P, rtol=1e-9, atol=1e-15)
