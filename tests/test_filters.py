"""The generic Gaussian filter: an analytic linear case, batch independence, missing
measurements, guards, and the registry."""
import subprocess
import sys

import numpy as np
import pytest

from aligngym.estimators.filters import FILTERS, UnknownFilter, make_filter
from aligngym.estimators.model import Observation, Transition


def scalar_maps(batch=3, r=0.25):
    transition = Transition(noise=np.zeros((batch, 1, 1)), matrix=np.ones((batch, 1, 1)))

    def observe(z, t, R=None):
        return Observation(noise=np.full((batch, 1, 1), r) if R is None else R,
                           matrix=np.ones((batch, 1, 1)), z=z, t=t)
    return transition, observe


def test_kf_estimates_a_constant_like_the_weighted_mean():
    rng = np.random.default_rng(3)
    transition, observe = scalar_maps()
    z = 2.0 + 0.5 * rng.standard_normal((40, 3))
    f = make_filter("kf")
    f.reset(np.zeros((3, 1)), np.full((3, 1, 1), 4.0))
    for k in range(40):
        f.predict(transition)
        f.update(observe(z[k][:, None], float(k)))
    info = 1 / 4.0 + 40 / 0.25
    np.testing.assert_allclose(f.P[:, 0, 0], 1 / info, rtol=1e-12)
    np.testing.assert_allclose(f.x[:, 0], z.sum(0) / 0.25 / info, rtol=1e-12)


@pytest.mark.parametrize("name", ["kf", "ukf", "sakf"])
def test_missing_measurement_is_skipped_not_flagged(name):
    """A NaN measurement in the middle of an episode: no divergence flag, and the filter
    equals one that made no update at that epoch."""
    transition, observe = scalar_maps()
    f, g = make_filter(name), make_filter(name)
    for filt in (f, g):
        filt.reset(np.zeros((3, 1)), np.full((3, 1, 1), 4.0))
    for k in range(6):
        z = np.full((3, 1), 1.0 + 0.1 * k)
        gap = z.copy()
        if k == 2:
            gap[1, 0] = np.nan
        f.predict(transition)
        f.update(observe(gap, 10.0 + k))
        g.predict(transition)
        if k == 2:  # episode 1 skips this update: carry its prediction by hand
            x1, P1 = g.x[1].copy(), g._pending[0][1] + g._pending[1][1]
        g.update(observe(z, 10.0 + k))
        if k == 2:
            g.x[1], g.P[1] = x1, P1
    assert not f.health.diverged.any()
    np.testing.assert_allclose(f.x, g.x, rtol=1e-12)
    np.testing.assert_allclose(f.P, g.P, rtol=1e-12)


def test_partly_missing_measurement_uses_the_present_component():
    """z = [x, x] with the second component missing equals the one-component update."""
    B = 2
    transition = Transition(noise=np.zeros((B, 1, 1)), matrix=np.ones((B, 1, 1)))
    two = Observation(noise=np.broadcast_to(np.diag([0.5, 0.1]), (B, 2, 2)).copy(),
                      matrix=np.ones((B, 2, 1)), z=np.array([[1.0, np.nan], [1.0, np.nan]]))
    one = Observation(noise=np.full((B, 1, 1), 0.5), matrix=np.ones((B, 1, 1)),
                      z=np.ones((B, 1)))
    f, g = make_filter("kf"), make_filter("ckf")
    for filt, obs in ((f, two), (g, one)):
        filt.reset(np.zeros((B, 1)), np.full((B, 1, 1), 2.0))
        filt.predict(transition)
        filt.update(obs)
    np.testing.assert_allclose(f.x, g.x, rtol=1e-12)
    np.testing.assert_allclose(f.P, 2.0 * 0.5 / 2.5, rtol=1e-12)


def test_missing_component_of_a_nonlinear_measurement_leaves_the_update():
    """h(x) = [sin x0, x0 + x1] with one component missing per episode equals the
    update with that component removed (sigma-point moments, masked gain)."""
    x0 = np.array([[0.3, -0.2], [0.3, -0.2]])
    P0 = np.broadcast_to(np.diag([0.1, 0.2]), (2, 2, 2)).copy()
    R = np.broadcast_to(np.diag([0.01, 0.04]), (2, 2, 2)).copy()
    both = Observation(noise=R, fn=lambda x: np.stack(
        [np.sin(x[..., 0]), x[..., 0] + x[..., 1]], -1),
        z=np.array([[0.25, np.nan], [np.nan, 0.1]]))
    f = make_filter("ukf")
    f.reset(x0, P0)
    f.predict(Transition(noise=np.zeros((2, 2, 2)), matrix=np.broadcast_to(np.eye(2),
                                                                           (2, 2, 2))))
    f.update(both)
    assert not f.health.diverged.any()
    for b, (component, value) in enumerate(((0, 0.25), (1, 0.1))):
        one = Observation(noise=R[b:b + 1, component:component + 1, component:component + 1],
                          fn=lambda x, c=component: np.stack(
                              [np.sin(x[..., 0]), x[..., 0] + x[..., 1]], -1)[..., c:c + 1],
                          z=np.array([[value]]))
        g = make_filter("ukf")
        g.reset(x0[b:b + 1], P0[b:b + 1])
        g.predict(Transition(noise=np.zeros((1, 2, 2)), matrix=np.eye(2)[None]))
        g.update(one)
        # atol: P's exact zeros come out as round-off (1e-19) that differs by path
        np.testing.assert_allclose(f.x[b], g.x[0], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(f.P[b], g.P[0], rtol=1e-12, atol=1e-15)


def test_non_positive_definite_covariance_is_flagged_not_propagated():
    transition, observe = scalar_maps()
    R = np.full((3, 1, 1), 0.25)
    R[0] = -10.0  # S = P + R < 0 for episode 0
    f = make_filter("imakf")
    f.reset(np.zeros((3, 1)), np.full((3, 1, 1), 4.0))
    f.predict(transition)
    f.update(observe(np.ones((3, 1)), 1.0, R))
    assert list(f.health.diverged) == [True, False, False]
    assert "not positive definite" in f.health.reason[0]
    assert np.all(np.isfinite(f.P))


def test_nan_in_the_process_is_flagged():
    """A NaN reaching the state (e.g. from NaN sensor data) is numerical failure."""
    _, observe = scalar_maps()
    bad = Transition(noise=np.zeros((3, 1, 1)),
                     fn=lambda x: np.where(np.arange(3)[:, None, None] == 2, np.nan, x))
    f = make_filter("ukf")
    f.reset(np.zeros((3, 1)), np.full((3, 1, 1), 4.0))
    f.predict(bad)
    f.update(observe(np.ones((3, 1)), 5.0))
    assert list(f.health.diverged) == [False, False, True]


def test_registry_and_unknown_names():
    assert {"kf", "ekf", "sakf", "makf", "imakf", "ukf", "ckf"} <= set(FILTERS)
    assert make_filter("sghkf-4").rule.level == 4 and make_filter("ghkf-3").rule.order == 3
    with pytest.raises(UnknownFilter, match="known filters: ckf, ekf, imakf, imakf-n, imakf-r"):
        make_filter("ukf-typo")
    with pytest.raises(UnknownFilter, match="sparse-grid level must be an integer in"):
        make_filter("sghkf-0")
    with pytest.raises(UnknownFilter, match="Gauss-Hermite order must be an integer in"):
        make_filter("ghkf-x")


def test_cli_unknown_filter_lists_known_names(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "aligngym.scenarios.cli", "bench", "paper003",
                           "--filters", "kf,nope", "--episodes", "1", "--out", str(tmp_path)],
                          capture_output=True, text=True)
    assert proc.returncode != 0
    assert "unknown filter 'nope'; known filters: ckf, ekf" in proc.stderr
    assert "Traceback" not in proc.stderr
