"""Paper 002 (static base, large azimuth error) checked against physics: every default
filter from the paper's 58.5 deg start reaches the static self-alignment floors of each
episode, on ideal data (floor 0) and on the paper's sensors, with its NEES in the
chi-square band when its priors match the simulated sensors; convergence where a
small-angle KF stalls; and the campaign's output contract."""
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from aligngym.estimators.alignment import run_alignment
from aligngym.estimators.euler_integrals import stack_integrals
from aligngym.estimators.euler_kinematics import C_p_n
from aligngym.estimators.euler_large import PAPER002, EulerLargeMisalignmentModel, SmallAngleModel
from aligngym.estimators.catalogue import make_filter
from aligngym.estimators.metrics import static_alignment_floor
from aligngym.models.earth import OMEGA_IE
from aligngym.models.units import arcmin, deg, deg_per_h, ug
from aligngym.scenarios.campaign import analyse_run, episode_seeds, prepare_all
from aligngym.scenarios.cli import main
from aligngym.scenarios.experiments import experiment
from aligngym.sensors.imu import ImuSpec, TriadSpec

DEFAULT_FILTERS = experiment("paper002").default_filters

FIXED_BIASES = ImuSpec(
    gyro=TriadSpec(bias_fixed=(0.01 * deg_per_h, -0.008 * deg_per_h, 0.006 * deg_per_h),
                   white_noise_density=0.01 * deg_per_h),
    accel=TriadSpec(bias_fixed=(40 * ug, -50 * ug, 30 * ug)))


def episode(duration, azimuth_deg, level_deg=0.5, seed=3):
    exp = experiment("paper002", fine_duration=duration, azimuth_error_deg=azimuth_deg,
                     level_error_sigma_deg=level_deg)
    config = replace(exp.scenario_config(), imu=FIXED_BIASES)
    return exp, exp.prepare_episode(seed, config)


def run(name, exp, ep, model=None):
    """``name`` on one episode (a model of that episode, repeated per start, if given)."""
    model = model or exp.model([ep], ep.start_error[None])
    return analyse_run(name, "x", run_alignment(make_filter(name), model),
                       [ep] * model.batch, exp)


def static_floor(ep):
    """The episode's static self-alignment floors phi E, N, U (rad)."""
    return static_alignment_floor(ep.C_s_n_true[-1], ep.gyro_bias, ep.accel_bias, ep.lat,
                                  ep.h)


@pytest.fixture(scope="module")
def long_static():
    """One 3600 s episode with fixed biases (heading floor -3.6')."""
    return episode(3600.0, 5.0)


LONG_STARTS = (5.0, 58.5)
"""Azimuth errors (deg) of the long static run's two EKF starts."""


@pytest.fixture(scope="module")
def long_static_ekf(long_static):
    """The EKF on the long static episode from each of LONG_STARTS, one batch: final
    error (2, 3) rad."""
    exp, ep = long_static
    starts = np.array([[*ep.start_error[:2], a * deg] for a in LONG_STARTS])
    return run("ekf", exp, ep, exp.model([ep] * len(starts), starts)).error_n[:, -1]


@pytest.mark.parametrize("azimuth_deg, heading_tol", [(5.0, 0.36), (58.5, 8.0)])
def test_long_static_run_reaches_the_physical_floors(long_static, long_static_ekf,
                                                     azimuth_deg, heading_tol):
    """3600 s, the paper's P0/Q/R, the EKF. From a 5 deg azimuth error every axis within
    10 % of the floor; from the paper's 58.5 deg the heading within 8' of its floor and
    the level within 0.1'. With the old velocity equation's false heading sensitivity
    (ALGORITHMS 3.5) the 58.5 deg run ended at +86.5'; what is left (4.6') is the EKF's
    own transient (test_ideal_data_from_58_deg_every_filter_reaches_zero)."""
    exp, ep = long_static
    floor = static_floor(ep)
    final = long_static_ekf[LONG_STARTS.index(azimuth_deg)]
    np.testing.assert_allclose(final[:2], floor[:2], rtol=0.1, atol=0.1 * arcmin)
    assert abs(final[2] - floor[2]) < heading_tol * arcmin, (final[2] - floor[2]) / arcmin


def final_from_floor(name, exp, episodes, tuning=None, start=None, P0=None):
    """A default run of ``name`` on the episodes from their own start (or from start
    (B, 3) rad): (final error minus the episode's floor (B, 3) rad, final sigma (B, 3)
    rad, final NEES (B,), diverged). P0: {member: (10, 10)}, the experiment's model with
    these members' initial covariance in place of its own."""
    if start is None:
        start = exp.start_errors(episodes)["large-azimuth"]
    if tuning is None:
        model = exp.model(episodes, start)
        if P0:
            _, own = model.initial()
            for b, P in P0.items():
                own[b] = P
            model = EulerLargeMisalignmentModel(model.integrals, model.C0, model.tuning,
                                                P0=own, feedback_below=model.feedback_below)
    else:
        C0 = np.swapaxes(C_p_n(start), -1, -2) @ np.stack([e.C_b_n_true[0] for e in episodes])
        model = EulerLargeMisalignmentModel(stack_integrals([e.integrals for e in episodes]),
                                            C0, tuning, feedback_below=5 * deg)
    r = analyse_run(name, "x", run_alignment(make_filter(name), model), episodes, exp)
    floors = np.stack([static_floor(e) if e.gyro_bias.any() else np.zeros(3)
                       for e in episodes])
    return r.error_n[:, -1] - floors, r.result.sigma_n[:, -1], r.nees[:, -1], r.diverged


@pytest.fixture(scope="module")
def ideal_episodes():
    """Two 600 s episodes of error-free sensors (floor 0) from the paper's 58.5 deg start
    (level errors drawn, 1 deg)."""
    exp = experiment("paper002")
    config = replace(exp.scenario_config(), imu=ImuSpec())
    return exp, [exp.prepare_episode(s, config) for s in episode_seeds(5, 2)]


# Measured on ideal data (arcmin of heading): ekf 4.6, ukf 6.6, sghkf-2 0.7, sghkf-4 2.3.
@pytest.mark.parametrize("name", DEFAULT_FILTERS)
def test_ideal_data_from_58_deg_every_filter_reaches_zero(default_runs, name):
    """Error-free sensors, the paper's P0/Q/R, 600 s from 58.5 deg: heading within 8' of 0,
    level within 0.1', inside the filter's own 3 sigma, not diverged.

    Why 8' and not 0: on a static base the heading and the east drift are one observable
    combination (eps_E + Omega cos L alpha_U); whatever error the large-angle transient
    leaves along the unobservable direction stays. Its size is each Gaussian filter's own
    approximation of that transient and scales with the drift prior: the EKF's 4.6' at the
    paper's 0.1 deg/h is 0.4' at 0.03 deg/h, 36' at 0.3 deg/h (and 0.02' from a 5 deg start,
    1.4' from 40 deg), the same for any epoch from 0.1 to 2 s and any feedback threshold;
    an EKF linearised at the truth leaves 0.7'. The false heading sensitivity of the old
    velocity equation left 74-339' here."""
    d, sigma, _, diverged = default_runs(name)["ideal"]
    assert np.all(np.abs(d[:, 2]) < 8 * arcmin), d[:, 2] / arcmin
    assert np.all(np.abs(d[:, 2]) < 3 * sigma[:, 2])
    assert np.all(np.abs(d[:, :2]) < 0.1 * arcmin), d[:, :2] / arcmin
    assert not diverged.any()


@pytest.fixture(scope="module")
def paper_episodes():
    """Six 600 s episodes of the paper's sensors (gyro 0.01 deg/h bias and random drift,
    accelerometer 50 ug), the paper's 58.5 deg start."""
    exp = experiment("paper002")
    return exp, prepare_all(exp, episode_seeds(0, 6), None, False, 1, progress=False)


@pytest.mark.parametrize("name", DEFAULT_FILTERS)
def test_paper_settings_reach_each_episodes_floors(default_runs, name):
    """The paper's literal P0/Q/R: every episode's heading within 8' of its floor
    -eps_E/(Omega cos L) + alpha_N tan L, its level within 0.1' of -nabla_N/g, nabla_E/g
    (biases rotated to n). Measured: ekf 4.3-4.9', ukf 6.4-7.0', sghkf-2 0.5-1.1',
    sghkf-4 2.0-2.5'."""
    d, sigma, _, diverged = default_runs(name)["paper"]
    assert np.all(np.abs(d[:, 2]) < 8 * arcmin), d[:, 2] / arcmin
    assert np.all(np.abs(d[:, :2]) < 0.1 * arcmin), d[:, :2] / arcmin
    assert not diverged.any()


FITTED = replace(PAPER002, euler_sigma=(1 * deg, 1 * deg, 5 * deg))
"""The paper's tuning with P0 fitted to a 5 deg start (1, 1, 5 deg)."""


def fitted_start(ep):
    """The episode's start from a 5 deg azimuth error (its level errors kept): the start
    ``experiment("paper002", azimuth_error_deg=5.0)`` draws for that seed."""
    return np.array([*ep.start_error[:2], 5.0 * deg])


def test_with_a_prior_that_fits_the_start_every_filter_keeps_the_bayesian_residual(
        ideal_episodes, default_runs):
    """On a static base heading and east drift are one observable combination c = eps_E +
    Omega cos L phi_U; an exact Bayesian estimator that knows c keeps the heading residual
    k phi_U, k = s_eps^2 / (s_eps^2 + (Omega cos L s_phi)^2) (s_eps: the drift prior, s_phi:
    P0's heading sigma). From a 5 deg start with P0 fitted to it (1, 1, 5 deg) the
    transient is linear enough for every rule: each default filter ends within 0.3' of
    k phi_U = 2.94' (measured 2.81-3.13'). With the paper's 45/45/60 deg P0 the same start
    leaves the UKF at 1.2', its points spread over P0 (benchmarks/paper002_transient.py,
    docs/paper002.md). The episode is the first ideal one (seed 5000000, error-free
    sensors), run as the last member of ``default_runs``' batches."""
    exp, ideal = ideal_episodes
    ep = ideal[0]
    assert ep.seed == episode_seeds(5, 1)[0]
    start = fitted_start(ep)
    tuning = FITTED
    k = tuning.gyro_bias_sigma ** 2 / (tuning.gyro_bias_sigma ** 2 + (
        OMEGA_IE * np.cos(ep.lat) * tuning.euler_sigma[2]) ** 2)
    assert k * start[2] / arcmin == pytest.approx(2.94, abs=0.01)
    for name in DEFAULT_FILTERS:
        final = default_runs(name)["fitted"][0][0, 2]         # its floor is 0
        assert abs(final - k * start[2]) < 0.3 * arcmin, (name, final / arcmin)


def test_the_best_filter_is_within_1_arcmin_of_the_floors(default_runs):
    """sghkf-2 (the UKF's points at kappa = 3 - n, without its beta): heading RMS from the
    floors below 1'."""
    d = default_runs("sghkf-2")["paper"][0]
    assert np.sqrt(np.mean(d[:, 2] ** 2)) < 1 * arcmin


@pytest.fixture(scope="module")
def default_runs(ideal_episodes, paper_episodes):
    """name -> {"ideal": ..., "paper": ..., "fitted": ...}: ``final_from_floor`` of a
    default run over the ideal and the paper's episodes and, as the last member, the
    first ideal episode from its ``fitted_start`` with the ``FITTED`` P0
    (test_with_a_prior_that_fits_the_start_every_filter_keeps_the_bayesian_residual), run
    once per filter as one batch (the same experiment and tuning, a P0 per member; the
    members of a batch are independent)."""
    exp, ideal = ideal_episodes
    _, paper = paper_episodes
    episodes = ideal + paper + ideal[:1]
    start = np.concatenate([exp.start_errors(ideal + paper)["large-azimuth"],
                            fitted_start(ideal[0])[None]])
    P0 = {len(episodes) - 1: FITTED.initial_covariance(1)[0]}
    parts = {"ideal": slice(0, len(ideal)), "paper": slice(len(ideal), -1),
             "fitted": slice(-1, None)}
    runs = {}

    def get(name):
        if name not in runs:
            out = final_from_floor(name, exp, episodes, start=start, P0=P0)
            runs[name] = {part: tuple(a[rows] for a in out) for part, rows in parts.items()}
        return runs[name]
    return get


MATCHED = replace(PAPER002, accel_bias_sigma=50 * ug, gyro_bias_sigma=0.01 * deg_per_h,
                  accel_psd=(1 * ug) ** 2, measurement_sigma=0.001)
"""The paper's tuning matched to the simulated sensors: bias priors 50 ug and 0.01 deg/h,
accelerometer noise 1 ug/sqrt(Hz) (the sensors have none) and a 1 mm/s velocity sigma
(the measured velocity is the INS's own, noise-free). The paper's 0.02 mg prior is smaller
than its 50 ug bias, which puts the unobservable accelerometer bias outside its prior
(final NEES 15-17 over 50 episodes against a band of 6.9-9.2); its 0.1 deg/h drift prior,
0.05 mg/sqrt(Hz) and 0.1 m/s are conservative."""


@pytest.mark.parametrize("name", [
    "ekf", "sghkf-2", "sghkf-4",
    pytest.param("ukf", marks=pytest.mark.xfail(strict=True, reason=(
        "the kappa = 0 UKF gains information on the unobservable accelerometer biases "
        "(sigma 31-38 ug from the 50 ug prior while their errors grow to 94-116 ug; "
        "NEES 24 over 50 episodes); the EKF and the sparse grids keep the prior")))])
def test_matched_priors_reach_the_floors_with_nees_in_the_chi_square_band(paper_episodes,
                                                                          name):
    """Priors and noise matching the sensors: every episode's heading within 1' of its
    floor and within its own sigma (3.0'), and the mean final NEES over the six episodes
    (8 states: Euler errors, accelerometer x, y and gyro biases) in its two-sided 95 %
    chi-square band. Measured over 50 episodes: heading RMS from the floors 0.19-0.20',
    NEES 8.4, 8.7, 8.3 (band 6.9-9.2); on these six 0.17', NEES 9.8-10.8 (band 5.1-11.5)."""
    exp, episodes = paper_episodes
    d, sigma, nees, diverged = final_from_floor(name, exp, episodes, MATCHED)
    assert np.all(np.abs(d[:, 2]) < 1 * arcmin), d[:, 2] / arcmin
    assert np.all(np.abs(d[:, 2]) < sigma[:, 2])
    n = len(episodes)
    lo, hi = chi2.ppf([0.025, 0.975], 8 * n) / n
    assert lo < nees.mean() < hi, (nees.mean(), lo, hi)
    assert not diverged.any()


@pytest.fixture(scope="module")
def large_azimuth():
    return episode(600.0, 58.5)


@pytest.mark.parametrize("name", ["ukf", "sghkf-3"])
def test_sigma_point_filters_converge_from_58_deg(large_azimuth, name):
    exp, ep = large_azimuth
    result = run(name, exp, ep)
    heading, sigma = abs(result.error_n[0, -1, 2]), result.result.sigma_n[0, -1, 2]
    assert heading < 60 * arcmin and heading < 3 * sigma  # from 3510', consistent
    assert np.all(np.abs(result.error_n[0, -1, :2]) < 1 * arcmin)
    assert not result.diverged[0]


def test_small_angle_kf_does_not_converge_from_58_deg(large_azimuth):
    exp, ep = large_azimuth
    model = exp.model([ep], ep.start_error[None])
    small = SmallAngleModel(model.integrals, model.C0, exp.tuning())
    assert abs(run("kf", exp, ep, small).error_n[0, -1, 2]) > 5 * 60 * arcmin


def test_bench_paper002_json_and_resume(tmp_path):
    """bench's JSON summary (its keys, the sparse grid's point count, the CSV's rows) and
    --resume giving the same numbers. The command's contract is under test, not the
    alignment: 60 s of fine alignment (bench --set), not the paper's 600 s."""
    out = tmp_path / "b"
    args = ["bench", "paper002", "--episodes", "2", "--filters", "ekf,sghkf-2", "--out",
            str(out), "--workers", "1", "--no-figures", "--set", "fine_duration=60"]
    assert main(args + ["--json", str(tmp_path / "a.json")]) == 0
    summary = json.loads((tmp_path / "a.json").read_text())
    assert set(summary) == {"fine", "data_faults", "nees_band"}
    assert set(summary["fine"]) == {"ekf", "sghkf-2"}
    assert summary["data_faults"]["flagged_episodes"] == 0
    for stats in summary["fine"].values():
        assert set(stats) == {"mean_arcmin", "std_arcmin", "rms_arcmin", "diverged_fraction",
                              "converged_fraction", "not_converged_fraction", "lost_fraction",
                              "convergence_s", "points", "us_per_epoch"}
        assert len(stats["rms_arcmin"]) == 3
    assert summary["fine"]["sghkf-2"]["points"] == 21  # 2n + 1, n = 10
    assert len((out / "results.csv").read_text().splitlines()) == 1 + 2 * 2
    (out / "episodes" / "seed_1.npz").unlink()  # as if interrupted
    assert main(args + ["--resume", "--json", str(tmp_path / "b.json")]) == 0
    assert json.loads((tmp_path / "b.json").read_text())["fine"]["ekf"]["rms_arcmin"] == \
        summary["fine"]["ekf"]["rms_arcmin"]


def test_bench_bad_filter_level_is_one_line(capsys):
    assert main(["bench", "paper002", "--filters", "sghkf-0", "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert "sparse-grid level must be an integer in [1, 6]" in err
    assert "Traceback" not in err


def scenario_with_filter_table(tmp_path, table):
    text = (Path(__file__).parents[1] / "scenarios" / "data" /
            "static-large-azimuth.toml").read_text()
    path = tmp_path / "custom.toml"
    path.write_text(text + "\n[filter]\n" + table + "\n")
    return str(path)


def test_non_positive_definite_initial_covariance_in_a_scenario_file(tmp_path, capsys):
    P0 = np.diag([0.1] * 10)
    P0[0, 1] = P0[1, 0] = 0.5  # |correlation| > 1: indefinite
    rows = ", ".join("[" + ", ".join(f"{v:g}" for v in row) + "]" for row in P0)
    path = scenario_with_filter_table(tmp_path, f"initial_covariance = [{rows}]")
    assert main(["bench", "paper002", "--scenario", path, "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "filter.initial_covariance is not positive definite" in err[0]


def test_scenario_filter_table_is_used_and_checked(tmp_path, capsys):
    path = scenario_with_filter_table(tmp_path, "euler_sigma_deg = [10.0, 10.0, 80.0]")
    exp = experiment("paper002", scenario=path)
    np.testing.assert_allclose(np.rad2deg(exp.tuning().euler_sigma), [10, 10, 80])
    bad = scenario_with_filter_table(tmp_path, "euler_sigma_deg = [10.0, -1.0, 80.0]")
    assert main(["bench", "paper002", "--scenario", bad, "--episodes", "1"]) == 2
    assert "filter.euler_sigma_deg must be 3 values in (0, 90] deg" in capsys.readouterr().err
    assert main(["bench", "paper003", "--scenario", path, "--episodes", "1"]) == 2
    assert "paper003 runs on the ship-prescribed or ship-waves world" in \
        capsys.readouterr().err


def test_threaded_batch_chunks_give_the_same_result():
    """run_filter split over threads (batch chunks) equals the single batch exactly."""
    from aligngym.scenarios.campaign import prepare_all, run_filter

    exp = experiment("paper002", fine_duration=20.0)
    episodes = prepare_all(exp, [1, 2, 3], None, False, 1, progress=False)
    start = exp.start_errors(episodes)["large-azimuth"]
    one = run_filter("sghkf-3", "x", start, episodes, exp, threads=1)
    two = run_filter("sghkf-3", "x", start, episodes, exp, threads=2)
    np.testing.assert_array_equal(one.error_n, two.error_n)
    np.testing.assert_array_equal(one.result.P, two.result.P)
    np.testing.assert_array_equal(one.nees, two.nees)
