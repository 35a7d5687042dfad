"""The generic Gaussian filter: an analytic linear case, batch independence, missing
measurements, guards, and the registry."""
import subprocess
import sys

import numpy as np
import pytest

from aligngym.estimators.catalogue import FILTERS, UnknownFilter, make_filter
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


# --- the catalogue against its documented values (SPEC 5, ALGORITHMS 4.3, 004) ---

FADING = ["sakf", "makf", "imakf", "makf-n", "imakf-n", "sakf-r", "makf-r", "imakf-r",
          "sgkf", "sgkf-gated"]


@pytest.mark.parametrize("name", FADING)
def test_the_fading_filters_take_the_fading_options(name):
    policy = make_filter(name, rho=0.8, floor=1.5, cap=9.0).adaptation
    assert (policy.rho, policy.floor, policy.cap) == (0.8, 1.5, 9.0)


def test_the_other_filters_ignore_the_fading_options():
    assert type(make_filter("kf", rho=0.8).adaptation).__name__ == "NoAdaptation"


def test_the_strong_tracking_and_reduced_dimension_filters_as_documented():
    """000's SGKF: 7 GH points on the nonlinear states; the fading starts 60 s after the
    fine start (ALGORITHMS 4.3 step 7), derivative-free, only in motion; the gated
    variant skips innovations beyond chi-square 0.999."""
    for name in ("rdghkf", "sgkf", "sgkf-gated"):
        assert make_filter(name).rule.order == 7
    for name in ("sgkf", "sgkf-gated"):
        policy = make_filter(name).adaptation
        assert (policy.warm_up, policy.derivative_free, policy.in_motion_only) == (
            60.0, True, True)
    assert make_filter("sgkf-gated").adaptation.outlier_probability == 0.999
    assert make_filter("sgkf").adaptation.outlier_probability is None


def test_the_stukf_points_sit_at_sqrt_1_5_sigma():
    """004's STUKF on 15 states: n + kappa = 1.5 (points at 1.22 sigma)."""
    xi = make_filter("stukf").rule._weights(15)[0]
    np.testing.assert_allclose(np.abs(xi).max(), np.sqrt(1.5), rtol=1e-12)


@pytest.mark.parametrize("name, ok", [("sghkf-1", True), ("sghkf-6", True),
                                      ("sghkf-7", False), ("ghkf-1", True),
                                      ("ghkf-9", True), ("ghkf-0", False),
                                      ("ghkf-10", False)])
def test_the_level_and_order_ranges(name, ok):
    if ok:
        make_filter(name)
        return
    valid = "[1, 6]" if name.startswith("sghkf") else "[1, 9]"
    with pytest.raises(UnknownFilter) as info:
        make_filter(name)
    assert str(info.value).endswith(f"must be an integer in {valid}")   # plain, no quotes


def test_filter_needs_joins_the_rule_and_the_policy():
    from aligngym.estimators.catalogue import filter_needs, register_filter
    from aligngym.estimators.fading_factors import MeasurementAxisFading
    from aligngym.estimators.rules import ReducedGaussHermiteRule
    register_filter("test-both-needs", lambda: ReducedGaussHermiteRule(3),
                    MeasurementAxisFading, fading=True)
    try:
        assert filter_needs("test-both-needs") == {"conditionally-linear", "axes"}
    finally:
        FILTERS.pop("test-both-needs")


@pytest.mark.parametrize("name", ["", "has space", "a,b", "a:b", 3])
def test_register_filter_refuses_a_bad_name(name):
    from aligngym.estimators.catalogue import register_filter
    from aligngym.estimators.rules import CubatureRule
    with pytest.raises(ValueError, match="a non-empty name without spaces"):
        register_filter(name, CubatureRule)


@pytest.mark.parametrize("name", ["kf", "sghkf-9", "ghkf-x"])
def test_register_filter_refuses_a_built_in_name(name):
    from aligngym.estimators.catalogue import register_filter
    from aligngym.estimators.rules import CubatureRule
    with pytest.raises(ValueError, match="is a built-in filter"):
        register_filter(name, CubatureRule)


def test_register_filter_checks_its_factories_and_passes_rho_to_a_fading_one():
    from aligngym.estimators.catalogue import register_filter
    from aligngym.estimators.adaptation import NoAdaptation
    from aligngym.estimators.fading_factors import SingleFadingFactor
    from aligngym.estimators.rules import CubatureRule
    with pytest.raises(TypeError, match="must be factories"):
        register_filter("t-a", CubatureRule(), NoAdaptation)
    with pytest.raises(TypeError, match="must be factories"):
        register_filter("t-a", CubatureRule, NoAdaptation())
    with pytest.raises(TypeError, match=r"bad\(\) raised ZeroDivisionError"):
        def bad():
            return 1 / 0
        register_filter("t-a", bad)
    with pytest.raises(TypeError, match="returned NoAdaptation, not an IntegrationRule"):
        register_filter("t-a", NoAdaptation)
    with pytest.raises(TypeError, match=r"CubatureRule\(\) returned CubatureRule, not an Adapt"):
        register_filter("t-a", CubatureRule, CubatureRule)
    seen = {}

    def fading(**options):
        seen.update(options)
        return SingleFadingFactor(**options)
    try:
        entry = register_filter("t-fading", CubatureRule, fading, fading=True)
        assert seen == {"rho": 0.95} and entry.description == "user filter t-fading"
        assert make_filter("t-fading", rho=0.7).adaptation.rho == 0.7
        entry = register_filter("t-plain", CubatureRule, description="mine")
        assert (entry.description, entry.fading, entry.model) == ("mine", False, "")
        assert FILTERS["t-plain"] is entry
    finally:
        FILTERS.pop("t-fading", None), FILTERS.pop("t-plain", None)


def user_entry():
    from aligngym.estimators.catalogue import FilterEntry
    from aligngym.estimators.adaptation import NoAdaptation
    from aligngym.estimators.rules import CubatureRule
    return FilterEntry(CubatureRule, NoAdaptation, "an entry")


def user_rule():
    from aligngym.estimators.rules import CubatureRule
    return CubatureRule()


def user_class():
    from aligngym.estimators.rules import CubatureRule
    return CubatureRule


def user_raises():
    raise RuntimeError("broken")


def user_number():
    return 3


@pytest.mark.parametrize("factory, description", [
    ("user_entry", "an entry"), ("user_rule", "user filter test_filters:user_rule"),
    ("user_class", "user filter test_filters:user_class")])
def test_an_imported_filter(factory, description, monkeypatch):
    monkeypatch.syspath_prepend(str(__import__("pathlib").Path(__file__).parent))
    spec = f"test_filters:{factory}"
    try:
        f = make_filter(spec)
        assert type(f.rule).__name__ == "CubatureRule"
        assert FILTERS[spec].description == description
    finally:
        FILTERS.pop(spec, None)


@pytest.mark.parametrize("spec, message", [
    ("no_such_module_x:f", "cannot import 'f' from 'no_such_module_x'"),
    ("test_filters:no_such", "cannot import 'no_such' from 'test_filters'"),
    ("test_filters:user_raises", "user_raises() raised RuntimeError: broken"),
    ("test_filters:user_number", "must return a FilterEntry, an IntegrationRule or its "
                                 "class, not int")])
def test_an_imported_filter_that_fails_is_one_line(spec, message, monkeypatch):
    monkeypatch.syspath_prepend(str(__import__("pathlib").Path(__file__).parent))
    with pytest.raises(UnknownFilter) as info:
        make_filter(spec)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert spec not in FILTERS
