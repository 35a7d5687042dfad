"""The Kalman loop's own paths against a Kalman filter written out here in numpy:
repeated prediction, what the update hands to the policies and records, an adapted
P_pred and R, rejected and missing components with a correlated R, angle wrapping, the
Joseph form at a near-perfect measurement, the unscented update written out by hand, and
each guard (one bad episode flagged at its time with its reason, the others unchanged)."""
import numpy as np
import pytest

from aligngym.estimators import filters as filters_module
from aligngym.estimators.adaptation import AdaptationPolicy, Adjustment, NoAdaptation
from aligngym.estimators.filters import FilterHealth, GaussianFilter
from aligngym.estimators.catalogue import make_filter
from aligngym.estimators.model import Observation, Transition
from aligngym.estimators.rules import LinearizationRule, UnscentedRule

B, N, M = 4, 3, 2
RNG = np.random.default_rng(41)
PHI = np.eye(N) + 0.1 * RNG.standard_normal((B, N, N))
Q = np.einsum("bij,bkj->bik", *(2 * [0.2 * RNG.standard_normal((B, N, N))])) + 0.01 * np.eye(N)
H = RNG.standard_normal((B, M, N))
R = np.array([[0.30, 0.12], [0.12, 0.20]]) * np.ones((B, 1, 1))   # correlated
X0 = RNG.standard_normal((B, N))
P0 = np.einsum("bij,bkj->bik", *(2 * [RNG.standard_normal((B, N, N))])) + 0.5 * np.eye(N)
Z = RNG.standard_normal((B, M))


def transition(fn: bool = False) -> Transition:
    if fn:
        return Transition(noise=Q.copy(), fn=lambda x: np.einsum("bij,b...j->b...i", PHI, x))
    return Transition(noise=Q.copy(), matrix=PHI.copy())


def observation(z=Z, fn: bool = False, noise=R, t: float = 1.0) -> Observation:
    z = np.array(z, float)
    if fn:
        return Observation(noise=noise.copy(), fn=lambda x: np.einsum("bij,b...j->b...i", H, x),
                           z=z, t=t)
    return Observation(noise=noise.copy(), matrix=H.copy(), z=z, t=t)


def kf_update(x, P, z, Hm=H, Rm=R):
    """The textbook update, one episode at a time, on the components of z present."""
    x_new, P_new = x.copy(), P.copy()
    for b in range(len(x)):
        keep = np.isfinite(z[b])
        Hb, Rb = Hm[b][keep], Rm[b][np.ix_(keep, keep)]
        S = Hb @ P[b] @ Hb.T + Rb
        K = P[b] @ Hb.T @ np.linalg.inv(S)
        x_new[b] = x[b] + K @ (z[b][keep] - Hb @ x[b])
        P_new[b] = (np.eye(N) - K @ Hb) @ P[b]
    return x_new, P_new


def predicted(P=P0, x=X0):
    return np.einsum("bij,bj->bi", PHI, x), PHI @ P @ np.swapaxes(PHI, -1, -2) + Q


class Recorder(AdaptationPolicy):
    """Records the context; optionally scales P_pred and R, or rejects components."""

    def __init__(self, p_scale=1.0, r_scale=1.0, rejected=None, p_pred=None):
        self.p_scale, self.r_scale, self.rejected, self.p_pred = p_scale, r_scale, rejected, p_pred
        self.seen = []

    def adapt(self, ctx):
        self.seen.append(ctx)
        p_pred = (self.p_pred if self.p_pred is not None
                  else self.p_scale * (ctx.PhiPPhi + ctx.Q))
        return Adjustment(p_pred, self.r_scale * ctx.R, np.zeros((ctx.R.shape[0], 0)),
                          self.rejected)


def run(rule=None, policy=None, z=Z, fn=False, predictions=1, joseph=True):
    f = GaussianFilter("test", rule or LinearizationRule(), policy or Recorder(), joseph)
    f.reset(X0, P0)
    for _ in range(predictions):
        f.predict(transition(fn))
    return f, f.update(observation(z, fn))


@pytest.mark.parametrize("fn", [False, True], ids=["matrix", "function"])
def test_two_predictions_without_an_update_propagate_twice(fn):
    x1, P1 = predicted()
    x2, P2 = predicted(P1, x1)
    f, report = run(rule=UnscentedRule() if fn else None, fn=fn, predictions=2)
    x, P = kf_update(x2, P2, Z)
    np.testing.assert_allclose(f.x, x, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(f.P, P, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("fn", [False, True], ids=["matrix", "function"])
def test_the_policy_and_the_record_see_the_unadapted_innovation_S_and_H(fn):
    policy = Recorder(p_scale=3.0, r_scale=2.0)
    f, report = run(rule=UnscentedRule() if fn else None, policy=policy, fn=fn)
    x_pred, P_pred = predicted()
    S = H @ P_pred @ np.swapaxes(H, -1, -2) + R
    innovation = Z - np.einsum("bij,bj->bi", H, x_pred)
    (ctx,) = policy.seen
    np.testing.assert_allclose(ctx.S, S, rtol=1e-9)
    np.testing.assert_allclose(ctx.H, H, rtol=1e-9)   # statistical linearisation is exact
    np.testing.assert_allclose(ctx.innovation, innovation, rtol=1e-9)
    np.testing.assert_allclose(report.unadapted_innovation, innovation, rtol=1e-9)
    np.testing.assert_allclose(report.unadapted_S, S, rtol=1e-9)
    # ... while the update used the adapted ones
    x, P = kf_update(x_pred, 3.0 * P_pred, Z, Rm=2.0 * R)
    np.testing.assert_allclose(f.x, x, rtol=1e-9)
    np.testing.assert_allclose(f.P, P, rtol=1e-9)
    np.testing.assert_allclose(report.S, 3.0 * S - 3.0 * R + 2.0 * R, rtol=1e-9)


def test_an_episode_without_measurements_is_not_adapted():
    z = Z.copy()
    z[1] = np.nan
    f, report = run(policy=Recorder(p_scale=3.0, r_scale=2.0), z=z)
    x_pred, P_pred = predicted()
    np.testing.assert_allclose(f.P[1], P_pred[1], rtol=1e-12)     # not 3 P_pred
    np.testing.assert_allclose(f.x[1], x_pred[1], rtol=1e-12)


@pytest.mark.parametrize("fn", [False, True], ids=["matrix", "function"])
def test_a_rejected_component_is_the_update_without_it(fn):
    rejected = np.zeros((B, M), bool)
    rejected[0, 1] = rejected[2, 0] = True
    f, report = run(rule=UnscentedRule() if fn else None, policy=Recorder(rejected=rejected), fn=fn)
    z = np.where(rejected, np.nan, Z)
    x, P = kf_update(*predicted(), z)
    np.testing.assert_allclose(f.x, x, rtol=1e-9)
    np.testing.assert_allclose(f.P, P, rtol=1e-9)
    assert report.innovation[0, 1] == report.innovation[2, 0] == 0.0
    assert not report.valid[0, 1] and not report.valid[2, 0] and report.valid[1].all()


@pytest.mark.parametrize("name", ["kf", "ukf", "ckf"])
def test_a_missing_component_with_a_correlated_R(name):
    """R has off-diagonal terms: the update uses R's block of the present components."""
    z = Z.copy()
    z[0, 0] = z[3, 1] = np.nan
    f = make_filter(name)
    f.reset(X0, P0)
    f.predict(transition(fn=name != "kf"))
    report = f.update(observation(z, fn=name != "kf"))
    x, P = kf_update(*predicted(), z)
    np.testing.assert_allclose(f.x, x, rtol=1e-9)
    np.testing.assert_allclose(f.P, P, rtol=1e-9, atol=1e-12)
    assert report.innovation[0, 0] == report.innovation[3, 1] == 0.0


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def test_angles_wrap_in_the_innovation_the_prediction_and_the_update():
    """Angle 0 of the state and of the measurement: near +-pi the differences wrap, and
    a near-perfect fix across +-pi brings the estimate to it, wrapped."""
    step = Transition(noise=np.full((1, 1, 1), 1e-4),
                      fn=lambda x: x + 0.2)             # 3.1 + 0.2 -> 3.3 - 2 pi
    f = make_filter("ukf")
    f.reset(np.array([[3.1]]), np.full((1, 1, 1), 1e-4), angles=(0,))
    f.predict(step)
    x_pred = 3.3 - 2 * np.pi
    np.testing.assert_allclose(f.x[0, 0], x_pred, rtol=1e-12)
    z = np.pi - 0.01
    report = f.update(Observation(noise=np.full((1, 1, 1), 1e-8), fn=lambda x: x, angles=(0,),
                         z=np.array([[z]])))
    innovation = z - x_pred - 2 * np.pi                  # -0.168 rad: the short way
    np.testing.assert_allclose(report.unadapted_innovation[0, 0], innovation, rtol=1e-9)
    gain = 2e-4 / (2e-4 + 1e-8)
    np.testing.assert_allclose(f.x[0, 0], wrap(x_pred + gain * innovation), rtol=1e-9)
    assert f.x[0, 0] > 3.0                               # across +-pi, wrapped


def test_the_joseph_form_keeps_a_near_perfect_measurement_positive_definite():
    """R = 1e-20 P: P+ = P R / (P + R) = 1e-20; P - K S K^T rounds to 0 (not positive
    definite), the Joseph form keeps (1 - K)^2 P + K^2 R = 1e-20."""
    f = make_filter("kf")
    f.reset(np.zeros((1, 1)), np.ones((1, 1, 1)))
    f.predict(Transition(noise=np.zeros((1, 1, 1)), matrix=np.ones((1, 1, 1))))
    f.update(Observation(noise=np.full((1, 1, 1), 1e-20), matrix=np.ones((1, 1, 1)),
                         z=np.ones((1, 1))))
    assert not f.health.diverged.any()
    np.testing.assert_allclose(f.P[0, 0, 0], 1e-20, rtol=1e-6)


def test_the_unscented_update_of_a_nonlinear_measurement_written_out():
    """h(x) = [sin x0, x0 x1] with the unscented points of alpha 1, beta 2, kappa 0
    (points at +-sqrt(n) columns of the Cholesky factor, W0 = 0, W0c = 2)."""
    x0, P = np.array([0.4, -0.7]), np.array([[0.09, 0.02], [0.02, 0.16]])
    Rn, z = np.diag([0.01, 0.02]), np.array([0.5, -0.2])
    h = lambda x: np.stack([np.sin(x[..., 0]), x[..., 0] * x[..., 1]], -1)
    L = np.linalg.cholesky(P)
    points = np.vstack([x0, x0 + np.sqrt(2) * L.T, x0 - np.sqrt(2) * L.T])
    wm = np.array([0.0] + 4 * [0.25])
    wc = np.array([2.0] + 4 * [0.25])
    y = h(points)
    y_bar = wm @ y
    S = (wc[:, None] * (y - y_bar)).T @ (y - y_bar) + Rn
    P_xz = (wc[:, None] * (points - x0)).T @ (y - y_bar)
    K = P_xz @ np.linalg.inv(S)
    f = make_filter("ukf")
    f.reset(x0[None], P[None])
    f.predict(Transition(noise=np.zeros((1, 2, 2)), matrix=np.eye(2)[None]))
    f.update(Observation(noise=Rn[None], fn=h, z=z[None]))
    np.testing.assert_allclose(f.x[0], x0 + K @ (z - y_bar), rtol=1e-12)
    np.testing.assert_allclose(f.P[0], P - K @ S @ K.T, rtol=1e-12)


# --- the guards: one bad episode is flagged at its time, the others are unchanged ---

def test_a_flag_keeps_the_first_time_and_reason():
    health = FilterHealth.healthy(3)
    health.flag(np.array([True, False, False]), 2.0, "first")
    health.flag(np.array([True, True, False]), 5.0, "second")
    assert list(health.diverged) == [True, True, False]
    assert list(health.time[:2]) == [2.0, 5.0] and np.isnan(health.time[2])
    assert health.reason == ["first", "second", ""]


def test_an_initial_covariance_not_positive_definite_is_flagged_at_zero():
    P = P0.copy()
    P[2] = -np.eye(N)
    f = make_filter("kf")
    f.reset(X0, P)
    assert list(f.health.diverged) == [False, False, True, False]
    assert f.health.time[2] == 0.0
    assert f.health.reason[2] == "initial covariance not positive definite"


def solo(name, b, fn, epochs=3):
    """Episode b run alone through the same epochs."""
    g = make_filter(name)
    g.reset(X0[b:b + 1], P0[b:b + 1])
    for k in range(epochs):
        g.predict(Transition(noise=Q[b:b + 1], matrix=PHI[b:b + 1]) if not fn else
                  Transition(noise=Q[b:b + 1], fn=lambda x: np.einsum(
                      "bij,b...j->b...i", PHI[b:b + 1], x)))
        g.update(Observation(noise=R[b:b + 1], z=Z[b:b + 1], t=1.0 + k, **(
            {"matrix": H[b:b + 1]} if not fn else
            {"fn": lambda x: np.einsum("bij,b...j->b...i", H[b:b + 1], x)})))
    return g


def assert_others_unchanged(f, name, bad, fn):
    for b in set(range(B)) - {bad}:
        g = solo(name, b, fn)
        np.testing.assert_allclose(f.x[b], g.x[0], rtol=1e-9)
        np.testing.assert_allclose(f.P[b], g.P[0], rtol=1e-9)


@pytest.mark.parametrize("name", ["kf", "ukf"])
def test_a_nan_prediction_is_flagged_and_frozen_the_others_go_on(name):
    fn = name == "ukf"
    f = make_filter(name)
    f.reset(X0, P0)
    for k in range(3):
        step = transition(fn)
        if k == 1:
            step.noise[1] = np.nan
        f.predict(step)
        f.update(observation(fn=fn, t=1.0 + k))
        if k == 0:
            P_before = f.P[1].copy()
        if k == 1:       # the prediction stands (P of the epoch before): then frozen
            frozen = f.x[1].copy()
    assert list(f.health.diverged) == [False, True, False, False]
    assert f.health.time[1] == 2.0
    assert f.health.reason[1] == "predicted state or covariance NaN/inf"
    np.testing.assert_array_equal(f.x[1], frozen)
    np.testing.assert_array_equal(f.P[1], P_before)
    assert_others_unchanged(f, name, 1, fn)


@pytest.mark.parametrize("name", ["kf", "ukf"])
def test_an_innovation_covariance_not_positive_definite_is_flagged(name):
    fn = name == "ukf"
    f = make_filter(name)
    f.reset(X0, P0)
    for k in range(3):
        f.predict(transition(fn))
        noise = R.copy()
        if k == 1:
            noise[3] = -1e3 * np.eye(M)
        f.update(observation(fn=fn, noise=noise, t=1.0 + k))
    assert list(f.health.diverged) == [False, False, False, True]
    assert (f.health.time[3], f.health.reason[3]) == (
        2.0, "innovation covariance not positive definite")
    assert_others_unchanged(f, name, 3, fn)


def test_an_innovation_covariance_singular_to_working_precision_is_flagged(monkeypatch):
    """solve_each reports episode 2 singular (a positive definite S that LU cannot
    factor): flagged, its gain zero, the others updated."""
    real = filters_module.solve_each

    def singular_two(A, Bm):
        X, solved = real(A, Bm)
        X[2], solved[2] = np.nan, False
        return X, solved
    monkeypatch.setattr(filters_module, "solve_each", singular_two)
    f, report = run(policy=Recorder())
    assert list(f.health.diverged) == [False, False, True, False]
    assert f.health.reason[2] == "innovation covariance singular"
    np.testing.assert_array_equal(f.x[2], predicted()[0][2])   # not updated
    np.testing.assert_array_equal(f.P[2], P0[2])
    x, P = kf_update(*predicted(), Z)
    keep = [0, 1, 3]
    np.testing.assert_allclose(f.x[keep], x[keep], rtol=1e-9)
    np.testing.assert_allclose(f.P[keep], P[keep], rtol=1e-9)


class WrongMoments(UnscentedRule):
    """A rule whose measurement moments are wrong for some episodes: P_zz a hundredth
    of the truth in episode 0 (P - P_xz S^-1 P_xz^T indefinite), E[z] NaN in episode 3
    with finite P_zz and P_xz (the state update NaN)."""

    def _moments(self, fmap, mean, cov):
        y, P_yy, P_xy = super()._moments(fmap, mean, cov)
        if isinstance(fmap, Observation):
            P_yy = P_yy.copy()
            P_yy[0] *= 0.01
            y = y.copy()
            y[3] = np.nan
        return y, P_yy, P_xy


def test_a_posterior_not_positive_definite_or_a_nan_state_is_flagged():
    noise = 1e-6 * np.eye(M) * np.ones((B, 1, 1))
    f = GaussianFilter("wrong", WrongMoments(), Recorder())
    f.reset(X0, P0)
    f.predict(transition(fn=True))
    f.update(observation(fn=True, noise=noise))
    assert list(f.health.diverged) == [True, False, False, True]
    assert f.health.reason[0] == f.health.reason[3] == (
        "covariance not positive definite or state NaN")
    np.testing.assert_allclose(f.x[[0, 3]], predicted()[0][[0, 3]], rtol=1e-14)  # not updated
    x, P = kf_update(*predicted(), Z, Rm=noise)
    np.testing.assert_allclose(f.x[1:3], x[1:3], rtol=1e-6)


class NegativeWeights(LinearizationRule):
    """A rule with negative weights whose predicted covariance of episode 1 is
    indefinite (one eigenvalue -1e-3)."""

    has_negative_weights = True

    def _moments(self, fmap, mean, cov):
        return super()._moments(fmap, mean, cov)

    def moments(self, fmap, mean, cov):
        y, P_yy, P_xy = super().moments(fmap, mean, cov)
        if isinstance(fmap, Transition):
            P_yy = P_yy.copy()
            vals, vecs = np.linalg.eigh(P_yy[1] + Q[1])
            vals[0] = -1e-3
            P_yy[1] = vecs @ np.diag(vals) @ vecs.T - Q[1]
        return y, P_yy, P_xy


class PositiveNegativeWeights(LinearizationRule):
    """A rule with negative weights whose predictions happen to be positive definite."""

    has_negative_weights = True


def test_an_indefinite_prediction_of_a_negative_weight_rule_is_floored_and_counted():
    f = GaussianFilter("negative", NegativeWeights(), NoAdaptation())
    f.reset(X0, P0)
    f.predict(transition())
    f.update(observation())
    assert not f.health.diverged.any()
    assert list(f.health.repairs) == [0, 1, 0, 0]
    x_pred, P_pred = predicted()
    vals, vecs = np.linalg.eigh(P_pred[1])
    vals[0] = -1e-3
    vals = np.maximum(vals, 1e-12 * np.trace(vecs @ np.diag(vals) @ vecs.T) / N)
    floored = vecs @ np.diag(vals) @ vecs.T
    x, P = kf_update(x_pred[1:2], floored[None], Z[1:2], H[1:2], R[1:2])
    np.testing.assert_allclose(f.x[1], x[0], rtol=1e-9)
    np.testing.assert_allclose(f.P[1], P[0], rtol=1e-7, atol=1e-12)


def test_an_adapted_prediction_nan_or_beyond_repair_is_flagged(monkeypatch):
    """The policy's P_pred is NaN in episode 0 and indefinite in 2; the floor is made
    to fail (identity) so that 2 stays indefinite."""
    p_pred = predicted()[1].copy()
    p_pred[0] = np.nan
    p_pred[2] = -np.eye(N)
    monkeypatch.setattr(filters_module, "floor_eigenvalues", lambda P: P)
    f = GaussianFilter("negative", PositiveNegativeWeights(), Recorder(p_pred=p_pred))
    f.reset(X0, P0)
    f.predict(transition())
    f.update(observation())
    assert list(f.health.diverged) == [True, False, True, False]
    assert f.health.reason[0] == "predicted covariance NaN/inf"
    assert f.health.reason[2] == "predicted covariance not positive definite"
    assert list(f.health.repairs) == [0, 0, 1, 0]


# --- mutation survivors: the union of needs, a batch-wide outage, a NaN state alone,
# --- a diverged episode's record, three components with one missing ---------------------

def test_filter_needs_is_the_union_when_rule_and_policy_need_the_same():
    from aligngym.estimators.fading_factors import MeasurementAxisFading
    from aligngym.estimators.catalogue import FILTERS, filter_needs, register_filter
    from aligngym.estimators.rules import CubatureRule

    class AxesCubature(CubatureRule):
        needs = frozenset({"axes"})
    register_filter("test-axes-twice", AxesCubature, MeasurementAxisFading, fading=True)
    try:
        assert filter_needs("test-axes-twice") == {"axes"}
    finally:
        FILTERS.pop("test-axes-twice")


@pytest.mark.parametrize("name", ["kf", "ukf"])
def test_an_outage_of_the_whole_batch_leaves_the_prediction(name):
    """Every component of every episode missing (a GNSS outage shared by the batch):
    no gain, x and P are the prediction's, nothing flagged."""
    fn = name == "ukf"
    f = make_filter(name)
    f.reset(X0, P0)
    f.predict(transition(fn))
    report = f.update(observation(np.full((B, M), np.nan), fn=fn))
    x_pred, P_pred = predicted()
    np.testing.assert_allclose(f.x, x_pred, rtol=1e-12)
    np.testing.assert_allclose(f.P, P_pred, rtol=1e-12)
    assert not f.health.diverged.any() and not report.valid.any()
    assert np.all(report.innovation == 0.0)


def test_a_nan_state_with_a_finite_covariance_is_flagged():
    f = make_filter("kf")
    f.reset(X0, P0)
    f.predict(transition())
    f.x[2, 0] = np.nan
    f.update(observation())
    assert list(f.health.diverged) == [False, False, True, False]
    assert f.health.reason[2] == "predicted state or covariance NaN/inf"
    x, P = kf_update(*predicted(), Z)
    keep = [0, 1, 3]
    np.testing.assert_allclose(f.x[keep], x[keep], rtol=1e-9)
    np.testing.assert_allclose(f.P[keep], P[keep], rtol=1e-9)


def test_a_diverged_episodes_record_is_inert():
    """Episode 2 diverged at reset: at a later update with a missing component, its
    recorded components are invalid and its innovation zero, not NaN."""
    P = P0.copy()
    P[2] = -np.eye(N)
    f = make_filter("kf")
    f.reset(X0, P)
    f.predict(transition())
    z = Z.copy()
    z[2, 1] = np.nan
    report = f.update(observation(z))
    assert not report.valid[2].any() and report.valid[[0, 1, 3]].all()
    assert np.all(report.innovation[2] == 0.0)


@pytest.mark.parametrize("name", ["kf", "ukf"])
def test_three_correlated_components_with_the_middle_one_missing(name):
    """R fully correlated over three components, the middle one missing in episode 1,
    the first and last in episode 3: the update is the textbook one on R's block of the
    present components (the cross terms with a missing one leave no trace)."""
    rng = np.random.default_rng(7)
    H3 = rng.standard_normal((B, 3, N))
    A = rng.standard_normal((3, 3))
    R3 = (A @ A.T + 0.5 * np.eye(3)) * np.ones((B, 1, 1))
    z = rng.standard_normal((B, 3))
    z[1, 1] = z[3, 0] = z[3, 2] = np.nan
    fn = name == "ukf"
    f = make_filter(name)
    f.reset(X0, P0)
    f.predict(transition(fn))
    f.update(Observation(noise=R3.copy(), z=z, t=1.0, **(
        {"fn": lambda x: np.einsum("bij,b...j->b...i", H3, x)} if fn else {"matrix": H3})))
    x, P = kf_update(*predicted(), z, H3, R3)
    np.testing.assert_allclose(f.x, x, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(f.P, P, rtol=1e-9, atol=1e-12)


def test_the_update_returns_what_it_computed_and_leaves_only_its_state():
    """The report: the posterior, the innovation and S the gain used (adapted), and the
    NIS of the unadapted innovation over the components present, written out here per
    episode; on the filter nothing but its state."""
    z = Z.copy()
    z[1, 0] = np.nan
    f, report = run(policy=Recorder(p_scale=3.0, r_scale=2.0), z=z)
    np.testing.assert_array_equal(report.x, f.x)
    np.testing.assert_array_equal(report.P, f.P)
    x_pred, P_pred = predicted()
    for b in range(B):
        keep = np.isfinite(z[b])
        Hb = H[b][keep]
        e = z[b][keep] - Hb @ x_pred[b]
        S = Hb @ P_pred[b] @ Hb.T + R[b][np.ix_(keep, keep)]
        np.testing.assert_allclose(report.nis[b], e @ np.linalg.solve(S, e), rtol=1e-9)
        assert report.nis_dof[b] == keep.sum()
        S_adapted = Hb @ (3.0 * P_pred[b]) @ Hb.T + 2.0 * R[b][np.ix_(keep, keep)]
        np.testing.assert_allclose(report.S[b][np.ix_(keep, keep)], S_adapted, rtol=1e-9)
    assert report.factors.shape == (B, 0)
    assert set(vars(f)) == {"name", "rule", "adaptation", "joseph", "x", "P", "angles",
                            "health", "_pending"}


def test_a_retune_is_an_input_of_the_update():
    """PolicyTuning given to update() is the policy retuned before it (one floor per
    episode, which the factors then respect); a policy without fading factors refuses
    it in one line."""
    from aligngym.estimators.adaptation import PolicyTuning
    floor = np.array([1.0, 4.0, 1.0, 9.0])
    given, before = make_filter("sakf"), make_filter("sakf")
    for f in (given, before):
        f.reset(X0, P0)
        f.predict(transition())
    report = given.update(observation(), tuning=PolicyTuning(floor=floor))
    before.adaptation.retune(floor)
    expected = before.update(observation())
    np.testing.assert_array_equal(given.x, before.x)
    np.testing.assert_array_equal(given.P, before.P)
    np.testing.assert_array_equal(report.factors, expected.factors)
    assert np.all(report.factors[:, 0] >= floor) and report.factors[3, 0] == 9.0
    kf = make_filter("kf")
    kf.reset(X0, P0)
    kf.predict(transition())
    with pytest.raises(ValueError, match="adaptation 'none' has no fading factors"):
        kf.update(observation(), tuning=PolicyTuning(floor=2.0))
