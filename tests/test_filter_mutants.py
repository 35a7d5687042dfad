"""What the mutation run of estimators/filters.py (issue 41) showed untested, against
hand values and a Kalman update written out in numpy: the NIS is taken over the valid
components only and is NaN without one or for an episode not live; a missing
component's noise is never read, and the report gives it a unit row and column of S and
False in both valid masks; a diverged episode goes through the rule at x = 0, P = I."""
import numpy as np
import pytest

from aligngym.estimators.catalogue import make_filter
from aligngym.estimators.filters import normalised_innovation_squared
from aligngym.estimators.model import Observation, Transition

NAN = np.nan


def test_the_nis_is_over_the_valid_components_and_nan_without_one_or_not_live():
    """Episode 0: both components, e^T S^-1 e by hand. 1: the second component missing,
    with a nonzero innovation and a zero row and column of S there (S itself singular):
    e0^2 / S00. 2: no component: NaN, 0 degrees of freedom. 3: both components, episode
    not live: NaN."""
    S2 = np.array([[2.0, 0.5], [0.5, 1.0]])
    e = np.array([[1.0, -2.0], [3.0, 5.0], [0.0, 0.0], [1.0, 1.0]])
    S = np.stack([S2, np.diag([4.0, 0.0]), S2, S2])
    valid = np.array([[True, True], [True, False], [False, False], [True, True]])
    live = np.array([True, True, True, False])
    nis, dof = normalised_innovation_squared(e, S, valid, live)
    (a, b), (_, d) = S2
    e0, e1 = e[0]                    # e^T S^-1 e with the adjugate of S2
    by_hand = (d * e0 ** 2 - 2 * b * e0 * e1 + a * e1 ** 2) / (a * d - b * b)
    np.testing.assert_allclose(nis[:2], [by_hand, 9.0 / 4.0], rtol=1e-12)
    assert np.isnan(nis[2]) and np.isnan(nis[3])
    np.testing.assert_array_equal(dof, [2, 1, 0, 2])


B, N, M = 4, 2, 2
H = np.array([[1.0, 0.5], [0.0, 1.0]])
R = np.array([[0.3, 0.1], [0.1, 0.2]])
PHI = np.array([[1.0, 0.1], [0.0, 1.0]])
Q = 0.01 * np.eye(N)
X0 = np.array([[0.1, -0.2], [0.3, 0.0], [-0.1, 0.4], [0.2, 0.2]])
P0 = np.array([[[1.0, 0.2], [0.2, 0.5]]] * 3 + [-np.eye(N)])  # episode 3 diverges at reset
Z = np.array([[0.4, -0.1], [0.2, NAN], [NAN, NAN], [0.1, 0.3]])


@pytest.mark.parametrize("name", ["kf", "ukf"])
def test_a_missing_component_is_not_read_and_is_reported_unused(name):
    """The missing components' rows and columns of R are NaN (a receiver without a fix
    for them): the update is the textbook one on the present components; the report's S
    has unit rows and columns where unused (episode 2 has no component, episode 3
    diverged at reset: S = I); valid and unadapted_valid are the (B, m) masks of the
    components used; the NIS is the textbook one for episodes 0 and 1, NaN for 2 and 3."""
    noise = np.broadcast_to(R, (B, M, M)).copy()
    for b in range(B):
        gone = np.isnan(Z[b])
        noise[b][gone, :] = noise[b][:, gone] = NAN
    f = make_filter(name)
    f.reset(X0, P0)
    f.predict(Transition(noise=np.broadcast_to(Q, (B, N, N)).copy(),
                         matrix=np.broadcast_to(PHI, (B, N, N)).copy()))
    model = ({"matrix": np.broadcast_to(H, (B, M, N)).copy()} if name == "kf" else
             {"fn": lambda x: np.einsum("ij,b...j->b...i", H, x)})
    report = f.update(Observation(noise=noise, z=Z.copy(), t=1.0, **model))

    used = np.array([[True, True], [True, False], [False, False], [False, False]])
    assert not f.health.diverged[:3].any()
    for mask in (report.valid, report.unadapted_valid):
        assert mask.dtype == bool
        np.testing.assert_array_equal(mask, used)
    for b in range(3):
        x, P = PHI @ X0[b], PHI @ P0[b] @ PHI.T + Q
        keep = used[b]
        if keep.any():
            Hb, Rb = H[keep], R[np.ix_(keep, keep)]
            S = Hb @ P @ Hb.T + Rb
            e = Z[b][keep] - Hb @ x
            np.testing.assert_allclose(report.S[b][np.ix_(keep, keep)], S, rtol=1e-9)
            np.testing.assert_allclose(report.nis[b], e @ np.linalg.solve(S, e), rtol=1e-9)
            K = P @ Hb.T @ np.linalg.inv(S)
            x, P = x + K @ e, (np.eye(N) - K @ Hb) @ P
        else:
            assert np.isnan(report.nis[b])
        np.testing.assert_allclose(f.x[b], x, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(f.P[b], P, rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(report.S[b][~keep], np.eye(M)[~keep])
        np.testing.assert_array_equal(report.S[b][:, ~keep], np.eye(M)[:, ~keep])
    np.testing.assert_array_equal(report.S[3], np.eye(M))
    assert np.isnan(report.nis[3])
    np.testing.assert_array_equal(report.nis_dof, [2, 1, 0, 0])
    np.testing.assert_array_equal(f.x[3], X0[3])
    np.testing.assert_array_equal(f.P[3], P0[3])


def test_a_diverged_episode_goes_through_the_rule_at_zero_and_the_identity():
    """_harmless (what a rule sees of a diverged episode, so that its state cannot turn
    the batch's linear algebra into NaN): x = 0 and P = I there, the others as they are."""
    f = make_filter("kf")
    f.reset(X0, P0)
    x, P = f._harmless(f.x, f.P)
    np.testing.assert_array_equal(x, np.vstack([X0[:3], np.zeros((1, N))]))
    np.testing.assert_array_equal(P, np.concatenate([P0[:3], np.eye(N)[None]]))


def test_a_diverged_episode_stays_frozen_through_predictions_without_an_update():
    """Two predictions in a row (no update between): the live episode's P is
    Phi (Phi P Phi^T + Q) Phi^T + Q by hand; the episode diverged at reset (P = -I) keeps
    its P through both and the update."""
    f = make_filter("kf")
    f.reset(np.ones((2, 2)), np.stack([np.eye(2), -np.eye(2)]))
    assert list(f.health.diverged) == [False, True]
    step = Transition(noise=0.1 * np.tile(np.eye(2), (2, 1, 1)),
                      matrix=2.0 * np.tile(np.eye(2), (2, 1, 1)))
    f.predict(step)
    f.predict(step)
    f.update(Observation(noise=np.ones((2, 1, 1)), matrix=np.ones((2, 1, 2)),
                         z=np.ones((2, 1)), t=1.0))
    np.testing.assert_array_equal(f.P[1], -np.eye(2))
    P_pred = 4.0 * (4.0 * np.eye(2) + 0.1 * np.eye(2)) + 0.1 * np.eye(2)   # 16.5 I
    S = np.ones((1, 2)) @ P_pred @ np.ones((2, 1)) + 1.0
    K = P_pred @ np.ones((2, 1)) / S
    expected = (np.eye(2) - K @ np.ones((1, 2))) @ P_pred
    np.testing.assert_allclose(f.P[0], expected, rtol=1e-12)
