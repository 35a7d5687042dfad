"""The wave-driven ship (SPEC 4.1's second motion source): motion of the paper's order,
truth fidelity, and the paper-003 pipeline on it."""
import numpy as np
import pytest

from aligngym.models.attitude import quat_to_euler
from aligngym.models.units import arcsec
from aligngym.models.waves import (WaveShipMotion, WaveShipWorld, heave_response, jonswap_components,
                          sway_centre_velocity)
from aligngym.models.discrete_run import SmoothRun
from aligngym.scenarios.config import load_scenario
from aligngym.scenarios.fidelity import fidelity_errors
from aligngym.scenarios.simulate import simulate


def test_jonswap_sea_has_the_significant_wave_height():
    motion = WaveShipMotion(significant_wave_height=2.0, components=400)
    a, w, k, phase = jonswap_components(motion, np.random.default_rng(0))
    # Hs = 4 sqrt(m0), m0 = sum a^2 / 2 (the 0.5-3 wp band holds ~97 % of the energy).
    assert 4 * np.sqrt(np.sum(a ** 2) / 2) == pytest.approx(2.0, rel=0.05)
    np.testing.assert_allclose(k, w ** 2 / 9.81)


RUN = 600.0
"""One 600 s run of ship-waves-rotary (seed 0) serves the motion's order, the fidelity
check and the pipeline (campaign seed 0's episode, a 120 s coarse stage and 480 s of fine
alignment): MuJoCo simulates it once (the truth cache)."""


@pytest.fixture(scope="module")
def episode():
    return simulate(load_scenario("ship-waves-rotary").with_options(duration=RUN), seed=0)


def test_wave_motion_is_of_the_papers_order(episode):
    euler = np.rad2deg(quat_to_euler(episode.truth.q_b_n))
    std = euler.std(0)
    assert 0.5 < std[0] < 10 and 0.5 < std[1] < 10  # pitch, roll: degrees
    assert abs(euler[:, 2].mean() - 30.0) < 5.0 and std[2] < 10  # autopilot on 30 deg
    np.testing.assert_allclose(episode.truth.gimbal_angles[-1], np.radians([6.0, 18.0]) * RUN)
    # Different seeds, different seas.
    other = simulate(load_scenario("ship-waves-rotary").with_options(duration=10.0), seed=3)
    assert not np.allclose(other.truth.q_b_n[-1], episode.truth.q_b_n[1000])


def test_fidelity_wave_driven_600s():
    """SPEC 3 limits over 600 s at 100 Hz, asserted 10x better, as on the prescribed ship
    (the smooth truth of MuJoCo's steps and a wrench every step: measured 0.0033 arcsec,
    0.047 mm/s, 11 mm; MuJoCo's piecewise-constant rates gave 0.46 arcsec, 0.70 mm/s)."""
    err = fidelity_errors(load_scenario("ship-waves-rotary").with_options(duration=RUN),
                          seed=0)
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
def floating():
    """A 300 s sea: the world (its sea components) and the hull centre of mass's plane
    position (m) and velocity (m/s) at 500 Hz."""
    world = WaveShipWorld(WaveShipMotion(), np.random.default_rng(4))
    run = SmoothRun(world.run(300.0))
    return world, run.t, *run.point_kinematics(np.zeros(3))


def test_heave_is_the_linear_response_to_the_sea(floating):
    """Once the start-up transient has decayed (60 s, e^-7), MuJoCo's hull heaves as
    linear theory says: sum of a_i |H(w_i)| cos(w_i t - phase_i + arg H(w_i)) over the
    realised sea components, velocity to 1 % of its std (measured 0.2 %); its centre of
    mass does not move horizontally."""
    world, t, position, velocity = floating
    a, w, _, phase = world.sea
    H = heave_response(world.motion, w)
    arg = w * t[:, None] - phase + np.angle(H)
    heave = np.sum(a * np.abs(H) * np.cos(arg), axis=1)
    heave_rate = -np.sum(a * w * np.abs(H) * np.sin(arg), axis=1)
    late = t >= 60.0
    assert np.abs(velocity[late, 2] - heave_rate[late]).max() < 0.01 * heave_rate[late].std()
    assert np.abs(position[late, 2] - heave[late]).max() < 0.01
    assert np.abs(velocity[:, :2]).max() < 1e-3


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sway_centre_velocity_from_the_sea_state(seed):
    """The heave-velocity std from (Hs, Tp, gamma) and the hull's response is that of a
    realised sea (sum a_i^2 w_i^2 |H_i|^2 / 2 over its components), within 5 %."""
    motion = WaveShipMotion()
    a, w, _, _ = jonswap_components(motion, np.random.default_rng(seed))
    realised = np.sqrt(np.sum(a ** 2 * w ** 2 * np.abs(heave_response(motion, w)) ** 2) / 2)
    std, period = sway_centre_velocity(motion)
    assert std[:2].tolist() == [0.0, 0.0]
    assert realised == pytest.approx(std[2], rel=0.05)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_heave_velocity_is_the_narrow_band_process_of_kf_sway(seed):
    """kf-sway's model of the wave-driven heave velocity (std, period and damping from the
    sea state): the autocorrelation of a realised sea's heave velocity,
    sum c_i cos(w_i tau) / sum c_i with c_i = a_i^2 w_i^2 |H_i|^2, follows the
    oscillator's exp(-zeta w tau) cos(w tau) within 0.15 over two periods."""
    from aligngym.scenarios.experiments.paper003 import sway_spectrum
    config = load_scenario("ship-waves-rotary")
    spectrum = sway_spectrum(config)
    a, w, _, _ = jonswap_components(config.motion, np.random.default_rng(seed))
    c = a ** 2 * w ** 2 * np.abs(heave_response(config.motion, w)) ** 2
    tau = np.arange(0.0, 2 * spectrum.period[2], 0.25)
    realised = np.cos(np.outer(tau, w)) @ c / c.sum()
    w_model = 2 * np.pi / spectrum.period[2]
    model = np.exp(-spectrum.damping * w_model * tau) * np.cos(w_model * tau)
    assert np.abs(realised - model).max() < 0.15
    assert spectrum.sigma[2] == pytest.approx(sway_centre_velocity(config.motion)[0][2])


def test_wave_measurement_sigma_covers_the_heave_peaks(floating):
    """The derived R: the calm-sea floor along E and N, and along U the margin above the
    expected largest heave-velocity peak, which the measured largest peak matches."""
    from aligngym.scenarios.experiments.paper003 import SWAY_R_FLOOR, SWAY_R_MARGIN, sway_measurement_sigma
    _, t, _, velocity = floating
    sigma = sway_measurement_sigma(load_scenario("ship-waves-rotary"), duration=240.0)
    assert sigma[:2] == (SWAY_R_FLOOR, SWAY_R_FLOOR)
    largest = np.abs(velocity[t >= 60.0, 2]).max()
    assert largest == pytest.approx(sigma[2] / SWAY_R_MARGIN, rel=0.3)
    assert largest < sigma[2]


def test_paper003_pipeline_runs_on_the_wave_driven_ship():
    from aligngym.scenarios.analyses.paper003 import coarse_errors
    from aligngym.scenarios.experiments.paper003 import Paper003Experiment, run_campaign
    result = run_campaign(episodes=1, seed=0, filters=["kf"], progress=False, workers=1,
                          experiment=Paper003Experiment(scenario="ship-waves-rotary",
                                                        fine_duration=RUN - 120.0))
    run = result.runs[0]
    assert np.all(np.isfinite(run.error_n)) and not run.result.diverged.any()
    # Level from coarse alignment is within a degree; the filter keeps it there.
    assert np.all(np.abs(np.rad2deg(coarse_errors(result)[0, :2])) < 1.0)
    assert np.all(np.abs(np.rad2deg(run.error_n[0, -1, :2])) < 1.0)
