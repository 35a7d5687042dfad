"""Each episode's status from a real run whose final estimate is planted (issue 46): a
filter lost but honest (145 deg off, its sigma 200 deg), one lost and confident (145 deg
off, sigma 1'), one wrong and confident (3 deg off, sigma 1'), one not converged (3 deg
off, sigma 5 deg) and the run as it ends (converged); the tables, the JSON summary, the
tidy rows and assert_alignment's check all give the same four statuses."""
from dataclasses import replace

import numpy as np
import pytest

from aligngym.models.attitude import rotvec_to_dcm
from aligngym.models.units import arcmin, deg
from aligngym.scenarios.campaign import (CampaignResult, analyse_run, episode_metrics,
                                         episode_seeds, run_filter)
from aligngym.scenarios.experiments import experiment

PLANTED = [  # (heading error, heading sigma, status)
    (145 * deg, 200 * deg, "lost"),
    (145 * deg, 1 * arcmin, "lost"),
    (3 * deg, 1 * arcmin, "diverged"),
    (3 * deg, 5 * deg, "not converged"),
    (None, None, "converged"),
]


@pytest.fixture(scope="module")
def planted():
    """Paper 002's static base, 5 episodes of 60 s from a 5 deg start (the EKF converges
    to a few arcmin in every one), the final estimate and sigma of episodes 0-3 planted."""
    exp = experiment("paper002", fine_duration=60.0, azimuth_error_deg=5.0)
    seeds = episode_seeds(3, len(PLANTED))
    episodes = [exp.prepare_episode(s) for s in seeds]
    run = run_filter("ekf", "large-azimuth", exp.start_errors(episodes)["large-azimuth"],
                     episodes, exp)
    result = run.result
    C, sigma = result.C_s_n.copy(), result.sigma_n.copy()
    for b, (heading, sig, _) in enumerate(PLANTED):
        if heading is not None:
            C[b, -1] = rotvec_to_dcm(-np.array([0.0, 0.0, heading])) @ episodes[b].C_s_n_true[-1]
            sigma[b, -1, 2] = sig
    judged = analyse_run("ekf", "large-azimuth", replace(result, C_s_n=C, sigma_n=sigma),
                         episodes, exp)
    return exp, seeds, episodes, judged


def test_each_planted_filter_has_its_status(planted):
    _, _, _, run = planted
    assert run.status.tolist() == [s for _, _, s in PLANTED], run.reason
    assert run.reason[0] == run.reason[1] == "final error > 10 deg"
    assert run.reason[2] == "final error > 5 x 3 sigma"
    assert run.reason[3] == "final error > the 60' band"
    assert run.diverged.tolist() == [False, False, True, False, False]


def test_the_tables_json_rows_and_assert_alignment_say_the_same(planted):
    from aligngym.testing import _check_run
    exp, seeds, episodes, run = planted
    result = CampaignResult(exp, seeds, episodes, {}, runs=[run], seed=3)
    fine = result.summary()["fine"]["ekf"]
    assert (fine["converged_fraction"], fine["not_converged_fraction"],
            fine["diverged_fraction"], fine["lost_fraction"]) == (0.2, 0.2, 0.2, 0.4)
    table = exp.format_tables(result)
    assert "conv. not conv. diverged  lost" in table
    assert "20%       20%      20%   40%" in table
    rows = [episode_metrics(run, b, exp, episodes[b].fine_start) for b in range(len(seeds))]
    assert [r["status"] for r in rows] == [s for _, _, s in PLANTED]
    assert [r["diverged"] for r in rows] == [False, False, True, False, False]
    measured, text = _check_run(run, "ekf", "static-large-azimuth", "large-azimuth",
                                len(seeds), 3, seeds, None, None)
    assert (measured["lost"], measured["diverged"], measured["not_converged"],
            measured["converged"]) == (2, 1, 1, 1)
    assert "1 of 5 episodes diverged; 2 of 5 episodes lost" in text.splitlines()[0]
