"""The sensor role (sensors.base, sensors.suite) and the Doppler velocity log added
through it in one file (sensors/dvl.py) plus a [dvl] table: its velocity against the
truth by an independent route, its errors' statistics, its lost pings, its table's
checks, and a user's own sensor registered in a test."""
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binomtest, chi2

from aligngym.models.attitude import quat_to_dcm
from aligngym.models.earth import TangentPlane
from aligngym.models.truth import NavigationTruth
from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.registry import DATA_DIR
from aligngym.scenarios.simulate import simulate
from aligngym.sensors.base import (SENSORS, Sensor, SensorRecord, SensorTruth,
                                   register_sensor)
from aligngym.sensors.dvl import DopplerVelocityLog, DvlSpec

DVL_TABLE = """
[dvl]
rate_hz = 5.0
velocity_sigma = 0.01
bias_sigma = 0.02
scale_factor_sigma = 0.005
lever_arm_b_m = [1.0, -4.0, -3.0]
dropouts_s = [[10.0, 12.0]]
"""


def with_table(tmp_path: Path, table: str, scenario: str = "ship-sway-rotary",
               duration: float = 30.0) -> Path:
    text = (DATA_DIR / f"{scenario}.toml").read_text()
    path = tmp_path / f"{scenario}-extra.toml"
    path.write_text(re.sub(r"duration_s = [0-9.]+", f"duration_s = {duration}", text)
                    + table)
    return path


@pytest.fixture(scope="module")
def ship(tmp_path_factory):
    """30 s of the swaying ship (its rotary IMU on the gimbal) with a DVL, seed 4: the
    erroneous and the ideal episode."""
    config = load_scenario(with_table(tmp_path_factory.mktemp("dvl"), DVL_TABLE))
    return simulate(config, seed=4), simulate(config, seed=4, ideal=True)


def test_the_table_is_read_in_its_units(ship):
    spec = dict(ship[0].config.sensors)["dvl"]
    assert spec == DvlSpec(rate=5.0, velocity_sigma=0.01, bias_sigma=0.02,
                           scale_factor_sigma=0.005, lever_arm_b=(1.0, -4.0, -3.0),
                           dropouts=((10.0, 12.0),))


def test_ideal_velocity_is_the_transducers_velocity_over_the_ground(ship):
    """Independent route: the transducers' position in the plane, r + C_b^t l (from the
    geodetic truth and the attitude), differenced with the five-point stencils (central
    inside, one-sided at the ends, error ~1e-8 m/s at 100 Hz) and turned into the carrier
    frame, against the ideal DVL at every ping, the first and last too (the sensor
    differences the attitude instead: 2e-5 m/s measured; the earth rate taken into the
    body rate would be 2.5e-4)."""
    episode = ship[1]
    record, tr = episode.measurements["dvl"], episode.truth
    config = episode.config
    plane = TangentPlane(config.latitude, config.longitude, config.height)
    arm = np.array([1.0, -4.0, -3.0])
    C_t_n = plane.C_t_n(tr.lat, tr.lon)
    C_b_n = quat_to_dcm(tr.q_b_n)
    p = plane.from_geodetic(tr.lat, tr.lon, tr.h) + np.einsum(
        "nji,njk,k->ni", C_t_n, C_b_n, arm)
    dt = tr.t[1] - tr.t[0]
    k = np.searchsorted(tr.t, record.t)
    assert k[0] == 0 and k[-1] == tr.t.size - 1
    v_t = np.empty((k.size, 3))
    i = k[1:-1]
    v_t[1:-1] = (p[i - 2] - 8 * p[i - 1] + 8 * p[i + 1] - p[i + 2]) / (12 * dt)
    v_t[0] = (-25 * p[0] + 48 * p[1] - 36 * p[2] + 16 * p[3] - 3 * p[4]) / (12 * dt)
    v_t[-1] = (25 * p[-1] - 48 * p[-2] + 36 * p[-3] - 16 * p[-4] + 3 * p[-5]) / (12 * dt)
    v_b = np.einsum("nji,njk,nk->ni", C_b_n[k], C_t_n[k], v_t)
    valid = record.valid
    assert valid.sum() > 100 and valid[0] and valid[-1]
    np.testing.assert_allclose(record.v_b[valid], v_b[valid], atol=5e-5)
    # The lever arm matters here: the IMU's own velocity is 0.2-1 m/s away.
    imu_b = np.einsum("nji,nj->ni", C_b_n[k], tr.v_n[k])
    assert np.abs(imu_b - v_b).max() > 0.2


def test_errors_are_the_drawn_bias_scale_and_white_noise(ship):
    """v = (1 + k) v_true + b + w: the recorded bias and scale explain the difference to
    the ideal episode (same seed, same truth) up to white noise of the stated sigma
    (variance inside its 99.9 % chi-square band, mean per axis inside 4 sigma/sqrt(n))."""
    real, ideal = (episode.measurements["dvl"] for episode in ship)
    ok = real.valid & ideal.valid
    noise = real.v_b[ok] - (1.0 + real.scale_error) * ideal.v_b[ok] - real.bias
    n = noise.size
    low, high = chi2.ppf([0.0005, 0.9995], n) / n
    assert low < np.mean(noise ** 2) / 0.01 ** 2 < high
    assert np.all(np.abs(noise.mean(0)) < 4 * 0.01 / np.sqrt(ok.sum()))
    assert np.any(real.bias != 0.0) and real.scale_error != 0.0
    assert np.all(ideal.bias == 0.0) and ideal.scale_error == 0.0


def constant_truth(seconds: float = 100.0, rate: float = 100.0) -> SensorTruth:
    """A carrier at rest heading north, level (the DVL reads 0 there)."""
    n = int(seconds * rate) + 1
    zeros = np.zeros(n)
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    truth = NavigationTruth(t=np.arange(n) / rate, lat=zeros + 0.7, lon=zeros, h=zeros,
                            v_n=np.zeros((n, 3)), q_b_n=quat, q_s_n=quat,
                            gimbal_angles=np.zeros((n, 2)))
    return SensorTruth(truth=truth, plane=TangentPlane(0.7, 0.0, 0.0))


def test_bias_and_scale_are_drawn_per_episode_with_their_sigma():
    """400 episodes' draws: the bias' per-axis variance and the scale factor's inside
    their 99.9 % chi-square bands."""
    dvl = DopplerVelocityLog(DvlSpec(bias_sigma=0.05, scale_factor_sigma=0.01))
    truth = constant_truth(seconds=2.0)
    draws = [dvl.measure(truth, np.random.default_rng(seed), ideal=False)
             for seed in range(400)]
    bias = np.array([d.bias for d in draws])
    scale = np.array([float(d.scale_error) for d in draws])
    low, high = chi2.ppf([0.0005, 0.9995], 1200) / 1200
    assert low < np.mean(bias ** 2) / 0.05 ** 2 < high
    low, high = chi2.ppf([0.0005, 0.9995], 400) / 400
    assert low < np.mean(scale ** 2) / 0.01 ** 2 < high


def test_lost_pings_random_and_in_windows():
    """dropout_probability 0.2 loses a binomial share of the pings (two-sided p > 0.001);
    the windows lose every ping stamped inside [start, end), which read NaN; the fault
    record has the windows."""
    spec = DvlSpec(rate=10.0, dropout_probability=0.2, dropouts=((20.0, 30.0),))
    record = DopplerVelocityLog(spec).measure(constant_truth(), np.random.default_rng(1),
                                              ideal=False)
    window = (record.t >= 20.0) & (record.t < 30.0)
    assert not record.valid[window].any()
    lost = int((~record.valid[~window]).sum())
    assert binomtest(lost, int((~window).sum()), 0.2).pvalue > 1e-3
    assert np.isnan(record.v_b[~record.valid]).all()
    assert np.isfinite(record.v_b[record.valid]).all()
    assert DopplerVelocityLog(spec).faults(record, 100.0) == [("dvl_dropout", 20.0, 30.0)]
    ideal = DopplerVelocityLog(spec).measure(constant_truth(), np.random.default_rng(1),
                                             ideal=True)
    assert ideal.valid.sum() == (~window).sum()     # ideal: the windows only


def test_a_dvl_leaves_every_other_output_of_the_seed_as_it_was(ship, tmp_path):
    """Its random stream is its own: the IMU data, the encoders, the GNSS fixes and the
    truth of the same seed are bit-identical without the table (the USV, with GNSS); the
    export carries dvl_* arrays and the dropout in the fault record."""
    usv = [simulate(load_scenario(with_table(tmp_path, table, "usv-mems-swing")), seed=4)
           for table in (DVL_TABLE, "")]
    for name in ("dtheta", "dv", "gimbal_encoder"):
        np.testing.assert_array_equal(getattr(usv[0], name), getattr(usv[1], name))
    for name, value in usv[1].measurements["gps"].arrays().items():
        np.testing.assert_array_equal(usv[0].measurements["gps"].arrays()[name], value)
    # ... and the DVL's own record is the same without the receiver (no shared stream).
    path = with_table(tmp_path, DVL_TABLE, "usv-mems-swing")
    path.write_text(re.sub(r"\[gps\][^[]*", "", path.read_text()))
    alone = simulate(load_scenario(path), seed=4)
    assert "gps" not in alone.measurements
    for name, value in usv[0].measurements["dvl"].arrays().items():
        np.testing.assert_array_equal(alone.measurements["dvl"].arrays()[name], value)
    with_dvl = ship[0]
    without = simulate(load_scenario(with_table(tmp_path, "")), seed=4)
    arrays = with_dvl.arrays()
    assert {"dvl_t", "dvl_v_b", "dvl_valid", "dvl_bias", "dvl_scale_error"} <= set(arrays)
    assert "dvl_t" not in without.arrays()
    assert ("dvl_dropout", 10.0, 12.0) in zip(with_dvl.faults.kind, with_dvl.faults.start,
                                              with_dvl.faults.end)


@pytest.mark.parametrize("table, message", [
    ("[dvl]\nrate_hz = 0.0\n", "dvl.rate_hz = 0 Hz is out of range (0, 50]"),
    ("[dvl]\nrate_hz = 3.0\n", "dvl.rate_hz = 3 Hz must divide run.imu_rate_hz = 100 Hz"),
    ("[dvl]\nrate = 2.0\n", "dvl.rate: rate is in Hz; write rate_hz"),
    ("[dvl]\nvelocity_sgima = 0.1\n", "did you mean velocity_sigma?"),
    ("[dvl]\ndropout_probability = 1.0\n", "dvl.dropout_probability = 1 is out of range"),
    ("[dvl]\nlever_arm_b_m = [1.0, 2.0]\n", "dvl.lever_arm_b_m must be 3 numbers"),
    ("[dvl]\ndropouts_s = [[5.0, 4.0]]\n", "dvl.dropouts_s: window (5, 4) must have end > start"),
    ("[dvll]\nrate_hz = 1.0\n", "did you mean [dvl]?"),
])
def test_a_bad_table_is_one_line_naming_the_key(tmp_path, table, message):
    with pytest.raises(ConfigError) as info:
        load_scenario(with_table(tmp_path, table))
    assert message in str(info.value) and "\n" not in str(info.value)


def test_the_car_cannot_carry_a_dvl(tmp_path):
    path = with_table(tmp_path, "[dvl]\nrate_hz = 1.0\n", "ring-road-odometer")
    with pytest.raises(ConfigError, match=r"\[dvl\]: the car world cannot carry it \(only "
                                          r"ship-prescribed, ship-waves\)"):
        load_scenario(path)


@dataclass(frozen=True)
class DepthSpec:
    sigma: float = 0.1


@dataclass(frozen=True)
class DepthReadings(SensorRecord):
    PREFIX = "depth_"
    t: object
    up: object


class DepthGauge(Sensor):
    """A user's sensor, registered in a test: the IMU's height with white noise."""

    section = "depth"
    spec_type = DepthSpec
    units = {"sigma": "_m"}
    stream = "depth"

    def measure(self, truth, rng, ideal):
        tr = truth.truth
        noise = 0.0 if ideal else self.spec.sigma * rng.standard_normal(tr.t.size)
        return DepthReadings(t=tr.t, up=tr.h + noise)


def test_a_users_sensor_is_one_class_and_one_table(tmp_path):
    register_sensor(DepthGauge)
    try:
        config = load_scenario(with_table(tmp_path, "[depth]\nsigma_m = 0.5\n"))
        episode = simulate(config, seed=2)
        readings = episode.measurements["depth"]
        noise = readings.up - episode.truth.h
        low, high = chi2.ppf([0.0005, 0.9995], noise.size) / noise.size
        assert low < np.mean(noise ** 2) / 0.5 ** 2 < high
        assert "depth_up" in episode.arrays()
        with pytest.raises(ConfigError, match=r"depth.sigma: sigma is in m; write sigma_m"):
            load_scenario(with_table(tmp_path, "[depth]\nsigma = 0.5\n"))
        with pytest.raises(ValueError, match=r"section 'run' must be a name other than"):
            register_sensor(type("Clock", (DepthGauge,), {"section": "run"}))
    finally:
        SENSORS.pop("depth", None)


def test_a_sensors_stream_is_new_for_its_name_and_the_seed():
    """A stream by a new name is neither one of the six named ones nor another name's,
    and the same name and seed give the same draws."""
    from aligngym.scenarios.simulate import episode_rngs
    draws = {name: episode_rngs(7)[name].standard_normal(4)
             for name in ("motion", "imu_realization", "imu_noise", "encoder", "odometer",
                          "gps", "dvl", "depth")}
    assert len({tuple(d) for d in draws.values()}) == len(draws)
    np.testing.assert_array_equal(episode_rngs(7)["dvl"].standard_normal(4), draws["dvl"])
    assert not np.array_equal(episode_rngs(8)["dvl"].standard_normal(4), draws["dvl"])


def test_an_empty_table_is_the_default_sensor(tmp_path):
    """An empty [dvl] or [gps] table carries the sensor with its spec's defaults."""
    from aligngym.sensors.gps import GpsSpec
    config = load_scenario(with_table(tmp_path, "[dvl]\n\n[gps]\n"))
    assert dict(config.sensors) == {"dvl": DvlSpec()} and config.gps == GpsSpec()
    assert list(config.sensor_specs()) == ["encoder", "gps", "dvl"]


def moving_truth(seconds: float = 10.0, rate: float = 100.0) -> SensorTruth:
    """A carrier heading north-east at 5 m/s, level, not turning."""
    truth = constant_truth(seconds, rate)
    n = truth.truth.t.size
    v_n = np.tile([3.0, 4.0, 0.0], (n, 1))
    return SensorTruth(truth=NavigationTruth(**{**vars(truth.truth), "v_n": v_n}),
                       plane=truth.plane)


def test_the_error_model_is_scale_on_the_velocity_then_bias():
    """Without white noise, every ping reads exactly (1 + k) v + b, with k and b the
    record's (v the velocity in the hull frame: 5 m/s rotated by the heading)."""
    spec = DvlSpec(velocity_sigma=0.0, bias_sigma=0.05, scale_factor_sigma=0.05)
    record = DopplerVelocityLog(spec).measure(moving_truth(), np.random.default_rng(3),
                                              ideal=False)
    v = np.array([3.0, 4.0, 0.0])             # level, heading north: hull axes = E, N, U
    expected = np.broadcast_to((1.0 + record.scale_error) * v + record.bias,
                               record.v_b.shape)
    np.testing.assert_allclose(record.v_b, expected, rtol=0, atol=1e-12)
    assert abs(float(record.scale_error)) > 1e-3 and np.abs(record.bias).min() > 1e-4


def test_the_record_is_the_dvl_stream_of_the_seed(ship):
    """The episode's DVL record is what the sensor measures from the seed's "dvl" stream
    (no other stream's draws)."""
    from aligngym.scenarios.simulate import episode_rngs
    episode = ship[0]
    truth = SensorTruth(truth=episode.truth, plane=TangentPlane(
        episode.config.latitude, episode.config.longitude, episode.config.height))
    again = DopplerVelocityLog(dict(episode.config.sensors)["dvl"]).measure(
        truth, episode_rngs(4)["dvl"], ideal=False)
    for name, value in again.arrays().items():
        np.testing.assert_array_equal(episode.measurements["dvl"].arrays()[name], value)


def test_dropout_windows_are_clipped_to_the_run():
    dvl = DopplerVelocityLog(DvlSpec(dropouts=((5.0, 50.0), (60.0, 70.0))))
    record = dvl.measure(constant_truth(seconds=10.0), np.random.default_rng(0), True)
    assert dvl.faults(record, 10.0) == [("dvl_dropout", 5.0, 10.0)]


def test_registration_refuses_a_taken_section_or_stream():
    class Other(DopplerVelocityLog):
        stream = "dvl-other"
    with pytest.raises(ValueError, match=r"section \[dvl\] is taken by aligngym.sensors.dvl"):
        register_sensor(Other)
    for stream in ("imu_noise", "gps"):
        clash = type("Clash", (DopplerVelocityLog,), {"section": "clash", "stream": stream})
        with pytest.raises(ValueError, match=f"stream '{stream}' is taken"):
            register_sensor(clash)
    for section in ("world", "schedule"):
        with pytest.raises(ValueError, match="must be a name other than"):
            register_sensor(type("Bad", (DepthGauge,), {"section": section}))
    assert "clash" not in SENSORS and SENSORS["dvl"] is DopplerVelocityLog
