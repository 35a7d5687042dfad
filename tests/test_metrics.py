"""The alignment metrics against closed forms and hand computations (SciPy's rotations
for the attitude, Somigliana's normal gravity written out here)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from aligngym.estimators.metrics import (convergence_time, euler_error, misalignment, nees,
                                         static_alignment_floor)

DEG = np.pi / 180


def test_misalignment_is_the_rotation_vector_from_the_estimate_to_the_truth():
    phi = np.array([[0.01, -0.02, 0.3], [1e-5, 2e-5, -3e-5]])
    C_est = Rotation.from_euler("zxy", [[40, 3, -2], [-170, 1, 5]], degrees=True).as_matrix()
    C_true = Rotation.from_rotvec(phi).as_matrix() @ C_est
    np.testing.assert_allclose(misalignment(C_true, C_est), phi, rtol=1e-9, atol=1e-15)


def _body_to_enu(pitch, roll, heading_cw):
    """C_b^n of a body at pitch, roll (deg) and heading (deg clockwise from north), ENU:
    Rz(-heading) Rx(pitch) Ry(roll), SciPy's intrinsic sequence."""
    return Rotation.from_euler("ZXY", [-heading_cw, pitch, roll], degrees=True).as_matrix()


def test_euler_error_is_pitch_roll_and_clockwise_heading_wrapped():
    true = _body_to_enu(2.0, -1.0, 179.0)
    est = _body_to_enu(2.5, -1.25, -178.0)            # heading 2 deg past north-south
    np.testing.assert_allclose(euler_error(true, est) / DEG, [0.5, -0.25, 3.0], atol=1e-9)
    np.testing.assert_allclose(euler_error(est, true) / DEG, [-0.5, 0.25, -3.0], atol=1e-9)
    np.testing.assert_allclose(euler_error(true, true), 0.0, atol=1e-12)


def test_convergence_time_is_the_first_time_after_which_the_error_stays_within():
    t = np.arange(6.0)
    error = np.array([[5, 3, 0.5, 2, 0.5, 0.1],        # back outside at 3: converged at 4
                      [0.1, 0.1, -0.2, 0.1, 0.1, 0.1],  # always within: at t[0]
                      [5, 5, 5, 5, 5, 5],              # never: t[-1]
                      [5, 5, 5, 5, 5, -0.5],           # only the last epoch: t[-1]
                      [-5, 0.1, 0.1, 0.1, 0.1, 0.1]])  # only the first outside: t[1]
    np.testing.assert_array_equal(convergence_time(t, error, 1.0), [4.0, 0.0, 5.0, 5.0, 1.0])
    np.testing.assert_array_equal(convergence_time(t, error, 0.2), [5.0, 0.0, 5.0, 5.0, 1.0])


BAND = 5 * DEG / 60          # a 5' convergence band


def judge(error, sigma, flagged=None, reasons=None, rule=None):
    from aligngym.estimators.metrics import StatusRule
    error, sigma = np.atleast_2d(error), np.atleast_2d(sigma)
    B = error.shape[0]
    flagged = np.zeros(B, bool) if flagged is None else np.asarray(flagged)
    return (rule or StatusRule()).apply(error, sigma, BAND, flagged, reasons or [""] * B)


def test_divergence_is_beyond_five_times_three_sigma_and_the_floor():
    """ratio 5 x 3 sigma = 15 sigma, and 1 arcmin: an error of exactly 15 sigma is not
    diverged, 15.01 sigma is; below the 1' floor nothing is, however small the sigma.
    Errors here stay under 10 deg, so none is lost."""
    arcmin = DEG / 60
    error = np.array([[0.0, 0.0, 0.15], [0.0, 0.1501, 0.0], [0.9 * arcmin, 0.0, 0.0],
                      [1.1 * arcmin, 0.0, 0.0], [-0.1501, 0.0, 0.0]])
    sigma = np.array([[0.01] * 3, [0.01] * 3, [1e-3 * arcmin] * 3, [1e-3 * arcmin] * 3,
                      [0.01] * 3])
    status, reason = judge(error, sigma)
    assert status.tolist() == ["not converged", "diverged", "converged", "diverged",
                               "diverged"]
    assert reason[1] == "final error > 5 x 3 sigma"


def test_the_four_statuses_of_an_honest_and_a_confident_filter():
    """The issue's cases: lost-but-honest (145 deg off, sigma 200 deg: it knows) and
    lost-and-confident are both lost, beyond 10 deg whatever the sigma; 8 deg off with a
    3 deg sigma is not converged (the filter says so), 8 deg off with a 1' sigma is
    diverged; 0.5' off with a 1' sigma converged; exactly 10 deg is not lost."""
    arcmin = DEG / 60
    error = np.array([[0.0, 0.0, 145.0], [0.0, 0.0, -145.0], [0.0, 0.0, 8.0],
                      [0.0, 0.0, 8.0], [0.5 / 60, 0.0, 0.0], [0.0, 0.0, 10.0]]) * DEG
    sigma = np.array([[1.0, 1.0, 200.0 * 60], [1.0, 1.0, 1.0], [1.0, 1.0, 180.0],
                      [1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 1.0, 200.0]]) * arcmin
    status, reason = judge(error, sigma)
    assert status.tolist() == ["lost", "lost", "not converged", "diverged", "converged",
                               "not converged"]
    assert reason[:4] == ["final error > 10 deg", "final error > 10 deg",
                          "final error > the 5' band", "final error > 5 x 3 sigma"]
    assert reason[4] == ""


def test_status_at_its_edges_and_when_several_reasons_hold():
    """An error of exactly the floor, or of exactly the band: converged; a sigma of
    exactly pi: converged, above pi not converged; a flag or a NaN is diverged before
    any other reason (a NaN with 100 rad, a flag with a lost error)."""
    from aligngym.estimators.metrics import StatusRule
    rule = StatusRule()
    error = np.array([[rule.floor, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0],
                      [np.nan, 0.0, 100.0], [0.0, 0.0, BAND], [0.0, 0.0, 0.0],
                      [0.0, 0.0, 0.0]])
    sigma = np.array([[1e-9] * 3, [1.0, 1.0, np.pi], [1.0] * 3, [1.0] * 3,
                      [1.0, 1.0, 1.0], [1.0, 1.0, 3.2], [1.0, np.nan, 1.0]])
    flagged = np.array([False, False, True, False, False, False, False])
    status, reason = judge(error, sigma, flagged, ["", "", "frozen", "", "", "", ""])
    assert status.tolist() == ["converged", "converged", "diverged", "diverged",
                               "converged", "not converged", "diverged"]
    assert reason == ["", "", "frozen", "final error or sigma not finite", "",
                      "attitude sigma > 180 deg", "final error or sigma not finite"]


def test_status_fractions_count_each_status():
    from aligngym.estimators.metrics import status_fractions
    fractions = status_fractions(np.array(["lost", "converged", "converged", "diverged"]))
    assert fractions == {"converged_fraction": 0.5, "not_converged_fraction": 0.0,
                         "diverged_fraction": 0.25, "lost_fraction": 0.25}


def test_nees_is_the_mahalanobis_square_by_hand():
    P = np.array([[[4.0, 1.0], [1.0, 2.0]], [[1.0, 0.0], [0.0, 9.0]]])
    e = np.array([[1.0, -1.0], [2.0, 3.0]])
    # [[4, 1], [1, 2]]^-1 = [[2, -1], [-1, 4]] / 7: (2 + 2 + 4) / 7 for (1, -1)
    np.testing.assert_allclose(nees(e, P), [8.0 / 7.0, 4.0 + 1.0], rtol=1e-12)


@pytest.mark.parametrize("lat_deg", [0.0, 40.0, -60.0])
def test_static_floor_is_the_closed_form(lat_deg):
    """phi_E = -nabla_N / g, phi_N = nabla_E / g, phi_U = -eps_E / (Omega cos L) + phi_N
    tan L, biases given in a frame turned 30 deg about Up from ENU."""
    lat = lat_deg * DEG
    s2 = np.sin(lat) ** 2
    g = 9.7803253359 * (1 + 0.00193185265241 * s2) / np.sqrt(1 - 0.00669437999013 * s2)
    C = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    eps_b, nabla_b = np.array([1e-7, -2e-7, 3e-7]), np.array([1e-3, 5e-4, -2e-3])
    eps, nabla = C @ eps_b, C @ nabla_b
    phi_N = nabla[0] / g
    expected = [-nabla[1] / g, phi_N,
                -eps[0] / (7.2921151467e-5 * np.cos(lat)) + phi_N * np.tan(lat)]
    np.testing.assert_allclose(static_alignment_floor(C, eps_b, nabla_b, lat), expected,
                               rtol=1e-9)
    batched = static_alignment_floor(np.stack([C, C]), np.stack([eps_b, 2 * eps_b]),
                                     np.stack([nabla_b, 2 * nabla_b]), lat)
    np.testing.assert_allclose(batched, [expected, 2 * np.array(expected)], rtol=1e-9)


def test_a_rule_with_its_own_thresholds():
    """StatusRule's fields are its thresholds: lost beyond 5 deg, diverged beyond 2 x 3
    sigma and 0.5', a sigma bound of 90 deg; a band of 2.5' is named as such."""
    from aligngym.estimators.metrics import StatusRule
    arcmin = DEG / 60
    rule = StatusRule(ratio=2.0, floor=0.5 * arcmin, lost_bound=5 * DEG,
                      sigma_bound=np.pi / 2)
    error = np.array([[0, 0, 6 * DEG], [0, 0, 7 * arcmin], [0, 0, 3 * arcmin],
                      [0, 0, 0.1 * arcmin]])
    sigma = np.array([[1, 1, 60.0], [1, 1, 1.0], [1, 1, 1.0], [1, 1, 100 * 60.0]]) * arcmin
    status, reason = rule.apply(error, sigma, 2.5 * arcmin, np.zeros(4, bool), [""] * 4)
    assert status.tolist() == ["lost", "diverged", "not converged", "not converged"]
    assert reason == ["final error > 5 deg", "final error > 2 x 3 sigma",
                      "final error > the 2.5' band", "attitude sigma > 90 deg"]


def test_an_error_and_a_sigma_both_nan_is_diverged():
    status, reason = judge([[np.nan, 0.0, 0.0]], [[np.nan, 1.0, 1.0]])
    assert status.tolist() == ["diverged"]
    assert reason == ["final error or sigma not finite"]


def test_the_fractions_of_no_episode_are_zero():
    from aligngym.estimators.metrics import status_fractions
    assert set(status_fractions(np.array([], dtype=str)).values()) == {0.0}
