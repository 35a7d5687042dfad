"""The Sage-Husa baseline (``estimators.sage_husa``): its recursion by hand, its estimate
against the innovations' known statistics (stationary and after a step), missing
components, the model's correlations kept, and refused options."""
import numpy as np
import pytest

from aligngym.estimators.adaptation import AdaptationContext
from aligngym.estimators.catalogue import make_filter
from aligngym.estimators.sage_husa import SageHusaNoise


def context(e: np.ndarray, R: np.ndarray, hph: np.ndarray,
            valid: np.ndarray | None = None) -> AdaptationContext:
    """An update of B episodes with innovations e (B, m), model R (m, m) and
    H P_pred H^T = diag(hph) (m,)."""
    B, m = e.shape
    n = 2
    S = np.broadcast_to(R + np.diag(hph), (B, m, m)).copy()
    zeros = np.zeros((B, n, n))
    return AdaptationContext(innovation=e, valid=valid, S=S, P_xz=np.zeros((B, n, m)),
                             PhiPPhi=zeros, Q=zeros, R=np.broadcast_to(R, (B, m, m)).copy(),
                             H=np.zeros((B, m, n)))


def test_the_recursion_by_hand():
    """d_0 = 1 (the first sample alone), d_1 = (1 - b) / (1 - b^2) = 1 / (1 + b); each
    sample is (e^2 - HPH) / R in units of R; the bounds hold it."""
    policy = SageHusaNoise(forgetting=0.9, floor=0.1, cap=100.0)
    policy.reset(1)
    R, hph = np.diag([4.0, 1.0]), np.array([1.0, 0.5])
    a = policy.adapt(context(np.array([[3.0, 0.1]]), R, hph))
    # component 0: (9 - 1) / 4 = 2; component 1: (0.01 - 0.5) / 1 < 0 -> floor 0.1
    np.testing.assert_allclose(a.factors, [[2.0, 0.1]])
    np.testing.assert_allclose(a.R[0], np.diag([8.0, 0.1]))
    assert a.P_pred is None
    a = policy.adapt(context(np.array([[1.0, 2.0]]), R, hph))
    d = 1.0 / 1.9
    expect = [(1 - d) * 2.0 + d * (1.0 - 1.0) / 4.0, (1 - d) * 0.1 + d * (4.0 - 0.5)]
    np.testing.assert_allclose(a.factors, [expect])
    a = policy.adapt(context(np.array([[1e3, 0.0]]), R, hph))
    assert a.factors[0, 0] == 100.0                        # the cap


def test_the_estimate_is_the_innovations_noise_and_follows_a_step():
    """Innovations of variance sigma^2 + HPH: the estimate averages to sigma^2 (within 3 %
    over 4000 updates of 64 episodes); after sigma grows 6x it is within 25 % of the new
    sigma^2 within 5 / (1 - b) updates, where a fading memory of b puts it."""
    rng = np.random.default_rng(1)
    B, hph, R = 64, 0.3, np.array([[1.0]])
    policy = SageHusaNoise()
    policy.reset(B)
    ratios = []
    for k in range(4000):
        sigma = 0.5 if k < 3000 else 3.0
        e = rng.standard_normal((B, 1)) * np.sqrt(sigma ** 2 + hph)
        ratios.append(policy.adapt(context(e, R, np.array([hph]))).factors[:, 0])
    ratios = np.array(ratios)
    assert abs(ratios[500:3000].mean() / 0.25 - 1.0) < 0.03
    settle = 3000 + int(5 / (1 - policy.forgetting))
    assert abs(ratios[settle:].mean() / 9.0 - 1.0) < 0.05
    assert np.all(np.abs(ratios[settle:].mean(0) / 9.0 - 1.0) < 0.25)


def test_a_missing_component_keeps_its_estimate_and_the_correlations_stay():
    policy = SageHusaNoise(forgetting=0.5)
    policy.reset(2)
    R = np.array([[4.0, 1.0], [1.0, 1.0]])
    hph = np.zeros(2)
    first = policy.adapt(context(np.array([[4.0, 2.0], [2.0, 1.0]]), R, hph)).factors
    valid = np.array([[True, False], [True, True]])
    a = policy.adapt(context(np.array([[0.0, 50.0], [2.0, 1.0]]), R, hph, valid))
    assert a.factors[0, 1] == first[0, 1]               # kept: component 1 of episode 0
    assert a.factors[0, 0] != first[0, 0]
    corr = lambda M: M[0, 1] / np.sqrt(M[0, 0] * M[1, 1])  # noqa: E731
    for b in range(2):
        assert corr(a.R[b]) == pytest.approx(corr(R), rel=1e-12)
    third = policy.adapt(context(np.array([[0.0, 1.0], [2.0, 1.0]]), R, hph)).factors
    # episode 0's component 1 at its second update: d_1 = 1 / (1 + b)
    d = 1.0 / 1.5
    assert third[0, 1] == pytest.approx((1 - d) * first[0, 1] + d * 1.0)


@pytest.mark.parametrize("options, message", [
    ({"forgetting": 1.0}, "forgetting must be in (0, 1)"),
    ({"floor": 0.0}, "need 0 < floor <= 1 <= cap"),
    ({"cap": 0.5}, "need 0 < floor <= 1 <= cap"),
])
def test_options_out_of_range_are_refused(options, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        SageHusaNoise(**options)


def test_it_is_in_the_catalogue():
    filt = make_filter("sage-husa")
    assert isinstance(filt.adaptation, SageHusaNoise)
