"""Your own IMU in a scenario file: [imu] takes a preset plus datasheet overrides, or a
full datasheet, in the units its keys name; the simulated sensor shows the datasheet's
Allan deviations (allantools against the closed forms), and the paper filters run on it
with a belief built from the same datasheet."""
from pathlib import Path

import allantools
import numpy as np
import pytest

from aligngym.models.units import deg_per_h, deg_per_sqrt_h, mg, ug
from aligngym.scenarios.campaign import run_campaign
from aligngym.scenarios.cli import main
from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.experiments import experiment
from aligngym.scenarios.simulate import simulate
from aligngym.sensors.imu import IMU_PRESETS

DATA = Path(__file__).parents[1] / "scenarios" / "data"
MEMS = """[imu]
gyro_bias_deg_h = 10.0
gyro_arw_deg_sqrt_h = 0.3
gyro_bias_instability_deg_h = 3.0
gyro_correlation_time_s = 100.0
accel_bias_ug = 500.0
accel_vrw_ug_sqrt_hz = 60.0
"""
"""A MEMS datasheet: 10 deg/h repeatability, ARW 0.3 deg/sqrt(h), bias instability 3
deg/h (Gauss-Markov, 100 s); 500 ug, VRW 60 ug/sqrt(Hz)."""


def scenario_with_imu(tmp_path, shipped, imu_table):
    """The shipped scenario with its [imu] table replaced."""
    text = (DATA / f"{shipped}.toml").read_text()
    head, rest = text.split("[imu]", 1)
    tail = rest[rest.index("\n["):] if "\n[" in rest else ""
    path = tmp_path / f"{shipped}-own-imu.toml"
    path.write_text(head + imu_table + tail)
    return path


def test_datasheet_keys_reach_the_spec_in_si(tmp_path):
    config = load_scenario(str(scenario_with_imu(tmp_path, "static-large-azimuth", MEMS)))
    g, a = config.imu.gyro, config.imu.accel
    assert config.imu_preset == "datasheet"
    np.testing.assert_allclose([g.bias_sigma, g.white_noise_density, g.bias_instability],
                               [10 * deg_per_h, 0.3 * deg_per_sqrt_h, 3 * deg_per_h])
    np.testing.assert_allclose([a.bias_sigma, a.white_noise_density], [500 * ug, 60 * ug])
    assert g.scale_factor_sigma == 0.0 and a.random_walk == 0.0     # not given: none


def test_a_preset_with_overrides_keeps_the_rest(tmp_path):
    table = '[imu]\npreset = "paper004-mems"\naccel_bias_ug = 100.0\ngyro_scale_factor_ppm = 300\n'
    config = load_scenario(str(scenario_with_imu(tmp_path, "usv-mems-swing", table)))
    preset = IMU_PRESETS["paper004-mems"]
    assert config.imu.accel.bias_sigma == pytest.approx(100 * ug)
    assert config.imu.gyro.scale_factor_sigma == pytest.approx(3e-4)
    assert config.imu.gyro.bias_sigma == preset.gyro.bias_sigma
    assert config.imu.accel.white_noise_density == preset.accel.white_noise_density


@pytest.mark.parametrize("line, message", [
    ("gyro_arw_deg_sqrt_h = -0.3", "imu.gyro_arw_deg_sqrt_h = -0.3 is out of range [0, 100]"),
    ("gyro_correlation_time_s = 0", "imu.gyro_correlation_time_s = 0 is out of range (0, 1e+06]"),
    ("accel_vrw_m_s_sqrt_h = 0.1", "the accel white noise density is given twice"),
    ("gyro_arw = 0.3", "imu.gyro_arw is not a parameter; valid: bias_frame, preset,"),
    ("accel_bias_ug = \"big\"", "imu.accel_bias_ug must be a number"),
])
def test_bad_datasheet_values_are_one_line_errors(tmp_path, capsys, line, message):
    table = "[imu]\naccel_vrw_ug_sqrt_hz = 60.0\n" + line + "\n"
    path = scenario_with_imu(tmp_path, "static-large-azimuth", table)
    with pytest.raises(ConfigError, match="imu."):
        load_scenario(str(path))
    assert main(["simulate", str(path), "--out", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def gauss_markov_avar(tau, sigma, tc):
    """Allan variance of a first-order Gauss-Markov process (sigma, correlation time tc)."""
    r = tau / tc
    return sigma ** 2 * (tc / tau) ** 2 * (2 * r - 3 + 4 * np.exp(-r) - np.exp(-2 * r))


def test_the_simulated_imu_has_the_datasheet_allan_deviations(tmp_path):
    """One hour at rest, 100 Hz: the gyros' overlapping Allan deviation against ARW / sqrt
    (tau) plus the Gauss-Markov bias instability's closed form, the accelerometers'
    against VRW / sqrt(tau); each axis at 1 s within 5 %, at 10 and 30 s within 20 %,
    the three axes' mean at 100 s within 30 % (about 36 windows of an hour)."""
    path = scenario_with_imu(tmp_path, "static-large-azimuth", MEMS)
    config = load_scenario(str(path)).with_options(duration=3600.0)
    episode = simulate(config, seed=1)
    dt = config.imu_interval
    taus = np.array([1.0, 10.0, 30.0, 100.0])
    g, a = config.imu.gyro, config.imu.accel
    gyro = np.sqrt(g.white_noise_density ** 2 / taus
                   + gauss_markov_avar(taus, g.bias_instability, g.correlation_time))
    accel = a.white_noise_density / np.sqrt(taus)
    ratios = {}
    for name, data, expected in (("gyro", episode.dtheta, gyro), ("accel", episode.dv, accel)):
        ratios[name] = np.array([
            allantools.oadev(data[:, ax] / dt, rate=1 / dt, data_type="freq",
                             taus=taus)[1] / expected for ax in range(3)])
    for r in ratios.values():
        np.testing.assert_allclose(r[:, 0], 1.0, rtol=0.05)
        np.testing.assert_allclose(r[:, 1:3], 1.0, rtol=0.2)
        assert abs(r[:, 3].mean() - 1.0) < 0.3, r


def test_paper_filters_run_on_a_users_mems_with_a_matching_belief(tmp_path):
    """Paper 004's boat with the MEMS datasheet above instead of the paper's: the
    filter's belief follows the datasheet (bias sigma with the instability folded in,
    noise densities), the paper's filters run, none diverges, heading within its 3 sigma."""
    path = scenario_with_imu(tmp_path, "usv-mems-swing", MEMS)
    exp = experiment("paper004", scenario=str(path), fine_duration=240.0)
    tuning = exp.tuning(exp.scenario_config())
    assert tuning.gyro_bias_sigma == pytest.approx(np.hypot(10, 3) * deg_per_h)
    assert tuning.gyro_noise_density == pytest.approx(0.3 * deg_per_sqrt_h)
    assert tuning.accel_bias_sigma == pytest.approx(max(500 * ug, 0.1 * mg))
    result = run_campaign(exp, episodes=2, seed=2, filters=["ukf-3n", "ekf"], workers=1,
                          progress=False)
    for run in result.runs:
        assert not run.diverged.any(), run.filter
        final, sigma = run.error_n[:, -1], run.result.sigma_n[:, -1]
        assert np.all(np.abs(final[:, 2]) < 3 * sigma[:, 2]), (run.filter, final, sigma)
