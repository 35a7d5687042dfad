"""pytest plugin (entry point ``pytest11``): the fixtures ``aligngym_episode``, a factory
of simulated episodes for users' tests, and ``aligngym_alignment``, the alignment-bound
check of ``aligngym.testing`` from any start. Imports the testbed only when a test uses
them."""
from __future__ import annotations

import pytest


@pytest.fixture
def aligngym_episode():
    """make(scenario, seed=0, duration=None, ideal=False) -> ``scenarios.simulate.Episode``:
    the scenario's sensor data (imu_t, dtheta, dv, gimbal_encoder, and the other sensors'
    records in measurements) and its navigation truth (``episode.truth``) for one seed;
    duration in s (None: the scenario's); ideal: error-free sensors."""
    def make(scenario: str, seed: int = 0, duration: float | None = None,
             ideal: bool = False):
        from aligngym.scenarios.config import load_scenario
        from aligngym.scenarios.simulate import simulate
        config = load_scenario(scenario)
        if duration is not None:
            config = config.with_options(duration=duration)
        return simulate(config, seed=seed, ideal=ideal)
    return make


@pytest.fixture
def aligngym_alignment():
    """check(filter, scenario, episodes=5, seed=0, heading_rms_arcmin=None,
    level_rms_arcmin=None, start=None, **settings) -> the measured errors:
    ``aligngym.testing.assert_alignment`` (start: one of the experiment's start names,
    None for its first, "all" for each against the same bounds; arcmin), failing the test
    with a per-episode table when a bound is exceeded or an episode diverged."""
    from aligngym.testing import assert_alignment
    return assert_alignment
