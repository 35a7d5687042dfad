"""A scenario file's errors name each key as the file writes it (unit suffix included,
whichever check found the value bad: the loader's, a sensor's or a world's) and suggest
the closest valid key or choice for a misspelt one, in one line."""
import re
import tomllib

import pytest

from aligngym.scenarios.config import DATA_DIR, ConfigError, _build, load_scenario


def edited(name: str, old: str, new: str, tmp_path) -> str:
    text = (DATA_DIR / f"{name}.toml").read_text()
    assert re.search(old, text, flags=re.M), old
    path = tmp_path / "edited.toml"
    path.write_text(re.sub(old, new, text, count=1, flags=re.M))
    return str(path)


@pytest.mark.parametrize("name, old, new, expected", [
    # missing and out-of-range values, named as written
    ("ship-waves-rotary", r"^duration_s = .*\n", "", "missing key run.duration_s"),
    ("ship-waves-rotary", r"^heave_period_s = .*$", "heave_period_s = -2.5",
     "motion.heave_period_s = -2.5 is out of range [2, 30]"),
    ("usv-mems-swing", r"^hull_size_m = .*$", "hull_size_m = [-3.0, 6.0, 1.0]",
     "motion.hull_size_m[0] = -3 m is out of range [0.5, 500]"),
    ("ring-road-odometer", r"^radius_m = .*$", "radius_m = -5.0",
     "motion.radius_m = -5 m is out of range"),
    ("ring-road-odometer", r"^\[odometer\]\n", "[odometer]\nnominal_radius_m = -3.0\n",
     "odometer.nominal_radius_m must be > 0 m, got -3.0"),
    ("figure8-gps", r"^\[gps\]\n", "[gps]\nrate_hz = -3.0\n",
     "gps.rate_hz = -3.0 Hz is out of range (0, 100]"),
    # misspelt keys: the closest valid one suggested, in every table
    ("ship-waves-rotary", r"^\[motion\]\n", "[motion]\nsignificant_wave_hieght_m = 2.0\n",
     "motion.significant_wave_hieght_m is not a parameter; did you mean "
     "significant_wave_height_m? valid: "),
    ("ship-sway-rotary", r"^\[origin\]\n", "[origin]\nlatitud_deg = 3.0\n",
     "origin.latitud_deg is not a parameter; did you mean latitude_deg? valid: "
     "latitude_deg, longitude_deg, height_m"),
    ("ship-sway-rotary", r"^imu_rate_hz", "imu_rate_hzz",
     "run.imu_rate_hzz is not a parameter; did you mean imu_rate_hz?"),
    ("ship-sway-rotary", r"^\[imu\]\n", "[imu]\ngyro_bias_deg_hr = 3.0\n",
     "imu.gyro_bias_deg_hr is not a parameter; did you mean gyro_bias_deg_h?"),
    ("static-large-azimuth", r"^\[motion\]\n", "[motion]\nyaw_degg = 3.0\n",
     "motion.yaw_degg is not a parameter of the static platform; did you mean yaw_deg?"),
    ("ship-sway-rotary", r'^world = "ship-prescribed"', 'world = "ship-prescibed"',
     "world = 'ship-prescibed' is unknown; did you mean 'ship-prescribed'? valid choices: "
     "car, ship-prescribed, ship-waves, static-platform"),
    ("figure8-gps", r'^preset = "rtk"', 'preset = "rkt"',
     "gps.preset = 'rkt' is unknown; did you mean 'rtk'?"),
    ("ship-sway-rotary", r"\Z", "\n[gpss]\nrate_hz = 1.0\n",
     "'gpss' is neither a key (name, paper, experiment, world) nor a table ([origin], "
     "[run], [imu], [motion], [encoder], [odometer], [gps], [filter], [indexer], [faults], [dvl])"
     "; did you mean [gps]?"),
    ("ship-sway-rotary", r"^\[origin\]\n", "[origin]\nimu_rate_hz = 100.0\n",
     "origin.imu_rate_hz is not a parameter; valid: latitude_deg, longitude_deg, height_m"),
    # a check that reports radians keeps the SI name: no radian under a _deg_s key
    ("usv-mems-swing", r"^slew_rate_deg_s = .*$", "slew_rate_deg_s = 400.0",
     "indexer.slew_rate = 6.98132 is out of range (0, 6.28319] (SI units)"),
    # nothing close: no suggestion
    ("ship-sway-rotary", r"^\[motion\]\n", "[motion]\nzzz = 1.0\n",
     "motion.zzz is not a parameter; valid: "),
])
def test_an_error_names_the_key_as_written_and_the_closest_one(name, old, new, expected,
                                                                tmp_path):
    path = edited(name, old, new, tmp_path)
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    message = str(info.value)
    assert expected in message and "\n" not in message


def test_an_unknown_key_of_origin_or_run_is_refused():
    """[origin] and [run] keys are checked like the others' (a misspelt one used to be
    dropped without a word, and the default taken)."""
    text = (DATA_DIR / "ship-sway-rotary.toml").read_text()
    assert "[run]\n" in text
    for table in ("origin", "run"):
        raw = text.replace(f"[{table}]\n", f"[{table}]\nnote_s = 1.0\n")
        with pytest.raises(ConfigError, match=rf"^{table}.note_s is not a parameter; "):
            _build(tomllib.loads(raw), "s.toml")
