"""Each experiment's NEES and its truth-to-state map, probed on hand-built states of a
short real run at every epoch: the run's covariance replaced by a diagonal one with a
different variance v_i for every state i, a state component moved by +delta and
-delta. For a state that enters the error linearly, NEES(+d) + NEES(-d) - 2 NEES(0) =
2 d^2 / v_i exactly, whatever the run's own error: a slice that reads another state, or
another state's variance, misses it by the ratio of two variances. The accumulated
estimate of a closed-loop model (its series, after feedback) and the state (before
feedback) are one estimate: the same delta in either gives the same NEES. The attitude
is probed through the model's attitude (C_s_n, Euler models) or the error the engine
hands in (error_n)."""
from dataclasses import replace

import numpy as np
import pytest

from aligngym.scenarios.campaign import run_campaign
from aligngym.scenarios.experiments import experiment

def _biases(gyro: int, accel: int, fed_back: bool, accel_axes: int = 3) -> list:
    """The bias states: (state index, the model's series key of its accumulated estimate
    or None, (the episode's drawn bias, its component))."""
    return ([(gyro + j, "gyro_bias" if fed_back else None, ("gyro_bias", j))
             for j in range(3)]
            + [(accel + j, "accel_bias" if fed_back else None, ("accel_bias", j))
               for j in range(accel_axes)])


SHORT = {
    # experiment: (filter, settings, [(state index, series key or None, its truth or
    # None)], attitude)
    "paper000": ("ekf", {"fine_duration": 20.0, "starts": ("coarse",)},
                 _biases(9, 12, fed_back=True), ("C_s_n", (0, 1, 2))),
    "paper001": ("lckf", {"fine_duration": 20.0},
                 [(i, None, None) for i in range(0, 6)] + _biases(9, 12, fed_back=True),
                 ("error_n", (6, 7, 8))),
    "paper002": ("ekf", {"fine_duration": 20.0}, _biases(7, 5, False, accel_axes=2),
                 ("C_s_n", (0, 1, 2))),
    "paper003": ("kf", {"fine_duration": 20.0}, _biases(6, 9, fed_back=False),
                 ("error_n", (3, 4, 5))),
    "paper004": ("ekf", {"fine_duration": 20.0}, _biases(9, 12, fed_back=True),
                 ("error_n", (0, 1, 2))),
}
DELTA = 1.0
"""The probe's step, in units of the state's sigma sqrt(v_i) (large against the
rounding of NEES values of 10^4; a state that enters linearly is exact at any step)."""


@pytest.fixture(scope="module", params=sorted(SHORT))
def probe(request):
    """(experiment, its run's FineResult with a diagonal P, episodes, error_n, case)."""
    name = request.param
    filter_name, settings, _, _ = SHORT[name]
    exp = experiment(name, **settings)
    result = run_campaign(exp, episodes=2, seed=0, filters=[filter_name], workers=1,
                          progress=False)
    run = result.runs[0]
    fine = run.result
    n = fine.x.shape[-1]
    variances = 1e-6 * (1.0 + np.arange(n)) ** 2
    P = np.broadcast_to(np.diag(variances), fine.P.shape).copy()
    attitude = list(SHORT[name][3][1])
    if SHORT[name][3][0] == "error_n":          # rotated into the filter's frame:
        P[..., attitude, attitude] = variances[attitude[0]]   # isotropic there
    return exp, replace(fine, P=P), result.episodes, run.error_n, SHORT[name]


def second_difference(exp, episodes, base, moved):
    """NEES(+d) + NEES(-d) - 2 NEES(0) (B, K+1); moved(sign) -> (FineResult, error_n)."""
    return (exp.nees(*_args(moved(+1.0), episodes)) + exp.nees(*_args(moved(-1.0), episodes))
            - 2.0 * exp.nees(*_args(base, episodes)))


def _args(pair, episodes):
    fine, error_n = pair
    return fine, episodes, error_n


def test_each_state_reads_its_own_component_and_variance(probe):
    exp, fine, episodes, error_n, (_, _, states, _) = probe
    variances = fine.P[0, 0].diagonal()
    assert exp.nees_dof() == len(states) + 3
    for index, _, _ in states:
        step = DELTA * np.sqrt(variances[index])

        def moved(sign):
            x = fine.x.copy()
            x[..., index] += sign * step
            return replace(fine, x=x), error_n
        np.testing.assert_allclose(second_difference(exp, episodes, (fine, error_n), moved),
                                   2 * DELTA ** 2, rtol=1e-6, err_msg=f"state {index}")


def test_the_accumulated_estimate_and_the_state_are_one_estimate(probe):
    """Before feedback (the estimate in the state) and after (in the model's series)."""
    exp, fine, episodes, error_n, (_, _, states, _) = probe
    fed = [(i, key) for i, key, _ in states if key is not None]
    if not fed:
        pytest.skip(f"paper{exp.paper}'s bias states are the whole estimate")
    variances = fine.P[0, 0].diagonal()
    for index, key in fed:
        j = index - min(i for i, k in fed if k == key)
        step = 3.0 * np.sqrt(variances[index])
        x = fine.x.copy()
        x[..., index] += step
        series = {**fine.series, key: fine.series[key].copy()}
        series[key][..., j] += step
        before = exp.nees(replace(fine, x=x), episodes, error_n)
        after = exp.nees(replace(fine, series=series), episodes, error_n)
        np.testing.assert_allclose(before, after, rtol=1e-9)
        assert not np.allclose(before, exp.nees(fine, episodes, error_n), rtol=1e-3)


def test_the_attitude_reads_the_misalignment_and_its_variance(probe):
    from aligngym.models.attitude import rotvec_to_dcm
    exp, fine, episodes, error_n, (_, _, _, (how, indices)) = probe
    variances = fine.P[0, 0].diagonal()
    x = fine.x.copy()
    if how == "C_s_n":
        x[..., list(indices)] = 0.0        # the Euler error estimate fed back
    flat = replace(fine, x=x)
    for axis, index in enumerate(indices):
        step = DELTA * np.sqrt(variances[index])
        if how == "error_n":
            def moved(sign):
                e = error_n.copy()
                e[..., axis] += sign * step
                return flat, e
            rtol = 1e-6
        else:                              # a turn of the model's attitude about an n axis
            def moved(sign):
                turn = np.zeros(3)
                turn[axis] = sign * step
                return replace(flat, C_s_n=rotvec_to_dcm(turn) @ flat.C_s_n), error_n
            rtol = 2e-2                    # the Euler error of a turn, near the truth
        np.testing.assert_allclose(second_difference(exp, episodes, (flat, error_n), moved),
                                   2 * DELTA ** 2, rtol=rtol, err_msg=f"attitude axis {axis}")


def test_the_truth_enters_as_the_estimate_does(probe):
    """The drawn bias and the estimate moved by the same delta leave the NEES unchanged
    (the error is their difference); the truth moved
    alone changes it."""
    exp, fine, episodes, error_n, (_, _, states, _) = probe
    from dataclasses import replace as with_fields
    for index, _, (name, j) in [s for s in states if s[2] is not None]:
        step = np.sqrt(fine.P[0, -1, index, index])
        x = fine.x.copy()
        x[..., index] += step
        moved = []
        for e in episodes:
            bias = getattr(e, name).astype(float).copy()
            bias[j] += step
            moved.append(with_fields(e, **{name: bias}))
        base = exp.nees(fine, episodes, error_n)
        np.testing.assert_allclose(exp.nees(replace(fine, x=x), moved, error_n), base,
                                   rtol=1e-6, err_msg=f"state {index}")
        assert not np.allclose(exp.nees(fine, moved, error_n), base, rtol=1e-9), index


def test_the_attitude_estimate_in_the_state_and_in_the_attitude_are_one(probe):
    """Euler models (C_s_n): the model's attitude C_s_n holds the whole estimate, the
    state's Euler error x[0:3] the part not yet fed back (C_s_n = C_p_n(x) C_ins). With
    C_s_n kept, an unfed estimate of 3 sigma per axis in the state leaves the NEES as it
    was to second order (1 %): the truth-to-state map turns C_s_n back by x, and the
    error is x minus the true Euler error. A map that turned it the wrong way, or added
    the truth, would move each axis by 6 sigma."""
    exp, fine, episodes, error_n, (_, _, _, (how, indices)) = probe
    if how != "C_s_n":
        pytest.skip(f"paper{exp.paper}'s attitude is the error the engine hands in")
    variances = fine.P[0, 0].diagonal()
    x = fine.x.copy()
    x[..., list(indices)] = 0.0
    flat = replace(fine, x=x)
    unfed = x.copy()
    unfed[..., list(indices)] = 3.0 * np.sqrt(variances[list(indices)])
    np.testing.assert_allclose(exp.nees(replace(fine, x=unfed), episodes, error_n),
                               exp.nees(flat, episodes, error_n), rtol=1e-2)


def test_paper001_the_ins_error_enters_as_the_state_does(probe):
    """Paper 001's position, velocity and attitude states are the INS's own errors (in e):
    an INS moved from where it was by dr (m, E N U) and dv (m/s), an attitude error
    moved by dphi (rad, E N U), and the state moved by the same amounts in e, leave the
    state errors unchanged; the INS moved alone changes them by exactly -dr, -dv, -dphi.
    (Sign flips and wrong operators at the INS's errors, which the second differences
    above cannot see: they move every NEES by a constant.)"""
    exp = probe[0]
    if exp.paper != "001":
        pytest.skip("paper 001's map of the INS's errors")
    from aligngym.estimators.loose_gps import PHI, POSITION, VELOCITY
    from aligngym.models.earth import C_n_e, radii
    from aligngym.scenarios.experiments.paper001 import state_errors
    _, fine, episodes, error_n, _ = probe
    s = fine.series
    d_enu, d_v, d_phi = np.array([3.0, -2.0, 1.5]), np.array([0.2, -0.1, 0.05]), \
        np.array([1e-4, -2e-4, 5e-4])
    R_M, R_N = radii(s["lat"])
    series = {**s, "lat": s["lat"] + d_enu[1] / (R_M + s["h"]),
              "lon": s["lon"] + d_enu[0] / ((R_N + s["h"]) * np.cos(s["lat"])),
              "h": s["h"] + d_enu[2], "v_n": s["v_n"] + d_v}
    C = C_n_e(s["lat"], s["lon"])
    x = fine.x.copy()
    x[..., POSITION] += np.einsum("bkij,j->bki", C, d_enu)
    x[..., VELOCITY] += np.einsum("bkij,j->bki", C, d_v)
    x[..., PHI] += np.einsum("bkij,j->bki", C, d_phi)
    base = state_errors(fine, episodes, error_n)
    both = state_errors(replace(fine, series=series, x=x), episodes, error_n + d_phi)
    np.testing.assert_allclose(both[..., :9], base[..., :9], atol=2e-3)
    moved_position = {**s, **{k: series[k] for k in ("lat", "lon", "h")}}
    alone = state_errors(replace(fine, series=moved_position), episodes, error_n) - base
    np.testing.assert_allclose(np.einsum("bkji,bkj->bki", C, alone[..., POSITION]),
                               np.broadcast_to(-d_enu, alone[..., POSITION].shape), atol=2e-3)
    alone = state_errors(replace(fine, series={**s, "v_n": series["v_n"]}), episodes,
                         error_n) - base
    np.testing.assert_allclose(np.einsum("bkji,bkj->bki", C, alone[..., VELOCITY]),
                               np.broadcast_to(-d_v, alone[..., VELOCITY].shape), atol=1e-12)
    alone = state_errors(fine, episodes, error_n + d_phi) - base
    np.testing.assert_allclose(np.einsum("bkji,bkj->bki", C, alone[..., PHI]),
                               np.broadcast_to(-d_phi, alone[..., PHI].shape), atol=1e-15)
    faster = [replace(e, true_v_n=e.true_v_n + d_v) for e in episodes]   # the truth moved
    alone = state_errors(fine, faster, error_n) - base
    np.testing.assert_allclose(np.einsum("bkji,bkj->bki", C, alone[..., VELOCITY]),
                               np.broadcast_to(d_v, alone[..., VELOCITY].shape), atol=1e-12)


def test_paper003_hull_bias_nees_is_about_the_unmodelled_floor():
    """Paper 003's setup with biases fixed in the hull frame: the NEES is the attitude's
    alone, about the static floor those biases set (``unmodelled_floor``). An attitude
    error on the floor has NEES 0; moved from it by d, with an isotropic covariance v,
    |d|^2 / v whatever the rotation into the filter's frame (a closed form)."""
    exp = experiment("paper003", "paper", fine_duration=20.0)
    assert exp.nees_dof() == 3
    result = run_campaign(exp, episodes=2, seed=0, filters=["kf"], workers=1, progress=False)
    fine, episodes = result.runs[0].result, result.episodes
    floor = exp.unmodelled_floor(episodes)
    assert floor.shape == (2, 3) and np.all(np.abs(floor) > 0)
    K = fine.t.size
    on_floor = np.broadcast_to(floor[:, None], (2, K, 3)).copy()
    v = 1e-8
    P = np.broadcast_to(v * np.eye(fine.P.shape[-1]), fine.P.shape).copy()
    fine = replace(fine, P=P)
    np.testing.assert_allclose(exp.nees(fine, episodes, on_floor), 0.0, atol=1e-18)
    d = np.array([2e-4, -1e-4, 3e-4])
    np.testing.assert_allclose(exp.nees(fine, episodes, on_floor + d), d @ d / v, rtol=1e-9)


def test_paper004_attitude_state_error_is_estimate_minus_truth(probe):
    """Paper 004's state errors begin with the attitude estimate minus the truth, as a
    rotation vector: an estimate turned by -d from the truth (C_est = exp([-d x]) C_true)
    has the error log(C_est C_true^T) = -d, through the error the engine hands in
    (``metrics.misalignment``). (The sign, which a diagonal covariance cannot see.)"""
    exp = probe[0]
    if exp.paper != "004":
        pytest.skip("paper 004's map of the attitude error")
    from aligngym.estimators.metrics import misalignment
    from aligngym.models.attitude import dcm_to_rotvec, rotvec_to_dcm
    from aligngym.scenarios.experiments.paper004 import state_errors
    _, fine, episodes, _, _ = probe
    C_true = fine.C_s_n
    d = np.array([3e-3, -2e-3, 5e-3])
    C_est = rotvec_to_dcm(-d) @ C_true
    expected = dcm_to_rotvec(C_est @ np.swapaxes(C_true, -1, -2))     # the definition
    np.testing.assert_allclose(expected, np.broadcast_to(-d, expected.shape), atol=1e-15)
    error_n = misalignment(C_true, C_est)
    np.testing.assert_allclose(state_errors(fine, episodes, error_n)[..., :3], expected,
                               atol=1e-12)
