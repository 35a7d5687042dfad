"""Every integration rule is exact on a linear-Gaussian model: the generic filter with
each rule of the catalogue (and the parametrised families), given the model as
functions (the non-linear update path: sigma points, statistical linearisation, P -
K S K^T) or as matrices (the linear path: the Joseph form), matches the closed-form
Kalman filter written here from the textbook equations to 1e-9 relative, epoch by epoch,
mean and covariance. Rules whose points cannot carry a covariance (one point: the
level-1 sparse grid, the order-1 Gauss-Hermite rule) are exact for the mean only and are
checked for that."""
import numpy as np
import pytest

from aligngym.estimators.adaptation import NoAdaptation
from aligngym.estimators.filters import GaussianFilter
from aligngym.estimators.catalogue import FILTERS, filter_entry
from aligngym.estimators.model import Observation, Transition
from aligngym.estimators.rules import (GaussHermiteRule, LinearizationRule,
                                       ReducedGaussHermiteRule, SparseGridGaussHermiteRule,
                                       UnscentedRule)

N, M, B, EPOCHS = 5, 3, 3, 8
NONLINEAR = (0, 2)
"""States the reduced-dimension rule integrates over (the rest it takes exactly)."""


def _catalogue_rules():
    """{name: rule factory}: every rule of the catalogue (its named filters, one per
    distinct rule, and the sghkf-L / ghkf-m families) and UKF variants besides."""
    rules = {}
    for name, entry in FILTERS.items():
        rule = entry.rule()
        rules.setdefault(rule.name, entry.rule)
    for name in ("sghkf-2", "sghkf-3", "sghkf-4", "sghkf-5", "ghkf-2", "ghkf-3"):
        rule = filter_entry(name).rule
        rules.setdefault(rule().name, rule)
    for factory in (lambda: UnscentedRule(alpha=0.5, beta=2.0, kappa=1.0),
                    lambda: UnscentedRule(kappa=-1.0), lambda: ReducedGaussHermiteRule(3),
                    lambda: SparseGridGaussHermiteRule(3, "linear")):
        rules.setdefault(factory().name, factory)
    return rules


RULES = _catalogue_rules()
MEAN_ONLY = {rule.name: rule for rule in (SparseGridGaussHermiteRule(1), GaussHermiteRule(1))}
"""The one-point rules (not in RULES): exact for the mean alone."""


@pytest.fixture(scope="module")
def model():
    """A random stable linear model: F, H, Q, R, x0, P0 and measurements z (EPOCHS, B, M)
    drawn from it."""
    rng = np.random.default_rng(41)
    F = np.eye(N) + 0.1 * rng.standard_normal((N, N))
    H = rng.standard_normal((M, N))
    A = rng.standard_normal((N, N))
    Q = 0.01 * (A @ A.T + N * np.eye(N))
    C = rng.standard_normal((M, M))
    R = 0.1 * (C @ C.T + M * np.eye(M))
    D = rng.standard_normal((N, N))
    P0 = D @ D.T + np.eye(N)
    x0 = rng.standard_normal((B, N))
    z = rng.standard_normal((EPOCHS, B, M)) * 2.0
    return F, H, Q, R, x0, P0, z


def closed_form(model):
    """The textbook Kalman filter, per episode: [(x (B, N), P (B, N, N))] per epoch."""
    F, H, Q, R, x0, P0, z = model
    out = []
    x, P = x0.copy(), np.broadcast_to(P0, (B, N, N)).copy()
    for k in range(EPOCHS):
        for b in range(B):
            xp = F @ x[b]
            Pp = F @ P[b] @ F.T + Q
            S = H @ Pp @ H.T + R
            K = np.linalg.solve(S, H @ Pp).T
            x[b] = xp + K @ (z[k, b] - H @ xp)
            P[b] = (np.eye(N) - K @ H) @ Pp
        out.append((x.copy(), 0.5 * (P + np.swapaxes(P, -1, -2))))
    return out


def maps(model, k, as_functions, jacobian=True):
    """The epoch's transition and observation, as matrices or as functions of the points
    (with their Jacobians, or without, so that the EKF differences them, and the
    conditionally linear form for the reduced-dimension rule)."""
    F, H, Q, R, _, _, z = model
    Fb, Hb = np.broadcast_to(F, (B, N, N)), np.broadcast_to(H, (B, M, N))
    Qb, Rb = np.broadcast_to(Q, (B, N, N)).copy(), np.broadcast_to(R, (B, M, M)).copy()
    if not as_functions:
        return (Transition(noise=Qb, matrix=Fb),
                Observation(noise=Rb, matrix=Hb, z=z[k], t=float(k + 1)))

    def linear(Mx):
        def fn(points):                                   # (B, P, n) -> (B, P, d)
            return np.einsum("ij,bpj->bpi", Mx, points)

        def conditional(zeta):                            # F(zeta) x + g(zeta)
            shape = zeta.shape[:2]
            return (np.broadcast_to(Mx, (*shape, *Mx.shape)),
                    np.zeros((*shape, Mx.shape[0])))
        def jac(mean):
            return np.broadcast_to(Mx, (mean.shape[0], *Mx.shape))
        return fn, conditional, jac if jacobian else None

    f_fn, f_cond, f_jac = linear(F)
    h_fn, h_cond, h_jac = linear(H)
    return (Transition(noise=Qb, fn=f_fn, jacobian=f_jac, conditional=f_cond,
                       nonlinear=NONLINEAR),
            Observation(noise=Rb, fn=h_fn, jacobian=h_jac, conditional=h_cond,
                        nonlinear=NONLINEAR, z=z[k], t=float(k + 1)))


@pytest.mark.parametrize("as_functions", [True, False], ids=["non-linear path",
                                                              "linear path"])
@pytest.mark.parametrize("rule", sorted(RULES), ids=str)
def test_every_rule_is_the_closed_form_kalman_filter_on_a_linear_model(model, rule,
                                                                        as_functions):
    run_against_the_closed_form(model, rule, as_functions, rtol=1e-9)


def test_the_ekf_by_central_differences_is_the_closed_form_to_their_rounding(model):
    """No Jacobian: differences with h = 1e-6 carry rounding eps |x| / h ~ 1e-10 into each
    Jacobian entry; over 8 epochs the filter stays within 1e-7 of the closed form."""
    run_against_the_closed_form(model, LinearizationRule().name, True, rtol=1e-7,
                                jacobian=False)


def run_against_the_closed_form(model, rule, as_functions, rtol, jacobian=True):
    x0, P0 = model[4], model[5]
    reference = closed_form(model)
    f = GaussianFilter(rule, RULES[rule](), NoAdaptation())
    f.reset(x0, np.broadcast_to(P0, (B, N, N)))
    for k in range(EPOCHS):
        transition, observation = maps(model, k, as_functions, jacobian)
        f.predict(transition)
        f.update(observation)
        x_ref, P_ref = reference[k]
        assert not f.health.diverged.any(), f.health.reason
        np.testing.assert_allclose(f.x, x_ref, rtol=rtol, atol=rtol * np.abs(x_ref).max())
        np.testing.assert_allclose(f.P, P_ref, rtol=rtol, atol=rtol * np.abs(P_ref).max())


@pytest.mark.parametrize("rule", sorted(MEAN_ONLY), ids=str)
def test_a_one_point_rule_carries_the_mean_and_no_covariance(model, rule):
    """One point at the mean: E[F x] exact, Cov[F x] zero (the map's spread is lost)."""
    F, H, Q, R, x0, P0, z = model
    transition, _ = maps(model, 0, True)
    mean, cov, cross = MEAN_ONLY[rule].moments(transition, x0,
                                               np.broadcast_to(P0, (B, N, N)))
    np.testing.assert_allclose(mean, x0 @ F.T, rtol=1e-12)
    np.testing.assert_allclose(cov, 0.0, atol=1e-12)
    np.testing.assert_allclose(cross, 0.0, atol=1e-12)


def test_the_catalogue_rules_are_all_here():
    """Every distinct rule of the catalogue is among those checked above."""
    names = {entry.rule().name for entry in FILTERS.values()}
    assert names <= set(RULES)
    assert len(RULES) >= 12
