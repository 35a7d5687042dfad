"""Names the command line, the gymnasium registration and the configs share, with no
heavy imports (the CLI's help and its option errors answer without MuJoCo or SciPy)."""
from __future__ import annotations

from pathlib import Path

DATA_DIR = Path(__file__).parent / "data"
"""The shipped scenario files."""

PAPERS = ("paper000", "paper001", "paper002", "paper003", "paper004")
"""Papers with a campaign (``aligngym bench``)."""

GENERIC_ENV_ID = "aligngym/Alignment-v0"
"""The env id for any scenario file that names an experiment:
``gym.make(GENERIC_ENV_ID, scenario="path/to/my.toml", ...)``."""


def _shipped_experiments() -> dict[str, str]:
    """{shipped scenario: its experiment} from each file's ``experiment`` key (read with
    tomllib alone: no scenario validation, no heavy imports)."""
    import tomllib
    out = {}
    for path in sorted(DATA_DIR.glob("*.toml")):
        name = tomllib.loads(path.read_text()).get("experiment", "")
        if name:
            out[path.stem] = name
    return out


SCENARIO_PAPER = _shipped_experiments()
"""Shipped scenarios with an alignment pipeline (each names it in its file; the env is
registered for these)."""


def scenario_names() -> list[str]:
    """Names of the scenario files shipped with the package."""
    return sorted(p.stem for p in DATA_DIR.glob("*.toml"))


def env_id(scenario: str) -> str:
    """Gymnasium id of a scenario name: ship-sway-rotary -> aligngym/ShipSwayRotary-v0."""
    return "aligngym/" + "".join(part.capitalize() for part in scenario.split("-")) + "-v0"
