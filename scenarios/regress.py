"""Scenario regression: each paper's campaign with a fixed seed and a small episode count,
compared metric by metric with a stored baseline (``aligngym regress``).

A baseline (``scenarios/data/baselines/regress_<paper>.json``, package data) holds the campaign's settings and
its metrics flattened to "path -> value" (the JSON summary's paths, plus each run's mean
final NEES). Tolerances per kind of metric, and why:

- errors in arcmin, deg, m or m/s, and NEES: 1e-4 relative (with an absolute floor of 1e-6):
  another CPU or BLAS changes the last bits, which the fading-factor filters amplify
  (measured: up to 1.4e-6 relative from a last-bit change of MuJoCo's kinematics), while
  any change of the physics, the sensors or a filter moves them by far more than 1e-3;
- status fractions (converged, not converged, diverged, lost): exact (an episode that
  flips is a regression to look at);
- heading convergence times: 1 s, the filter step (a rounding flip moves one epoch).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from aligngym.scenarios.atomic import json_text, write_text
from aligngym.scenarios.config import ConfigError

if TYPE_CHECKING:
    from aligngym.scenarios.campaign.plan import CampaignSpec

BASELINE_DIR = Path(__file__).resolve().parent / "data" / "baselines"

def campaigns() -> dict[str, dict]:
    """The regression campaign of each experiment that declares one (``Experiment.regress``:
    episodes, seed, filters and the settings that differ from its defaults; a shorter
    fine alignment keeps the suite quick, the filters still converge). Filters that
    diverge on these episodes are left out: a diverging filter amplifies last bits without
    bound, so its numbers are not reproducible across machines."""
    from aligngym.scenarios.experiments import regress_campaigns
    return regress_campaigns()


SKIPPED = ("us_per_epoch", "ms_per_epoch", "ms_per_epoch_chunks")
"""Summary entries that are measurements of this machine (or of the campaign's plan, the
chunks a batch ran in), not results."""


def tolerance(path: str) -> tuple[float, float]:
    """(relative, absolute) tolerance of a metric, by its kind (module docstring)."""
    if path.endswith("_fraction"):
        return 0.0, 0.0
    if path.endswith("convergence_s") or path.endswith("convergence_p90_s"):
        return 0.0, 1.0
    return 1e-4, 1e-6


def flatten(tree: dict | list | float, prefix: str = "") -> dict[str, float]:
    """Nested summary -> {"a/b/0": value}; list items are indexed by position."""
    items = tree.items() if isinstance(tree, dict) else enumerate(tree)
    out: dict[str, float] = {}
    for key, value in items:
        path = f"{prefix}/{key}" if prefix else str(key)
        if isinstance(value, (dict, list, tuple)):
            out.update(flatten(value, path))
        elif isinstance(value, str):
            continue          # settings (names, levels), not metrics
        elif not any(path.endswith(s) for s in SKIPPED):
            out[path] = math.nan if value is None else float(value)
    return out


def campaign_metrics(paper: str, workers: int | None = None,
                     spec: CampaignSpec | None = None) -> dict[str, float]:
    """Run a paper's regression campaign (spec: its ``campaign.plan.regress_plan``, if
    made already) and flatten its results."""
    from aligngym.scenarios.campaign.plan import regress_plan

    spec = regress_plan([paper])[paper] if spec is None else spec
    result = spec.run(workers=workers, progress=False)
    metrics = flatten(result.summary())
    for run in result.runs:
        metrics[f"nees_final_mean/{run.filter}/{run.start}"] = float(np.mean(run.nees[:, -1]))
    return metrics


@dataclass(frozen=True)
class Difference:
    """One metric against its baseline; ok when within tolerance."""

    path: str
    baseline: float
    now: float

    @property
    def ok(self) -> bool:
        if self.baseline == self.now or (math.isnan(self.baseline) and math.isnan(self.now)):
            return True                       # also inf == inf
        rel, absolute = tolerance(self.path)
        return abs(self.now - self.baseline) <= max(absolute, rel * abs(self.baseline))

    @property
    def moved(self) -> bool:
        return not (self.now == self.baseline
                    or (math.isnan(self.baseline) and math.isnan(self.now)))


def compare(baseline: dict[str, float], now: dict[str, float]) -> tuple[list[Difference],
                                                                        list[str]]:
    """Differences of the common metrics, and the paths present on one side only."""
    common = sorted(set(baseline) & set(now))
    missing = sorted(set(baseline) ^ set(now))
    return [Difference(p, baseline[p], now[p]) for p in common], missing


def baseline_path(paper: str, directory: Path = BASELINE_DIR) -> Path:
    return Path(directory) / f"regress_{paper}.json"


BASELINE_SCHEMA = 1
"""The baseline files' layout ("schema"; the shipped ones, without it, are of this
layout): a baseline of another schema is refused (docs/campaign-directory.md)."""


def read_baseline(path: Path, settings: dict) -> dict:
    """A baseline file (an object with "settings", equal to the paper's regression
    campaign's, and numeric "metrics"), or a one-line ConfigError naming it, what is wrong
    and what to do (``--update`` writes it again)."""
    fix = "run with --update to write it again (or restore the file)"
    try:
        stored = json.loads(path.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise ConfigError(f"baseline {path} cannot be read ({exc.strerror}); {fix}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"baseline {path} is not UTF-8 (byte {exc.start}), a damaged or "
                          f"foreign file; {fix}") from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"baseline {path} is not valid JSON ({exc.msg} at line "
                          f"{exc.lineno}); {fix}") from None
    if not (isinstance(stored, dict) and isinstance(stored.get("metrics"), dict)
            and all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))
                    for v in stored["metrics"].values())):
        raise ConfigError(f"baseline {path} is not a baseline (an object with 'settings' "
                          f"and numeric 'metrics'); {fix}")
    stored["metrics"] = {k: math.nan if v is None else v      # null: a NaN written strictly
                         for k, v in stored["metrics"].items()}
    schema = stored.get("schema", BASELINE_SCHEMA)
    if schema != BASELINE_SCHEMA:
        raise ConfigError(f"baseline {path} has schema {schema!r}, not this aligngym's "
                          f"({BASELINE_SCHEMA}); {fix}")
    if stored.get("settings") != settings:
        raise ConfigError(f"baseline {path} was made with other settings "
                          f"({str(stored.get('settings'))[:200]}); {fix}")
    return stored


def regress(papers: list[str], update: bool = False, directory: Path = BASELINE_DIR,
            workers: int | None = None) -> tuple[bool, str]:
    """Run the regression campaigns; with update, store their metrics as the baselines.
    Returns (passed, report): the report has a line per paper and a table of the metrics
    that moved (beyond tolerance first)."""
    from aligngym.scenarios.registry import experiment_names
    names = experiment_names()          # checked before any experiment is imported
    if not papers:
        raise ConfigError("--papers is empty; valid: " + ", ".join(names))
    unknown = [p for p in papers if p not in names]
    if unknown:
        raise ConfigError(f"--papers: {', '.join(unknown)} unknown; valid: "
                          + ", ".join(names))
    if not Path(directory).is_dir() and not update:
        raise ConfigError(f"no baseline directory {directory} (the baselines ship "
                          "with the package in aligngym/scenarios/data/baselines); pass "
                          "--baselines DIR")
    known = campaigns()
    without = [p for p in papers if p not in known]
    if without:
        raise ConfigError(f"--papers: {', '.join(without)} declares no regression "
                          "campaign (Experiment.regress); with one: " + ", ".join(known))
    from aligngym.scenarios.campaign.plan import regress_plan
    plan = regress_plan(papers)          # every paper's campaign checked before the first
    lines, passed = [], True
    for paper in papers:
        path = baseline_path(paper, directory)
        if update:
            now = campaign_metrics(paper, workers, plan[paper])
            path.parent.mkdir(parents=True, exist_ok=True)
            write_text(path, json_text({"schema": BASELINE_SCHEMA, "settings": known[paper],
                                        "metrics": now},        # NaN as null: strict JSON
                                       indent=1, sort_keys=True))   # never a truncated one
            lines.append(f"{paper}: baseline written ({len(now)} metrics) to {path}")
            continue
        if not path.is_file():
            raise ConfigError(f"no baseline for {paper} at {path}; run with --update")
        stored = read_baseline(path, known[paper])
        now = campaign_metrics(paper, workers, plan[paper])
        diffs, missing = compare(stored["metrics"], now)
        bad = [d for d in diffs if not d.ok]
        moved = [d for d in diffs if d.moved and d.ok]
        passed &= not bad and not missing
        lines.append(f"{paper}: {len(diffs)} metrics, {len(bad)} beyond tolerance, "
                     f"{len(moved)} moved within it, {len(missing)} missing or new")
        if bad or moved:
            lines.append(f"  {'metric':52s} {'baseline':>14s} {'now':>14s} {'rel':>9s}")
            for d in bad + moved:
                rel = abs(d.now - d.baseline) / max(abs(d.baseline), 1e-300)
                lines.append(f"  {d.path:52s} {d.baseline:14.7g} {d.now:14.7g} {rel:9.1e}"
                             + ("  REGRESSION" if not d.ok else ""))
        for p in missing:
            lines.append(f"  {p}: only in the {'baseline' if p in stored['metrics'] else 'run'}")
    return passed, "\n".join(lines)
