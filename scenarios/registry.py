"""Names the command line, the gymnasium registration and the configs share, with no
heavy imports (the CLI's help and its option errors answer without MuJoCo or SciPy)."""
from __future__ import annotations

from pathlib import Path

DATA_DIR = Path(__file__).parent / "data"
"""The shipped scenario files."""

PAPERS = ("paper000", "paper001", "paper002", "paper003", "paper004")
"""Papers with a campaign (``aligngym bench``)."""

SCENARIO_PAPER = {"ring-road-odometer": "paper000", "figure8-gps": "paper001", "ship-sway-rotary": "paper003", "ship-waves-rotary": "paper003",
                  "static-large-azimuth": "paper002", "usv-mems-swing": "paper004",
                  "usv-mems-waves": "paper004"}
"""Shipped scenarios with an alignment pipeline (the env is registered for these)."""


def scenario_names() -> list[str]:
    """Names of the scenario files shipped with the package."""
    return sorted(p.stem for p in DATA_DIR.glob("*.toml"))


def env_id(scenario: str) -> str:
    """Gymnasium id of a scenario name: ship-sway-rotary -> aligngym/ShipSwayRotary-v0."""
    return "aligngym/" + "".join(part.capitalize() for part in scenario.split("-")) + "-v0"
