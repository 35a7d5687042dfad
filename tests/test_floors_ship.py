"""Ideal-data and physical-floor checks of every default filter of papers 003 and 004
(issue 24 item 3): checks that would have caught paper 002's false heading sensitivity.

Errors are the misalignment phi E, N, U of ``FilterRun.error_n`` (local level n, ENU);
sigma is the filter's own 1-sigma of the same axes (``sigma_n``); both at the last epoch.
NEES is ``FilterRun.nees`` at the last epoch only (not averaged over time: successive
epochs are correlated, so a time average has no chi-square law); its band is the 95 %
two-sided band of the mean of n independent chi-square(dof) values, chi2(dof n) / n.
"""
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.stats import chi2

from aligngym.estimators.metrics import static_alignment_floor
from aligngym.models.units import arcmin, deg
from aligngym.scenarios.campaign import episode_seeds, run_filter
from aligngym.scenarios.experiments import experiment
from aligngym.scenarios.experiments.paper004 import MISALIGNMENTS
from aligngym.sensors.imu import ImuSpec

EXP3 = experiment("paper003")
"""Paper 003 as shipped: 120 s coarse (i_b0) alignment, 600 s fine, R from the sway."""
SEEDS3 = episode_seeds(7, 4)          # aligngym regress's paper003 campaign seed
EXP4 = experiment("paper004", fine_duration=540.0)
"""Paper 004, moderate swing, large start, the fine run cut at 600 s: the start of the
paper's accuracy window, after the indexer's first 180 deg turn (300-306 s)."""
SEEDS4 = episode_seeds(13, 4)         # aligngym regress's paper004 campaign seed
CORNERS = np.array([[1.0, -1.0, 1.0], [-1.0, 1.0, -1.0]]) * np.deg2rad(
    MISALIGNMENTS["large"][0])
"""The largest starts paper 004 draws: corners of its uniform box, +-(10, -10, 60) deg."""


def nees_band(dof: int, n: int) -> np.ndarray:
    """95 % two-sided band of the mean NEES of n independent episodes, dof states."""
    return chi2.ppf([0.025, 0.975], dof * n) / n


def final(run, rows) -> SimpleNamespace:
    """The last epoch of a run's episodes rows: error, sigma (B, 3) rad; nees (B,)."""
    return SimpleNamespace(error=run.error_n[rows, -1], sigma=run.result.sigma_n[rows, -1],
                           nees=run.nees[rows, -1])


def show(value, sigma=None) -> str:
    """Errors (and sigmas) in arcmin, for the assertion messages."""
    text = np.array2string(np.asarray(value) / arcmin, precision=4)
    if sigma is None:
        return text
    return f"{text}' (sigma {np.array2string(np.asarray(sigma) / arcmin, precision=4)}')"


# --- paper 003: rotary SINS on the swaying ship ---------------------------------------------
@pytest.fixture(scope="module")
def ship():
    """Paper 003's ship, 4 episodes of seed 7: erroneous sensors ("real"), the same sway
    with error-free sensors ("ideal"), and one error-free episode in a calm sea (no
    sway, the gimbal turning; "calm"). Every default filter from the mean coarse error
    (real) and from the largest coarse error per axis (all), with the experiment's
    tuning (the datasheet and the sway's R) on every data set."""
    config = EXP3.scenario_config()
    error_free = replace(config, imu=ImuSpec())
    motion = replace(config.motion, yaw_amplitude=0.0, pitch_amplitude=0.0,
                     roll_amplitude=0.0, linear_amplitude=(0.0, 0.0, 0.0))
    real, ideal = [], []
    for seed in SEEDS3:       # the same sway twice: the truth is cached per motion
        real.append(EXP3.prepare_episode(seed))
        ideal.append(EXP3.prepare_episode(seed, config=error_free))
    # No linear phases drawn (with zero amplitudes they change nothing): the calm truth
    # is then the one every seed shares (tests/test_paper003.py's calm runs have it too).
    calm = EXP3.prepare_episode(SEEDS3[0], config=replace(error_free, motion=motion,
                                                          random_linear_phase=False))
    starts = EXP3.start_errors(real)
    tuning = EXP3.tuning(config)
    n, runs = len(real), {}
    # One batch per filter (its episodes are independent): [real, ideal, calm] from the
    # largest error, then real from the mean error.
    start = np.vstack([np.broadcast_to(starts["max"], (2 * n + 1, 3)),
                       np.broadcast_to(starts["mean"], (n, 3))])
    for name in EXP3.default_filters:
        run = run_filter(name, "max", start, real + ideal + [calm] + real, EXP3,
                         tuning=tuning)
        runs[name] = {"real": {"mean": final(run, slice(2 * n + 1, None)),
                               "max": final(run, slice(0, n))},
                      "ideal": final(run, slice(n, 2 * n)), "calm": final(run, [2 * n])}
    return SimpleNamespace(real=real, starts=starts, runs=runs)


def test_every_default_filter_is_checked():
    assert set(EXP3.default_filters) == {"kf", "sakf", "makf", "imakf"}
    assert set(EXP4.default_filters) == {p if isinstance(p, str) else p.values[0]
                                         for p in FILTERS4}


@pytest.mark.parametrize("name", EXP3.default_filters)
def test_003_error_free_calm_sea_from_the_largest_coarse_error_ends_at_zero(ship, name):
    """Error-free IMU, no sway, the gimbal turning, from the campaign's largest coarse
    error per axis (about 0.6', 0.03', 178'): the floor is 0, and the filter must end
    within 0.002' of level and 0.03' of heading (measured at 600 s: 6e-5' and 0.0028' for
    all four filters, the start's decayed transient; 0.03' is 1/25 of its own heading
    sigma of 0.76'; paper 002's false heading sensitivity left 75-340')."""
    assert abs(ship.starts["max"][2]) > 1 * deg         # the start is large
    run = ship.runs[name]["calm"]
    assert np.all(np.abs(run.error[:, :2]) < 0.002 * arcmin), show(run.error, run.sigma)
    assert np.all(np.abs(run.error[:, 2]) < 0.03 * arcmin), show(run.error, run.sigma)


PAPER_MODEL_G = pytest.mark.xfail(strict=True, reason=(
    "the paper's model (003 eq. 23-35, ALGORITHMS 2.4) has dV/phi = -[g^i x]: the sway's "
    "acceleration, left out, rectifies with the feedback into a phi_N bias of -1.3 sigma "
    "(-0.0034' to -0.0041' at 600 s); [dW^i x] in that block removes it (+0.33 sigma)"))


@pytest.mark.parametrize("name", [pytest.param(n, marks=PAPER_MODEL_G)
                                  for n in EXP3.default_filters])
def test_003_error_free_sensors_under_the_sway_leave_no_systematic_error(ship, name):
    """Error-free IMU under the paper's sway (random linear phases per episode), from the
    largest coarse error: the only error left is the filter's response to the sway,
    which its R (1.25 x the sway peak) covers: every episode within 3 sigma per axis, and
    the mean over the 4 episodes (where the random-phase response averages out: what
    stays is phase-independent, a model error) within 0.5 sigma per axis (a systematic
    half sigma already adds 25 % to that axis's share of the NEES).

    FINDING (the paper's model, not a coding slip): all four filters fail on phi_N, -1.30 sigma on average
    (-0.0034' to -0.0041' against 0.0029'), the same sign in every episode; E and U
    average 0.02-0.12 sigma. Cause, shown in a scratch copy: the 12-state model's
    dV/phi block is -[g^i x] T where the integral measures [dW^i x] (the sway's
    acceleration is left out); with the closed-loop feedback the attitude error
    correlates with the sway and the dropped term rectifies. The bias grows with
    (A_N 2 pi / T_N)^2 (x4 for twice the North amplitude, /4 for twice the period), is
    independent of the start, vanishes open loop, and with [dW^i x] in that block drops
    to +0.33 sigma (-0.0145' -> -0.0002' at 300 s)."""
    run = ship.runs[name]["ideal"]
    z = run.error / run.sigma
    assert np.all(np.abs(z) < 3.0), show(run.error, run.sigma)
    assert np.all(np.abs(z.mean(0)) < 0.5), (f"mean error / sigma {z.mean(0)}; "
                                             + show(run.error, run.sigma))


@pytest.mark.parametrize("name", EXP3.default_filters)
def test_003_error_free_sensors_under_the_sway_stay_within_the_paper_models_bound(ship,
                                                                                  name):
    """The same error-free sway, against the stated bound of the paper's own model (its
    dV/phi block -[g^i x], the finding above): every episode within 3 sigma per axis,
    the 4-episode mean within 0.5 sigma on E and U, and phi_N's systematic error below
    1.6 sigma and 0.005' (measured -1.30 sigma, -0.0034' to -0.0041' per episode, the
    same for all four filters). A larger rectification fails here; its removal fails the
    strict xfail above."""
    run = ship.runs[name]["ideal"]
    z = run.error / run.sigma
    info = f"mean error / sigma {z.mean(0)}; " + show(run.error, run.sigma)
    assert np.all(np.abs(z) < 3.0), info
    assert np.all(np.abs(z.mean(0)[[0, 2]]) < 0.5), info
    assert abs(z.mean(0)[1]) < 1.6, info
    assert np.all(np.abs(run.error[:, 1]) < 0.005 * arcmin), info


def unmodulated_floor(episode) -> np.ndarray:
    """phi E, N, U (rad) that the episode's drawn biases would leave on a still base
    without the rotation, at the last epoch's attitude (biases rotated to n)."""
    return static_alignment_floor(episode.C_s_n_true[-1], episode.gyro_bias,
                                  episode.accel_bias, episode.lat, episode.h)


@pytest.mark.parametrize("start", ["mean", "max"])
@pytest.mark.parametrize("name", EXP3.default_filters)
def test_003_modulated_biases_leave_no_floor_and_the_nees_is_in_band(ship, name, start):
    """Erroneous sensors, the paper's sway, from the mean (the experiment's default) and
    the largest coarse error. The double-axis gimbal modulates all three axes of the
    sensor-frame biases, so no bias floor is left (the floor is 0; hull-frame biases,
    which it cannot modulate, are ``--setup paper``'s, tests/test_paper003.py): every
    episode within 3 sigma per axis, the level RMS over episodes 10x below the level
    floors the same biases would leave unmodulated (measured 0.0045' / 0.0038' against
    0.37' / 0.20'; heading is not compared: at 600 s its sigma, 0.76', set by the sway's
    R, is of the order of the unmodulated heading floors of these 0.01 deg/h gyros,
    0.56' RMS), and the mean final NEES of the 9 attitude and bias states (4 episodes)
    in its band 5.33-13.61. Measured: |error| <= 1.96 sigma (phi_N, which carries the
    sway's systematic part above), NEES 6.31 (kf, sakf), 6.44 (makf, imakf) from the
    mean start, 6.38 / 6.48 from the largest."""
    run = ship.runs[name]["real"][start]
    assert np.all(np.abs(run.error) < 3.0 * run.sigma), show(run.error, run.sigma)
    floor = np.stack([unmodulated_floor(e) for e in ship.real])
    rms = lambda a: np.sqrt(np.mean(a ** 2, axis=0))    # noqa: E731
    assert np.all(rms(run.error[:, :2]) < 0.1 * rms(floor[:, :2])), (show(rms(run.error)),
                                                               show(rms(floor)))
    low, high = nees_band(9, len(ship.real))
    assert low < run.nees.mean() < high, run.nees


# --- paper 004: small boat, MEMS IMU on an azimuth indexer, GNSS ---------------------------
@pytest.fixture(scope="module")
def boat():
    """Paper 004's moderate swing, 4 episodes of seed 13 from their large starts
    (uniform in +-10, +-10, +-60 deg) with erroneous IMU and GNSS ("real"), and error-free
    IMU and GNSS (one data set: the prescribed swing does not depend on the seed) from
    the two CORNERS ("ideal"), every default filter believing the datasheet."""
    config = EXP4.scenario_config()
    real = [EXP4.prepare_episode(seed) for seed in SEEDS4]
    error_free = replace(config, imu=ImuSpec(), gps=replace(
        config.gps, position_sigma_h=0.0, position_sigma_v=0.0, velocity_sigma=0.0))
    ideal = EXP4.prepare_episode(SEEDS4[0], config=error_free)
    draws = EXP4.start_errors(real)["large"]
    n, runs = len(real), {}
    for name in EXP4.default_filters:
        run = run_filter(name, "large", np.vstack([draws, CORNERS]),
                         real + [ideal] * len(CORNERS), EXP4)
        runs[name] = {"real": final(run, slice(0, n)), "ideal": final(run, slice(n, None)),
                      "diverged": run.result.diverged}
    return SimpleNamespace(real=real, draws=draws, runs=runs)


def issue27(text):
    return pytest.mark.xfail(strict=True, reason="issue 27: " + text)


STUKF_IDEAL = issue27(
    "with its points at sqrt(1.5) sigma (STUKF_SPREAD; real data now in band, NEES mean "
    "10.8, was 37 with kappa = 3 - n) one corner's transient is still 1.7 sigma: ideal "
    "13' / -50' (sigma 29.5') at 600 s (60' / -96' at sqrt(3) sigma); the z gyro (indexer "
    "axis, unmodulated) takes the heading transient")
FILTERS4 = [
    "stukf",
    pytest.param("stekf", marks=issue27(
        "the STEKF's large-start transient is the method's (PSINS's alignvn_stekf "
        "matches ours to 0.4-1.3' of heading). Ideal: heading 460' / -398' (sigma 28') "
        "at 600 s; real: NEES 9.0/292.7/12.7/17.4, mean 83 (146 before the reset's "
        "P <- G P G^T); its small-angle velocity feedback (6.8) also leaves 1.4 m/s at a "
        "52 deg estimate (tests/test_rotation_vector.py)")),
    "ukf-3n",
    "ekf",
]


@pytest.mark.parametrize("name", [pytest.param("stukf", marks=STUKF_IDEAL), *FILTERS4[1:]])
def test_004_error_free_data_from_the_largest_start_end_inside_one_sigma(boat, name):
    """Error-free IMU and GNSS from the corners of the large start, +-(10, -10, 60) deg,
    600 s: the floor is 0, so the filter's error is only its start transient, which
    must not use up its own 1 sigma on any axis (sigma 0.53' level, 28-29' heading:
    the MEMS noise it believes; were the transient larger, the same filter on real
    data could not be consistent). Measured for ukf-3n: 0.01' level, 0.22' / 1.32'
    heading with the reset's P <- G P G^T (0.19' and 15' / -18' before it)."""
    run = boat.runs[name]["ideal"]
    assert not boat.runs[name]["diverged"].any()
    assert np.all(np.abs(run.error) < run.sigma), show(run.error, run.sigma)


STATED_004 = {"stukf": (2.2, 1.0), "stekf": (21.0, 5.0)}
"""Bounds, in units of the filter's own final sigma (heading, level), of the ST filters'
large-start transient on error-free data at 600 s, about 1.3x what they leave at the
two corners: stukf 1.7 sigma heading (13' and -50', sigma 29.5'), 0.53 sigma level;
stekf 16.5 sigma heading (460' and -398', sigma 28'), 3.8 sigma level (2.0', sigma
0.53')."""


@pytest.mark.parametrize("name", list(STATED_004))
def test_004_error_free_data_from_the_largest_start_stays_within_the_stated_bound(boat,
                                                                                  name):
    """The corners of the large start on error-free data, for the two ST filters that
    fail the 1-sigma bound above: stukf (one corner's heading transient through the z
    gyro, the indexer axis, which the rotation does not modulate; 60' / -96' with kappa
    = 3 - n) and stekf (the method's: PSINS's alignvn_stekf on the experiment's episodes follows
    ours within 0.43' of heading over 600-2000 s on 2 episodes,
    benchmarks/psins/filters_004.py; its small-angle
    velocity feedback leaves 1.4 m/s at a 52 deg estimate). Not diverged, and every axis
    within the stated multiple of its own sigma. A worse transient fails here; one
    inside 1 sigma would turn the strict xfail above into a failure."""
    heading, level = STATED_004[name]
    run = boat.runs[name]["ideal"]
    z = np.abs(run.error) / run.sigma
    assert not boat.runs[name]["diverged"].any()
    assert np.all(z[:, 2] < heading), show(run.error, run.sigma)
    assert np.all(z[:, :2] < level), show(run.error, run.sigma)


@pytest.mark.parametrize("name", FILTERS4)
def test_004_indexing_leaves_no_floor_and_the_nees_is_in_band(boat, name):
    """Erroneous IMU and GNSS, the 4 episodes' own large starts, 600 s. Floors: on a still
    base level would sit at nabla_h^n / g (2 mg: 7') and heading at -eps_E / (Omega cos L)
    (2 deg/h at 28.2 N: 9 deg); the 180 deg turns about the hull's z axis flip the
    horizontal gyro and accelerometer biases in n, so after the first turn (300 s) both
    are observable and no floor is left: the z (indexer-axis) biases stay unmodulated,
    but eps_z drives heading only through its drift and nabla_z is vertical. Before the
    turn no floor can be asserted either: the +-10/5 deg swing partly modulates the
    horizontal biases while the heading is still tens of degrees off. So: every
    episode within 3 sigma per axis and the mean final NEES of the 9 attitude and bias
    states in its band 5.33-13.61. Measured: ukf-3n heading <= 1.8 sigma, NEES
    8.7/8.0/2.4/8.0, mean 6.8; stukf <= 2.6 sigma, NEES 9.6/26.3/1.2/6.1, mean 10.8 (37
    with kappa = 3 - n)."""
    run = boat.runs[name]["real"]
    assert np.abs(boat.draws[:, 2]).max() > 30 * deg          # the start is large
    assert not boat.runs[name]["diverged"].any()
    assert np.all(np.abs(run.error) < 3.0 * run.sigma), show(run.error, run.sigma)
    low, high = nees_band(9, len(boat.real))
    assert low < run.nees.mean() < high, run.nees
