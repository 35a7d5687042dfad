"""Names the command line, the gymnasium registration and the configs share, with no
heavy imports (the CLI's help and its option errors answer without MuJoCo or SciPy)."""
from __future__ import annotations

from pathlib import Path

DATA_DIR = Path(__file__).parent / "data"
"""The shipped scenario files."""

EXPERIMENTS_DIR = Path(__file__).parent / "experiments"
"""One module per shipped experiment, named as the experiment (paper000 ... paper004)."""

_REGISTERED: dict[str, type] = {}
"""Experiments registered at run time (``scenarios.experiments.register_experiment``)."""


def experiment_names() -> tuple[str, ...]:
    """Every experiment ``bench``, ``regress`` and a scenario's ``experiment`` key can
    name: the shipped modules of ``scenarios/experiments/`` (found without importing
    them) and the registered ones."""
    import pkgutil
    shipped = [m.name for m in pkgutil.iter_modules([str(EXPERIMENTS_DIR)])
               if not m.name.startswith("_")]
    return tuple(sorted(shipped)) + tuple(sorted(set(_REGISTERED) - set(shipped)))


GENERIC_ENV_ID = "aligngym/Alignment-v1"
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
"""Shipped scenarios whose file names an experiment. The other shipped files (the
``*-paper`` ones) run their experiment's named setup (``experiments.setup_for``); every
shipped file has an env id."""


def scenario_names() -> list[str]:
    """Names of the scenario files shipped with the package."""
    return sorted(p.stem for p in DATA_DIR.glob("*.toml"))


def env_id(scenario: str) -> str:
    """Gymnasium id of a scenario name: ship-sway-rotary -> aligngym/ShipSwayRotary-v1."""
    return "aligngym/" + "".join(part.capitalize() for part in scenario.split("-")) + "-v1"
