"""The episode bank and the seed splits.

A bank is a directory of prepared episodes (``campaign.PreparedEpisode``, one .npz per
seed), simulated once and loaded by every later ``reset`` of an env (or campaign) that
needs the same episode. Its episodes live in ``BANK/<experiment>-<key>/episodes/``, where
the key is a hash of what decides a prepared episode: the experiment's settings (the
env's episode and epoch length among them), the scenario file's bytes and the aligngym
version (a changed simulation under the same version needs a new bank; ``bank.json``
says what the key holds). A file that does not load, or holds another seed, is named
and simulated again.

The seed splits keep training, model selection and scoring apart: episode seeds
[0, 1.6e9) are "train", [1.6e9, 1.8e9) "validation", [1.8e9, 2^31 - 1) "test". The k-th
episode of a split is its first seed + k (``split_seeds``); an env made with ``split``
draws its episodes among the split's first ``split_episodes`` and refuses an
``episode_seed`` from another split.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path

from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.truth_cache import prepared_code_sha256

SPLITS: dict[str, tuple[int, int]] = {"train": (0, 1_600_000_000),
                                      "validation": (1_600_000_000, 1_800_000_000),
                                      "test": (1_800_000_000, 2 ** 31 - 1)}
"""Episode-seed ranges [first, end) of the splits."""
BUILD_CHUNK = 64
"""Episodes a bank build holds in memory at once."""


def check_split(split: str) -> tuple[int, int]:
    """The split's seed range; an unknown name is a one-line error."""
    if split not in SPLITS:
        raise ConfigError(f"split = {split!r}; valid: " + ", ".join(SPLITS))
    return SPLITS[split]


def split_seeds(split: str, episodes: int, first: int = 0) -> list[int]:
    """Episode seeds first .. first + episodes - 1 of a split (its first seed + k)."""
    lo, hi = check_split(split)
    if not (isinstance(episodes, int) and episodes >= 0 and isinstance(first, int)
            and first >= 0 and lo + first + episodes <= hi):
        raise ConfigError(f"episodes {first}..{first + episodes - 1} of split {split!r}: "
                          f"need 0 <= first and first + episodes <= {hi - lo}")
    return list(range(lo + first, lo + first + episodes))


def split_of(seed: int) -> str:
    """The split an episode seed belongs to."""
    for name, (lo, hi) in SPLITS.items():
        if lo <= seed < hi:
            return name
    raise ConfigError(f"episode seed {seed} is outside every split [0, {2 ** 31 - 1})")


def check_seed_in_split(seed: int, split: str) -> None:
    """Refuse (one line) an episode seed of another split."""
    if split_of(seed) != split:
        lo, hi = SPLITS[split]
        raise ConfigError(f"episode_seed {seed} is in the {split_of(seed)!r} split; this "
                          f"env takes {split!r} seeds, [{lo}, {hi})")


def _numbers_as_floats(value):
    """Settings as the key holds them: 20 and 20.0 are the same setting."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, (list, tuple)):
        return [_numbers_as_floats(v) for v in value]
    if isinstance(value, dict):
        return {k: _numbers_as_floats(v) for k, v in value.items()}
    return str(value)


def bank_key(experiment) -> dict:
    """What decides an experiment's prepared episodes (the bank's key, as JSON): its
    settings but those that concern the filters only (``Experiment.filter_settings``),
    the scenario file's bytes, the simulation code and the versions of aligngym, MuJoCo
    and NumPy."""
    import mujoco
    import numpy
    from importlib.metadata import PackageNotFoundError, version
    try:
        release = version("aligngym")
    except PackageNotFoundError:          # run from a source tree that is not installed
        release = "source"
    config = experiment.scenario_file()
    digest = hashlib.sha256(Path(config.source).read_bytes()).hexdigest()
    return json.loads(json.dumps({"experiment": type(experiment).__module__.rsplit(".", 1)[-1],
                                  "settings": _numbers_as_floats(
                                      {name: value for name, value in asdict(experiment).items()
                                       if name not in experiment.filter_settings}),
                                  "scenario_sha256": digest,
                                  "code_sha256": prepared_code_sha256(),
                                  "aligngym": release, "mujoco": mujoco.__version__,
                                  "numpy": numpy.__version__}, default=str))


def bank_directory(root: str | Path, key: dict) -> Path:
    """The bank's campaign-style directory for an experiment's key (holds ``episodes/``)."""
    text = json.dumps(key, sort_keys=True)
    name = f"{key['experiment']}-{hashlib.sha256(text.encode()).hexdigest()[:16]}"
    return Path(root) / name


BANK_SCHEMA = 1
"""The layout of a bank (bank.json's "schema"; a bank.json without one is of this
layout): a bank.json of another schema is refused (docs/campaign-directory.md)."""


def check_bank_manifest(manifest: Path, data: bytes, key: dict) -> None:
    """Refuse, in one line naming the file, a bank.json that does not read (not UTF-8, not
    JSON, not an object), of another schema, or not this experiment's key (a copied or
    foreign file)."""
    directory = manifest.parent
    fix = (f"delete {directory} (its episodes are simulated again) or use another bank "
           "directory")
    try:
        saved = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        reason = (f"not UTF-8 (byte {exc.start})" if isinstance(exc, UnicodeDecodeError)
                  else f"not valid JSON ({exc.msg} at line {exc.lineno})")
        raise ConfigError(f"bank {manifest} is {reason}, a damaged file; {fix}") from None
    if not isinstance(saved, dict):
        raise ConfigError(f"bank {manifest} holds a JSON {type(saved).__name__}, not the "
                          f"bank's key (a foreign file); {fix}")
    schema = saved.pop("schema", BANK_SCHEMA)
    if schema != BANK_SCHEMA:
        raise ConfigError(f"bank {manifest}: its schema {schema!r} is not this aligngym's "
                          f"({BANK_SCHEMA}); use the aligngym that wrote it, or another "
                          "bank directory")
    if saved != key:
        differ = sorted(k for k in set(saved) | set(key) if saved.get(k) != key.get(k))
        raise ConfigError(f"bank {manifest} is not this experiment's key (it differs in "
                          f"{', '.join(differ)[:120]}: a copied, damaged or foreign file); "
                          f"{fix}")


class EpisodeBank:
    """Prepared episodes of one experiment under ``root`` (see the module docstring):
    ``get(seed)`` loads the episode, or simulates and stores it."""

    def __init__(self, root: str | Path, experiment) -> None:
        from aligngym.scenarios.atomic import write_json
        self.experiment = experiment
        key = bank_key(experiment)
        self.directory = bank_directory(root, key)
        self.episodes = self.directory / "episodes"
        manifest = self.directory / "bank.json"
        try:
            self.episodes.mkdir(parents=True, exist_ok=True)
            if not manifest.is_file():
                write_json(manifest, {**key, "schema": BANK_SCHEMA})
        except OSError as exc:
            raise ConfigError(f"bank {root}: cannot create {self.episodes} "
                              f"({exc.strerror})") from None
        try:
            data = manifest.read_bytes()
        except OSError as exc:
            raise ConfigError(f"bank {manifest} cannot be read ({exc.strerror}); delete "
                              f"{self.directory} or use another bank directory") from None
        check_bank_manifest(manifest, data, key)

    def path(self, seed: int) -> Path:
        return self.episodes / f"seed_{seed}.npz"

    def get(self, seed: int, config=None):
        """The prepared episode of this seed: loaded if the bank has it (a damaged file
        is named and replaced), else simulated and saved."""
        from aligngym.scenarios.campaign.executors import load_checked
        path = self.path(seed)
        if path.is_file():
            episode = load_checked(self.experiment.episode_class, path, seed)
            if episode is not None:
                return episode
        episode = self.experiment.prepare_episode(seed, config=config)
        episode.save(path)
        return episode

    def build(self, seeds: list[int], workers: int = 1, progress: bool = True,
              executor: str = "local", address: str | None = None) -> int:
        """Prepare the seeds the bank lacks, in parallel (local processes or Ray, with a
        progress bar); returns how many were simulated."""
        from aligngym.scenarios.campaign.executors import prepare_all
        missing = [s for s in seeds if not self.path(s).is_file()]   # damaged ones: named
        for i in range(0, len(seeds), BUILD_CHUNK):   # a chunk at a time in memory
            prepare_all(self.experiment, seeds[i:i + BUILD_CHUNK], self.directory,
                        resume=True, workers=workers, progress=progress, executor=executor,
                        address=address)
        return len(missing)
