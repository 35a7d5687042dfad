"""Scenario definitions, MuJoCo runners, the gymnasium env, campaigns and the CLI.

Importing this package registers one gymnasium id per shipped scenario with an alignment
pipeline, ``aligngym/<Scenario>-v0`` (e.g. ``aligngym/ShipSwayRotary-v0``), and the
generic ``aligngym/Alignment-v0`` for any scenario file that names an experiment
(``gym.make("aligngym/Alignment-v0", scenario="my.toml", ...)``); gymnasium 1.x ignores
plugin entry points, so registration is explicit here.
"""
import gymnasium

from aligngym.scenarios.registry import GENERIC_ENV_ID, SCENARIO_PAPER, env_id


# Scenarios with an alignment pipeline behind the env (ring-road-odometer's, paper 000,
# is not built yet).
ENV_SCENARIOS = sorted(SCENARIO_PAPER)
ENV_IDS = [env_id(name) for name in ENV_SCENARIOS]
for _name, _id in zip(ENV_SCENARIOS, ENV_IDS):
    if _id not in gymnasium.registry:
        # No max_episode_steps: the length is an option (episode_length / epoch_length
        # steps) and the env reports it as truncated itself; a registered limit would cut
        # longer episodes short, before their metrics and video.
        gymnasium.register(id=_id, entry_point="aligngym.scenarios.env:AlignmentEnv",
                           kwargs={"scenario": _name})
if GENERIC_ENV_ID not in gymnasium.registry:      # any scenario file naming an experiment
    gymnasium.register(id=GENERIC_ENV_ID, entry_point="aligngym.scenarios.env:AlignmentEnv")


def evaluate(env_id: str, estimator: str, episodes: int, seed: int = 0, **kwargs):
    """Per-episode metrics of an estimator run passively in the env (scenarios.env)."""
    from aligngym.scenarios.env import evaluate as _evaluate
    return _evaluate(env_id, estimator, episodes, seed, **kwargs)
