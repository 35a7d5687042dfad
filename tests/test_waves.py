"""The wave-driven ship (SPEC 4.1's second motion source): motion of the paper's order,
truth fidelity, and the paper-003 pipeline on it."""
import numpy as np
import pytest

from models.attitude import quat_to_euler
from models.units import arcsec
from models.waves import WaveShipMotion, jonswap_components
from scenarios.config import load_scenario
from scenarios.fidelity import fidelity_errors
from scenarios.simulate import simulate


def test_jonswap_sea_has_the_significant_wave_height():
    motion = WaveShipMotion(significant_wave_height=2.0, components=400)
    a, w, k, phase = jonswap_components(motion, np.random.default_rng(0))
    # Hs = 4 sqrt(m0), m0 = sum a^2 / 2 (the 0.5-3 wp band holds ~97 % of the energy).
    assert 4 * np.sqrt(np.sum(a ** 2) / 2) == pytest.approx(2.0, rel=0.05)
    np.testing.assert_allclose(k, w ** 2 / 9.81)


@pytest.fixture(scope="module")
def episode():
    return simulate(load_scenario("ship-waves-rotary").with_options(duration=300.0), seed=2)


def test_wave_motion_is_of_the_papers_order(episode):
    euler = np.rad2deg(quat_to_euler(episode.truth.q_b_n))
    std = euler.std(0)
    assert 0.5 < std[0] < 10 and 0.5 < std[1] < 10  # pitch, roll: degrees
    assert abs(euler[:, 2].mean() - 30.0) < 5.0 and std[2] < 10  # autopilot on 30 deg
    np.testing.assert_allclose(episode.truth.gimbal_angles[-1], np.radians([6.0, 18.0]) * 300)
    # Different seeds, different seas.
    other = simulate(load_scenario("ship-waves-rotary").with_options(duration=10.0), seed=3)
    assert not np.allclose(other.truth.q_b_n[-1], episode.truth.q_b_n[1000])


def test_fidelity_wave_driven_600s():
    """SPEC 3 limits over 600 s at 100 Hz. The margin is smaller than on the prescribed
    ship: MuJoCo's 2 ms steps rotate at piecewise-constant rates, which the two-sample
    coning term reads as ~0.05 arcsec/min of spurious coning (measured 0.45 arcsec)."""
    err = fidelity_errors(load_scenario("ship-waves-rotary").with_options(duration=600.0),
                          seed=1)
    assert err["attitude_rad"] < arcsec
    assert err["velocity_m_s"] < 5e-3
    assert err["position_m"] < 1.0


def test_paper003_pipeline_runs_on_the_wave_driven_ship():
    from scenarios.paper003 import Paper003Experiment, coarse_errors, run_campaign
    result = run_campaign(episodes=1, seed=0, filters=["kf"], progress=False, workers=1,
                          experiment=Paper003Experiment(scenario="ship-waves-rotary",
                                                        fine_duration=120.0))
    run = result.runs[0]
    assert np.all(np.isfinite(run.error_n)) and not run.result.diverged.any()
    # Level from coarse alignment is within a degree; the filter keeps it there.
    assert np.all(np.abs(np.rad2deg(coarse_errors(result)[0, :2])) < 1.0)
    assert np.all(np.abs(np.rad2deg(run.error_n[0, -1, :2])) < 1.0)
