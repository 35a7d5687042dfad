"""A new world is one class registered with ``register_world`` plus its scenario file: a
test-only world (an instrument slab on a pier's deck, at a height and attitude of its
own, its [motion] keys in units of its own) runs through the simulation and its truth
cache, bench, the env and assert_alignment, with paper 002's static-base alignment on
it, and its truth is checked against physics (earth rate and gravity at its height)."""
import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import pytest

import aligngym  # noqa: F401  (registers the env ids)
from aligngym.models.attitude import euler_to_quat, quat_rotate
from aligngym.models.earth import earth_rate_n, gravity_n
from aligngym.models.platform import StaticPlatformWorld
from aligngym.models.gimbal import GimbalRates
from aligngym.scenarios import registry
from aligngym.scenarios.cli import main
from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.experiments import register_experiment
from aligngym.scenarios.experiments.paper002 import Paper002Experiment
from aligngym.scenarios.simulate import simulate
from aligngym.scenarios.worlds import WORLDS, Prescribed, check_range, register_world
from aligngym.testing import assert_alignment


@dataclass(frozen=True)
class DeckMotion(GimbalRates):
    """The slab's attitude on the deck (rad) and the deck's height above the origin (m)."""

    yaw_mean: float = 0.5
    pitch: float = 0.0
    roll: float = 0.0
    deck_height: float = 0.0
    lever_arm_b: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gimbal_outer_rate: float = 0.0
    gimbal_inner_rate: float = 0.0

    @property
    def euler(self) -> np.ndarray:
        return np.array([self.pitch, self.roll, self.yaw_mean])


class DeckSlab(StaticPlatformWorld):
    """The marble slab held at the deck's height."""

    def joint_state(self, t):
        qpos, qvel, qacc = super().joint_state(t)
        qpos[:, 2] = self.motion.deck_height
        return qpos, qvel, qacc


class Pier(Prescribed):
    name = "test-pier"
    motion_type = DeckMotion
    units = {"deck_height": "_m"}
    view = (4.0, -25.0, 135.0, 0.9)

    def motion_fields(self, table):
        keys = {"yaw": "yaw_mean", "pitch": "pitch", "roll": "roll",
                "deck_height": "deck_height"}
        return {keys.get(key, key): value for key, value in table.items()}, False

    def check(self, config):
        check_range("motion.deck_height_m", config.motion.deck_height, 0.0, 100.0, "m")

    def scene(self, motion):
        return DeckSlab(motion)


@dataclass(frozen=True)
class PierExperiment(Paper002Experiment):
    """Paper 002's static base from 20 deg of azimuth, 60 s, on the pier."""

    worlds = ("test-pier",)
    fine_duration: float = 60.0
    azimuth_error_deg: float = 20.0
    default_filters: tuple[str, ...] = ("ekf",)
    default_episodes = 2


SCENARIO = """name = "pier"
experiment = "pier-static"
world = "test-pier"
[origin]
latitude_deg = 30.0
longitude_deg = 10.0
height_m = 0.0
[run]
duration_s = 60.0
imu_rate_hz = 100.0
[imu]
preset = "paper002-static"
[motion]
yaw_deg = 10.0
deck_height_m = 40.0
"""


@pytest.fixture
def pier(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    register_world(Pier)
    register_experiment("pier-static", PierExperiment)
    path = tmp_path / "pier.toml"
    path.write_text(SCENARIO)
    yield str(path)
    registry._REGISTERED.pop("pier-static", None)
    WORLDS.pop("test-pier", None)


def test_its_truth_is_the_earth_at_its_height(pier):
    """At rest on the deck: the IMU senses the earth rate and the normal gravity of its
    latitude and height (40 m up: 0.12 mm/s^2 less than on the ground), and its height
    is the deck's."""
    config = load_scenario(pier)
    assert config.motion == DeckMotion(yaw_mean=math.radians(10.0), deck_height=40.0)
    episode = simulate(config, seed=0, ideal=True)
    tr, dt = episode.truth, config.imu_interval
    np.testing.assert_allclose(tr.h, 40.0, atol=1e-6)
    q_s_n = tr.q_s_n[0]
    expected_f = -quat_rotate(np.array([q_s_n[0], *-q_s_n[1:]]), gravity_n(tr.lat[0], 40.0))
    expected_w = quat_rotate(np.array([q_s_n[0], *-q_s_n[1:]]), earth_rate_n(tr.lat[0]))
    np.testing.assert_allclose(episode.dv.mean(0) / dt, expected_f, atol=1e-6)
    np.testing.assert_allclose(episode.dtheta.mean(0) / dt, expected_w, atol=1e-12)
    np.testing.assert_allclose(q_s_n, euler_to_quat(config.motion.euler), atol=1e-6)


def test_it_runs_in_bench_the_env_and_assert_alignment(pier, capsys):
    assert main(["bench", "pier-static", "--scenario", pier, "--workers", "1",
                 "--no-figures"]) == 0
    assert "2 runs" in capsys.readouterr().out
    env = gym.make("aligngym/Alignment-v1", scenario=pier, estimator="ekf",
                   episode_length=10.0)
    obs, _ = env.reset(seed=1)
    obs, *_ = env.step(np.zeros(env.action_space.shape))
    assert np.all(np.isfinite(obs))
    env.close()
    measured = assert_alignment("ekf", pier, episodes=2, heading_rms_arcmin=60.0,
                                level_rms_arcmin=1.0)
    assert measured["diverged"] == 0 and measured["heading_rms_arcmin"] < 60.0


def test_its_keys_and_worlds_are_checked_in_one_line(pier, tmp_path):
    for old, new, message in (
            ("deck_height_m = 40.0", "deck_height_m = 400.0",
             "motion.deck_height_m = 400 m is out of range [0, 100]"),
            ("deck_height_m = 40.0", "deck_height = 40.0",
             "motion.deck_height: deck_height is in m; write deck_height_m"),
            ('world = "test-pier"', 'world = "test-peir"', "did you mean 'test-pier'?")):
        path = tmp_path / "bad.toml"
        path.write_text(SCENARIO.replace(old, new))
        with pytest.raises(ConfigError) as info:
            load_scenario(path)
        assert message in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(ValueError, match="must have a name"):
        register_world(type("Nameless", (Pier,), {"name": ""}))


def test_a_taken_world_name_is_refused_and_a_users_world_caches_under_its_code(tmp_path):
    """A second class under the name "car" is refused; a world from outside the package
    is cached under a kind that carries a hash of its module's source, so an edited world
    never gets its old truth (the shipped worlds are in the cache's code hash; a world the
    package defines elsewhere is not)."""
    with pytest.raises(ValueError, match="world name 'car' is taken by aligngym.scenarios."
                                         "worlds.CarOnRoad"):
        register_world(type("Car", (Pier,), {"name": "car"}))
    assert WORLDS["car"].cache_kind("car-seeded") == "car-seeded"
    # a world the package defines outside the simulation's code (an experiment's, say)
    elsewhere = type("Elsewhere", (Pier,), {"name": "elsewhere",
                                            "__module__": "aligngym.estimators.rules"})
    assert elsewhere.cache_kind("elsewhere").startswith("elsewhere-")
    import importlib.util
    import sys
    kinds = []
    for rate in (1.0, 2.0):
        path = tmp_path / "my_world.py"
        path.write_text(f"from aligngym.scenarios.worlds import StaticPlatform\n"
                        f"class Turning(StaticPlatform):\n    name = 'turning'\n"
                        f"    rate = {rate}\n")
        spec = importlib.util.spec_from_file_location("my_world", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules["my_world"] = module
        spec.loader.exec_module(module)
        kinds.append(module.Turning.cache_kind("turning"))
    sys.modules.pop("my_world", None)
    assert kinds[0] != kinds[1] and all(k.startswith("turning-") for k in kinds)


def test_a_worlds_own_motion_keys_are_named_as_written(pier, tmp_path):
    path = tmp_path / "typo.toml"
    path.write_text(SCENARIO.replace("deck_height_m = 40.0", "deck_hieght_m = 40.0"))
    with pytest.raises(ConfigError, match=r"motion.deck_hieght_m is not a parameter; did "
                                          r"you mean deck_height_m\?"):
        load_scenario(path)


PLUGIN = '''
from dataclasses import dataclass
from aligngym.scenarios.experiments import register_experiment
from aligngym.scenarios.experiments.paper002 import Paper002Experiment
from aligngym.scenarios.worlds import StaticPlatform, register_world


@register_world
class PluginSlab(StaticPlatform):
    name = "plugin-slab"


@dataclass(frozen=True)
class PluginStatic(Paper002Experiment):
    worlds = ("plugin-slab",)
    fine_duration: float = 60.0
    azimuth_error_deg: float = 20.0
    default_filters: tuple[str, ...] = ("ekf",)
    default_episodes = 2


register_experiment("plugin-static", PluginStatic)
'''


def test_the_command_line_imports_a_users_plugin(tmp_path, monkeypatch, capsys):
    """``aligngym --plugin FILE.py bench ...``: the world and the experiment the file
    registers run from the command line; a plugin that cannot be imported is one line."""
    import sys
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my_plugin.py").write_text(PLUGIN)
    (tmp_path / "slab.toml").write_text(SCENARIO.replace('"pier-static"', '"plugin-static"')
                                        .replace('"test-pier"', '"plugin-slab"')
                                        .replace("deck_height_m = 40.0\n", ""))
    try:
        assert main(["--plugin", "my_plugin.py", "bench", "plugin-static", "--scenario",
                     "slab.toml", "--workers", "1", "--no-figures"]) == 0
        assert "2 runs" in capsys.readouterr().out
    finally:
        WORLDS.pop("plugin-slab", None)
        registry._REGISTERED.pop("plugin-static", None)
        sys.modules.pop("my_plugin", None)
    assert main(["--plugin", "no_such_plugin_module", "bench", "paper002"]) == 2
    assert ("aligngym: error: --plugin no_such_plugin_module: cannot import it: "
            "ModuleNotFoundError: No module named 'no_such_plugin_module'"
            in capsys.readouterr().err)
