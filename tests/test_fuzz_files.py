"""Fuzzed files (issue 47): every kind of file the project writes and reads again (a
campaign directory's campaign.json, settings.json, summary.json, results.csv, tables.txt
and episode files; a bank's bank.json and episode files; a regression baseline; a truth
cache entry) is truncated at random lengths, has random bytes flipped, gets non-UTF-8
bytes, is emptied, is swapped with a file of another kind, or (JSON, CSV, npz) holds
content of the wrong shape; each command that reads the kind then runs in-process.

Every case either refuses in one line (exit status 2 from the command line, a
ConfigError from Python; the line names the file; no traceback; the directory's names,
sizes and mtimes unchanged), or recovers as documented (a damaged episode file or bank
episode is named in one line and simulated again, a damaged results.csv on --resume is
named and rewritten at the end, a damaged truth cache entry is recomputed and replaced),
or the damage left a valid file (a flipped digit, a CSV cut at a line's end) and the
command does its work. The valid originals are made once per module (a campaign of one
short episode, a bank of one) and copied per case; the simulation, the filters and the
regression campaign are stubbed where the work would start (after the files are read).
docs/campaign-directory.md lists the files and when each is refused."""
import contextlib
import io
import json
import os
import random
import re
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import aligngym  # noqa: F401  (registers the env ids)
import aligngym.scenarios.campaign.engine as engine
import aligngym.scenarios.regress as regress_module
from aligngym.scenarios import truth_cache
from aligngym.scenarios.cli import main
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.experiments import experiment, experiment_class

BENCH = ["bench", "paper002", "--episodes", "1", "--filters", "ekf", "--set",
         "fine_duration=20", "--no-figures", "--workers", "1"]
QUICK = {"episode_length": 12.0, "settings": {"coarse_duration": 20.0, "t_k1": 8.0,
                                              "t_k2": 20.0}}
BANK = ["bank", "ship-sway-rotary", "--episodes", "1", "--episode-length", "12",
        "--workers", "1", "--set", "coarse_duration=20", "--set", "t_k1=8",
        "--set", "t_k2=20"]
SHIP_ID = "aligngym/ShipSwayRotary-v1"


class Accepted(Exception):
    """The files were read and accepted: the work (filters, regression campaign) would
    start here."""


# --- the files: kind -> (tree, path inside it), and the commands reading each ----------
KINDS = {
    "campaign.json": ("campaign", "campaign.json"),
    "settings.json": ("campaign", "settings.json"),
    "summary.json": ("campaign", "summary.json"),
    "results.csv": ("campaign", "results.csv"),
    "tables.txt": ("campaign", "tables.txt"),
    "episode": ("campaign", "episodes/seed_0.npz"),
    "bank.json": ("bank", "BANKDIR/bank.json"),
    "bank-episode": ("bank", "BANKDIR/episodes/seed_0.npz"),
    "baseline": ("baselines", "regress_paper002.json"),
    "truth-entry": ("truth", "ENTRY"),
}
COMMANDS = {
    "campaign.json": ["rerun", "resume"], "settings.json": ["report"],
    "summary.json": ["report"], "results.csv": ["report", "resume"],
    "tables.txt": ["report"], "episode": ["resume", "rerun"],
    "bank.json": ["bank", "gym"], "bank-episode": ["bank", "gym"],
    "baseline": ["regress"], "truth-entry": ["truth"],
}
RECOVERED = {("episode", "resume"), ("episode", "rerun"), ("bank-episode", "bank"),
             ("bank-episode", "gym"), ("results.csv", "resume"), ("truth-entry", "truth")}
"""Documented recoveries: the damaged file is named in one line (or not, when it is
still valid) and replaced; the others refuse."""
JSON_KINDS = {"campaign.json", "settings.json", "summary.json", "bank.json", "baseline"}
NPZ_KINDS = {"episode", "bank-episode", "truth-entry"}
SWAPS = {"campaign.json": ["summary.json", "bank.json", "episode"],
         "settings.json": ["summary.json", "campaign.json", "episode"],
         "summary.json": ["settings.json", "baseline", "tables.txt"],
         "results.csv": ["tables.txt", "summary.json", "episode"],
         "tables.txt": ["episode", "results.csv"],
         "episode": ["bank-episode", "summary.json", "truth-entry"],
         "bank.json": ["campaign.json", "settings.json", "bank-episode"],
         "bank-episode": ["episode", "bank.json", "truth-entry"],
         "baseline": ["summary.json", "campaign.json", "results.csv"],
         "truth-entry": ["episode", "summary.json"]}
"""The file of another kind swapped in (an npz for a JSON file, a JSON for an npz, a
JSON of another shape)."""
JSON_SHAPES = ["[]", "3", '"text"', "null", "{}", "drop:0", "drop:1", "drop:2", "type:0",
               "type:1", "type:2", "schema"]
"""Valid JSON of the wrong shape: another type at the top, an object without one of the
original's first keys, one of them of another type, an unknown schema version."""
CSV_SHAPES = ["header-only", "other-header", "short-row", "not-a-number", "bad-status"]
NPZ_SHAPES = ["no-arrays", "text-arrays", "npy"]


def mutations(kind: str) -> list[str]:
    out = (["empty"] + [f"truncate:{i}" for i in range(4)] + [f"flip:{i}" for i in range(4)]
           + [f"nonutf8:{i}" for i in range(2)] + [f"swap:{k}" for k in SWAPS[kind]])
    if kind in JSON_KINDS:
        out += [f"json:{s}" for s in JSON_SHAPES]
    if kind == "results.csv":
        out += [f"csv:{s}" for s in CSV_SHAPES]
    if kind in NPZ_KINDS:
        out += [f"npz:{s}" for s in NPZ_SHAPES]
    return out


CASES = [(kind, command, mutation) for kind in KINDS for command in COMMANDS[kind]
         for mutation in mutations(kind)]


def damaged(kind: str, mutation: str, originals: dict) -> bytes:
    """The original file of this kind, damaged as the mutation says (deterministic)."""
    data = originals["bytes"][kind]
    name, _, arg = mutation.partition(":")
    rng = random.Random(f"{kind} {mutation}")
    if name == "empty":
        return b""
    if name == "truncate":
        return data[:rng.randrange(1, len(data))]
    if name == "flip":
        out = bytearray(data)
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(len(out))
            out[i] ^= rng.randrange(1, 256)
        return bytes(out)
    if name == "nonutf8":
        i = rng.randrange(len(data))
        return data[:i] + b"\xff\xfe\x80\xc3" + data[i:]
    if name == "swap":
        return originals["bytes"][arg]
    if name == "json":
        value = json.loads(data)
        keys = list(value)
        if arg.startswith("drop:"):
            del value[keys[int(arg[5:]) % len(keys)]]
        elif arg.startswith("type:"):
            key = keys[int(arg[5:]) % len(keys)]
            value[key] = 2.5 if isinstance(value[key], str) else "x"
        elif arg == "schema":
            value["schema"] = 99
        else:
            return arg.encode()
        return json.dumps(value, indent=2).encode()
    if name == "csv":
        lines = data.decode().splitlines(keepends=True)
        if arg == "header-only":
            return lines[0].encode()
        if arg == "other-header":
            return b"seed,phi_E_deg,phi_N_deg,phi_U_deg\n0,1,2,3\n"
        if arg == "short-row":
            return "".join(lines[:1] + [lines[1].rsplit(",", 3)[0] + "\n"]).encode()
        if arg == "not-a-number":
            return "".join(lines[:1] + [re.sub(r",(-?\d+\.\d+),", ",x1.5y,", lines[1], 1)]
                           ).encode()
        header = lines[0].rstrip("\n").split(",")
        row = lines[1].rstrip("\n").split(",")
        row[header.index("status")] = "convergxd"
        return (lines[0] + ",".join(row) + "\n").encode()
    buffer = io.BytesIO()          # npz of the wrong shape
    if arg == "no-arrays":
        np.savez(buffer)
    elif arg == "text-arrays":
        with np.load(io.BytesIO(data)) as f:
            np.savez(buffer, **{n: np.array(["x"] * max(1, f[n].size)) for n in f.files})
    else:
        np.save(buffer, np.arange(5.0))
    return buffer.getvalue()


OPTIONAL = {"campaign.json": {"paper", "schema"}, "summary.json": {"fine", "nees_band"},
            "settings.json": {"scenario_file", "scenario_toml", "seed", "episodes", "seeds",
                              "filters", "starts", "nees_dof", "command", "platform",
                              "versions", "written_utc"}}
"""Keys a reader may find missing: a campaign.json of an older aligngym has no "paper"
and no "schema" (read as schema 1),
a summary.json none of issue 46's "nees_band"; the report does not read the summary's
experiment part ("fine"), and shows the optional settings it finds."""
UNREAD = {"summary.json": {"fine"}}
"""Keys whose value the reader does not look at."""


def must_refuse(kind: str, mutation: str, originals: dict) -> bool:
    """Whether the damage leaves nothing a reader could accept: an empty file, non-UTF-8
    bytes, a file of another kind, the wrong shape; a truncated JSON file; a drop or a
    retype of a key the reader needs. A byte flip or a cut at a line's end may leave a
    valid file; tables.txt is free text (any UTF-8 text is a table)."""
    if kind == "tables.txt" and mutation.startswith(("swap:results", "truncate", "flip")):
        return False
    if mutation.startswith(("json:drop", "json:type")):
        keys = list(json.loads(originals["bytes"][kind]))
        key = keys[int(mutation.rsplit(":", 1)[1]) % len(keys)]
        drop = mutation.startswith("json:drop")
        return key not in UNREAD.get(kind, ()) and not (drop and key in OPTIONAL.get(kind, ()))
    if mutation.startswith("truncate"):
        return kind in JSON_KINDS
    return mutation.startswith(("empty", "nonutf8", "swap", "json", "csv", "npz"))


# --- the originals, made once -----------------------------------------------------------
def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def _truth_arrays():
    rng = np.random.default_rng(3)
    return {"truth.q_b_n": rng.normal(size=(41, 4)), "imu_t": np.arange(41) * 0.01,
            "dtheta": rng.normal(size=(40, 3)), "dv": rng.normal(size=(40, 3))}


TRUTH_KEY = ("fuzz", 1)


@pytest.fixture(scope="module")
def originals(tmp_path_factory):
    root = tmp_path_factory.mktemp("originals")
    code, _, err = _run(BENCH + ["--out", str(root / "campaign")])
    assert code == 0, err
    code, _, err = _run(BANK + ["--out", str(root / "bank")])
    assert code == 0, err
    shutil.copytree(regress_module.BASELINE_DIR, root / "baselines")
    previous = os.environ.get(truth_cache.TRUTH_CACHE_ENV)
    os.environ[truth_cache.TRUTH_CACHE_ENV] = str(root / "truth")
    try:
        truth_cache.cached_arrays("fuzz-truth", TRUTH_KEY, _truth_arrays)
    finally:
        if previous is None:
            os.environ.pop(truth_cache.TRUTH_CACHE_ENV)
        else:
            os.environ[truth_cache.TRUTH_CACHE_ENV] = previous
    names = {"BANKDIR": next((root / "bank").iterdir()).name,
             "ENTRY": next((root / "truth").glob("*.npz")).name}
    paths = {}
    for kind, (tree, rel) in KINDS.items():
        for key, value in names.items():
            rel = rel.replace(key, value)
        paths[kind] = (tree, rel)
    episode = experiment("paper002").episode_class.load(
        root / "campaign" / "episodes" / "seed_0.npz")
    env = gym.make(SHIP_ID, cache_episodes=0, **QUICK)
    bank_experiment = env.unwrapped.experiment
    env.close()
    bank_episode = bank_experiment.episode_class.load(root / "bank" / paths["bank-episode"][1])
    return {"root": root, "paths": paths,
            "bytes": {k: (root / t / r).read_bytes() for k, (t, r) in paths.items()},
            "episodes": {"episode": episode, "bank-episode": bank_episode},
            "bank_experiment": type(bank_experiment)}


def snapshot(folder: Path) -> dict:
    """Names, sizes and mtimes under folder (the campaign lock's holder line is rewritten
    by every bench that takes the lock, refused or not: left out)."""
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*")) if p.name != ".campaign.lock"}


def notes(err: str) -> list[str]:
    """The lines of our own on stderr (progress bars left out)."""
    return [line for line in re.split(r"[\r\n]", err) if line.startswith("aligngym")]


@pytest.mark.parametrize("kind,command,mutation", CASES,
                         ids=[f"{k}-{c}-{m}" for k, c, m in CASES])
def test_damaged_file_is_refused_in_one_line_or_recovered(originals, tmp_path, monkeypatch,
                                                          kind, command, mutation):
    tree, rel = originals["paths"][kind]
    folder = tmp_path / tree
    shutil.copytree(originals["root"] / tree, folder)
    path = folder / rel
    path.write_bytes(damaged(kind, mutation, originals))
    before = snapshot(folder)
    monkeypatch.chdir(tmp_path)

    def stop(*args, **kwargs):
        raise Accepted

    def prepared(*args, **kwargs):            # the episodes read (or replaced): stop here
        engine_prepare(*args, **kwargs)
        raise Accepted
    engine_prepare = engine.prepare_all
    monkeypatch.setattr(engine, "prepare_all", prepared)
    monkeypatch.setattr(regress_module, "campaign_metrics", stop)
    for key, cls in (("episode", experiment_class("paper002")),
                     ("bank-episode", originals["bank_experiment"])):
        pristine = originals["episodes"][key]
        monkeypatch.setattr(cls, "prepare_episode",
                            lambda self, seed, config=None, e=pristine: e)

    error, code, err = None, None, io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            if command == "report":
                code = main(["report", str(folder)])
            elif command in ("rerun", "resume"):
                code = main(BENCH + ["--out", str(folder)]
                            + (["--resume"] if command == "resume" else []))
            elif command == "bank":
                code = main(BANK + ["--out", str(folder)])
            elif command == "regress":
                code = main(["regress", "--papers", "paper002", "--baselines", str(folder)])
            elif command == "gym":
                env = gym.make(SHIP_ID, bank=str(folder), cache_episodes=0, **QUICK)
                env.unwrapped._prepare(0)
                env.close()
                code = 0
            else:
                monkeypatch.setenv(truth_cache.TRUTH_CACHE_ENV, str(folder))
                arrays = truth_cache.cached_arrays("fuzz-truth", TRUTH_KEY, _truth_arrays)
                assert arrays.keys() == _truth_arrays().keys()
                assert all(np.array_equal(arrays[k], v) for k, v in _truth_arrays().items())
                code = 0
        except Accepted:
            code = 0
        except ConfigError as exc:                # the Python API's refusal
            error, code = str(exc), 2
    text = err.getvalue()
    assert "Traceback" not in text
    if code == 2:                                 # refused: one line, naming the file
        assert (kind, command) not in RECOVERED, (mutation, text or error)
        lines = text.strip().splitlines() if error is None else [error]
        assert len(lines) == 1 and "\n" not in lines[0], text
        line = lines[0]
        assert error is not None or line.startswith("aligngym: error: ")
        assert str(path) in line or (str(path.parent) in line and path.name in line), line
        assert any(w in line for w in ("--force", "delete", "re-run", "--update",
                                       "--resume", "new --out", "another bank")), line
        assert snapshot(folder) == before
        return
    assert code == 0, (code, text)
    named = [line for line in notes(text) if str(path) in line]
    if (kind, command) in RECOVERED:
        assert len(named) <= 1 and len(notes(text)) == len(named), text
        if kind in NPZ_KINDS and kind != "truth-entry":
            if named:                             # replaced by the simulated episode
                episode = type(originals["episodes"][kind]).load(path)
                assert int(episode.seed) == 0
        elif kind == "truth-entry" and path.read_bytes() != damaged(kind, mutation, originals):
            assert truth_cache._load(path) is not None          # replaced, loads
        return
    # accepted: the damage left a valid file (a flipped digit, a cut at a line's end)
    assert not must_refuse(kind, mutation, originals), (mutation, text)
    assert not notes(text), text
