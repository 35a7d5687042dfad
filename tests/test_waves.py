"""The wave-driven ship (SPEC 4.1's second motion source): motion of the paper's order,
truth fidelity, and the paper-003 pipeline on it."""
import numpy as np
import pytest

from models.attitude import quat_to_euler
from models.units import arcsec
from models.waves import (WaveShipMotion, WaveShipWorld, jonswap_components,
                          sway_centre_velocity)
from models.world import SmoothRun
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
    """SPEC 3 limits over 600 s at 100 Hz, asserted 10x better, as on the prescribed ship
    (the smooth truth of MuJoCo's steps and a wrench every step: measured 0.0025 arcsec,
    0.021 mm/s, 6 mm; MuJoCo's piecewise-constant rates gave 0.46 arcsec, 0.70 mm/s)."""
    err = fidelity_errors(load_scenario("ship-waves-rotary").with_options(duration=600.0),
                          seed=1)
    assert err["attitude_rad"] < 0.1 * arcsec
    assert err["velocity_m_s"] < 0.5e-3
    assert err["position_m"] < 0.1


def zero_crossing_period(x: np.ndarray, dt: float) -> float:
    """Mean period (s) between upward zero crossings of a decaying oscillation x."""
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    return float(np.diff(up).mean() * dt)


@pytest.mark.parametrize("axis, period_name", [(0, "pitch_period"), (1, "roll_period"),
                                               (None, "heave_period")])
def test_free_decay_at_the_natural_periods(axis, period_name):
    """Calm sea, an initial pitch or roll rate, or heave velocity: the hull oscillates at
    its natural period (damped: T / sqrt(1 - zeta^2)) and decays at zeta."""
    motion = WaveShipMotion(significant_wave_height=0.0)
    world = WaveShipWorld(motion, np.random.default_rng(0))
    if axis is None:
        world.data.qvel[2] = 0.1
    else:
        world.data.qvel[3 + axis] = 0.01
    run = world.run(40.0)
    signal = run.pos[:, 2] if axis is None else run.omega[:-1, axis]
    zeta = motion.damping_ratio
    expected = getattr(motion, period_name) / np.sqrt(1 - zeta ** 2)
    assert zero_crossing_period(signal, run.dt) == pytest.approx(expected, rel=0.01)
    # Logarithmic decrement over one period: exp(-zeta w_n T_d).
    peaks = [np.abs(signal[:int(expected / run.dt)]).max(),
             np.abs(signal[int(expected / run.dt):int(2 * expected / run.dt)]).max()]
    decay = np.exp(-zeta * 2 * np.pi / getattr(motion, period_name) * expected)
    assert peaks[1] / peaks[0] == pytest.approx(decay, rel=0.05)


@pytest.fixture(scope="module")
def centre_velocity():
    """Velocity (m/s, E N U) of the hull's centre of mass at 500 Hz over a 600 s sea."""
    motion = WaveShipMotion()
    run = SmoothRun(WaveShipWorld(motion, np.random.default_rng(4)).run(600.0))
    return motion, run.point_kinematics(np.zeros(3))[1]


def test_sway_centre_velocity_from_the_sea_state(centre_velocity):
    """The heave velocity std predicted from (Hs, Tp, gamma) and the hull's heave response
    is the measured one; the centre of mass does not move horizontally."""
    motion, v = centre_velocity
    std, period = sway_centre_velocity(motion)
    v = v[int(60 / 0.002):]          # after the start-up transient
    assert v[:, 2].std() == pytest.approx(std[2], rel=0.08)
    assert np.abs(v[:, :2]).max() < 1e-3
    # The mean zero-crossing period of the heave velocity (s).
    assert zero_crossing_period(v[:, 2], 0.002) == pytest.approx(period[2], rel=0.1)


def test_heave_velocity_is_the_narrow_band_process_of_kf_sway(centre_velocity):
    """kf-sway's model of the wave-driven heave velocity (std, period and damping from the
    sea state): the measured autocorrelation follows the oscillator's
    exp(-zeta w tau) cos(w tau) over the first two periods (measured within 0.1)."""
    from scenarios.paper003 import sway_spectrum
    _, v = centre_velocity
    spectrum = sway_spectrum(load_scenario("ship-waves-rotary"))
    u = v[int(60 / 0.002)::50, 2]                   # 10 Hz, after the transient
    w = 2 * np.pi / spectrum.period[2]
    assert u.std() == pytest.approx(spectrum.sigma[2], rel=0.08)
    for tau in np.arange(0.5, 14.0, 0.5):
        lag = int(round(tau * 10))
        measured = np.mean(u[:-lag] * u[lag:]) / u.var()
        model = np.exp(-spectrum.damping * w * tau) * np.cos(w * tau)
        assert abs(measured - model) < 0.15, tau


def test_wave_measurement_sigma_covers_the_heave_peaks(centre_velocity):
    """The derived R: the calm-sea floor along E and N, and along U the margin above the
    expected largest heave-velocity peak, which the measured largest peak matches."""
    from scenarios.paper003 import SWAY_R_FLOOR, SWAY_R_MARGIN, sway_measurement_sigma
    _, v = centre_velocity
    sigma = sway_measurement_sigma(load_scenario("ship-waves-rotary"), duration=540.0)
    assert sigma[:2] == (SWAY_R_FLOOR, SWAY_R_FLOOR)
    largest = np.abs(v[int(60 / 0.002):, 2]).max()
    assert largest == pytest.approx(sigma[2] / SWAY_R_MARGIN, rel=0.3)
    assert largest < sigma[2]


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
