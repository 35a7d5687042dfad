"""The gymnasium ids, registered when ``aligngym`` is imported (gymnasium 1.x loads no
plugin entry points; ``gym.register_envs(aligngym)`` or the ``"aligngym:<id>"`` form of
``gym.make`` are the usual ways to make sure it is): ``aligngym/<Scenario>-v1`` for every
shipped scenario file (e.g. ``aligngym/ShipSwayRotary-v1``; a ``*-paper`` file's id,
e.g. ``aligngym/ShipSwayRotaryPaper-v1``, runs its experiment's paper setup), and
``aligngym/Alignment-v1`` for any scenario file that names an experiment or is a named
setup's own (``gym.make("aligngym/Alignment-v1", scenario="my.toml", ...)``).
Registration imports gymnasium only; the env and its experiment load at ``gym.make``."""
from __future__ import annotations

import gymnasium

from aligngym.scenarios.registry import GENERIC_ENV_ID, env_id, scenario_names

ENTRY_POINT = "aligngym.scenarios.env:AlignmentEnv"
VECTOR_ENTRY_POINT = "aligngym.scenarios.vector_env:AlignmentVectorEnv"
"""``gym.make_vec``'s default for these ids: N episodes through batched filters in one
process (``vectorization_mode="sync"`` or ``"async"`` make N single envs instead)."""

ENV_SCENARIOS = scenario_names()
"""Every shipped scenario (``scenarios/data/``) has an env id: its file names its
experiment (``experiment`` key, the default setup), or it is the file a named setup runs
on (a ``*-paper`` file: its experiment's ``--setup paper``, ``experiments.setup_for``);
``tests/test_paper_setups_env.py`` makes and steps each."""
ENV_IDS = [env_id(name) for name in ENV_SCENARIOS]
"""Their ids, in the order of ENV_SCENARIOS."""


def register_envs() -> None:
    """Register every id above once (a second call changes nothing). No
    max_episode_steps: the length is an option (episode_length / epoch_length steps) and
    the env reports it as truncated itself; a registered limit would cut longer episodes
    short, before their metrics and video."""
    for name, id_ in zip(ENV_SCENARIOS, ENV_IDS):
        if id_ not in gymnasium.registry:
            gymnasium.register(id=id_, entry_point=ENTRY_POINT, kwargs={"scenario": name},
                               vector_entry_point=VECTOR_ENTRY_POINT)
    if GENERIC_ENV_ID not in gymnasium.registry:
        gymnasium.register(id=GENERIC_ENV_ID, entry_point=ENTRY_POINT,
                           vector_entry_point=VECTOR_ENTRY_POINT)
