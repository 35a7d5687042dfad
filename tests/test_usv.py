"""Paper 004's boat (SPEC 4.5): the azimuth indexer's MuJoCo servo against its analytic
response, the scenario's truth fidelity with the indexer turning, GNSS on the prescribed
world, and bad indexer input."""
import math

import numpy as np
import pytest

from aligngym.models.attitude import euler_to_dcm
from aligngym.models.indexer import IndexerSpec, simulate_indexer
from aligngym.models.units import arcsec, deg
from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.simulate import simulate

NAME = "usv-mems-swing"


@pytest.fixture(scope="module")
def config():
    return load_scenario(NAME)


@pytest.fixture(scope="module")
def servo():
    return simulate_indexer(IndexerSpec(), 660.0)


def test_command_holds_each_stop_for_the_dwell_and_slews_between():
    spec = IndexerSpec()
    t, angle = spec.breakpoints(1000.0)
    np.testing.assert_allclose(t[:7], [0, 300, 306, 606, 612, 912, 918])
    np.testing.assert_allclose(angle[:7] / deg, [0, 0, 180, 180, 0, 0, 180])
    explicit = IndexerSpec(schedule=((0.0, 0.0), (10.0, 0.0), (20.0, math.pi / 2)))
    np.testing.assert_allclose(explicit.command(np.array([5.0, 15.0, 40.0])),
                               [0.0, math.pi / 4, math.pi / 2])


def test_servo_lags_the_ramp_by_2_zeta_rate_over_wn_and_settles(servo):
    """A second-order position loop driven by a ramp of rate r lags it by 2 zeta r / w_n
    in steady state, and comes to rest at the stop."""
    spec = IndexerSpec()
    w_n = 2 * math.pi * spec.natural_frequency
    lag = 2 * spec.damping_ratio * spec.slew_rate / w_n
    i = np.searchsorted(servo.t, 304.0)          # 4 s into the 6 s slew: 16 time constants
    assert servo.command[i] - servo.angle[i] == pytest.approx(lag, rel=1e-3)
    assert lag > 1 * deg                            # the lag is real, not rounding
    settled = np.searchsorted(servo.t, 316.0)
    assert abs(servo.angle[settled] - math.pi) < 1e-6
    back = np.searchsorted(servo.t, 630.0)
    assert abs(servo.angle[back]) < 1e-6
    # The smooth truth is MuJoCo's motion: its rate matches MuJoCo's joint rate to the
    # semi-implicit step's half-step offset (h/2 x the largest acceleration).
    angle, rate, accel = servo.state(servo.t)
    assert np.abs(angle - servo.angle).max() < 1e-12
    assert np.abs(rate - servo.rate).max() < spec.servo_step / 2 * np.abs(accel).max() * 1.2


def test_a_shorter_servo_run_is_the_start_of_a_longer_one():
    """The servo is causal and its command does not depend on the run's length: a 60 s
    run (what a short episode simulates, ``indexer_run``) and a 600 s one give the same
    truth bit for bit, all but the last 0.1 s (the spline's end condition)."""
    spec = IndexerSpec(dwell=20.0)                     # slews at 20 s and 46 s
    excite = lambda t: 0.05 * np.sin(0.7 * t)          # noqa: E731
    short, long = simulate_indexer(spec, 60.0, excite), simulate_indexer(spec, 600.0, excite)
    t = np.linspace(0.0, 59.9, 30001)
    for a, b in zip(short.state(t), long.state(t)):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("t_max", [0.5, 59.99, 60.0, 60.01, 600.0, 601.0])
def test_the_cached_servo_run_covers_the_times_asked_for(t_max):
    """indexer_run's block rounding never leaves a time beyond its run (the spline would
    extrapolate silently): the run reaches max t, by less than a block plus a step."""
    from aligngym.models.indexer import SERVO_BLOCK, indexer_run
    spec = IndexerSpec(stops=(0.0,))
    run = indexer_run(spec, np.array([0.0, t_max]))
    assert t_max <= run.t[-1] < t_max + SERVO_BLOCK + 2 * spec.servo_step


def test_hull_yaw_acceleration_deflects_the_servo_by_its_stiffness():
    """The rotor's reaction to the hull's yaw acceleration a: deflection -a / w_n^2 (quasi
    static, the swing is far below the servo's bandwidth)."""
    spec = IndexerSpec(stops=(0.0,))
    w = 2 * math.pi / 10.0
    amplitude = 3 * deg * w * w                     # 3 deg yaw swing at 10 s
    run = simulate_indexer(spec, 60.0, lambda t: amplitude * np.cos(w * t))
    w_n = 2 * math.pi * spec.natural_frequency
    late = run.t > 30.0
    expected = -amplitude * np.cos(w * run.t[late]) / w_n ** 2
    assert np.abs(run.angle[late] - expected).max() < 0.05 * np.abs(expected).max()


def test_encoder_reads_the_servo_angle_and_the_truth_has_it(config):
    episode = simulate(config.with_options(duration=620.0), seed=3)
    truth, reading = episode.truth, episode.gimbal_encoder
    t = truth.t
    servo = simulate_indexer(config.motion.indexer, 620.0,
                             config.motion.hull_yaw_accel)
    np.testing.assert_allclose(truth.gimbal_angles[:, 0], servo.state(t)[0], atol=1e-12)
    assert np.all(truth.gimbal_angles[:, 1] == 0.0)
    resolution = config.encoder.resolution
    assert np.abs(reading[:, 0] - truth.gimbal_angles[:, 0]).max() <= resolution / 2 + 1e-12
    # at rest on 180 deg between the slews, turning in them
    assert abs(truth.gimbal_angles[np.searchsorted(t, 450.0), 0] - math.pi) < 1e-3
    # the IMU turns with the indexer: C_s^n = C_b^n Rz(angle)
    from aligngym.models.attitude import quat_to_dcm, rot_z
    i = np.searchsorted(t, 450.0)
    C_s_b = quat_to_dcm(truth.q_b_n[i]).T @ quat_to_dcm(truth.q_s_n[i])
    np.testing.assert_allclose(C_s_b, rot_z(truth.gimbal_angles[i, 0]), atol=1e-12)


def test_fidelity_600s_with_the_indexer_turning(config):
    """SPEC section 3 on this scenario (two slews inside the 600 s): 10x tighter."""
    from aligngym.scenarios.fidelity import fidelity_errors
    err = fidelity_errors(config.with_options(duration=620.0), seed=0)
    assert err["attitude_rad"] < 0.1 * arcsec
    assert err["velocity_m_s"] < 0.5e-3
    assert err["position_m"] < 0.1


def test_ideal_gnss_is_the_antenna_of_the_prescribed_hull(config):
    """The antenna (MuJoCo site) against the motion's own analytic kinematics:
    r = sway centre + C_b^t antenna_b, v = v_centre + C_b^t (omega x antenna_b)."""
    from aligngym.models.earth import TangentPlane
    from aligngym.models.truth import plane_truth
    cfg = config.with_options(duration=60.0)
    episode = simulate(cfg, seed=0, ideal=True)
    m = cfg.motion
    t = episode.measurements["gps"].t
    assert np.allclose(np.diff(t), 1.0)
    centre, v_centre, _ = m.sway_centre(t)
    euler, _, _ = m.euler(t)
    C_b_t = euler_to_dcm(euler)
    omega, _ = m.hull_angular_rate(t)
    arm = np.asarray(m.antenna_b)
    r = centre + C_b_t @ arm
    v = v_centre + np.einsum("nij,nj->ni", C_b_t, np.cross(omega, arm))
    plane = TangentPlane(cfg.latitude, cfg.longitude, cfg.height)
    q = np.broadcast_to([1.0, 0, 0, 0], (t.size, 4))
    expected = plane_truth(plane, t, r, v, q, q, np.zeros((t.size, 2)))
    np.testing.assert_allclose(episode.measurements["gps"].lat, expected.lat, atol=1e-12)
    np.testing.assert_allclose(episode.measurements["gps"].lon, expected.lon, atol=1e-12)
    np.testing.assert_allclose(episode.measurements["gps"].h, expected.h, atol=1e-6)
    np.testing.assert_allclose(episode.measurements["gps"].v_n, expected.v_n, atol=1e-9)
    # the antenna is not the IMU: 2 m up the mast, its velocity is the swing's
    assert np.abs(episode.measurements["gps"].v_n - episode.truth.v_n[::100]).max() > 0.1


@pytest.mark.parametrize("table, field", [
    ("schedule = [[0.0, 0.0], [100.0, 90.0], [50.0, 0.0]]", "indexer.schedule"),
    ("dwell_s = -1.0", "indexer.dwell"),
    ("natural_frequency_hz = 0.0", "indexer.natural_frequency"),
    ("stops_deg = [0.0, \"half\"]", "indexer.stops"),
    ("dwell_deg = 300.0", "indexer.dwell_deg"),
])
def test_bad_indexer_input_is_one_line_naming_the_field(tmp_path, table, field):
    from aligngym.scenarios.config import DATA_DIR
    key = table.split(" =")[0]
    lines = [line for line in (DATA_DIR / f"{NAME}.toml").read_text().splitlines()
             if not line.startswith(key + " ")]
    text = "\n".join(lines).replace("[indexer]\n", f"[indexer]\n{table}\n")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as error:
        load_scenario(str(path))
    message = str(error.value)
    assert field in message and "\n" not in message


def edited(tmp_path, name, *replacements):
    """A shipped scenario's file with (old, new) text replacements, as a path."""
    from aligngym.scenarios.registry import DATA_DIR
    text = (DATA_DIR / f"{name}.toml").read_text()
    for old, new in replacements:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / f"{name}-edited.toml"
    path.write_text(text)
    return str(path)


def test_indexer_and_constant_gimbal_rates_exclude_each_other(tmp_path):
    for name in (NAME, "usv-mems-waves"):
        path = edited(tmp_path, name, ("gimbal_outer_rate_deg_s = 0.0",
                                       "gimbal_outer_rate_deg_s = 6.0"))
        with pytest.raises(ConfigError, match="gimbal"):
            load_scenario(path)


# --- the wave-driven boat ------------------------------------------------------------------
WAVES = "usv-mems-waves"
SLEWS = "schedule = [[0.0, 0.0], [20.0, 0.0], [26.0, 180.0], [50.0, 180.0], [56.0, 0.0]]"


SLEWING_SEED = 2
"""The seed of the slewing wave boat's checks below: one sea, so one MuJoCo run of the
floating hull (seeded: the truth cache keys it by the seed) serves all three."""


def waves_with_slews(tmp_path, duration=80.0):
    """The wave-driven boat with two slews early in a short run."""
    return load_scenario(edited(tmp_path, WAVES, ("stops_deg = [0.0, 180.0]", SLEWS),
                                ("dwell_s = 300.0\n", ""),
                                ("duration_s = 2000.0", f"duration_s = {duration}")))


@pytest.fixture(scope="module")
def slewing(tmp_path_factory):
    """``waves_with_slews``, 80 s, for every check of the slewing wave boat."""
    return waves_with_slews(tmp_path_factory.mktemp("waves"))


def test_wave_boat_servo_follows_its_command_inside_the_floating_hull(slewing):
    """The indexer is a MuJoCo actuator in the floating hull's model: the encoder follows
    the ramp with the servo's lag 2 zeta rate / w_n (within 20 %), rests on each stop, and
    the IMU turns with it relative to the hull."""
    from aligngym.models.attitude import quat_to_dcm, rot_z
    config = slewing
    spec = config.motion.indexer
    episode = simulate(config, seed=SLEWING_SEED)
    t, angle = episode.truth.t, episode.truth.gimbal_angles[:, 0]
    w_n = 2 * math.pi * spec.natural_frequency
    lag = 2 * spec.damping_ratio * spec.slew_rate / w_n       # rad behind the ramp
    mid = np.searchsorted(t, 23.0)
    assert abs((spec.command(t[mid:mid + 1], 80.0)[0] - angle[mid]) / lag - 1.0) < 0.2
    for when, stop in ((45.0, math.pi), (75.0, 0.0)):
        assert abs(angle[np.searchsorted(t, when)] - stop) < 1e-4
    reading = episode.gimbal_encoder[:, 0]
    assert np.abs(reading - angle).max() <= config.encoder.resolution / 2 + 1e-12
    i = np.searchsorted(t, 30.0)
    C_s_b = quat_to_dcm(episode.truth.q_b_n[i]).T @ quat_to_dcm(episode.truth.q_s_n[i])
    np.testing.assert_allclose(C_s_b, rot_z(angle[i]), atol=1e-12)


def test_wave_boat_fidelity_with_the_indexer_slewing(slewing):
    """SPEC section 3 on the wave-driven boat over two slews (80 s, 10x tighter than the
    600 s bar, which the drift rates extrapolate to)."""
    from aligngym.scenarios.fidelity import fidelity_errors
    err = fidelity_errors(slewing, seed=SLEWING_SEED)
    assert err["attitude_rad"] < 0.1 * arcsec
    assert err["velocity_m_s"] < 0.5e-3
    assert err["position_m"] < 0.1


def test_wave_boat_gnss_is_the_antenna_on_the_rigid_hull(slewing):
    """Ideal fixes at the antenna: the IMU's truth plus the hull's C_b^n (antenna - IMU
    lever arm), and the rigid body's velocity relation, at every fix (80 s: both slews)."""
    from aligngym.models.attitude import quat_to_dcm
    from aligngym.models.earth import radii
    config = slewing
    episode = simulate(config, seed=SLEWING_SEED, ideal=True)
    tr, gps = episode.truth, episode.measurements["gps"]
    i = np.searchsorted(tr.t, gps.t)
    arm_n = np.einsum("nij,j->ni", quat_to_dcm(tr.q_b_n[i]),
                      np.subtract(config.motion.antenna_b, config.motion.lever_arm_b))
    R_M, R_N = radii(tr.lat[i])
    north = (gps.lat - tr.lat[i]) * (R_M + tr.h[i])
    east = (gps.lon - tr.lon[i]) * (R_N + tr.h[i]) * np.cos(tr.lat[i])
    np.testing.assert_allclose(np.stack([east, north, gps.h - tr.h[i]], -1), arm_n,
                               atol=1e-6)
    # velocity: the IMU's plus d/dt (C_b^n arm), the derivative by central differences
    # of the truth at the IMU rate (error ~dt^2 omega^3 |arm| ~ 1e-5 m/s)
    arm_b = np.subtract(config.motion.antenna_b, config.motion.lever_arm_b)
    C = quat_to_dcm(tr.q_b_n)
    dt = tr.t[1] - tr.t[0]
    inner = i[(i > 0) & (i < tr.t.size - 1)]
    turning = np.einsum("nij,j->ni", C[inner + 1] - C[inner - 1], arm_b) / (2 * dt)
    expected = tr.v_n[inner] + turning
    np.testing.assert_allclose(gps.v_n[np.isin(i, inner)], expected, atol=1e-3)
    assert np.abs(turning).max() > 0.1         # the arm's own swing velocity is large


def test_wave_boat_servo_step_is_the_physics_step(tmp_path):
    path = edited(tmp_path, WAVES, ("damping_ratio = 0.7 ",
                                    "servo_step_s = 0.001\ndamping_ratio = 0.7 "))
    with pytest.raises(ConfigError, match="indexer.servo_step"):
        load_scenario(path)
