"""Scenario files for the tests: a shipped scenario with its run's duration changed and
lines added, written to a folder."""
import re
from pathlib import Path

from aligngym.scenarios.registry import DATA_DIR


def shipped_with(folder: Path, name: str, duration: float, extra: str = "",
                 motion: str = "") -> str:
    """The path of shipped scenario ``name`` rewritten into folder: ``duration_s`` set to
    duration, the lines ``motion`` added at the top of its [motion] table and ``extra``
    (e.g. [[schedule]] entries) at its end."""
    text = re.sub(r"duration_s = [0-9.]+", f"duration_s = {duration}",
                  (DATA_DIR / f"{name}.toml").read_text())
    text = text.replace("[motion]\n", f"[motion]\n{motion}")
    path = Path(folder) / f"{name}-{abs(hash(extra + motion))}.toml"
    path.write_text(text + extra)
    return str(path)
