"""pytest plugin (entry point ``pytest11``): the fixture ``aligngym_episode``, a factory
of simulated episodes for users' tests. Imports the testbed only when a test uses it."""
from __future__ import annotations

import pytest


@pytest.fixture
def aligngym_episode():
    """make(scenario, seed=0, duration=None, ideal=False) -> ``scenarios.simulate.Episode``:
    the scenario's sensor data (imu_t, dtheta, dv, gimbal_encoder, extra sensors) and its
    navigation truth (``episode.truth``) for one seed; duration in s (None: the
    scenario's); ideal: error-free sensors."""
    def make(scenario: str, seed: int = 0, duration: float | None = None,
             ideal: bool = False):
        from aligngym.scenarios.config import load_scenario
        from aligngym.scenarios.simulate import simulate
        config = load_scenario(scenario)
        if duration is not None:
            config = config.with_options(duration=duration)
        return simulate(config, seed=seed, ideal=ideal)
    return make
