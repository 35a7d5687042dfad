"""Paper 002's static marble platform (SPEC 4.4): MuJoCo sensors, truth, ideal IMU,
fidelity, scenario file and command line."""
import mujoco
import numpy as np
import pytest

from aligngym.models.attitude import euler_to_dcm, quat_rotate, quat_to_euler
from aligngym.models.earth import earth_rate_n, normal_gravity
from aligngym.models.platform import StaticPlatformMotion, StaticPlatformWorld
from aligngym.models.units import arcsec, deg
from aligngym.models.world import PrescribedWorld
from aligngym.scenarios.config import DATA_DIR, ConfigError, load_scenario
from aligngym.scenarios.simulate import simulate

NAME = "static-large-azimuth"


@pytest.fixture(scope="module")
def config():
    return load_scenario(NAME)


@pytest.fixture(scope="module")
def episode(config):
    return simulate(config.with_options(duration=20.0), seed=0, ideal=True)


def test_scenario_file_loads_the_paper_002_setup(config):
    assert (config.paper, config.world, config.imu_preset) == ("002", "static-platform",
                                                                "paper002-static")
    assert (config.duration, config.imu_rate) == (600.0, 100.0)
    assert config.latitude == pytest.approx(40 * deg) and config.longitude == pytest.approx(
        116 * deg) and config.height == 0.0
    m = config.motion
    np.testing.assert_allclose([m.yaw_mean, m.pitch, m.roll], np.array([30, 0.3, -0.2]) * deg)
    assert not m.has_gimbal and m.lever_arm_b == (0.0, 0.0, 0.0)


def test_mujoco_gyro_reads_zero_and_accelerometer_the_model_gravity():
    motion = StaticPlatformMotion()
    world = StaticPlatformWorld(motion)
    s = world.sample(np.array([0.0, 5.0]))
    assert np.all(s.omega_ts_s == 0.0)
    adr, dim = world._adr["imu_accel"]
    C_t_s = euler_to_dcm(motion.euler).T
    qpos, qvel, qacc = world.joint_state(np.array([5.0]))
    world.data.qpos[:], world.data.qvel[:], world.data.qacc[:] = qpos[0], qvel[0], qacc[0]
    mujoco.mj_inverse(world.model, world.data)
    np.testing.assert_allclose(world.data.sensordata[adr:adr + dim],
                               C_t_s @ -world.model.opt.gravity, atol=1e-13)
    np.testing.assert_allclose(s.a_t, 0.0, atol=1e-13)
    np.testing.assert_allclose(quat_to_euler(s.q_s_t), np.tile(motion.euler, (2, 1)),
                               atol=1e-14)


def test_one_sensor_pass_equals_mujoco_at_every_time():
    """The broadcast shortcut is exact: MuJoCo run at each time gives the same samples."""
    world = StaticPlatformWorld(StaticPlatformMotion(yaw_mean=-150 * deg, pitch=-2 * deg,
                                                     roll=4 * deg))
    t = np.array([0.0, 0.01, 123.4, 600.0])
    fast, full = world.sample(t), PrescribedWorld.sample(world, t)
    for name in ("t", "r_t", "v_t", "a_t", "q_s_t", "q_b_t", "omega_ts_s", "gimbal_angles"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(full, name), err_msg=name)


def test_truth_is_static(episode, config):
    tr = episode.truth
    assert np.all(tr.v_n == 0.0)
    for x in (tr.lat, tr.lon, tr.h, tr.q_s_n):
        assert np.all(x == x[0])
    assert tr.lat[0] == pytest.approx(config.latitude, abs=1e-15)
    assert tr.lon[0] == pytest.approx(config.longitude, abs=1e-15)
    assert abs(tr.h[0]) < 1e-9
    np.testing.assert_array_equal(tr.q_b_n, tr.q_s_n)
    np.testing.assert_allclose(quat_to_euler(tr.q_s_n[0]), config.motion.euler, atol=1e-14)
    assert np.all(tr.gimbal_angles == 0.0) and np.all(episode.gimbal_encoder == 0.0)


def test_ideal_imu_senses_earth_rate_and_gravity(episode, config):
    dt = config.imu_interval
    C_n_b = euler_to_dcm(config.motion.euler).T
    lat = config.latitude
    np.testing.assert_allclose(episode.dtheta.mean(0) / dt, C_n_b @ earth_rate_n(lat),
                               rtol=0, atol=1e-12)
    f = episode.dv.mean(0) / dt
    assert np.linalg.norm(f) == pytest.approx(float(normal_gravity(lat, 0.0)), abs=1e-9)
    np.testing.assert_allclose(f, C_n_b @ [0.0, 0.0, normal_gravity(lat, 0.0)], atol=1e-9)
    # Every increment is the same, not only the mean; in n the specific force is g up.
    assert np.all(episode.dtheta == episode.dtheta[0]) and np.all(episode.dv == episode.dv[0])
    np.testing.assert_allclose(quat_rotate(episode.truth.q_s_n[0], f),
                               [0.0, 0.0, normal_gravity(lat, 0.0)], atol=1e-9)


def test_erroneous_imu_shows_the_drawn_biases(config):
    short = config.with_options(duration=20.0)
    ideal = simulate(short, seed=4, ideal=True)
    real = simulate(short, seed=4)
    for key in ("lat", "h", "v_n", "q_s_n"):
        np.testing.assert_array_equal(getattr(ideal.truth, key), getattr(real.truth, key))
    gyro = (real.dtheta - ideal.dtheta).mean(0) / short.imu_interval
    accel = (real.dv - ideal.dv).mean(0) / short.imu_interval
    # 0.01 deg/h white noise over 20 s averages to ~2e-9 rad/s; no accelerometer noise.
    np.testing.assert_allclose(gyro, real.imu_realization.gyro.bias, atol=2e-8)
    np.testing.assert_allclose(accel, real.imu_realization.accel.bias, atol=1e-12)


def test_fidelity_600s(config):
    """SPEC 3 (1 arcsec, 5 mm/s, 1 m over 600 s at 100 Hz); we assert 10x better. ~7 s:
    the cost is the strapdown's 60 000 steps, not the world."""
    from aligngym.scenarios.fidelity import fidelity_errors

    err = fidelity_errors(config, seed=0)
    assert err["attitude_rad"] < 0.1 * arcsec
    assert err["velocity_m_s"] < 0.5e-3
    assert err["position_m"] < 0.1


def _variant(tmp_path, old, new):
    text = (DATA_DIR / f"{NAME}.toml").read_text()
    assert old in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.parametrize("old, new, message", [
    ("pitch_deg = 0.3", "pitch_deg = 45.0", r"motion.pitch_deg = 45 deg is out of range \[-10, 10\]"),
    ("roll_deg = -0.2", "roll_deg = -12", r"motion.roll_deg = -12 deg is out of range \[-10, 10\]"),
    ("yaw_deg = 30.0", "yaw_deg = 400", r"motion.yaw_deg = 400 deg is out of range \[-360, 360\]"),
    ("yaw_deg = 30.0", "yaw_deg = \"north\"", r"motion.yaw_deg: expected a number"),
    ("yaw_deg = 30.0", "gimbal_outer_rate_deg_s = 6.0",
     r"motion.gimbal_outer_rate_deg_s is not a parameter of the static platform; "
     r"valid: pitch_deg, roll_deg, yaw_deg"),
])
def test_bad_motion_names_the_field(tmp_path, old, new, message):
    with pytest.raises(ConfigError, match=message):
        load_scenario(str(_variant(tmp_path, old, new)))


def test_cli_simulate_and_bad_file(tmp_path, capsys):
    from aligngym.scenarios.cli import main

    out = tmp_path / "static.npz"
    assert main(["simulate", NAME, "--duration", "10", "--out", str(out)]) == 0
    f = np.load(out)
    assert f["t"].size == 1001 and f["dtheta"].shape == (1000, 3)
    assert np.all(f["v_n"] == 0.0) and str(f["scenario"]) == NAME
    assert "gyro_bias" in f and np.all(f["gimbal_encoder"] == 0.0)
    capsys.readouterr()
    bad = _variant(tmp_path, "pitch_deg = 0.3", "pitch_deg = 45.0")
    assert main(["simulate", str(bad), "--out", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "motion.pitch_deg = 45 deg" in err
