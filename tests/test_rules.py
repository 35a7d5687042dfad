"""Integration rules against the ALGORITHMS 3.2 oracles, and the linear-model equivalence
of every sigma-point filter with the KF."""
import numpy as np
import pytest

from estimators.filters import make_filter
from estimators.inertial_fine import run_fine_alignment
from estimators.rules import (CubatureRule, GaussHermiteRule, SparseGridGaussHermiteRule,
                              UnscentedRule, gauss_hermite_1d)

RULES = [UnscentedRule(), UnscentedRule(kappa=None), CubatureRule(), GaussHermiteRule(3),
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


@pytest.mark.parametrize("name", ["ukf", "ckf", "sghkf-2"])
def test_sigma_point_filters_reproduce_the_kf_on_the_linear_model(name):
    from scenarios.paper003 import Paper003Experiment, prepare_episode, start_attitude
    exp = Paper003Experiment(fine_duration=60.0)
    episode = prepare_episode(exp, 1)
    tuning = exp.tuning(exp.scenario_config())
    start = start_attitude([episode], np.array([0.01, -0.01, 0.05]))
    runs = {}
    for f in ("kf", name):
        runs[f] = run_fine_alignment(make_filter(f), episode.inputs, start, tuning,
                                     episode.lat, episode.h)
    np.testing.assert_allclose(runs[name].C_s_n, runs["kf"].C_s_n, atol=1e-10)
    np.testing.assert_allclose(runs[name].sigma_n, runs["kf"].sigma_n, rtol=1e-6)
