"""The campaign directory: its lock (one writer at a time), its manifest
(``campaign.json``: the experiment's settings and the seed), which decides whether a
directory may be used, resumed or replaced, and the check that a resumed campaign does
not replace finished results."""
from __future__ import annotations

import csv
import errno
import hashlib
import json
import os
import socket
import time
from contextlib import contextmanager
from dataclasses import asdict, replace
from pathlib import Path
from typing import Iterator

from aligngym.scenarios.atomic import is_temporary, write_json
from aligngym.scenarios.campaign.experiment import Experiment
from aligngym.scenarios.config import ConfigError

LOCK_NAME = ".campaign.lock"
_HELD: dict[Path, int] = {}
"""Directories this process holds: path -> the lock file's descriptor."""


@contextmanager
def campaign_lock(out: Path) -> Iterator[None]:
    """Hold DIR/.campaign.lock for the block (an exclusive ``flock``, which the kernel
    releases when the holder dies, so a killed run leaves no stale lock); a second
    writer is refused in one line naming the holder (pid, host, start time). Nested
    holds by this process are free. Leftover temporary files of killed writers are
    removed once the lock is taken (nobody else can be writing them)."""
    import fcntl
    out = Path(out).resolve()
    if out in _HELD:                       # held by an outer block of this process
        yield
        return
    path = out / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise ConfigError(f"--out {out}: cannot create its lock file ({exc.strerror})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
        os.close(fd)
        if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise ConfigError(f"--out {out} is in use by {holder}; wait for it to finish "
                              "or use another --out") from None
        raise
    os.ftruncate(fd, 0)
    os.write(fd, f"pid {os.getpid()} on {socket.gethostname()} since "
                 f"{time.strftime('%Y-%m-%d %H:%M:%S')}".encode())
    _HELD[out] = fd
    for leftover in [*out.glob(".*"), *(out / "episodes").glob("*")]:
        if is_temporary(leftover) and leftover.is_file():
            leftover.unlink(missing_ok=True)
    try:
        yield
    finally:
        os.close(_HELD.pop(out))           # releases the flock


MANIFEST_SCHEMA = 1
"""The campaign.json layout this version reads: one holding a "schema" other than this
(a later aligngym's) is refused in one line; one without is of this layout."""


def manifest_of(experiment: Experiment, seed: int) -> dict:
    """What decides a campaign's episodes, as campaign.json holds it: the paper, the
    experiment's settings, the seed, a hash of the resolved scenario (the file's content
    with every preset it pulls in: an edited file is another campaign) and a hash of the
    code that prepares an episode and the library versions (``simulation_versions``, the
    bank's code: episodes prepared by other code are another campaign)."""
    from aligngym.scenarios.truth_cache import simulation_versions
    config = repr(replace(experiment.scenario_config(), source=""))   # not where it lies
    return json.loads(json.dumps({
        "schema": MANIFEST_SCHEMA, "paper": experiment.paper,
        "experiment": asdict(experiment), "seed": seed,
        "scenario_sha256": hashlib.sha256(config.encode()).hexdigest(),
        "simulation_sha256": hashlib.sha256(simulation_versions().encode()).hexdigest()}))


def differences(saved: dict, current: dict) -> list[str]:
    """The manifest entries that differ ("seed", "experiment.fine_duration", ...)."""
    out = []
    for key in sorted(set(saved) | set(current)):
        a, b = saved.get(key), current.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            out += [f"{key}.{k}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
        elif a != b:
            what = {"scenario_sha256": "scenario (its content)",
                    "simulation_sha256": "simulation (its code or library versions)"}
            out.append(key if key not in what else what[key] if a
                       else what[key].split(" (")[0] + " (not recorded: a campaign of an "
                       "older aligngym)")
    return out


def check_manifest(out: Path, experiment: Experiment, seed: int, resume: bool,
                   force: bool = False, filters: list[str] | None = None) -> bool:
    """Check that out may be used (the caller holds its ``campaign_lock``): a directory
    holding a campaign needs resume (the same experiment, scenario content and seed, from
    its campaign.json, and filters that include every filter of its finished results) or
    force (its episode files, tables, series, plots, settings and report are removed,
    so nothing of another seed mixes in); then write the manifest. A directory holding
    this same campaign (the same manifest and filters) is resumed without asking: True
    is returned then, False otherwise."""
    manifest = out / "campaign.json"
    episodes = [p for p in (out / "episodes").glob("seed_*.npz") if not is_temporary(p)]
    held = manifest.is_file() or bool(episodes)
    current = manifest_of(experiment, seed)
    same = False
    if held and not (resume or force):
        saved = _readable_manifest(manifest)
        if saved is None:
            raise ConfigError(f"--out {out} holds a campaign whose campaign.json is missing "
                              "or does not read; use --force to replace it or a new --out")
        saved = _with_defaults(saved, current)
        same = saved == current
        if not same:
            raise ConfigError(f"--out {out} holds another campaign ({manifest} differs in "
                              f"{', '.join(differences(saved, current))}); use --force to "
                              "replace it or a new --out")
        resume = True
    if resume and episodes and not manifest.is_file():
        raise ConfigError(f"--resume: {out} has episode files but no campaign.json, so "
                          "their experiment and seed are unknown; use --force to replace them")
    if resume and manifest.is_file():
        saved = _with_defaults(read_manifest(manifest), current)
        if saved != current:
            raise ConfigError(f"--resume: {manifest} was written by a different campaign "
                              f"(it differs in {', '.join(differences(saved, current))}); "
                              "use a new --out directory or --force")
        finished = finished_filters(out)
        missing = [f for f in finished if f not in (filters or finished)]
        if missing:
            union = [*finished, *[f for f in filters or () if f not in finished]]
            raise ConfigError(f"--resume: {out}'s results hold {', '.join(finished)}; "
                              f"--filters {','.join(filters or ())} would drop "
                              f"{', '.join(missing)}: name them too (--filters "
                              f"{','.join(union)}) or use a new --out")
    if force and not resume:      # nothing of the old campaign survives to mix in
        for old in [*episodes, *out.glob("*.csv"), *out.glob("*.png"),
                    out / "timeseries.npz", out / "tables.txt", out / "summary.json",
                    out / "settings.json", out / "report.html", manifest]:
            old.unlink(missing_ok=True)
    write_json(manifest, current)
    return same


def _with_defaults(saved: dict, current: dict) -> dict:
    """A saved manifest with what older campaigns lack and mean by default: this
    schema, and the paper the current experiment is of."""
    return {"schema": MANIFEST_SCHEMA, "paper": current["paper"], **saved}


def _manifest_problem(saved) -> str | None:
    """What makes a decoded campaign.json not a manifest (None: it is one): an object
    with "experiment" (an object) and "seed" (an integer); "paper", "scenario_sha256" and
    "simulation_sha256" strings when present (older campaigns lack them)."""
    if not isinstance(saved, dict):
        return f"holds a JSON {type(saved).__name__}, not an object"
    if not isinstance(saved.get("experiment"), dict):
        return "has no \"experiment\" object"
    seed = saved.get("seed")
    if not isinstance(seed, int) or isinstance(seed, bool):
        return "has no integer \"seed\""
    for key in ("paper", "scenario_sha256", "simulation_sha256"):
        if key in saved and not isinstance(saved[key], str):
            return f"\"{key}\" is not a string"
    return None


def _decoded_manifest(manifest: Path):
    """(campaign.json decoded, None) or (None, what is wrong); OSError passes."""
    data = manifest.read_bytes()
    try:
        return json.loads(data.decode("utf-8")), None
    except UnicodeDecodeError as exc:
        return None, f"is not UTF-8 (byte {exc.start})"
    except json.JSONDecodeError as exc:
        return None, f"does not read as JSON ({exc.msg} at line {exc.lineno})"


def _check_schema(manifest: Path, saved: dict) -> None:
    schema = saved.get("schema", MANIFEST_SCHEMA)
    if schema != MANIFEST_SCHEMA:
        raise ConfigError(f"--out: {manifest} has schema {schema!r}, not this aligngym's "
                          f"({MANIFEST_SCHEMA}); continue it with the aligngym that wrote "
                          "it, or use --force to start the campaign again or a new --out")


def _readable_manifest(manifest: Path) -> dict | None:
    """campaign.json as a dict, or None if it is missing or does not read as a manifest
    (``_manifest_problem``); one of another schema is a one-line error."""
    try:
        saved, problem = _decoded_manifest(manifest)
    except OSError:
        return None
    if problem is not None or _manifest_problem(saved) is not None:
        return None
    _check_schema(manifest, saved)
    return saved


def read_manifest(manifest: Path) -> dict:
    """campaign.json as a dict; a damaged or foreign one is a one-line error naming it
    and saying what to do."""
    try:
        saved, problem = _decoded_manifest(manifest)
    except OSError as exc:
        saved, problem = None, f"cannot be read ({exc.strerror or exc})"
    if problem is None:
        problem = _manifest_problem(saved)
    if problem is not None:
        raise ConfigError(f"--resume: {manifest} {problem}, so the episodes' experiment "
                          "and seed are unknown; use --force to start the campaign again "
                          "(its episodes are simulated anew) or a new --out")
    _check_schema(manifest, saved)
    return saved


def finished_filters(out: Path) -> list[str]:
    """The filters whose rows results.csv holds (in order), none without one; a results
    file that does not read (not UTF-8 CSV with a "filter" column, a row cut short) is
    named in one line on stderr and treated as none: it is written anew when the campaign
    finishes."""
    import io
    import sys
    path = out / "results.csv"
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return []
    except OSError as exc:
        problem = exc.strerror or str(exc)
    else:
        try:
            rows = list(csv.reader(io.StringIO(data.decode("utf-8"), newline="")))
            problem = None
        except UnicodeDecodeError as exc:
            problem = f"not UTF-8 (byte {exc.start})"
        except csv.Error as exc:
            problem = f"not CSV ({exc})"
        if problem is None:
            header = rows[0] if rows else []
            if "filter" not in header:
                problem = "no \"filter\" column"
            elif any(len(row) != len(header) for row in rows[1:]):
                problem = "a row of another length than the header (cut short?)"
    if problem is not None:
        print(f"aligngym: {path} does not read ({problem}); its filters are not checked "
              "against --filters, and it is written anew when the campaign finishes",
              file=sys.stderr)
        return []
    column = header.index("filter")
    return list(dict.fromkeys(row[column] for row in rows[1:] if row[column]))
