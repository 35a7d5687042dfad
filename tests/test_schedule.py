"""Disturbances that change within an episode (issue 44 item 1, first part): a scenario's
[[schedule]] changes the GNSS receiver's sigmas and multipath tails and the IMU's white
noise at given times, by steps or linear ramps; the sensors generate it (the errors'
statistics per segment against the scheduled sigma), a schedule that changes nothing
changes no number, and a bad entry is a one-line error naming it."""
import re

import numpy as np
import pytest
from scipy.stats import binomtest, chi2, t as student_t

from aligngym.models.attitude import quat_to_dcm
from aligngym.models.earth import TangentPlane
from aligngym.models.schedule import Schedule, ScheduleEntry
from aligngym.models.truth import NavigationTruth
from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.registry import DATA_DIR
from aligngym.scenarios.simulate import simulate
from aligngym.sensors.base import SensorTruth
from aligngym.sensors.gps import GnssReceiver, GpsSpec
from scenario_files import shipped_with


def test_profile_steps_and_ramps_by_hand():
    s = Schedule((ScheduleEntry(10.0, 0.0, "gps", (("velocity_sigma", 0.5),)),
                  ScheduleEntry(20.0, 4.0, "gps", (("velocity_sigma", 0.1),)),
                  ScheduleEntry(30.0, 0.0, "imu", (("gyro.white_noise_density", 1.0),))))
    t = np.array([0.0, 9.99, 10.0, 19.0, 20.0, 21.0, 23.0, 24.0, 100.0])
    np.testing.assert_allclose(
        s.profile("gps", "velocity_sigma", 0.02, t),
        [0.02, 0.02, 0.5, 0.5, 0.5, 0.4, 0.2, 0.1, 0.1], rtol=1e-15, atol=0)
    assert s.touches("gps", "velocity_sigma") and not s.touches("gps", "position_sigma_h")
    np.testing.assert_array_equal(s.profile("gps", "position_sigma_h", 0.02, t), 0.02)


@pytest.mark.parametrize("entries, message", [
    ([(5.0, 0.0, 1.0), (2.0, 0.0, 2.0)], "schedule[1].time_s = 2 s comes before"),
    ([(5.0, 10.0, 1.0), (8.0, 0.0, 2.0)], "schedule[1]: gps.velocity_sigma still ramps"),
    ([(150.0, 0.0, 1.0)], "schedule[0].time_s = 150 s is out of range [0, 100]"),
    ([(90.0, 20.0, 1.0)], "schedule[0].ramp_s = 20 s is out of range [0, 10]"),
])
def test_a_schedule_that_cannot_run_is_refused(entries, message):
    s = Schedule(tuple(ScheduleEntry(time, ramp, "gps", (("velocity_sigma", v),))
                       for time, ramp, v in entries))
    with pytest.raises(ValueError, match=re.escape(message)):
        s.check(100.0)


def resting_truth(fixes: int) -> SensorTruth:
    """An antenna at rest at the plane's origin, one fix a second."""
    t = np.arange(fixes, dtype=float)
    zeros = np.zeros(fixes)
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (fixes, 1))
    truth = NavigationTruth(t=t, lat=zeros + 0.5, lon=zeros, h=zeros, v_n=np.zeros((fixes, 3)),
                            q_b_n=quat, q_s_n=quat, gimbal_angles=np.zeros((fixes, 2)))
    return SensorTruth(truth=truth, plane=TangentPlane(0.5, 0.0, 0.0),
                       antenna=(t, np.zeros((fixes, 3)), np.zeros((fixes, 3))))


def test_gnss_errors_follow_the_scheduled_sigma_and_tails():
    """RTK (2 cm) to single point (2.5 m) by a 1000 s ramp, then a multipath burst
    (Student-t, 3 dof, same sigma), then Gaussian again: the velocity errors over each
    segment, standardized by the scheduled sigma, have unit variance (99.9 % chi-square
    band), and inside the burst the share beyond 3 sigma is the t law's (scipy's), 5x the
    Gaussian's."""
    schedule = Schedule((
        ScheduleEntry(20000.0, 1000.0, "gps", (("velocity_sigma", 2.5),)),
        ScheduleEntry(40000.0, 0.0, "gps", (("multipath_dof", 3.0),)),
        ScheduleEntry(70000.0, 0.0, "gps", (("multipath_dof", 0.0),))))
    receiver = GnssReceiver(GpsSpec(velocity_sigma=0.02), schedule)
    fixes = receiver.measure(resting_truth(90000), np.random.default_rng(5), ideal=False)
    t, v = fixes.t, fixes.v_n
    sigma = schedule.profile("gps", "velocity_sigma", 0.02, t)
    z = v / sigma[:, None]
    for a, b in ((0, 20000), (20000, 21000), (21000, 40000), (70000, 90000)):
        seg = z[(t >= a) & (t < b)].ravel()
        low, high = chi2.ppf([0.0005, 0.9995], seg.size) / seg.size
        assert low < np.mean(seg ** 2) < high, (a, b)
    burst = z[(t >= 40000) & (t < 70000)].ravel()
    beyond = int(np.sum(np.abs(burst) > 3.0))
    p_t = 2 * student_t.sf(3.0 * np.sqrt(3.0), 3)      # unit variance: t3 / sqrt(3)
    assert binomtest(beyond, burst.size, p_t).pvalue > 1e-3
    assert beyond > 4 * 0.0027 * burst.size




def test_a_schedule_to_the_same_values_changes_no_number(tmp_path):
    """GNSS sigmas and the IMU's white noise scheduled to the values they have: every
    array of the episode is bit-identical to the unscheduled one."""
    same = """
[[schedule]]
time_s = 30.0
ramp_s = 10.0
gps.position_sigma_h_m = 2.5
gps.velocity_sigma = 0.05
imu.gyro_arw_deg_sqrt_h = 0.1
"""
    plain = simulate(load_scenario(shipped_with(tmp_path, "usv-mems-swing", 60.0, "")), seed=3)
    config = load_scenario(shipped_with(tmp_path, "usv-mems-swing", 60.0, same))
    assert config.schedule
    scheduled = simulate(config, seed=3)
    for name, value in plain.arrays().items():
        np.testing.assert_array_equal(scheduled.arrays()[name], value, err_msg=name)


def test_an_imu_vibration_burst_is_white_noise_of_the_scheduled_density(tmp_path):
    """A static platform's accelerometer with white noise alone (10 ug/sqrt(Hz)), 300
    ug/sqrt(Hz) from 40 to 80 s: the velocity-increment errors (erroneous minus ideal)
    have variance density^2 dt in each segment (99.9 % chi-square band)."""
    text = (DATA_DIR / "static-large-azimuth.toml").read_text()
    text = re.sub(r"duration_s = [0-9.]+", "duration_s = 120.0", text)
    text = re.sub(r"\[imu\]\n(.*\n)*?\n", "[imu]\naccel_vrw_ug_sqrt_hz = 10.0\n\n", text,
                  count=1)
    path = tmp_path / "vibration.toml"
    path.write_text(text + "\n[[schedule]]\ntime_s = 40.0\nimu.accel_vrw_ug_sqrt_hz = "
                    "300.0\n\n[[schedule]]\ntime_s = 80.0\nimu.accel_vrw_ug_sqrt_hz = 10.0\n")
    config = load_scenario(path)
    noise = simulate(config, seed=1).dv - simulate(config, seed=1, ideal=True).dv
    dt = config.imu_interval
    mid = (np.arange(noise.shape[0]) + 0.5) * dt
    for a, b, density in ((0, 40, 10.0), (40, 80, 300.0), (80, 120, 10.0)):
        seg = noise[(mid >= a) & (mid < b)].ravel() / (density * 9.80665e-6 * np.sqrt(dt))
        low, high = chi2.ppf([0.0005, 0.9995], seg.size) / seg.size
        assert low < np.mean(seg ** 2) < high, (a, b, np.mean(seg ** 2))


@pytest.mark.parametrize("entry, message", [
    ("time_s = 10.0\ngps.rate_hz = 5.0\n", "schedule[0].gps.rate_hz is not a parameter a "
     "schedule may change; valid: multipath_dof, position_sigma_h_m"),
    ("time_s = 10.0\ngps.multipath_dof = 1.5\n", "schedule[0]: gps.multipath_dof = 1.5 "
     "must be 0 (Gaussian) or in (2, 1000]"),
    ("time_s = 10.0\ngps.position_sigma_h = 1.0\n", "schedule[0].gps.position_sigma_h: "
     "position_sigma_h is in m; write position_sigma_h_m"),
    ("time_s = 10.0\nodometer.scale_error = 0.1\n", "schedule[0] table = 'odometer' is "
     "unknown; valid choices: gps, imu"),
    ("time_s = 10.0\nimu.gyro_bias_deg_h = 1.0\n", "schedule[0].imu.gyro_bias_deg_h is not "
     "a parameter a schedule may change"),
    ("time_s = 10.0\nimu.accel_vrw_ug_sqrt_hz = -1.0\n", "schedule[0].imu."
     "accel_vrw_ug_sqrt_hz = -1.0 is out of range [0, 1e+06]"),
    ("time_s = 500.0\ngps.velocity_sigma = 1.0\n", "schedule[0].time_s = 500 s is out of "
     "range [0, 60]"),
    ("ramp_s = 5.0\ngps.velocity_sigma = 1.0\n", "schedule[0] has no time_s"),
    ("time_s = 10.0\n", "schedule[0] changes nothing"),
])
def test_a_bad_entry_is_one_line_naming_it(tmp_path, entry, message):
    path = shipped_with(tmp_path, "usv-mems-swing", 60.0, "\n[[schedule]]\n" + entry)
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_a_building_sea_is_the_physics_response_to_larger_waves(tmp_path):
    """The wave-driven ship whose sea builds from 1.5 m to 4.5 m significant height
    (every wave component's amplitude x3, from 20 s over 20 s): the hull is MuJoCo's
    response to it. Before the change the episode is bit-identical to the calm one (the
    increments up to the smooth truth's few samples of look-ahead); once the transient has
    died away (80-120 s), the hull's heave (the IMU's height less its lever arm's vertical)
    is 3x the calm episode's to 0.5 %: its vertical dynamics are linear in the sea's
    elevation (measured 0.1 %; the IMU's own height, 30 m forward, adds the roll-pitch
    products, 6 %)."""
    building = "\n[[schedule]]\ntime_s = 20.0\nramp_s = 20.0\nmotion." \
               "significant_wave_height_m = 4.5\n"
    calm = simulate(load_scenario(shipped_with(tmp_path, "ship-waves-rotary", 120.0, "")),
                    seed=2, ideal=True)
    rough = simulate(load_scenario(shipped_with(tmp_path, "ship-waves-rotary", 120.0,
                                            building)), seed=2, ideal=True)
    t = calm.truth.t
    before = t < 20.0
    np.testing.assert_array_equal(rough.truth.h[before], calm.truth.h[before])
    early = t[1:] < 19.5
    np.testing.assert_array_equal(rough.dv[early], calm.dv[early])
    lever = np.asarray(calm.config.motion.lever_arm_b)

    def heave(episode):
        tr = episode.truth
        return tr.h - np.einsum("nij,j->ni", quat_to_dcm(tr.q_b_n), lever)[:, 2]
    late = t >= 80.0
    expected = 3.0 * (heave(calm)[late] - heave(calm)[late].mean())
    residual = heave(rough)[late] - heave(rough)[late].mean() - expected
    assert np.std(residual) < 0.005 * np.std(expected), (np.std(residual), np.std(expected))
    assert np.std(expected) > 1.0                # the hull heaves by metres in that sea
