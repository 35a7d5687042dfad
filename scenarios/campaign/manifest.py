"""The campaign directory's manifest (``campaign.json``: experiment settings and seed),
which decides whether a directory may be used, resumed or replaced."""
from __future__ import annotations

import json
import os
from dataclasses import asdict
from pathlib import Path

from aligngym.scenarios.campaign.experiment import Experiment
from aligngym.scenarios.config import ConfigError


def check_manifest(out: Path, experiment: Experiment, seed: int, resume: bool,
                    force: bool = False) -> None:
    """Create out, or check that it may be used: a directory holding a campaign needs
    resume (the same experiment and seed, from its campaign.json) or force (its episode
    files, tables, series, plots, settings and report are removed, so nothing of another
    seed mixes in)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--out {out}: cannot create the directory ({exc.strerror})") from None
    if not os.access(out, os.W_OK):
        raise ConfigError(f"--out {out}: the directory is not writable")
    manifest = out / "campaign.json"
    episodes = [p for p in (out / "episodes").glob("seed_*.npz")
                if not p.name.endswith(".tmp.npz")]          # not half-written leftovers
    held = manifest.is_file() or bool(episodes)
    if held and not (resume or force):
        raise ConfigError(f"--out {out} holds a campaign; use --resume to continue it or "
                          "--force to replace it")
    if resume and episodes and not manifest.is_file():
        raise ConfigError(f"--resume: {out} has episode files but no campaign.json, so "
                          "their experiment and seed are unknown; use --force to replace them")
    current = {"paper": experiment.paper, "experiment": asdict(experiment), "seed": seed}
    current = json.loads(json.dumps(current))
    if resume and manifest.is_file():
        saved = json.loads(manifest.read_text())
        saved.setdefault("paper", current["paper"])
        if saved != current:
            raise ConfigError(f"--resume: {manifest} was written by a different experiment "
                              "or seed; use a new --out directory")
    if force and not resume:      # nothing of the old campaign survives to mix in
        for old in [*(out / "episodes").glob("seed_*.npz"), *out.glob("*.csv"),
                    *out.glob("*.png"), out / "timeseries.npz", out / "tables.txt",
                    out / "summary.json", out / "settings.json", out / "report.html",
                    manifest]:
            old.unlink(missing_ok=True)
    tmp = manifest.with_suffix(".tmp")
    tmp.write_text(json.dumps(current, indent=2))
    os.replace(tmp, manifest)      # atomic
