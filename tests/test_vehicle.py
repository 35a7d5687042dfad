"""Vehicle world: truth fidelity on the car (smooth and rough road), GPS and odometer
statistics, the figure-8 geometry, and bad input."""
import math
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from aligngym.models.units import arcsec
from aligngym.scenarios.config import DATA_DIR, load_scenario
from aligngym.scenarios.fidelity import fidelity_errors
from aligngym.scenarios.simulate import simulate
from aligngym.sensors.gps import GPS_PRESETS, measure


@pytest.mark.parametrize("name", ["ring-road-odometer", "figure8-gps"])
def test_fidelity_smooth_road_600s(name):
    """SPEC 3 (1 arcsec, 5 mm/s, 1 m) at the scenario's 100 Hz; we assert 10x better."""
    config = load_scenario(name).with_options(duration=600.0)
    config = replace(config, motion=replace(config.motion, start_time=5.0))
    err = fidelity_errors(config, seed=2)
    assert err["attitude_rad"] < 0.1 * arcsec
    assert err["velocity_m_s"] < 0.5e-3
    assert err["position_m"] < 0.1


def rough(name, duration):
    config = load_scenario(name).with_options(duration=duration, imu_rate=500.0)
    return replace(config, motion=replace(config.motion, start_time=2.0, roughness_rms=0.004))


@pytest.mark.parametrize("name", ["ring-road-odometer", "figure8-gps"])
def test_fidelity_rough_road_500hz_150s(name):
    """SPEC 3's bounds on a rough road at 500 Hz over 150 s (more than a lap of either
    track), asserted 10-20x better: 0.05 arcsec, 0.5 mm/s, 5 cm, about 5-7x what the
    figure-8 leaves (measured 0.005 / 0.009 arcsec, 0.04 / 0.10 mm/s, 3 / 7 mm on the
    ring / figure-8; the vibration's coning and sculling show within seconds). The 600 s
    SPEC run is the smooth-road test's; over 600 s rough the errors measured 0.016 /
    0.025 arcsec, 0.19 / 0.50 mm/s, 0.05 / 0.14 m."""
    err = fidelity_errors(rough(name, 150.0), seed=3)
    assert err["attitude_rad"] < 0.05 * arcsec and err["velocity_m_s"] < 0.5e-3
    assert err["position_m"] < 0.05


def test_smooth_road_run_is_shared_by_every_seed_and_changes_nothing(monkeypatch):
    """With no road heightfield the car's MuJoCo run is the same for every episode, so it
    is simulated once per process; each seed's sensor errors still differ, an episode
    equals the one simulated afresh, nobody can modify the shared truth, and a rough
    road gets its own run per seed."""
    from aligngym.scenarios import world_truth

    config = load_scenario("ring-road-odometer").with_options(duration=20.0)
    first, second = simulate(config, seed=0), simulate(config, seed=1)
    ideal = simulate(config, seed=1, ideal=True)
    for other in (second, ideal):
        assert np.shares_memory(other.truth.q_b_n, first.truth.q_b_n)
    assert not np.array_equal(first.dtheta, second.dtheta)
    with pytest.raises(ValueError, match="read-only"):
        first.truth.v_n[0, 0] = 1.0
    world_truth._shared_runs.clear()
    monkeypatch.setenv("ALIGNGYM_TRUTH_CACHE", "off")
    afresh = simulate(config, seed=1)
    assert not np.shares_memory(afresh.truth.q_b_n, second.truth.q_b_n)
    for name, value in second.arrays().items():
        np.testing.assert_array_equal(afresh.arrays()[name], value, err_msg=name)
    bumpy = rough("ring-road-odometer", 6.0)
    a, b = simulate(bumpy, seed=0), simulate(bumpy, seed=1)
    assert not np.array_equal(a.truth.q_b_n, b.truth.q_b_n)
    world_truth._shared_runs.clear()


def test_gps_error_statistics_and_heading_sigma():
    rng = np.random.default_rng(8)
    n = 20000
    lat = np.full(n, 0.5)
    speed = rng.uniform(6.0, 25.0, n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    v_n = np.stack([-speed * np.sin(yaw), speed * np.cos(yaw), np.zeros(n)], -1)
    for preset in ("rtk", "single-point"):
        spec = GPS_PRESETS[preset]
        out = measure(spec, np.arange(n, dtype=float), lat, np.zeros(n), np.zeros(n), v_n, rng)
        from aligngym.models.earth import radii
        R_M, R_N = radii(lat)
        north = (out["gps_lat"] - lat) * R_M
        east = out["gps_lon"] * R_N * np.cos(lat)
        assert np.std(north) == pytest.approx(spec.position_sigma_h, rel=0.1)
        assert np.std(east) == pytest.approx(spec.position_sigma_h, rel=0.1)
        assert np.std(out["gps_h"]) == pytest.approx(spec.position_sigma_v, rel=0.1)
        assert np.std(out["gps_v_n"] - v_n) == pytest.approx(spec.velocity_sigma, rel=0.1)
        err = (out["gps_heading"] - yaw + np.pi) % (2 * np.pi) - np.pi
        ok = out["gps_heading_valid"]
        assert np.std(err[ok] / out["gps_heading_sigma"][ok]) == pytest.approx(1.0, rel=0.1)
    # 001's oracle: 0.0175 m/s at 10 m/s gives 0.1 deg.
    from aligngym.sensors.gps import heading_from_velocity
    _, sigma = heading_from_velocity(np.array([[10.0, 0.0, 0.0]]), 0.0175)
    assert math.degrees(sigma[0]) == pytest.approx(0.100, abs=0.001)


def test_gps_outage_latency_and_low_speed_flags():
    spec = replace(GPS_PRESETS["rtk"], outages=((3.0, 5.0),), latency=0.2)
    t = np.arange(8, dtype=float)
    v = np.zeros((8, 3))
    v[:, 1] = [0, 1, 2, 8, 8, 8, 8, 8]
    out = measure(spec, t, np.full(8, 0.5), np.zeros(8), np.zeros(8), v,
                  np.random.default_rng(0))
    np.testing.assert_allclose(out["gps_t"], t + 0.2)
    assert list(out["gps_valid"]) == [True, True, True, False, False, True, True, True]
    assert np.isnan(out["gps_lat"][3])
    assert list(out["gps_heading_valid"][:3]) == [False, False, False]


@pytest.fixture(scope="module")
def figure8_episode():
    """150 s of figure8-gps, the car starting at 5 s: the start of the 600 s fidelity
    run's drive (``test_fidelity_smooth_road_600s``), so its smooth-road run is reused,
    not simulated again."""
    config = load_scenario("figure8-gps").with_options(duration=150.0)
    config = replace(config, motion=replace(config.motion, start_time=5.0))
    return simulate(config, seed=1)


def test_figure8_crosses_itself_and_turns_both_ways(figure8_episode):
    ep = figure8_episode
    from aligngym.models.earth import radii
    R_M, R_N = radii(ep.truth.lat[0])
    north = (ep.truth.lat - ep.truth.lat[0]) * R_M
    east = (ep.truth.lon - ep.truth.lon[0]) * R_N * np.cos(ep.truth.lat[0])
    xy = np.stack([east, north], -1)[::50]  # 0.5 s apart
    d = np.linalg.norm(xy[:, None] - xy[None], axis=-1)
    apart = np.abs(np.arange(len(xy))[:, None] - np.arange(len(xy))[None]) > 40  # > 20 s
    assert np.any((d < 3.0) & apart)  # it crosses itself
    yaw_rate = ep.dtheta[:, 2] / 0.01
    assert yaw_rate.max() > 0.05 and yaw_rate.min() < -0.05  # left and right turns
    assert np.abs(ep.cross_track[ep.truth.t > 30]).max() < 1.5


def test_figure8_gps_export(figure8_episode):
    arrays = figure8_episode.arrays()
    for key in ("gps_t", "gps_lat", "gps_lon", "gps_h", "gps_v_n", "gps_heading",
                "gps_heading_sigma", "gps_valid"):
        assert key in arrays
    assert arrays["gps_t"].size == 151 and arrays["gps_v_n"].shape == (151, 3)


def test_odometer_scale_error_and_slip():
    """Odometer distance vs the truth path length: the configured dK_D plus the tyres'
    slip and effective-radius error (reported: a few 1e-3). The car starts at 5 s, as in
    the scenario file: the first 120 s of the 600 s fidelity run's drive, reused."""
    config = load_scenario("ring-road-odometer").with_options(duration=120.0)
    assert config.motion.start_time == 5.0
    ep = simulate(config, seed=4)
    speed = np.linalg.norm(ep.truth.v_n[:, :2], axis=1)
    path = np.sum(0.5 * (speed[1:] + speed[:-1]) * np.diff(ep.truth.t))
    effective = ep.measurements["odometer"].distance[-1] / path - 1.0
    assert abs(effective - 0.003) < 0.02
    ideal = simulate(config, seed=4, ideal=True)
    effective_ideal = ideal.measurements["odometer"].distance[-1] / path - 1.0
    assert effective - effective_ideal == pytest.approx(0.003, rel=0.02)


@pytest.mark.parametrize("old, new, expected", [
    ("radius_m = 100.0", "radius_m = 100.0", None),
    ("radius_m = 100.0", "radius_m = -5.0", "motion.radius_m = -5 m is out of range"),
    ("speed = 8.0", "speed = 30.0", "lateral acceleration; the car holds at most"),
    ('track = "ring"', 'track = "oval"', "valid choices: figure8, ring"),
])
def test_vehicle_bad_input(tmp_path, old, new, expected):
    text = (DATA_DIR / "ring-road-odometer.toml").read_text().replace(old, new)
    path = tmp_path / "s.toml"
    path.write_text(text)
    proc = subprocess.run([sys.executable, "-m", "aligngym.scenarios.cli", "simulate", str(path),
                           "--duration", "0.1", "--out", str(tmp_path / "x.npz")],
                          capture_output=True, text=True)
    if expected is None:
        assert proc.returncode == 0, proc.stderr
    else:
        assert proc.returncode == 2 and expected in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1


def test_imu_rate_must_divide_physics_rate():
    proc = subprocess.run([sys.executable, "-m", "aligngym.scenarios.cli", "simulate",
                           "ring-road-odometer", "--imu-rate", "300", "--out", "x.npz"],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "must divide the car physics rate 500 Hz" in proc.stderr


def test_fidelity_car_with_gimbal():
    """The IMU on the double-axis gimbal on the car (6 and 18 deg/s): the truth stays
    self-consistent (500 Hz, so the strapdown's own error under vibration is small)."""
    config = load_scenario("ring-road-odometer").with_options(duration=60.0, imu_rate=500.0)
    config = replace(config, motion=replace(config.motion, start_time=2.0,
                                            gimbal_outer_rate=math.radians(6.0),
                                            gimbal_inner_rate=math.radians(18.0)))
    ep = simulate(config, seed=1, ideal=True)
    np.testing.assert_allclose(ep.truth.gimbal_angles[-1], np.radians([6.0, 18.0]) * 60.0)
    err = fidelity_errors(config, seed=1)
    assert err["attitude_rad"] < 0.1 * arcsec and err["velocity_m_s"] < 0.5e-3
    assert err["position_m"] < 0.1


def test_a_shorter_smooth_road_run_is_the_start_of_a_longer_one():
    """One run per motion on a smooth road: an episode cut from a longer run equals the
    episode simulated afresh at its own duration (GPS fixes and odometer included)."""
    from aligngym.scenarios import world_truth

    for name in ("figure8-gps", "ring-road-odometer"):
        base = load_scenario(name)
        world_truth._shared_runs.clear()
        simulate(base.with_options(duration=40.0), seed=2)             # the longer run
        cut = simulate(base.with_options(duration=23.0), seed=2)
        assert cut.truth.t.base is not None                            # a view of it
        world_truth._shared_runs.clear()
        with pytest.MonkeyPatch.context() as patch:
            patch.setenv("ALIGNGYM_TRUTH_CACHE", "off")
            afresh = simulate(base.with_options(duration=23.0), seed=2)
        for key, value in afresh.arrays().items():
            np.testing.assert_array_equal(cut.arrays()[key], value, err_msg=f"{name} {key}")
        world_truth._shared_runs.clear()
