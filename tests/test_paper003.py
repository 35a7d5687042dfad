"""Paper 003 fine alignment checked against physics, consistency, and the campaign's
output contract."""
import json
from dataclasses import dataclass, replace

import numpy as np
import pytest
from scipy.stats import chi2

from aligngym.estimators.metrics import static_alignment_floor
from aligngym.models.earth import OMEGA_IE
from aligngym.models.units import arcmin, deg, deg_per_h, ug
from aligngym.scenarios.cli import main
from aligngym.scenarios.analyses.paper003 import coarse_errors
from aligngym.scenarios.experiments.paper003 import (Paper003Experiment, prepare_episode,
                                                     run_campaign, run_filter)
from aligngym.sensors.imu import ImuSpec, TriadSpec

CONSTANT_BIASES = ImuSpec(
    gyro=TriadSpec(bias_sigma=0.01 * deg_per_h,
                   bias_fixed=(0.01 * deg_per_h, -0.008 * deg_per_h, 0.006 * deg_per_h)),
    accel=TriadSpec(bias_sigma=100 * ug, bias_fixed=(80 * ug, -100 * ug, 50 * ug)))


def calm(config, rotate=True, imu=None):
    """The ship without sway. Its linear phases are not drawn (random_linear_phase off):
    with zero amplitudes they change nothing, so every seed shares one truth."""
    motion = replace(config.motion, yaw_amplitude=0.0, pitch_amplitude=0.0,
                     roll_amplitude=0.0, linear_amplitude=(0.0, 0.0, 0.0))
    if not rotate:
        motion = replace(motion, gimbal_outer_rate=0.0, gimbal_inner_rate=0.0)
    return replace(config, motion=motion, imu=imu or config.imu, random_linear_phase=False)


@pytest.fixture(scope="module")
def experiment():
    return Paper003Experiment()


@pytest.fixture(scope="module")
def static_runs(experiment):
    """KF on a static IMU with constant biases only, without and with the rotation."""
    runs = {}
    for rotate in (False, True):
        config = calm(experiment.scenario_config(), rotate, CONSTANT_BIASES)
        episode = prepare_episode(experiment, 3, config=config)
        tuning = replace(experiment.tuning(config), measurement_sigma=(1e-3,) * 3)
        run = run_filter("kf", "x", np.array([0.1, -0.1, 1.0]) * deg, [episode], experiment,
                         tuning)
        runs[rotate] = (episode, run)
    return runs


def bias_floor(episode):
    """Static self-alignment floors phi E, N, U (rad), ENU, of the sensor-frame biases."""
    return static_alignment_floor(episode.C_s_n_true[-1], episode.gyro_bias,
                                  episode.accel_bias, episode.lat, episode.h)


def test_static_non_rotating_converges_to_the_bias_floor(static_runs):
    episode, run = static_runs[False]
    floor = bias_floor(episode)
    np.testing.assert_allclose(run.error_n[0, -1], floor, rtol=0.1)
    # The textbook heading floor (east drift / (Omega cos L)) alone, within 10 %.
    C = episode.C_s_n_true[-1]
    textbook = (C @ episode.gyro_bias)[0] / (OMEGA_IE * np.cos(episode.lat))
    assert abs(run.error_n[0, -1, 2]) == pytest.approx(abs(textbook), rel=0.1)


def test_rotation_modulation_removes_the_bias_floor(static_runs):
    """Dual-axis rotation makes the biases observable: the floors drop > 50x."""
    episode, run = static_runs[True]
    floor = np.abs(bias_floor(episode))
    assert np.all(np.abs(run.error_n[0, -1]) < floor / 50)
    assert not run.diverged.any()


def test_kf_nees_consistent_without_sway(experiment):
    """20 episodes, rotation on, no sway, errors drawn from P0: the average NEES of the
    9 attitude and bias states at the end of a 300 s fine alignment lies in its 95 %
    chi-square band (measured 8.74 in 7.24-10.95; 8.36 at 600 s)."""
    exp = replace(experiment, attitude_sigma_deg=(0.5, 0.5, 2.0), fine_duration=300.0)
    config = calm(exp.scenario_config())
    n = 20
    # One process: under xdist both cores are busy already, and a pool's forks and
    # pickled episodes cost more CPU than they save (one truth: every seed shares it).
    episodes = [prepare_episode(exp, seed, config) for seed in range(100, 100 + n)]
    # Without sway the velocity-integral measurement is clean to ~0.5 mm/s (lever-arm
    # rates from the gyros and encoders).
    tuning = replace(exp.tuning(config), measurement_sigma=(5e-4,) * 3)
    start = np.random.default_rng(5).standard_normal((n, 3)) * np.deg2rad(exp.attitude_sigma_deg)
    run = run_filter("kf", "x", start, episodes, exp, tuning)
    low, high = chi2.ppf([0.025, 0.975], 9 * n) / n
    assert low < run.nees[:, -1].mean() < high


SWAY_SEED = 11
"""The campaign seed of the swaying-ship campaigns here: the sway campaign's 4 episodes
are the first 4 of the sway-aware KF's 20 (one truth each, shared through the truth
cache: random linear phases make every seed's truth its own)."""


@pytest.fixture(scope="module")
def sway_campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    result = run_campaign(episodes=4, seed=SWAY_SEED, out_dir=out, progress=False,
                          filters=["kf", "sakf", "makf", "imakf", "makf-n", "imakf-n"])
    return out, result


def test_adaptive_filters_under_sway(sway_campaign):
    """The paper's sway: SAKF and the local-level multiple-factor filters stay converged
    and consistent; the printed i-axis MAKF/IMAKF are reported, not hidden (closing note)."""
    _, result = sway_campaign
    for run in result.runs:
        assert not run.result.diverged.any(), run.filter  # never numerically broken
        if run.filter in ("kf", "sakf", "makf-n", "imakf-n"):
            assert not run.diverged.any(), (run.filter, run.reason)
            final = np.abs(run.error_n[:, -1])
            assert np.all(final[:, :2] < 1.0 * arcmin) and np.all(final[:, 2] < 30 * arcmin)


def test_campaign_outputs_and_json_shape(sway_campaign, tmp_path):
    out, result = sway_campaign
    assert len(list((out / "episodes").glob("seed_*.npz"))) == 4  # one file per episode
    json_path = tmp_path / "s.json"
    from aligngym.scenarios.report import write_outputs
    write_outputs(result, out, json_path)
    for name in ("results.csv", "coarse.csv", "timeseries.npz", "fine_error_mean.png",
                 "fine_error_max.png"):
        assert (out / name).stat().st_size > 0
    summary = json.loads(json_path.read_text())
    assert set(summary) == {"coarse", "fine", "data_faults", "nees_band"}
    assert set(summary["coarse"]) == {"mean_deg", "max_deg", "min_deg"}
    assert all(len(v) == 3 for v in summary["coarse"].values())
    for per_start in summary["fine"].values():
        assert set(per_start) == {"mean", "max"}
        for stats in per_start.values():
            assert set(stats) == {"mean_arcmin", "std_arcmin", "rms_arcmin",
                                  "converged_fraction", "not_converged_fraction",
                                  "diverged_fraction", "lost_fraction"}
    lines = (out / "results.csv").read_text().splitlines()
    assert len(lines) == 1 + 4 * 6 * 2
    # The max start error is the largest coarse error by magnitude, per axis.
    coarse = np.rad2deg(coarse_errors(result))
    np.testing.assert_allclose(np.abs(summary["coarse"]["max_deg"]), np.abs(coarse).max(0))


# The campaign directory's handling is under test, not the alignment: a 30 s coarse
# stage and 60 s of fine alignment (bench --set).
FAST = ["--set", "fine_duration=60", "--set", "coarse_duration=30", "--set", "t_k1=10",
        "--set", "t_k2=30", "--no-figures"]


def test_resume_keeps_finished_episodes(tmp_path):
    out = tmp_path / "c"
    args = ["bench", "paper003", "--episodes", "2", "--filters", "kf", *FAST, "--out",
            str(out), "--json", str(tmp_path / "a.json"), "--workers", "1"]
    assert main(args) == 0
    files = sorted((out / "episodes").glob("*.npz"))
    assert len(files) == 2
    kept_mtime = files[0].stat().st_mtime_ns
    files[1].unlink()  # as if interrupted before the second episode finished
    assert main(args[:-4] + ["--json", str(tmp_path / "b.json"), "--resume",
                             "--workers", "1"]) == 0
    assert files[0].stat().st_mtime_ns == kept_mtime and files[1].is_file()
    assert json.loads((tmp_path / "a.json").read_text()) == json.loads(
        (tmp_path / "b.json").read_text())


def test_resume_refuses_another_experiment(tmp_path):
    out = tmp_path / "c"
    assert main(["bench", "paper003", "--episodes", "1", "--filters", "kf", *FAST, "--out",
                 str(out), "--workers", "1"]) == 0
    assert main(["bench", "paper003", "--episodes", "1", "--filters", "kf", *FAST, "--out",
                 str(out), "--seed", "5", "--resume", "--workers", "1"]) == 2


def test_the_same_command_twice_reuses_the_campaign_and_an_edited_scenario_is_refused(
        tmp_path, capsys):
    """The README's first command run twice: the second run finds this same campaign
    (settings, scenario content, seed), reuses its episode files, prints the same
    tables and exits 0. Once the scenario file is edited (the IMU rate), the directory
    holds another campaign: refused naming the scenario, with --resume as well."""
    scenario = tmp_path / "my.toml"
    from aligngym.scenarios.config import scenario_path
    scenario.write_text(scenario_path("ship-sway-rotary").read_text())
    out, summary = tmp_path / "c", tmp_path / "c" / "summary.json"
    base = ["bench", "paper003", "--episodes", "1", "--filters", "kf", "--workers", "1",
            *FAST, "--scenario", str(scenario), "--out", str(out), "--json", str(summary)]
    assert main(base) == 0
    first = capsys.readouterr()
    episode = next((out / "episodes").glob("*.npz"))
    kept = episode.stat().st_mtime_ns
    numbers = json.loads(summary.read_text())
    assert main(base) == 0
    second = capsys.readouterr()
    assert "holds this campaign already" in second.err
    assert episode.stat().st_mtime_ns == kept and json.loads(summary.read_text()) == numbers
    assert second.out.splitlines()[:-1] == first.out.splitlines()[:-1]   # but the time
    scenario.write_text(scenario.read_text().replace("imu_rate_hz = 100.0", "imu_rate_hz = 50.0"))
    for extra in ([], ["--resume"]):
        assert main(base + extra) == 2
        err = capsys.readouterr().err
        assert "differs in scenario (its content)" in err, err
        assert episode.stat().st_mtime_ns == kept


def test_a_campaign_of_other_simulation_code_is_refused(tmp_path, capsys, monkeypatch):
    """The manifest holds the hash of the code that prepares an episode and of the
    libraries (``simulation_versions``): episodes prepared by other code are not
    resumed."""
    from aligngym.scenarios import truth_cache
    out = tmp_path / "c"
    base = ["bench", "paper003", "--episodes", "1", "--filters", "kf", "--workers", "1",
            *FAST, "--out", str(out)]
    assert main(base) == 0
    capsys.readouterr()
    monkeypatch.setattr(truth_cache, "simulation_versions", lambda: "other code")
    assert main(base + ["--resume"]) == 2
    assert "differs in simulation (its code or library versions)" in capsys.readouterr().err


def test_outputs_checked_before_any_work(tmp_path, capsys):
    """An --out holding a campaign needs --resume or --force (which removes its episode
    files: no other seed's episodes mix in); an unwritable --json or --out is refused
    in one line before any episode is simulated."""
    out = tmp_path / "c"
    base = ["bench", "paper003", "--episodes", "1", "--filters", "kf", "--workers", "1", *FAST]
    assert main(base + ["--out", str(out)]) == 0
    capsys.readouterr()
    assert main(base + ["--out", str(out), "--seed", "5"]) == 2
    assert ("campaign.json differs in seed); use --force to replace it"
            in capsys.readouterr().err)
    assert main(base + ["--out", str(out), "--seed", "5", "--force"]) == 0
    from aligngym.scenarios.campaign import episode_seeds
    assert [p.name for p in (out / "episodes").glob("*.npz")] == [
        f"seed_{episode_seeds(5, 1)[0]}.npz"]
    (out / "campaign.json").unlink()          # episodes whose campaign is unknown
    capsys.readouterr()
    assert main(base + ["--out", str(out), "--resume"]) == 2
    assert "no campaign.json" in capsys.readouterr().err
    leftover = tmp_path / "only_tmp" / "episodes"
    leftover.mkdir(parents=True)
    (leftover / "seed_3.tmp.npz").write_bytes(b"half")   # not a campaign
    assert main(base + ["--out", str(leftover.parent)]) == 0
    blocker = tmp_path / "file"
    blocker.write_text("")
    capsys.readouterr()
    assert main(base + ["--json", str(blocker / "s.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--json" in err[0]
    assert main(base + ["--out", str(blocker / "d")]) == 2
    assert "--out" in capsys.readouterr().err


def test_hull_frame_biases_are_not_modulated():
    """[imu] bias_frame = "hull": the sensed bias, turned back into the hull frame, is the
    drawn constant; in the sensor frame it averages out (the gimbal modulates it)."""
    from aligngym.models.attitude import dcm_to_rotvec, quat_to_dcm, rotvec_to_dcm
    from aligngym.scenarios.config import load_scenario
    from aligngym.scenarios.simulate import simulate

    config = load_scenario("ship-sway-rotary-paper").with_options(duration=120.0)
    erroneous, ideal = simulate(config, seed=4), simulate(config, seed=4, ideal=True)
    dt = config.imu_interval
    # C_s^b from the truth's attitudes (not the gimbal formula the code uses), mid-interval.
    C_b_n, C_s_n = quat_to_dcm(ideal.truth.q_b_n), quat_to_dcm(ideal.truth.q_s_n)
    C_s_b_k = np.swapaxes(C_b_n, -1, -2) @ C_s_n
    C_s_b = rotvec_to_dcm(0.5 * dcm_to_rotvec(C_s_b_k[1:] @ np.swapaxes(C_s_b_k[:-1], -1,
                                                                      -2))) @ C_s_b_k[:-1]
    for name, sensed in (("gyro", erroneous.dtheta - ideal.dtheta),
                         ("accel", erroneous.dv - ideal.dv)):
        bias = getattr(erroneous.imu_realization, name).bias
        in_hull = np.einsum("mij,mj->mi", C_s_b, sensed).mean(0) / dt
        in_sensor = sensed.mean(0) / dt
        np.testing.assert_allclose(in_hull, bias, rtol=0.02, atol=0.02 * np.abs(bias).max())
        assert np.abs(in_sensor).max() < 0.2 * np.abs(bias).max()


@pytest.fixture(scope="module")
def paper_setup_calm():
    """The paper setup's episode 3 in a calm sea with constant biases (one episode for
    every filter below)."""
    from aligngym.scenarios.experiments import experiment as make_experiment

    exp = make_experiment("paper003", "paper")
    config = calm(exp.scenario_config(), imu=CONSTANT_BIASES)
    return exp, config, prepare_episode(exp, 3, config=config)


@pytest.mark.parametrize("name", ["kf", "sakf-r", "makf-r"])
def test_paper_setup_converges_to_the_unmodulated_bias_floors(paper_setup_calm, name):
    """The paper setup in a calm sea (biases fixed in the hull frame, calm-sea R): level
    and heading settle on accelerometer bias / g and -east drift / (Omega cos L) +
    phi_N tan L within 5 % (the tan L term alone is ~10 % here), not below them as with
    modulated biases."""
    exp, config, episode = paper_setup_calm
    assert config.imu_bias_frame == "hull"
    floor = static_alignment_floor(episode.C_b_n_true[-1], episode.gyro_bias,   # hull frame
                                   episode.accel_bias, episode.lat, episode.h)
    run = run_filter(name, "x", np.array([0.1, -0.1, 1.0]) * deg, [episode], exp)
    np.testing.assert_allclose(run.error_n[0, -1], floor, rtol=0.05)


PAPER_SETUP_IDEAL = {"kf": (15.0, 0.2), "sakf-r": (3.0, 0.05), "makf-r": (3.0, 0.05),
                     "imakf-r": (3.0, 0.05)}
"""Bounds (heading, level; arcmin, |final error|) of the paper setup's filters on
error-free sensors under the paper's sway, about 1.3-1.5x what they leave on 4 episodes of
seed 7 (kf 10.3' / 0.12', sakf-r 2.1' / 0.03', makf-r = imakf-r 2.3' / 0.035')."""


@pytest.fixture(scope="module")
def paper_setup_ideal():
    """Four episodes of the paper setup (seed 7) with error-free sensors, and the paper's
    start: the mean coarse error of the same episodes with the paper's sensors."""
    from aligngym.scenarios.campaign import episode_seeds
    from aligngym.scenarios.experiments import experiment as make_experiment
    exp = make_experiment("paper003", "paper")
    config = replace(exp.scenario_config(), imu=ImuSpec())
    seeds = episode_seeds(7, 4)
    start = exp.start_errors([exp.prepare_episode(s) for s in seeds])["mean"]
    return exp, [exp.prepare_episode(s, config=config) for s in seeds], start


@pytest.mark.parametrize("name", list(PAPER_SETUP_IDEAL))
def test_paper_setup_ideal_data_stays_within_its_stated_bound(paper_setup_ideal, name):
    """Error-free IMU under the paper's sway, the paper's setup (calm-sea R of 3 mm/s: the
    sway taken for white measurement noise) from the paper's start: no sensor error and
    no floor, so what is left is the setup's own response to the sway, within the stated
    bound. The KF's is the paper's claim itself (it is lost under sway: 10' of heading,
    flagged in 2 of 4 episodes, NEES 500-4600 on exact sensors); the R-scaling factors
    hold it at 2-2.3' (NEES of the 3 attitude states: sakf-r 6.5-15, makf-r and imakf-r,
    one filter here, 44-175; all overconfident, sakf-r least)."""
    exp, episodes, start = paper_setup_ideal
    heading, level = PAPER_SETUP_IDEAL[name]
    run = run_filter(name, "mean", np.broadcast_to(start, (len(episodes), 3)), episodes, exp)
    err = np.abs(run.error_n[:, -1]) / arcmin
    info = f"{name}: final |error| {np.round(err, 4).tolist()}', diverged {run.diverged}"
    assert np.all(err[:, 2] < heading), info
    assert np.all(err[:, :2] < level), info
    if name != "kf":
        assert not run.diverged.any(), info


def test_bench_paper_setup_table(tmp_path):
    """--setup paper: the R-scaling filters by default, the same JSON shape."""
    path = tmp_path / "p.json"
    assert main(["bench", "paper003", "--setup", "paper", "--episodes", "2", "--workers", "1",
                 *FAST, "--json", str(path)]) == 0
    summary = json.loads(path.read_text())
    assert set(summary["fine"]) == {"kf", "sakf-r", "makf-r", "imakf-r"}
    assert set(summary["fine"]["makf-r"]) == {"mean", "max"}
    # Sensor-frame biases are not the paper's setup: refused before any simulation.
    assert main(["bench", "paper003", "--setup", "paper", "--scenario", "ship-sway-rotary",
                 "--episodes", "1"]) == 2


@dataclass(frozen=True)
class FromTheMeanStart(Paper003Experiment):
    """Paper 003's experiment from the mean coarse error only."""

    starts = ("mean",)


def test_sway_aware_kf_keeps_its_measured_consistency_under_sway():
    """kf-sway (the sway velocity as narrow-band states, calm-sea R) under the paper's
    sway, 20 episodes: the mean final NEES of the 9 attitude and bias states lies between
    the low end of its 95 % chi-square band and 1.25x its high end.

    Not the band itself: kf-sway is about 24 % overconfident. Over 60 episodes (seeds 0, 7
    and 11, 20 each) its mean final NEES is 11.15 against the band [7.96, 10.1] (12.21,
    11.51 and 9.73 per seed; the band of 20 is [7.24, 10.95]); this test used to assert
    the band at seed 11 alone, the one seed of the three inside it. Its heading error is
    not always below the KF's either (RMS 0.196' against 0.206', 0.192' against 0.167',
    0.183' against 0.201'). A start covariance of the sway states 4x too small moves the
    NEES beyond the bound; their process noise does not (0.01x passes, as it did the band
    at seed 11): the attitude and bias states do not see it over 600 s."""
    n = 20
    # One process (the sway campaign above runs in worker processes): the campaign's
    # first 4 episodes reuse that campaign's truths.
    result = run_campaign(episodes=n, seed=SWAY_SEED, filters=["kf-sway"], workers=1,
                          progress=False, experiment=FromTheMeanStart())
    (run,) = result.runs
    assert run.filter == "kf-sway" and run.start == "mean"
    low, high = chi2.ppf([0.025, 0.975], 9 * n) / n
    assert low < run.nees[:, -1].mean() < 1.25 * high


def test_sway_aware_model_oracles(experiment):
    """The 18-state model: P0 positive definite; its velocity integral carries the start
    sway term -C_n^i(t1) v(t1) as the 12-state model's does; at t1 the measurement sees
    only dV's own uncertainty (that term cancels the oscillators' start); the
    oscillators' covariance is stationary (A P A^T + Q = P)."""
    from aligngym.estimators.inertial_fine import SWAY

    exp = replace(experiment, fine_duration=20.0)
    episode = prepare_episode(exp, 5)          # its own 140 s run, not the 720 s scenario
    start = np.array([0.01, -0.01, 0.05])
    sway, plain = exp.model([episode], start, "sway-aware"), exp.model([episode], start)
    _, P0 = sway.initial()
    _, P0_plain = plain.initial()
    assert np.all(np.linalg.eigvalsh(P0[0]) > 0)
    H0 = np.zeros((3, 18))
    H0[:, :3] = np.eye(3)
    H0[:, SWAY] = sway._C_n_i[0, 0] @ np.eye(3, 6, k=0)[:, [0, 3, 1, 4, 2, 5]]
    np.testing.assert_allclose(P0[0, :3, :3], P0_plain[0, :3, :3], atol=1e-15)
    np.testing.assert_allclose(H0 @ P0[0] @ H0.T, exp.velocity_sigma ** 2 * np.eye(3),
                               atol=1e-15)
    step = sway.transition(0)
    A, Q = step.matrix[0, SWAY, SWAY], step.noise[0, SWAY, SWAY]
    P_s = P0[0, SWAY, SWAY]
    np.testing.assert_allclose(A @ P_s @ A.T + Q, P_s, atol=1e-15)


@pytest.fixture(scope="module")
def paper_setup_episode():
    """Paper-setup episode 43 of campaign seed 7: its North sway near its peak at the fine
    start (without the start sway in P0 the East factor locked that channel out)."""
    from aligngym.scenarios.experiments import experiment as make_experiment
    exp = make_experiment("paper003", "paper")
    return exp, prepare_episode(exp, 7000043, config=exp.scenario_config())


def test_paper_setup_start_sway_in_p0_keeps_the_east_factor_from_locking_out(
        paper_setup_episode):
    """ALGORITHMS 2.3: the start sway -C_n^i(t1) v_D(t1) is a constant in every
    measurement; no R-scaling absorbs it. Without its P0 the East factor follows the
    persistent residual (median lambda_E over the last 300 s: 3.3e4 measured); with it, a
    few tens (58.5). 50 episodes of seed 7: 11 -> 1 episodes above 1000."""
    exp, episode = paper_setup_episode
    start = episode.coarse_error
    lam = {}
    for label, e in (("none", replace(exp, start_sway_sigma=(0.0,) * 3)), ("default", exp)):
        run = run_filter("makf-r", "x", start, [episode], e)
        lam[label] = np.nanmedian(run.result.factors[0, 300:, 0])
    assert lam["none"] > 1000.0 and lam["default"] < 100.0, lam


def test_paper_setup_divergence_is_judged_against_the_unmodelled_floor(paper_setup_episode):
    """Hull-frame biases leave a floor the sensor-frame model cannot hold: the judgement
    subtracts it. The filter ends near it (1.6' off a 3.2' heading floor, within 0.6 of
    its size, where the floor's mirror image is 6.4' away); a run ending on the floor (however
    far from zero, sigma small) is converged; one ending 45 sigma + 2' off it is diverged
    and says so."""
    from aligngym.models.attitude import rotvec_to_dcm
    from aligngym.scenarios.campaign.runs import analyse_run
    exp, episode = paper_setup_episode
    floor = exp.unmodelled_floor([episode])
    assert floor.shape == (1, 3) and abs(floor[0, 2]) > 0.5 * arcmin
    run = run_filter("makf-r", "x", episode.coarse_error, [episode], exp)
    np.testing.assert_allclose(run.floor, floor)
    assert not run.diverged[0]
    heading = run.error_n[0, -1, 2]
    assert abs(heading - floor[0, 2]) < 0.6 * abs(floor[0, 2]) < abs(heading + floor[0, 2])
    result = run.result
    for offset, lost in ((0.0, False), (15 * 3 * result.sigma_n[0, -1, 2] + 2 * arcmin, True)):
        phi = floor[0] + np.array([0.0, 0.0, offset])
        C_est = result.C_s_n.copy()
        C_est[0, -1] = rotvec_to_dcm(-phi) @ episode.C_s_n_true[-1]
        judged = analyse_run("makf-r", "x", replace(result, C_s_n=C_est), [episode], exp)
        assert judged.diverged[0] == lost, (offset, judged.reason)
        if lost:
            assert judged.reason[0] == "final error - floor > 5 x 3 sigma"
