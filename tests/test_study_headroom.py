"""examples/study.py's oracle and headroom arithmetic: the schedule's segments in env
steps, a piecewise policy, and the leaderboard entry's headroom and fractions (with
their paired bootstrap intervals) on rewards whose answer is known."""
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from aligngym.models.schedule import Schedule, ScheduleEntry

STUDY = Path(__file__).resolve().parents[1] / "examples" / "study.py"


@pytest.fixture(scope="module")
def study():
    spec = importlib.util.spec_from_file_location("study", STUDY)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_segments_start_at_the_first_update_beyond_each_boundary(study):
    """Fine run from 60 s, 1 s epochs: step k's update at 61 + k s. A change at 200 s
    with a 20 s ramp and one at 400 s: segments from the updates after 200, 220, 400 s;
    a boundary before the run or after its end is no segment."""
    schedule = Schedule((ScheduleEntry(200.0, 20.0, "gps", (("velocity_sigma", 1.0),)),
                         ScheduleEntry(400.0, 0.0, "gps", (("velocity_sigma", 0.1),)),
                         ScheduleEntry(900.0, 0.0, "gps", (("velocity_sigma", 0.2),))))
    assert schedule.boundaries() == (200.0, 220.0, 400.0, 900.0)
    starts = study.segment_starts(schedule, 60.0, 1.0, 600)
    assert starts == [140, 160, 340]
    policy = study.piecewise(np.arange(12.0).reshape(4, 3), starts, 2)
    assert policy(None, 139)[1].tolist() == [0.0, 1.0, 2.0]
    assert policy(None, 140)[0].tolist() == [3.0, 4.0, 5.0]
    assert policy(None, 599).shape == (2, 3) and policy(None, 599)[0, 0] == 9.0
    per_slot = study.piecewise(np.arange(24.0).reshape(2, 4, 3), starts, 2)
    assert per_slot(None, 150).tolist() == [[3.0, 4.0, 5.0], [15.0, 16.0, 17.0]]


def test_the_headroom_and_each_arms_fraction_of_it(study, tmp_path):
    """Best constant c, oracle c + 2, an arm halfway (c + 1 + noise): headroom 2, the
    arm's fraction near 1/2 with an interval around it, the oracle's exactly 1, the
    constant's 0; the entry is recorded once per scenario in the leaderboard file."""
    rng = np.random.default_rng(0)
    c = rng.normal(-10.0, 1.0, 50)
    arms = {"best constant": {"reward": c}, "oracle": {"reward": c + 2.0},
            "half": {"reward": c + 1.0 + rng.normal(0.0, 0.3, 50)},
            "default": {"reward": c - 4.0}}
    entry = study.headroom("x", arms["default"], arms["best constant"], arms["oracle"], arms)
    assert entry["headroom"] == pytest.approx(2.0) and entry["headroom_ci95"] == \
        pytest.approx([2.0, 2.0])
    assert entry["default"] == pytest.approx(c.mean() - 4.0)
    assert entry["arms"]["oracle"]["fraction"] == pytest.approx(1.0)
    assert entry["arms"]["best constant"]["fraction"] == 0.0
    half = entry["arms"]["half"]
    assert abs(half["fraction"] - 0.5) < 0.05
    lo, hi = half["fraction_ci95"]
    assert lo < half["fraction"] < hi and hi - lo < 0.2
    path = tmp_path / "headroom.json"
    study.record_headroom(path, entry)
    study.record_headroom(path, {**entry, "headroom": 3.0})
    study.record_headroom(path, {**entry, "scenario": "a"})
    saved = json.loads(path.read_text())
    assert [e["scenario"] for e in saved] == ["a", "x"] and saved[1]["headroom"] == 3.0


def test_no_headroom_gives_no_fraction_and_valid_json(study, tmp_path):
    """An oracle that never beat its starting point (the best constant, on every
    episode): headroom 0 and no fraction (None), never NaN in the leaderboard file."""
    c = np.linspace(-12.0, -8.0, 20)
    arms = {"best constant": {"reward": c}, "x": {"reward": c + 0.1}}
    entry = study.headroom("y", arms["x"], arms["best constant"], {"reward": c.copy()}, arms)
    assert entry["headroom"] == 0.0
    assert entry["arms"]["x"]["fraction"] is None and entry["arms"]["x"]["fraction_ci95"] is None
    path = tmp_path / "headroom.json"
    study.record_headroom(path, entry)
    assert json.loads(path.read_text())[0]["arms"]["x"]["fraction"] is None
