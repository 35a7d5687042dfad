"""Papers 000 and 001 (the car) against physics (issue 24, item 3): every default filter
on error-free data from the experiment's own start ends near 0, and on the paper's
sensors from the paper's own start at the floors the physics leaves, inside its own
sigma, with its NEES in the chi-square band over a small campaign.

Errors are ``FilterRun.error_n``: phi (E, N, U) in n with C_true = exp([phi x]) C_est,
rad; sigma the filter's 1 sigma of the same. NEES as the experiments define it (000: 9
states, Euler errors, gyro drift, accelerometer bias; 001: all 15). One batch per filter:
the real episodes and the ideal ones run together (same epochs, the same tuning: the
filter is told the paper's sensors whatever the data), so each filter runs once.
"""
from dataclasses import dataclass, replace

import numpy as np
import pytest
from scipy.stats import chi2

from aligngym.estimators.metrics import static_alignment_floor
from aligngym.models.earth import normal_gravity
from aligngym.models.units import arcmin
from aligngym.scenarios.campaign import episode_seeds, run_filter
from aligngym.scenarios.experiments import experiment
from aligngym.sensors.imu import ImuSpec

FILTERS_000 = experiment("paper000").default_filters
FILTERS_001 = experiment("paper001").default_filters
EPISODES = 3
SEED = 0

RING = """name = "ring-floors"
paper = "000"
world = "car"
[origin]
latitude_deg = 40.0
longitude_deg = 116.0
height_m = 0.0
[run]
duration_s = 370.0
imu_rate_hz = 100.0
[imu]
preset = "paper000-fog"
[motion]
track = "ring"
radius_m = 100.0
speed = 8.0
start_time_s = 5.0
stop_time_s = 300.0
imu_offset_b_m = [0.0, 0.3, 0.2]
[odometer]
preset = "paper000"
"""
"""ring-road-odometer shortened: drive 5-300 s, then 70 s standing (the paper's 600 s
and 300 s cost 6 s an episode)."""

FIGURE8 = """name = "figure8-floors"
paper = "001"
world = "car"
[origin]
latitude_deg = 30.5
longitude_deg = 114.3
height_m = 20.0
[run]
duration_s = 200.0
imu_rate_hz = 100.0
[imu]
preset = "paper001-van"
[motion]
track = "figure8"
radius_m = 300.0
speed = 16.7
start_time_s = 40.0
imu_offset_b_m = [0.0, 0.3, 0.2]
gps_antenna_b_m = [0.0, -0.5, 1.2]
[gps]
preset = "rtk"
"""
"""figure8-gps shortened: still 40 s (coarse alignment over 30 s), then 160 s at 60 km/h."""


def nees_band(dof: int, episodes: int) -> tuple[float, float]:
    """Two-sided 95 % band of the mean over ``episodes`` of one epoch's NEES (dof)."""
    lo, hi = chi2.ppf([0.025, 0.975], dof * episodes) / episodes
    return float(lo), float(hi)


def last(run, b, window: float = 60.0):
    """Episodes b's max |error| (.., 3) rad and max NEES over the last ``window`` s."""
    t = run.result.t
    k = t >= t[-1] - window - 1e-9
    return np.abs(run.error_n[b][..., k, :]).max(-2), run.nees[b][..., k].max(-1)


def arcmin_text(values) -> str:
    return np.array2string(np.asarray(values) / arcmin, precision=3, suppress_small=True)


def assert_within_stated(run, b, bound, label: str) -> None:
    """Episodes b's max |error| over the last 60 s within bound = (heading, level),
    arcmin: a method-limited filter's stated ideal-data bound."""
    heading, level = bound
    worst, _ = last(run, b)
    info = f"{label}: last 60 s max |error| {arcmin_text(worst)}'"
    assert np.all(worst[..., 2] < heading * arcmin), info
    assert np.all(worst[..., :2] < level * arcmin), info


def ideal_limit(dof: int) -> float:
    """NEES bound on noise-free data: a consistent filter's state error there is its
    transient alone, below the noise the chi-square counts; one-sided 97.5 %."""
    return float(chi2.ppf(0.975, dof))


# --- paper 000 ---------------------------------------------------------------------------------
@dataclass
class Car:
    """One paper's episodes for the floors: exp, the batch [real x EPISODES, ideal ...],
    start errors (B, 3) rad (real: the paper's own start; ideal: see the fixture), the
    batch labels and the count of real episodes."""

    exp: object
    episodes: list
    starts: np.ndarray
    labels: list
    real: int


def ideal_000_config(exp):
    """The experiment's scenario with error-free sensors: no IMU errors, no odometer
    scale error (as ``simulate(ideal=True)``: the mounting and the encoder's 2 mm pulses
    stay)."""
    config = exp.scenario_config()
    return replace(config, imu=ImuSpec(), odometer=replace(
        config.odometer, scale_error=0.0, scale_error_sigma=0.0))


def build_000(path) -> Car:
    exp = experiment("paper000", scenario=str(path), coarse_duration=45.0)
    real = [exp.prepare_episode(s) for s in episode_seeds(SEED, EPISODES)]
    ideal = exp.prepare_episode(SEED, ideal_000_config(exp))
    assert not ideal.gyro_bias.any() and not ideal.accel_bias.any()
    starts = np.concatenate([exp.start_errors(real)["coarse"],
                             exp.start_errors([ideal])["coarse"],
                             exp.start_errors([ideal])["large"]])
    return Car(exp, real + [ideal, ideal], starts,
               [f"seed {s}" for s in episode_seeds(SEED, EPISODES)]
               + ["ideal, coarse", "ideal, large"], EPISODES)


@pytest.fixture(scope="module")
def car000(tmp_path_factory):
    """Three episodes of the paper's sensors from the paper's coarse start (the
    odometer-aided coarse alignment over 15-60 s: level 2', heading 9.7, 10.8 and 2.3
    deg), and one ideal episode (every ideal episode is the same drive) from its own
    coarse start (15.3 deg of heading) and from the large start (30 deg, the coarse
    level errors kept)."""
    path = tmp_path_factory.mktemp("floors000") / "ring.toml"
    path.write_text(RING)
    return build_000(path)


class Runs:
    """Each filter run once over a car's batch, on demand."""

    def __init__(self, car: Car, exp=None):
        self.car, self.exp, self.done = car, exp or car.exp, {}

    def __call__(self, name):
        if name not in self.done:
            self.done[name] = run_filter(name, "batch", self.car.starts, self.car.episodes,
                                         self.exp)
        return self.done[name]


@pytest.fixture(scope="module")
def runs000(car000):
    return Runs(car000)


def level_floor_000(run, car: Car) -> tuple[np.ndarray, np.ndarray]:
    """At the last epoch (the car standing 70 s): the level floor phi_E = -r_N/g, phi_N =
    r_E/g of the accelerometer bias the filter has not estimated (r = true - estimated,
    IMU frame, rotated to n; r = the bias itself is the static-base floor), (B, 2) rad,
    and the filter's own 1 sigma of (level error - floor), from P (the Euler-error and
    bias states; closed loop, so the Euler errors are phi to first order), (B, 2) rad."""
    res, eps = run.result, car.episodes
    g = normal_gravity(eps[0].lat, eps[0].h)
    C = np.stack([e.C_s_n_true[-1] for e in eps])
    estimate = res.series["accel_bias"][:, -1] + res.x[:, -1, 12:15]
    r = np.einsum("bij,bj->bi", C, np.stack([e.accel_bias for e in eps]) - estimate)
    floor = np.stack([-r[:, 1] / g, r[:, 0] / g], -1)
    a = np.zeros((len(eps), 2, res.P.shape[-1]))
    a[:, 0, 0] = a[:, 1, 1] = 1.0
    a[:, 0, 12:15], a[:, 1, 12:15] = C[:, 1] / g, -C[:, 0] / g
    sigma = np.sqrt(np.einsum("bki,bij,bkj->bk", a, res.P[:, -1], a))
    return floor, sigma


def static_floor_000(car: Car) -> np.ndarray:
    """The static-base level floor of the drawn accelerometer bias, (B, 2) rad."""
    eps = car.episodes
    return static_alignment_floor(np.stack([e.C_s_n_true[-1] for e in eps]),
                                  np.stack([e.gyro_bias for e in eps]),
                                  np.stack([e.accel_bias for e in eps]), eps[0].lat,
                                  eps[0].h)[:, :2]


ISSUE27_CKF = ("the cubature method's, checked against an independent implementation "
               "(PSINS's ckf/ckfCT in Octave, the 000 model written from the equations, "
               "benchmarks/psins/ckf_000.py): the same heading epoch by epoch from both "
               "starts (ends within 0.05' of ours from the coarse start, both -22' to -29' "
               "at sigma 0.58' from 30 deg). Its points sit at sqrt(18) sigma = 127 deg of "
               "heading, where the third-degree rule gets the moments of sin and cos wrong "
               "(E[sin^2] 0.035 against 0.211): the first update moves the heading 75 deg "
               "where 32 are due. Here on ideal data the final NEES is 1.1e4 (15.3 deg) and "
               "4.3e5 (30 deg), flagged diverged from both; on this shortened drive "
               "the paper's sensors leave 18-27' of level (NEES 1.5e3-2.4e3)")
EKF_000 = ("the EKF's linearisation in phi_U, the filter's own limit: on this ideal drive "
           "from 2, 5, 10, 15.3, 20, 30 deg its final NEES is 2.1, 2.2, 2.5, 16.5, 167, 4244 "
           "(30 deg: level N 0.38' at sigma 0.024'; 15.3 deg: heading 3.9' in the last "
           "60 s), while rdghkf on the same model and data ends 0.9-1.0' of heading, NEES "
           "2.3 from every start; PSINS's ekf on the 000 model written from the equations "
           "(benchmarks/psins/ckf_000.py --filter ekf) ends within 0.11' of ours from "
           "both starts")

HEADING_000 = 3.0 * arcmin
LEVEL_000 = 0.1 * arcmin
HEADING_000_DRIVE = 10.0 * arcmin
"""3 sigma of a consistent filter's heading after the 240 s drive (3.4')."""


def case(name, start, marks=()):
    return pytest.param(name, start, marks=marks, id=f"{name}-{start}")


def test_every_default_filter_is_checked():
    """The parametrisations below name every default filter of 000 and 001."""
    assert sorted(FILTERS_000) == ["ckf", "ekf", "rdghkf", "sgkf"]
    assert sorted(FILTERS_001) == ["lckf", "rakf", "swakf"]


@pytest.mark.parametrize("name, start", [
    case("sgkf", "coarse"), case("sgkf", "large"),   # with its warm-up (ALGORITHMS 4.3.7)
    case("rdghkf", "coarse"), case("rdghkf", "large"),
    case("ckf", "coarse", pytest.mark.xfail(strict=True, reason=ISSUE27_CKF)),
    case("ckf", "large", pytest.mark.xfail(strict=True, reason=ISSUE27_CKF)),
    case("ekf", "coarse", pytest.mark.xfail(strict=True, reason=EKF_000)),
    case("ekf", "large", pytest.mark.xfail(strict=True, reason=EKF_000))])
def test_000_ideal_data_every_filter_reaches_zero(car000, runs000, name, start):
    """Error-free IMU and odometer, 240 s of driving on the 100 m ring then 70 s
    standing, from 15.3 deg (the coarse stage's own result on these data) or 30 deg of
    heading: over the last 60 s (standing) the heading within 3' of 0 and the level
    within 0.1', the NEES (9) below its 97.5 % point; at the end every axis inside 3
    sigma; not diverged.

    Why 3' and not 0: what is left is the finite drive and the filter's own large-angle
    transient; a consistent filter's heading sigma is 3.4' after this drive (the turns
    give the heading; 70 s of standing add little). rdghkf ends 0.9' from either
    start, level 0.01', NEES 2.3. The encoder's 2 mm pulses against the 0.02 m
    measurement sigma are nothing. Level: sigma 0.04'."""
    b = car000.labels.index(f"ideal, {start}")
    run = runs000(name)
    worst, nees = last(run, b)
    err, sigma = run.error_n[b, -1], run.result.sigma_n[b, -1]
    info = (f"{name} {start}: last 60 s max |error| {arcmin_text(worst)}', final error "
            f"{arcmin_text(err)}' sigma {arcmin_text(sigma)}', NEES max {nees:.1f} final "
            f"{run.nees[b, -1]:.1f}, diverged {run.diverged[b]}")
    assert not run.diverged[b], info
    assert worst[2] < HEADING_000, info
    assert np.all(worst[:2] < LEVEL_000), info
    assert np.all(np.abs(err) < 3 * sigma), info
    assert nees < ideal_limit(9), info


STATED_000 = {
    ("ckf", "coarse"): (150.0, 1.5), ("ckf", "large"): (1000.0, 10.0),
    ("ekf", "coarse"): (5.0, 0.1), ("ekf", "large"): (25.0, 0.5)}
"""Bounds (heading, level; arcmin, max |error| over the last 60 s on ideal data) of the
filters whose method cannot reach 3' / 0.1' there, 1.2-1.5x what they leave (ckf 112'
/ 1.0' from 15.3 deg, 865' / 7.7' from 30 deg; ekf 3.9' / 0.05' and 19' / 0.38'; the
ekf's level bound from 15.3 deg is the physics one)."""


@pytest.mark.parametrize("name, start", list(STATED_000))
def test_000_ideal_data_method_limited_filters_stay_within_their_stated_bound(
        car000, runs000, name, start):
    """The same error-free drive, for the filters that fail the physics bound above for
    a reason of their method, shown rather than assumed: ckf (points at sqrt(18) sigma =
    127 deg of heading, where the third-degree cubature gets sin and cos wrong; PSINS's
    ckf on the same model gives the same heading epoch by epoch on the experiment's own
    episodes, benchmarks/psins/ckf_000.py) and ekf (its linearisation in phi_U: final
    NEES 2.1-2.5 from 2-10 deg, 16.5 from 15.3, 4244 from 30 deg, where rdghkf on the
    same model ends at 0.9-1.0' from every start; PSINS's ekf on the independent model agrees within
    0.11', ``ckf_000.py --filter ekf``). A worse filter fails here; one that came to
    meet the physics bound would turn the strict xfail above into a failure."""
    b = car000.labels.index(f"ideal, {start}")
    assert_within_stated(runs000(name), b, STATED_000[name, start], f"{name} {start}")


@pytest.mark.parametrize("name", [
    "sgkf",
    "rdghkf",
    pytest.param("ckf", marks=pytest.mark.xfail(strict=True, reason=ISSUE27_CKF)),
    "ekf"])
def test_000_paper_sensors_reach_the_floors_with_nees_in_the_band(car000, runs000, name):
    """The paper's sensors, three episodes from the paper's coarse start, at the end of
    the 70 s still after 240 s of driving. Per episode: the level at the floor the
    accelerometer bias leaves (phi_E = -r_N/g, phi_N = r_E/g, r the bias the filter has
    not estimated, rotated to n: at rest the tilt and the bias are one observable
    combination; the turns, not the still, estimate most of the bias, so this is not the
    static -nabla_N/g, which is 0.03-0.74' here) within 3 sigma, the filter's own sigma
    of that combination (0.03'); the heading, which the turns give (no closed-form floor
    while driving: the gyrocompass term -eps_E/(Omega cos L), 6' per 0.02 deg/h, takes
    longer than 70 s), inside 3 sigma and within 10' (3 sigma of a consistent filter
    here: an inflated sigma does not pass). The mean final NEES (9 states) over the
    episodes in its two-sided 95 % band (one epoch, no time average)."""
    car, run = car000, runs000(name)
    n = car.real
    err, sigma = run.error_n[:n, -1], run.result.sigma_n[:n, -1]
    floor, floor_sigma = (v[:n] for v in level_floor_000(run, car))
    nees = run.nees[:n, -1]
    lo, hi = nees_band(9, n)
    info = (f"{name}: heading {arcmin_text(err[:, 2])}' sigma {arcmin_text(sigma[:, 2])}'; "
            f"level {arcmin_text(err[:, :2])}' floor {arcmin_text(floor)}' (static "
            f"{arcmin_text(static_floor_000(car)[:n])}') sigma {arcmin_text(floor_sigma)}'; "
            f"NEES {np.round(nees, 2)} band {lo:.2f}-{hi:.2f}; diverged {run.diverged[:n]}")
    assert not run.diverged[:n].any(), info
    assert np.all(np.abs(err[:, :2] - floor) < 3 * floor_sigma), info
    assert np.all(np.abs(err[:, 2]) < 3 * sigma[:, 2]), info
    assert np.all(np.abs(err[:, 2]) < HEADING_000_DRIVE), info
    assert lo < nees.mean() < hi, info


def test_000_odometer_start_velocity_is_outside_the_prior(car000):
    """Why the INS starts at a drawn velocity (``Paper000Experiment.start_velocity``):
    started at the odometer's velocity turned by the coarse attitude, its error is |v|
    times the coarse heading error (2.1 m/s on the ideal episode against P0's 0.1 m/s)
    and rdghkf, which reaches 0.9' from the drawn start, ends 20-24' off in heading on
    ideal data (NEES 234-255)."""
    exp = replace(car000.exp, start_velocity="odometer")
    n = car000.real            # the ideal members only (those asserted on), one batch
    ideal = Car(exp, car000.episodes[n:], car000.starts[n:], car000.labels[n:], 0)
    run = Runs(ideal)("rdghkf")
    for b, e in enumerate(ideal.episodes):
        error = np.linalg.norm(e.coarse_C_b_n @ e.v0_body - e.true_v_n[0])
        assert error > 10 * exp.velocity_sigma, error
        assert abs(run.error_n[b, -1, 2]) > 10 * arcmin, arcmin_text(run.error_n[b, -1])


# --- paper 001 ---------------------------------------------------------------------------------
def ideal_001_episode(exp, seed):
    """An episode of error-free IMU and GPS (as ``simulate(ideal=True)``); its GPS
    heading keeps the sigma the receiver states for the paper's 0.02 m/s velocity
    (sigma_v / |v_h|), so the filters weigh it as they do on real data."""
    config = exp.scenario_config()
    ideal = replace(config, imu=ImuSpec(), gps=replace(
        config.gps, position_sigma_h=0.0, position_sigma_v=0.0, velocity_sigma=0.0))
    e = exp.prepare_episode(seed, ideal)
    speed = np.hypot(e.gps_v_n[:, 0], e.gps_v_n[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = np.where(np.isfinite(e.gps_heading_sigma),
                         config.gps.velocity_sigma / speed, np.nan)
    return replace(e, gps_heading_sigma=sigma)


@pytest.fixture(scope="module")
def car001(tmp_path_factory):
    """Three episodes of the paper's sensors from the paper's start (the static coarse
    alignment over the first 30 s: heading errors -3.1, -16.8 and 5.0 deg, the 1 deg/h
    drift's gyrocompass error), and the ideal episode (every one is the same drive)
    three times, from those same three starts (on ideal data the coarse stage itself
    would leave 0)."""
    path = tmp_path_factory.mktemp("floors001") / "figure8.toml"
    path.write_text(FIGURE8)
    exp = experiment("paper001", scenario=str(path), coarse_duration=30.0)
    real = [exp.prepare_episode(s) for s in episode_seeds(SEED, EPISODES)]
    ideal = ideal_001_episode(exp, SEED)
    assert not ideal.gyro_bias.any() and not ideal.accel_bias.any()
    starts = exp.start_errors(real)["coarse"]
    return Car(exp, real + [ideal] * EPISODES, np.concatenate([starts, starts]),
               [f"seed {s}" for s in episode_seeds(SEED, EPISODES)]
               + [f"ideal from seed {s}'s start" for s in episode_seeds(SEED, EPISODES)],
               EPISODES)


@pytest.fixture(scope="module")
def runs001(car001):
    return Runs(car001)


ISSUE27_RAKF = ("issue 27 item 3: the GPS heading is the antenna's track, off the body "
                "heading by the sideslip (0.36 deg in the turns), with a sigma that ignores "
                "it; here rakf 2.3-2.7' off in heading on ideal data (NEES up to 40), "
                "10.6-13.2' off with sigma 1.9-2.2' on seeds 0-2 (mean NEES 44)")
ISSUE27_SWAKF = ("issue 27: swakf is overconfident (NEES 141 there); here 16' off in "
                 "heading on ideal data (NEES 420-460: the antenna-track heading, item 3), "
                 "mean NEES 75 on seeds 0-2 (still 27-48 without the GPS heading)")
HEADING_001 = 0.5 * arcmin
LEVEL_001 = 0.25 * arcmin


@pytest.mark.parametrize("name", [
    "lckf",
    pytest.param("rakf", marks=pytest.mark.xfail(strict=True, reason=ISSUE27_RAKF)),
    pytest.param("swakf", marks=pytest.mark.xfail(strict=True, reason=ISSUE27_SWAKF))])
def test_001_ideal_data_every_filter_reaches_zero(car001, runs001, name):
    """Error-free IMU and GPS, 10 s still then 160 s on the figure-8, from the paper's
    own starts (3-17 deg of heading): over the last 60 s (driving, turns included) the
    heading within 0.5' of 0 and the level within 0.25', the NEES (15) below its 97.5 %
    point; at the end every axis inside 3 sigma; not diverged.

    Why not 0: the transient from up to 17 deg, which the linear model carries as a
    small angle; lckf leaves 0.19' of heading and 0.14' of level from 17 deg (0.04'
    from 3-5 deg), against its final sigma of 0.90' and 0.28'. The GPS is exact."""
    run = runs001(name)
    b = np.arange(car001.real, len(car001.episodes))
    worst, nees = last(run, b)
    err, sigma = run.error_n[b, -1], run.result.sigma_n[b, -1]
    info = (f"{name}: last 60 s max |error| {arcmin_text(worst)}', final error "
            f"{arcmin_text(err)}' sigma {arcmin_text(sigma)}', NEES max {np.round(nees, 1)}, "
            f"diverged {run.diverged[b]}")
    assert not run.diverged[b].any(), info
    assert np.all(worst[:, 2] < HEADING_001), info
    assert np.all(worst[:, :2] < LEVEL_001), info
    assert np.all(np.abs(err) < 3 * sigma), info
    assert np.all(nees < ideal_limit(15)), info


STATED_001 = {"rakf": (3.5, 0.8), "swakf": (20.0, 4.0)}
"""Bounds (heading, level; arcmin, max |error| over the last 60 s on ideal data) of the
heading-aided filters with the paper's GPS heading sigma (eq. 4), about 1.3x what they
leave (rakf 2.7' / 0.61', swakf 16.3' / 3.1')."""


@pytest.mark.parametrize("name", list(STATED_001))
def test_001_ideal_data_heading_aided_filters_stay_within_their_stated_bound(
        car001, runs001, name):
    """The same error-free drive for the filters that fail the physics bound above, for
    a stated reason of the paper's heading observation: the GPS heading is the antenna's
    track, off the body heading by the car's sideslip (0.36 deg in the loops, measured in
    MuJoCo), while eq. 4's sigma (sigma_v / |v_h|, 0.07 deg) ignores it, so the
    constraint pulls the heading onto the track; swakf's selective weights pull hardest.
    With that offset in the sigma (``--heading-sigma sideslip``) both are consistent on
    these data (the test below). A worse filter fails here; one that came to meet the
    physics bound would turn the strict xfail above into a failure."""
    b = np.arange(car001.real, len(car001.episodes))
    assert_within_stated(runs001(name), b, STATED_001[name], name)


@pytest.fixture(scope="module")
def runs001_sideslip(car001):
    return Runs(car001, replace(car001.exp, heading_sigma="sideslip"))


@pytest.mark.parametrize("name, heading", [("rakf", 1.5), ("swakf", 3.5)])
def test_001_sideslip_sigma_makes_the_heading_aided_filters_consistent(
        car001, runs001_sideslip, name, heading):
    """``--heading-sigma sideslip`` (issue 27 item 3): eq. 4's sigma plus the kinematic
    sideslip (antenna lever arm x the INS's yaw rate / the GPS speed, in quadrature). On
    the ideal drive from the paper's three starts: the heading within ``heading`` arcmin
    over the last 60 s (rakf 1.07', swakf 2.8' measured: the offset is weighed, not
    removed), inside 3 sigma at the end, NEES (15) below its 97.5 % point (4.2 and 7.2
    measured, against 40 and 457 with eq. 4's sigma); rakf's mean final NEES on the
    paper's sensors in its band (12.5 on seeds 0-2, 44 with eq. 4); swakf's stays out of
    it (34.6: its selective weights claim more than they know), checked as such."""
    run = runs001_sideslip(name)
    b = np.arange(car001.real, len(car001.episodes))
    worst, nees = last(run, b)
    err, sigma = run.error_n[b, -1], run.result.sigma_n[b, -1]
    n = car001.real
    real = run.nees[:n, -1]
    lo, hi = nees_band(15, n)
    info = (f"{name}: last 60 s max |error| {arcmin_text(worst)}', final error "
            f"{arcmin_text(err)}' sigma {arcmin_text(sigma)}', NEES max {np.round(nees, 1)}; "
            f"paper's sensors NEES {np.round(real, 1)} band {lo:.2f}-{hi:.2f}")
    assert not run.diverged.any(), info
    assert np.all(worst[:, 2] < heading * arcmin), info
    assert np.all(np.abs(err) < 3 * sigma), info
    assert np.all(nees < ideal_limit(15)), info
    if name == "rakf":
        assert lo < real.mean() < hi, info
    else:                             # still overconfident on real data
        assert real.mean() > hi, info


@pytest.mark.parametrize("name", [
    "lckf",
    pytest.param("rakf", marks=pytest.mark.xfail(strict=True, reason=ISSUE27_RAKF)),
    pytest.param("swakf", marks=pytest.mark.xfail(strict=True, reason=ISSUE27_SWAKF))])
def test_001_paper_sensors_are_at_their_sigma_with_nees_in_the_band(car001, runs001,
                                                                     name):
    """The paper's sensors, three episodes from the paper's start, after 160 s of
    driving. The floor is 0 in motion: with RTK position and velocity through the
    figure-8's turns the heading and level are observable and the heading changes
    separate the horizontal accelerometer biases from the tilt (the static floors,
    nabla/g = 0.003' and -eps_E/(Omega cos L) = 4.4 deg for this IMU, hold only at rest,
    and the 10 s of still filtering are limited by the GPS velocity noise, not by them).
    Per episode every axis inside 3 sigma; the mean final NEES (15 states) over the
    episodes in its two-sided 95 % band (one epoch, no time average)."""
    run = runs001(name)
    n = car001.real
    err, sigma = run.error_n[:n, -1], run.result.sigma_n[:n, -1]
    nees = run.nees[:n, -1]
    lo, hi = nees_band(15, n)
    info = (f"{name}: error {arcmin_text(err)}' sigma {arcmin_text(sigma)}', NEES "
            f"{np.round(nees, 2)} band {lo:.2f}-{hi:.2f}, diverged {run.diverged[:n]}")
    assert not run.diverged[:n].any(), info
    assert np.all(np.abs(err) < 3 * sigma), info
    assert lo < nees.mean() < hi, info
