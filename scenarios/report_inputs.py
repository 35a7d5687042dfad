"""The files of a campaign directory read and checked for the report page
(``html_report``): which directories are campaigns (``REQUIRED``), settings.json and
summary.json (JSON objects of this ``SCHEMA``), results.csv (its columns, numbers and
statuses), tables.txt and the other text files (UTF-8), and a PNG's signature. A file that
does not read or check is refused in one line (``ConfigError``) naming the file and what
to do. Values keep the files' units (results.csv: arcmin, s, ms per epoch; summary.json's
"nees_band": s and fractions of epochs).
"""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from aligngym.estimators.metrics import STATUSES
from aligngym.scenarios.config import ConfigError

REQUIRED = ("settings.json", "results.csv", "tables.txt")
"""Files of a campaign directory the report reads (``write_outputs`` writes them)."""


def campaign_dirs(directory: str | Path) -> list[Path]:
    """The campaign directories of DIR: DIR itself when it holds one, else its
    immediate subdirectories that do. One-line ConfigError when DIR is missing or holds
    none."""
    root = Path(directory)
    if not root.is_dir():
        raise ConfigError(f"report DIR {root}: no such directory")
    if _is_campaign(root):
        return [root]
    subdirs = sorted(p for p in root.iterdir() if p.is_dir() and _is_campaign(p))
    if subdirs:
        return subdirs
    if (root / "campaign.json").is_file() or (root / "results.csv").is_file():
        missing = ", ".join(name for name in REQUIRED if not (root / name).is_file())
        raise ConfigError(f"report DIR {root}: campaign directory without {missing} "
                          "(written by this version's bench); run the same "
                          f"'aligngym bench ... --out {root} --resume' to add it")
    raise ConfigError(f"report DIR {root}: not a campaign directory (no {REQUIRED[0]}, "
                      f"{REQUIRED[1]}); write one with 'aligngym bench PAPER --out DIR'")


def _is_campaign(path: Path) -> bool:
    return all((path / name).is_file() for name in REQUIRED)


SCHEMA = 1
"""The layout of the campaign files this version writes and reads; a settings.json or
summary.json carrying another "schema" (a later aligngym's) is refused, one without one
is read as this layout (docs/campaign-directory.md)."""


def _again(path: Path) -> str:
    """What to do about a damaged or foreign file of a campaign directory."""
    return (f"write it again with the campaign's 'aligngym bench ... --out {path.parent} "
            "--resume' (settings.json holds its command line), or delete the directory "
            "and run the campaign anew")


def _refuse(path: Path, problem: str) -> ConfigError:
    return ConfigError(f"report {path}: {problem}; {_again(path)}")


def _read_text(path: Path) -> str:
    """A text file of the directory, UTF-8; one line naming it when it does not read."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise _refuse(path, f"cannot be read ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _refuse(path, f"is not UTF-8 text (byte {exc.start}), a damaged or "
                      "foreign file") from None
    if "\0" in text:
        raise _refuse(path, "holds NUL bytes, a damaged or foreign file")
    if not text.strip():
        raise _refuse(path, "is empty")
    return text


def _read_json(path: Path) -> dict:
    """A JSON object of the directory (settings.json, summary.json), its "schema" this
    version's or none; one line naming it otherwise."""
    try:
        value = json.loads(_read_text(path))
    except json.JSONDecodeError as exc:
        raise _refuse(path, f"is not valid JSON ({exc.msg} at line {exc.lineno}), a "
                      "damaged or truncated file") from None
    if not isinstance(value, dict):
        raise _refuse(path, f"holds a JSON {type(value).__name__}, not an object, a "
                      "foreign file")
    schema = value.get("schema", SCHEMA)
    if schema != SCHEMA:
        raise ConfigError(f"report {path}: its schema {schema!r} is not this aligngym's "
                          f"({SCHEMA}); report it with the aligngym that wrote it, or "
                          f"re-run the campaign into a new --out")
    return value


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_list_of(value, kind) -> bool:
    return isinstance(value, list) and all(isinstance(v, kind) for v in value)


SETTINGS_TYPES = {
    "paper": (str,), "scenario": (str,), "experiment": (dict,),
    "scenario_file": (str,), "scenario_toml": (str,), "seed": (int, type(None)),
    "episodes": (int,), "seeds": (list,), "filters": (list,), "starts": (list,),
    "nees_dof": (int, type(None)), "command": (list, type(None)), "platform": (str,),
    "versions": (dict,), "written_utc": (str,)}
"""settings.json's keys (``report.campaign_settings``) and their JSON types; the first
three are required."""


def _read_settings(directory: Path) -> dict:
    path = directory / "settings.json"
    settings = _read_json(path)
    for key, types in SETTINGS_TYPES.items():
        if key not in settings:
            if key in ("paper", "scenario", "experiment"):
                raise _refuse(path, f"has no {key!r}: not a campaign's settings file")
            continue
        value = settings[key]
        if not isinstance(value, types) or isinstance(value, bool):
            raise _refuse(path, f"{key!r} is a {type(value).__name__}, not a "
                          f"{' or '.join(t.__name__ for t in types).replace('NoneType', 'null')}")
    for key in ("filters", "starts"):
        if not _is_list_of(settings.get(key, []), str):
            raise _refuse(path, f"{key!r} is not a list of names")
    return settings


def _read_summary(path: Path) -> dict:
    """summary.json, with the parts the report shows checked: "data_faults" (required)
    and "nees_band" (from issue 46 on)."""
    summary = _read_json(path)
    faults = summary.get("data_faults")
    if not isinstance(faults, dict):
        raise _refuse(path, "has no \"data_faults\" object: not a campaign's summary")
    if not (isinstance(faults.get("flagged_episodes"), int)
            and isinstance(faults.get("episodes"), int)
            and isinstance(faults.get("by_kind", {}), dict)
            and all(isinstance(n, int) for n in faults.get("by_kind", {}).values())):
        raise _refuse(path, "\"data_faults\" does not hold counts (flagged_episodes, "
                      "episodes, by_kind)")
    bands = summary.get("nees_band", {})
    entries = ([e for per in bands.values() if isinstance(per, dict) for e in per.values()]
               if isinstance(bands, dict) else None)
    if (entries is None or not all(isinstance(per, dict) for per in bands.values())
            or not all(_nees_entry_ok(e) for e in entries)):
        raise _refuse(path, "\"nees_band\" is not {filter: {start: band entry}}")
    return summary


def _nees_entry_ok(entry) -> bool:
    if not isinstance(entry, dict):
        return False
    band = entry.get("band")
    optional = ("fraction_of_epochs_above", "fraction_of_epochs_below",
                "first_time_outside_s")
    number = lambda v: v is None or _is_number(v)  # noqa: E731  (null: not finite)
    return ((band is None or (isinstance(band, list) and len(band) in (0, 2)
                              and all(number(b) for b in band)))
            and number(entry.get("probability", 0.95))
            and all(entry.get(k) is None or _is_number(entry[k]) for k in optional)
            and isinstance(entry.get("text", ""), str))


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


RESULTS_NUMBERS = ("final_phi_E_arcmin", "final_phi_N_arcmin", "final_phi_U_arcmin",
                   "heading_convergence_s", "nees_mean", "covariance_repairs",
                   "ms_per_epoch")
"""results.csv's columns the report reads as numbers (empty, nan and inf allowed); it
needs them, "filter", "start" and "diverged" ("status": from issue 46 on)."""


def _read_results(path: Path) -> list[dict]:
    """results.csv's rows, checked: the columns the report reads, one field per column
    in every row, numbers where numbers go, a known status; one line naming the file and
    the first row at fault otherwise."""
    try:
        rows = list(csv.reader(io.StringIO(_read_text(path), newline="")))
    except csv.Error as exc:
        raise _refuse(path, f"is not CSV ({exc})") from None
    header, body = rows[0], rows[1:]
    missing = [c for c in ("filter", "start", "diverged", *RESULTS_NUMBERS) if c not in header]
    if missing:
        raise _refuse(path, f"has no column {missing[0]!r}: not a campaign's results table")
    if not body:
        raise _refuse(path, "has no rows (a truncated file)")
    out = []
    for number, row in enumerate(body, start=2):
        if len(row) != len(header):
            raise _refuse(path, f"line {number} has {len(row)} fields, the header "
                          f"{len(header)} (a truncated or damaged file)")
        entry = dict(zip(header, row))
        bad = next((c for c in RESULTS_NUMBERS if entry[c] not in ("", *_NUMBERLESS)
                    and not _parses(entry[c])), None)
        if bad is not None:
            raise _refuse(path, f"line {number}: {bad} = {entry[bad][:20]!r} is not a number")
        if entry.get("status", "") not in ("", *STATUSES) or entry["diverged"] not in (
                "True", "False"):
            raise _refuse(path, f"line {number}: status {entry.get('status', '')[:20]!r} or "
                          f"diverged {entry['diverged'][:20]!r} is not one the campaign writes")
        out.append(entry)
    return out


_NUMBERLESS = ("nan", "inf", "-inf")


def _parses(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
