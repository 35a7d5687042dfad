"""Fading-factor policies against a hand-computed example and the ALGORITHMS 2.2 oracles."""
import numpy as np
import pytest

from aligngym.estimators.adaptation import AdaptationContext, NoAdaptation
from aligngym.estimators.fading_factors import (ImprovedMultipleFadingFactors,
                                                MultipleFadingFactors, SingleFadingFactor)
from aligngym.models.attitude import rot_z


def adapt(policy, PhiPPhi, Q, H, R, e, axes=None):
    """P_pred and factors of a policy for one update's context."""
    S = H @ (PhiPPhi + Q) @ np.swapaxes(H, -1, -2) + R
    ctx = AdaptationContext(innovation=e, valid=np.isfinite(e), S=S,
                            P_xz=(PhiPPhi + Q) @ np.swapaxes(H, -1, -2), PhiPPhi=PhiPPhi,
                            Q=Q, R=R, H=H, axes=axes)
    adjustment = policy.adapt(ctx)
    P = PhiPPhi + Q if adjustment.P_pred is None else adjustment.P_pred
    return P, adjustment.factors

# n = 2 states, m = 1 measurement, H = [1 0].
PhiPPhi = np.array([[[2.0, 0.5], [0.5, 1.0]]])
Q = np.array([[[0.1, 0.0], [0.0, 0.2]]])
H = np.array([[[1.0, 0.0]]])
R = np.array([[[0.5]]])
e = np.array([[3.0]])  # first innovation: C_1 = e e^T = 9


def test_single_fading_factor_by_hand():
    # N = 9 - 0.1 - 0.5 = 8.4, M = 2, lambda = 4.2
    P, lam = adapt(SingleFadingFactor(), PhiPPhi, Q, H, R, e)
    assert lam[0, 0] == pytest.approx(4.2)
    np.testing.assert_allclose(P[0], [[8.5, 2.1], [2.1, 4.4]])


def test_multiple_fading_factors_by_hand():
    # N' = 8.4, lambda_1 = sqrt(8.4 / 2) = sqrt(4.2); second state unfaded.
    P, lam = adapt(MultipleFadingFactors(), PhiPPhi, Q, H, R, e)
    assert lam[0, 0] == pytest.approx(np.sqrt(4.2))
    np.testing.assert_allclose(P[0], [[8.5, 0.5 * np.sqrt(4.2)], [0.5 * np.sqrt(4.2), 1.2]])


def test_improved_multiple_fading_factors_by_hand():
    # N = 9 - 0.5 = 8.5, J = PhiPPhi + Q = [[2.1, 0.5], [0.5, 1.2]], lambda = sqrt(8.5/2.1)
    policy = ImprovedMultipleFadingFactors()
    P, lam = adapt(policy, PhiPPhi, Q, H, R, e)
    lam1 = np.sqrt(8.5 / 2.1)
    assert lam[0, 0] == pytest.approx(lam1)
    np.testing.assert_allclose(P[0], [[8.5, 0.5 * lam1], [0.5 * lam1, 1.2]])
    # Second epoch: C_2 = (rho C_1 + e_2^2) / (1 + rho) = (0.95 * 9 + 1) / 1.95 (003 eq. 50).
    _, lam = adapt(policy, PhiPPhi, Q, H, R, np.array([[1.0]]))
    C2 = (0.95 * 9.0 + 1.0) / 1.95
    assert lam[0, 0] == pytest.approx(max(1.0, np.sqrt((C2 - 0.5) / 2.1)))


def random_spd(rng, b, n):
    A = rng.standard_normal((b, n, n))
    return A @ np.swapaxes(A, -1, -2) + n * np.eye(n)


def test_consistent_innovations_reproduce_the_kf():
    """Oracle 1: C_k = H J H^T + R exactly -> every factor is 1 and P_pred is the KF's."""
    rng = np.random.default_rng(0)
    n, m = 6, 3
    PP, Qm = random_spd(rng, 4, n), 0.1 * random_spd(rng, 4, n)
    Hm = np.broadcast_to(np.hstack([np.eye(m), np.zeros((m, n - m))]), (4, m, n))
    Rm = 0.5 * np.broadcast_to(np.eye(m), (4, m, m))
    kf, _ = adapt(NoAdaptation(), PP, Qm, Hm, Rm, np.zeros((4, m)))
    for policy, J in ((SingleFadingFactor(), None), (MultipleFadingFactors(), PP),
                      (ImprovedMultipleFadingFactors(), PP + Qm)):
        J = PP + Qm if J is None else J
        C = Hm @ J @ np.swapaxes(Hm, -1, -2) + Rm
        policy.innovation_covariance = lambda e, valid, C=C: C  # exact statistics
        P, lam = adapt(policy, PP, Qm, Hm, Rm, np.zeros((4, m)))
        np.testing.assert_allclose(lam, 1.0, atol=1e-12)
        np.testing.assert_allclose(P, kf, atol=1e-12)


def test_inflated_channel_gives_its_factor_and_leaves_the_rest():
    """Oracle 2 and 3: C_ii - R_ii = kappa^2 J_ii -> lambda_i = kappa; P_pred[m:, m:] = J."""
    rng = np.random.default_rng(1)
    n, m, kappa = 5, 2, 3.0
    PP, Qm = random_spd(rng, 1, n), 0.1 * random_spd(rng, 1, n)
    Hm = np.hstack([np.eye(m), np.zeros((m, n - m))])[None]
    Rm = 0.2 * np.eye(m)[None]
    policy = ImprovedMultipleFadingFactors()
    J = PP + Qm
    C = Hm @ J @ np.swapaxes(Hm, -1, -2) + Rm
    C[0, 0, 0] = Rm[0, 0, 0] + kappa ** 2 * J[0, 0, 0]
    policy.innovation_covariance = lambda e, valid: C
    P, lam = adapt(policy, PP, Qm, Hm, Rm, np.zeros((1, m)))
    np.testing.assert_allclose(lam[0], [kappa, 1.0])
    np.testing.assert_allclose(P[0, m:, m:], J[0, m:, m:])
    assert np.all(np.linalg.eigvalsh(P[0]) > 0)


def test_local_level_factors_rotate_with_the_measurement_axes():
    """Along the observation's axes U, the factors equal those of the problem expressed
    in U's axes."""
    rng = np.random.default_rng(2)
    n, m = 6, 3
    PP, Qm = random_spd(rng, 1, n), 0.1 * random_spd(rng, 1, n)
    Hm = np.hstack([np.eye(m), np.zeros((m, n - m))])[None]
    Rm = np.diag([0.1, 0.2, 0.3])[None]
    e = rng.standard_normal((1, m)) * 5
    U = rot_z(0.7)[None]
    T = np.eye(n)[None].copy()
    T[0, :m, :m] = U[0]
    P, lam = adapt(MultipleFadingFactors(axes="local-level"), PP, Qm, Hm, Rm, e, axes=U)
    # Same problem with the measured states rotated into U's axes, paper's formula.
    rotated = MultipleFadingFactors()
    Tt = np.swapaxes(T, -1, -2)
    P_rot, lam_rot = adapt(rotated, T @ PP @ Tt, T @ Qm @ Tt, Hm,
                           U @ Rm @ np.swapaxes(U, -1, -2), np.einsum("bij,bj->bi", U, e))
    np.testing.assert_allclose(lam, lam_rot)
    np.testing.assert_allclose(T @ P @ Tt, P_rot, atol=1e-12)


def test_multiple_factors_reject_a_general_H():
    with pytest.raises(ValueError, match="H = \\[diag"):
        adapt(MultipleFadingFactors(), PhiPPhi, Q, np.array([[[1.0, 1.0]]]), R, e)


def test_missing_measurement_keeps_the_innovation_statistics():
    """An episode whose measurement is missing keeps C_{k-1} (its factor does not move);
    an episode whose first measurement is missing starts C at its first one (C = e e^T,
    not e e^T / (1 + rho))."""
    PP2, Q2, H2, R2 = (np.repeat(a, 2, axis=0) for a in (PhiPPhi, Q, H, R))

    def step(policy, e, valid):
        ctx = AdaptationContext(innovation=np.where(valid, e, 0.0), valid=valid, S=R2,
                                P_xz=np.zeros((2, 2, 1)), PhiPPhi=PP2, Q=Q2, R=R2, H=H2)
        return policy.adapt(ctx).factors[:, 0]

    policy = SingleFadingFactor()
    policy.reset(2)
    first = step(policy, np.array([[3.0], [3.0]]), np.array([[True], [False]]))
    assert first[0] == pytest.approx(4.2)          # (9 - 0.1 - 0.5) / 2
    second = step(policy, np.array([[1.0], [3.0]]), np.array([[False], [True]]))
    assert second[0] == pytest.approx(first[0])    # kept C_1 = 9
    assert second[1] == pytest.approx(4.2)         # started at e e^T = 9
    third = step(policy, np.array([[1.0], [1.0]]), np.array([[True], [True]]))
    C2 = (0.95 * 9.0 + 1.0) / 1.95
    np.testing.assert_allclose(third, (C2 - 0.6) / 2.0)


def test_measurement_fading_factors_oracles():
    """ALGORITHMS 2.10-2.11: consistent innovations leave R alone; an axis whose
    innovation variance exceeds H J H^T by kappa^2 R (along E, N, U) gets R scaled by
    kappa^2 along that axis only; P_pred is never faded."""
    from aligngym.estimators.fading_factors import MeasurementAxisFading, MeasurementFadingFactor

    rng = np.random.default_rng(7)
    n, m, kappa = 6, 3, 2.0
    PP, Qm = random_spd(rng, 1, n), 0.1 * random_spd(rng, 1, n)
    Hm = np.hstack([np.eye(m), np.zeros((m, n - m))])[None]
    Rm = np.diag([0.1, 0.2, 0.3])[None]
    U = rot_z(0.4)[None] @ np.array([[[1.0, 0, 0], [0, np.cos(0.3), -np.sin(0.3)],
                                      [0, np.sin(0.3), np.cos(0.3)]]])
    J = PP + Qm
    HJH = Hm @ J @ np.swapaxes(Hm, -1, -2)
    Ut = np.swapaxes(U, -1, -2)
    for inflate in (None, 1):
        C = HJH + Rm
        if inflate is not None:  # add (kappa^2 - 1) R^n_jj along local axis j
            e_j = Ut[:, :, inflate]
            R_n = U @ Rm @ Ut
            C = C + (kappa ** 2 - 1) * R_n[0, inflate, inflate] * e_j[..., :, None] * e_j[..., None, :]
        policy = MeasurementAxisFading()
        policy.innovation_covariance = lambda e, valid, C=C: C
        ctx = AdaptationContext(innovation=np.zeros((1, m)), valid=np.ones((1, m), bool),
                                S=C, P_xz=J @ np.swapaxes(Hm, -1, -2), PhiPPhi=PP, Q=Qm,
                                R=Rm, H=Hm, axes=U)
        adj = policy.adapt(ctx)
        assert adj.P_pred is None
        expected = np.ones(3) if inflate is None else np.array([1.0, kappa ** 2, 1.0])
        np.testing.assert_allclose(adj.factors[0], expected, rtol=1e-10)
        R_n, Rk_n = U @ Rm @ Ut, U @ adj.R @ Ut
        scale = np.sqrt(expected)
        np.testing.assert_allclose(Rk_n[0], scale[:, None] * R_n[0] * scale[None, :],
                                   rtol=1e-10, atol=1e-14)
    # Single factor on R, by hand: C_1 = 9, H J H^T = 2.1, tr R = 0.5 -> 13.8.
    policy = MeasurementFadingFactor()
    ctx = AdaptationContext(innovation=e, valid=np.isfinite(e), S=R, P_xz=PhiPPhi[:, :, :1],
                            PhiPPhi=PhiPPhi, Q=Q, R=R, H=H)
    adj = policy.adapt(ctx)
    assert adj.factors[0, 0] == pytest.approx((9.0 - 2.1) / 0.5)
    assert adj.P_pred is None
    np.testing.assert_allclose(adj.R, adj.factors[0, 0] * R)


def test_gated_strong_tracking_skips_an_outlier_and_fades_at_a_change_of_state():
    """outlier_probability 0.999 (1 dof: NIS > 10.83): a 10-sigma innovation (NIS 100)
    once is a sensor's outlier: lambda = 1 and C_k untouched, so the next quiet epoch is
    unfaded too (the ungated factor fires at it and carries it on); three in a row are a
    change of state, and the third fades (outlier_run 2)."""
    S = H @ (PhiPPhi + Q) @ np.swapaxes(H, -1, -2) + R        # 2.6
    quiet, big = np.array([[0.1]]), np.array([[10.0 * np.sqrt(S[0, 0, 0])]])

    def run(policy, innovations):
        policy.reset(1)
        return [adapt(policy, PhiPPhi, Q, H, R, e_k)[1][0, 0] for e_k in innovations]

    plain = run(SingleFadingFactor(), [quiet, big, quiet])
    gated = run(SingleFadingFactor(outlier_probability=0.999), [quiet, big, quiet])
    assert plain[1] > 10.0 and plain[2] > 1.0      # the outlier fades, and C_k carries it on
    assert gated == [1.0, 1.0, 1.0]
    change = run(SingleFadingFactor(outlier_probability=0.999), [quiet, big, big, big])
    assert change[:3] == [1.0, 1.0, 1.0] and change[3] > 10.0
    with pytest.raises(ValueError, match="outlier_probability must be in"):
        SingleFadingFactor(outlier_probability=1.0)


def test_the_outlier_gate_leaves_a_singular_member_to_its_filter():
    """A batch of two: episode 1's innovation covariance is singular (the filter flags
    it). The gate neither raises nor flags it, and episode 0's 10-sigma innovation is
    still gated as alone."""
    policy = SingleFadingFactor(outlier_probability=0.999)
    policy.reset(2)
    S = np.array([[[2.0]], [[0.0]]])
    e = np.array([[10.0 * np.sqrt(2.0)], [1.0]])
    zeros = np.zeros((2, 1, 1))
    ctx = AdaptationContext(innovation=e, valid=np.ones((2, 1), bool), S=S, P_xz=zeros,
                            PhiPPhi=zeros, Q=zeros, R=zeros, H=zeros)
    np.testing.assert_array_equal(policy._outliers(ctx, ctx.valid), [True, False])
