"""Property-based tests over scenario files: mutated keys, wrong types, NaN/inf, negative
and huge values, unknown keys and tables. Every case is either rejected with a one-line
ConfigError or simulates (1 s) to finite data; never a traceback of another kind."""
import copy
import tomllib

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aligngym.scenarios.config import DATA_DIR, ConfigError, _build, scenario_names
from aligngym.scenarios.simulate import simulate

BASE = {name: tomllib.loads((DATA_DIR / f"{name}.toml").read_text())
        for name in scenario_names()}

VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10 ** 12, 10 ** 12),
    st.booleans(), st.text(max_size=4), st.just("random"),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
    st.lists(st.integers(-5, 5), min_size=3, max_size=3), st.just([]), st.just({}))
SUFFIXES = ["_deg", "_s", "_m", "_hz", "_arcsec", "_deg_s", "x", ""]


@st.composite
def mutated_scenario(draw):
    name = draw(st.sampled_from(sorted(BASE)))
    raw = copy.deepcopy(BASE[name])
    for _ in range(draw(st.integers(1, 2))):
        kind = draw(st.sampled_from(["scale"] * 6 + ["value"] * 2 + [
            "rename", "drop", "add_key", "add_table", "top", "drop_table"]))
        tables = sorted(k for k, v in raw.items() if isinstance(v, dict))
        if kind == "add_table" or not tables:
            raw[draw(st.sampled_from(["faults", "Motion", "imu2", "x"]))] = {}
            continue
        if kind == "top":
            raw[draw(st.sampled_from(["world", "name", "paper", "wrold"]))] = draw(
                st.one_of(st.sampled_from(["car", "ship-waves", "ship", ""]), VALUES))
            continue
        table = draw(st.sampled_from(tables))
        if kind == "drop_table":
            del raw[table]
            continue
        keys = sorted(raw[table])
        if kind == "add_key" or not keys:
            raw[table][draw(st.sampled_from(["speed", "radius_m", "pitch_period",
                                             "foo_m", "preset", "duration_deg"]))] = draw(VALUES)
            continue
        key = draw(st.sampled_from(keys))
        if kind == "scale":     # the same kind of value, scaled: in range or just out
            factor = draw(st.sampled_from([-1.0, 0.0, 0.5, 2.0, 10.0, 1e3, 1e9]))
            value = raw[table][key]
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                raw[table][key] = type(value)(value * factor)
            elif isinstance(value, list) and all(isinstance(v, (int, float)) for v in value):
                raw[table][key] = [v * factor for v in value]
        elif kind == "value":
            raw[table][key] = draw(VALUES)
        elif kind == "rename":
            stem = key
            for suffix in sorted(SUFFIXES, key=len, reverse=True):
                if suffix and key.endswith(suffix):
                    stem = key[: -len(suffix)]
                    break
            raw[table][stem + draw(st.sampled_from(SUFFIXES))] = raw[table].pop(key)
        else:
            del raw[table][key]
    return name, raw


@settings(max_examples=1000, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(mutated_scenario())
def test_fuzzed_scenarios_rejected_in_one_line_or_finite(case):
    name, raw = case
    try:
        config = _build(raw, f"{name}.toml")
        config = config.with_options(duration=min(config.duration, 1.0))
    except ConfigError as exc:
        message = str(exc)
        assert message and "\n" not in message
        return
    episode = simulate(config, seed=0)
    for array in (episode.dtheta, episode.dv, episode.truth.q_s_n, episode.truth.v_n,
                  episode.truth.lat, episode.truth.h):
        assert np.all(np.isfinite(array)), name


def ship(**motion):
    raw = copy.deepcopy(BASE["ship-sway-rotary"])
    raw["motion"].update(motion)
    return raw


def rejected(raw) -> str:
    try:
        _build(raw, "case.toml")
    except ConfigError as exc:
        return str(exc)
    raise AssertionError("accepted")


def test_the_errors_a_new_user_met():
    """Each of the issue's reports, now a one-line error naming the field."""
    assert rejected(ship(pitch_period_deg=5)) == (
        "motion.pitch_period_deg: pitch_period is in s; write pitch_period_s")
    assert rejected(ship(pitch_period=5)) == (
        "motion.pitch_period: pitch_period is in s; write pitch_period_s")
    assert "must be finite" in rejected(ship(yaw_mean_deg=float("nan")))
    assert "must be finite" in rejected(ship(gimbal_inner_rate_deg_s=float("inf")))
    assert "expected a number" in rejected(ship(yaw_amplitude_deg=True))
    assert rejected(ship(lever_arm_b_m=[1.0])).startswith("motion.lever_arm_b_m must be 3")
    assert "must be a number" in rejected(ship(yaw_period_s=[7.0]))
    assert "is neither a key" in rejected({**ship(), "fault": {}})
    assert "'wrold' is neither a key" in rejected({**ship(), "wrold": "car"})
    raw = ship()
    del raw["world"]
    assert "missing key world" in rejected(raw)
    from aligngym.scenarios.config import load_scenario
    try:
        load_scenario("no/such/file.toml")
    except ConfigError as exc:
        assert "does not exist" in str(exc)
