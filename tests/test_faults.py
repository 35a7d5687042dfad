"""Data faults in scenario files (SPEC 4.6) and the pipelines' screen: each fault (IMU,
gimbal stall, GNSS outage and outlier, odometer slip) is in the episode's record,
flagged with its kind at its time, the IMU's repaired onto the run's grid; no
fault-free shipped scenario is flagged; a campaign counts the flagged episodes and its
filters survive."""
import numpy as np
import pytest

from aligngym.estimators.screen import screen_imu
from aligngym.scenarios.campaign import simulate_screened
from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.registry import DATA_DIR

FAULTS = """
[faults]
spikes = [[12.345, 10.0, 20.0]]
saturation = [[20.0, 0.5]]
gaps = [[30.0, 0.3]]
nans = [40.0]
"""


def with_faults(tmp_path, name, duration, table=FAULTS):
    text = (DATA_DIR / f"{name}.toml").read_text() + table
    path = tmp_path / f"{name}-faults.toml"
    path.write_text(text)
    return load_scenario(str(path)).with_options(duration=duration)


SENSOR_FAULTS = {
    # scenario: (duration s, text added to its [gps] / [odometer] table, [faults] table,
    #            {kind: time s})
    "ship-sway-rotary": (60.0, "", "[faults]\ngimbal_stalls = [[30.0, 1.0]]\n",
                         {"gimbal_stall": 30.0}),
    "usv-mems-swing": (320.0, "outages_s = [[100.0, 110.0]]\n"
                       "outliers = [[150.0, 30.0, -20.0, 0.0]]\n",
                       "[faults]\ngimbal_stalls = [[302.0, 1.0]]\n",
                       {"gnss_outage": 100.0, "gnss_outlier": 150.0, "gimbal_stall": 302.0}),
    "usv-mems-waves": (320.0, "", "[faults]\ngimbal_stalls = [[302.0, 1.0]]\n",
                       {"gimbal_stall": 302.0}),
    "figure8-gps": (200.0, "outages_s = [[100.0, 110.0]]\noutliers = [[150.0, 10.0, 0.0, 0.0]]\n",
                    "", {"gnss_outage": 100.0, "gnss_outlier": 150.0}),
    "ring-road-odometer": (150.0, "slips = [[120.0, 0.3, 0.5]]\n", "",
                           {"odometer_slip": 120.0}),
}


@pytest.mark.parametrize("name", sorted(SENSOR_FAULTS))
def test_every_sensor_fault_is_flagged_at_its_time(tmp_path, name):
    """Gimbal stalls (the constant-rate gimbal, and the indexer mid-slew on the prescribed
    and the wave-driven boat), GNSS outages and outliers (1 Hz fixes, RTK and 2.5 m
    single-point) and an odometer slip burst are each in the record and flagged once,
    within 0.2 s of their start (a filter epoch is 1 s), and nothing else is. First in the
    file: its car runs (the ring's 150 s, the figure-8's 200 s) are the longest of the
    file's, and the shorter ones the tests below ask of the same motions are their first
    part (``world_truth.shared_motion``), taken from the truth cache."""
    duration, sensor_rows, table, expected = SENSOR_FAULTS[name]
    text = (DATA_DIR / f"{name}.toml").read_text()
    for section in ("[gps]\n", "[odometer]\n"):
        if sensor_rows and section in text:
            text = text.replace(section, section + sensor_rows)
    path = tmp_path / f"{name}-faults.toml"
    path.write_text(text + table)
    config = load_scenario(str(path)).with_options(duration=duration)
    episode, flags = simulate_screened(config, seed=2)
    record = list(zip(episode.faults.kind, episode.faults.start))
    assert sorted(record) == sorted(expected.items())
    found = list(zip(flags["fault_kind"], flags["fault_time"]))
    assert sorted(kind for kind, _ in found) == sorted(expected), found
    for kind, when in found:
        assert 0.0 <= when - expected[kind] < 0.2, (kind, when)


@pytest.mark.parametrize("name", ["ship-sway-rotary", "ring-road-odometer",
                                  "usv-mems-swing", "static-large-azimuth"])
def test_every_fault_is_flagged_at_its_time_and_repaired(tmp_path, name):
    config = with_faults(tmp_path, name, 50.0)
    dt = config.imu_interval
    episode, flags = simulate_screened(config, seed=3)
    from aligngym.scenarios.simulate import simulate
    raw = simulate(config, seed=3)
    record = dict(zip(raw.faults.kind, raw.faults.start))
    assert set(record) == {"spike", "saturation", "gap", "nan"}
    assert raw.imu_t.size == config.imu_samples - round(0.3 / dt)     # the gap's samples
    found = dict(zip(flags["fault_kind"], flags["fault_time"]))
    assert set(found) == set(record)                                  # nothing else
    for kind, when in record.items():
        assert abs(found[kind] - when) < 0.5 * dt, kind
    assert episode.dtheta.shape == (config.imu_samples, 3)
    assert np.all(np.isfinite(episode.dtheta)) and np.all(np.isfinite(episode.dv))
    np.testing.assert_allclose(episode.imu_t, (np.arange(config.imu_samples) + 1) * dt)


def test_repaired_data_keep_the_strapdown_on_the_truth(tmp_path):
    """Ideal sensors with every fault, screened: a strapdown on the repaired increments
    stays within 10 arcsec and 20 mm/s of the truth over 60 s on the swaying ship
    (measured 6.7 arcsec, 12.6 mm/s: 0.8 s of data are lost to the rail and the gap, and
    the cubic spline through the good rates bridges them; a linear one left 13')."""
    from aligngym.estimators.strapdown import StrapdownState, run_strapdown
    from aligngym.models.attitude import quat_angle
    from aligngym.models.units import arcsec
    from aligngym.scenarios.simulate import imu_rails, simulate
    config = with_faults(tmp_path, "ship-sway-rotary", 60.0)
    raw = simulate(config, seed=1, ideal=True)
    screened = screen_imu(raw.imu_t, raw.dtheta, raw.dv, config.imu_interval,
                          config.imu_samples, *imu_rails(config))
    tr = raw.truth
    start = StrapdownState.from_arrays(tr.q_s_n[0], tr.v_n[0], tr.lat[0], tr.lon[0],
                                       tr.h[0])
    nav = run_strapdown(start, screened.dtheta, screened.dv, config.imu_interval)
    assert quat_angle(nav["q_b_n"][0], tr.q_s_n).max() < 10 * arcsec
    assert np.linalg.norm(nav["v_n"][0] - tr.v_n, axis=1).max() < 20e-3


@pytest.mark.parametrize("name", ["ship-sway-rotary", "ring-road-odometer", "figure8-gps",
                                  "usv-mems-swing", "static-large-azimuth"])
def test_fault_free_scenarios_are_not_flagged(name):
    """No false alarm on the shipped scenarios (the ring road's rough stretches and
    turns, the figure-8's accelerations, the boat through its first indexer slew at
    300-306 s; measured over the whole runs of two seeds each: none)."""
    config = load_scenario(name).with_options(
        duration=320.0 if name == "usv-mems-swing" else 120.0)
    _, flags = simulate_screened(config, seed=5)
    assert flags["fault_kind"].size == 0, list(zip(flags["fault_kind"], flags["fault_time"]))


def test_a_campaign_counts_flagged_episodes_and_its_filters_survive(tmp_path):
    from aligngym.scenarios.campaign import run_campaign
    from aligngym.scenarios.experiments import experiment
    from aligngym.scenarios.report import format_tables
    path = tmp_path / "static-faults.toml"
    path.write_text((DATA_DIR / "static-large-azimuth.toml").read_text() + FAULTS)
    runs = {}
    for label, scenario in (("clean", "static-large-azimuth"), ("faults", str(path))):
        exp = experiment("paper002", scenario=scenario, fine_duration=300.0)
        runs[label] = run_campaign(exp, episodes=2, seed=1, filters=["ukf"], workers=1,
                                   progress=False)
    faults = runs["faults"].summary()["data_faults"]
    assert faults["flagged_episodes"] == 2 and faults["by_kind"]["gap"] == 2
    assert runs["clean"].summary()["data_faults"]["flagged_episodes"] == 0
    assert "Data faults flagged: 2 of 2 episodes" in format_tables(runs["faults"])
    clean, faulty = (runs[k].runs[0] for k in ("clean", "faults"))
    assert not faulty.diverged.any()
    # the repaired data cost the filter next to nothing (arcmin, final)
    np.testing.assert_allclose(faulty.error_n[:, -1], clean.error_n[:, -1], atol=2e-4)


@pytest.mark.parametrize("table, field", [
    ("[faults]\nspikes = [[12.0, 10.0]]", "faults.spikes"),
    ("[faults]\ngaps = [[30.0, -1.0]]", "faults.gaps"),
    ("[faults]\nnans = [9999.0]", "faults.nans"),
    ("[faults]\nnans = \"soon\"", "faults.nans"),
    ("[faults]\nrails = [[1.0, 1.0]]", "faults.rails"),
    ("[faults]\ngimbal_stalls = [[10.0, 0.1]]",
     "faults.gimbal_stalls: each duration must be >= 0.2"),
    ("[faults]\ngimbal_stalls = [[10.0, 1.0], [12.9, 1.0]]",
     "faults.gimbal_stalls: stalls must not overlap"),
    ("[faults]\ngimbal_stalls = [[59.5, 1.0]]", "faults.gimbal_stalls: 59.5 s"),
])
def test_bad_fault_tables_are_one_line_errors(tmp_path, table, field):
    with pytest.raises(ConfigError) as error:
        with_faults(tmp_path, "ship-sway-rotary", 60.0, "\n" + table + "\n")
    message = str(error.value)
    assert field in message and "\n" not in message


def test_a_stalled_gimbal_stops_then_catches_up():
    """The stall's time warp: the rates vanish inside the stall, where the gimbal is the
    stall's duration behind its schedule less the STALL_RAMP stop; after the catch-up
    the motion is the nominal one again; rates and accelerations are the derivatives of
    the angles (finite differences), continuous through the stop and the catch-up."""
    from aligngym.models.ship import ShipSwayMotion
    from aligngym.models.gimbal import STALL_CATCH_UP, STALL_RAMP
    nominal = ShipSwayMotion()
    motion = ShipSwayMotion(gimbal_stalls=((100.0, 2.0),))
    t = np.arange(99.0, 100.0 + 2.0 * (1.0 + STALL_CATCH_UP) + 1.0, 1e-4)
    angle, rate, accel = motion.gimbal_state(t)
    inside = (t >= 100.0 + STALL_RAMP) & (t <= 102.0)
    assert np.abs(rate[inside]).max() < 1e-12
    # stopped at the schedule's angle of 100 + STALL_RAMP / 2 (the stop's mean time)
    np.testing.assert_allclose(angle[inside], nominal.gimbal_state(
        np.full(inside.sum(), 100.0 + STALL_RAMP / 2))[0], rtol=0, atol=1e-12)
    after = t >= 102.0 + STALL_CATCH_UP * 2.0
    before = t <= 100.0
    for mask in (before, after):
        np.testing.assert_allclose(angle[mask], nominal.gimbal_state(t[mask])[0],
                                   rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.gradient(angle, t, axis=0)[1:-1], rate[1:-1], atol=1e-7)
    np.testing.assert_allclose(np.gradient(rate, t, axis=0)[1:-1], accel[1:-1], atol=1e-5)
    assert np.abs(np.diff(accel, axis=0)).max() < 1e-2      # no step (peak ~3 rad/s^2)
    assert rate[:, 1].max() < 2.2 * nominal.gimbal_inner_rate   # the catch-up's rate


def test_the_expected_indexer_motion_is_the_servo_without_the_hull():
    """The screen's expectation of an indexer, its servo on a fixed base, follows the
    servo in the swaying hull through a slew to 5e-4 rad (the hull's excitation of the
    rotor; the servo lags the command by 0.03 rad)."""
    config = load_scenario("usv-mems-swing").with_options(duration=320.0)
    t = np.arange(295.0, 315.0, 0.01)
    expected = config.motion.expected_gimbal_angles(t)[:, 0]
    simulated = config.motion.gimbal_state(t)[0][:, 0]
    assert np.abs(expected - simulated).max() < 5e-4
    assert np.abs(config.motion.indexer.command(t, 320.0) - simulated).max() > 0.02


def test_a_stall_needs_a_gimbal(tmp_path):
    with pytest.raises(ConfigError, match="faults.gimbal_stalls: the static-platform scenario"):
        with_faults(tmp_path, "static-large-azimuth", 60.0,
                    "\n[faults]\ngimbal_stalls = [[10.0, 1.0]]\n")


def test_a_long_slip_is_one_flag_and_a_stall_in_motion_is_refused(tmp_path):
    """A 1.5 s, 3 m slip burst is one flag (its start and end are one burst); stalls
    belong in [faults], not in [motion]."""
    text = (DATA_DIR / "ring-road-odometer.toml").read_text().replace(
        "[odometer]\n", "[odometer]\nslips = [[60.0, 1.5, 3.0]]\n")
    path = tmp_path / "long-slip.toml"
    path.write_text(text)
    _, flags = simulate_screened(load_scenario(str(path)).with_options(duration=90.0), seed=2)
    assert list(flags["fault_kind"]) == ["odometer_slip"]
    assert 0.0 <= flags["fault_time"][0] - 60.0 < 0.2
    path.write_text((DATA_DIR / "ship-sway-rotary.toml").read_text().replace(
        "[motion]\n", "[motion]\ngimbal_stalls = [[10.0, 1.0]]\n"))
    with pytest.raises(ConfigError, match="motion.gimbal_stalls: stalls are faults"):
        load_scenario(str(path))


def test_the_fault_record_lists_the_gnss_faults_before_the_odometers(tmp_path):
    """A car with both a receiver (an outage) and an odometer (a slip): the record's rows
    are the IMU's, then the GNSS receiver's, then the odometer's, as before sensors were
    roles."""
    import re

    from aligngym.scenarios.simulate import simulate
    text = re.sub(r"duration_s = [0-9.]+", "duration_s = 60.0",
                  (DATA_DIR / "ring-road-odometer.toml").read_text())
    text = text.replace("[odometer]", "[odometer]\nslips = [[30.0, 0.3, 0.5]]")
    path = tmp_path / "both.toml"
    path.write_text(text + "\n[gps]\npreset = \"rtk\"\noutages_s = [[40.0, 45.0]]\n")
    episode = simulate(load_scenario(path), seed=0)
    assert list(episode.faults.kind) == ["gnss_outage", "odometer_slip"]
    np.testing.assert_array_equal(episode.faults.start, [40.0, 30.0])


def _numpy_spikes(rate: np.ndarray, floor: float) -> np.ndarray:
    """The spike test as whole-array NumPy steps: the candidates ``screen._spikes``
    compiles, then the same local median."""
    from aligngym.estimators import screen
    finite = np.isfinite(rate)
    x = np.where(finite, rate, 0.0)
    second = np.zeros_like(x)
    second[1:-1] = x[1:-1] - 0.5 * (x[:-2] + x[2:])
    size = np.abs(second)
    across = np.full_like(x, np.inf)
    across[1:-1] = np.abs(x[2:] - x[:-2])
    padded = np.pad(size, ((1, 1), (0, 0)))
    peak = (size >= padded[:-2]) & (size >= padded[2:])
    candidate = (size > floor) & peak & (across < 0.5 * size) & finite
    k, axis = np.nonzero(candidate)
    w = screen.SPIKE_WINDOW
    edge = np.pad(size, ((w, w), (0, 0)), mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(edge, 2 * w + 1, axis=0)
    spike = np.zeros_like(candidate)
    spike[k, axis] = size[k, axis] > screen.SPIKE_MADS * 1.4826 * np.median(
        windows[k, axis], axis=-1)
    return np.any(spike, axis=1)


@pytest.mark.parametrize("samples", [3, 4, 60, 20000])
def test_the_compiled_spike_candidates_flag_what_the_numpy_steps_flag(samples):
    """``screen._spikes`` (its candidates compiled) flags the samples the NumPy steps flag,
    on a swaying rate with spikes planted (one-sample, at the ends, beside a NaN, an inf,
    two in a row, a kink, a step) and non-finite samples: the same flags, and some are
    flagged."""
    from aligngym.estimators import screen
    rng = np.random.default_rng(samples)
    t = np.arange(samples) * 0.01
    rate = np.stack([0.05 * np.sin(0.7 * t + p) for p in (0.0, 1.0, 2.0)], -1)
    rate += rng.normal(scale=1e-4, size=rate.shape)
    for i in rng.choice(samples, size=max(1, samples // 50), replace=False):
        rate[i, rng.integers(3)] += rng.choice([-1.0, 1.0]) * rng.uniform(0.02, 1.0)
    rate[0, 0] += 0.5
    rate[-1, 2] -= 0.5
    if samples >= 60:
        rate[20, 1], rate[21, 1] = np.nan, 0.6
        rate[30, 0], rate[31, 0] = np.inf, -0.4
        rate[40:42, 2] += 0.3
        rate[45:47, 0] += (1.0, 0.6)      # a kink: its neighbours 0.6 apart, not a spike
        rate[50:, 1] += 0.2
    flags = screen._spikes(rate, 0.01)
    np.testing.assert_array_equal(flags, _numpy_spikes(rate, 0.01))
    assert samples <= 4 or flags.any()
