"""What the commands share: the parser with one-line errors, option value parsers (each
error names its option and the allowed range), experiment settings from --NAME and --set
NAME=VALUE, and output checks made before any work."""
from __future__ import annotations

import argparse
import math
from dataclasses import fields
from typing import NoReturn


EXECUTOR_CHOICES = ("local", "ray")
"""The built-in executors the command line offers (``campaign.executors.EXECUTORS``; one
registered from Python is for ``run_campaign``), named here so that --help loads no
campaign code."""


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump) and exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


class Version(argparse.Action):
    """--version: the installed package's version (read only when asked)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="print the version and exit"):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        from importlib.metadata import PackageNotFoundError, version
        try:
            text = version("aligngym")
        except PackageNotFoundError:
            text = "unknown (not installed)"
        print(f"aligngym {text}")
        parser.exit(0)


def float_option(field: str, allow_zero: bool = False):
    """Parser of a finite number > 0 (>= 0 with allow_zero) for the option ``field``."""
    return number_option(field, 0.0, strict=not allow_zero)


def seed_option(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seed must be an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"--seed must be an integer >= 0, got {value}")
    return value


def number_option(flag: str, minimum: float, strict: bool = False):
    """Parser of a finite number >= minimum (> with strict) for the option ``flag``."""
    bound = f"{'>' if strict else '>='} {minimum:g}"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{flag} must be a number, got {text!r}") from None
        if not math.isfinite(value) or (value <= minimum if strict else value < minimum):
            raise argparse.ArgumentTypeError(f"{flag} must be {bound}, got {text}")
        return value
    return parse


def integer_option(field: str, minimum: int = 1):
    """Parser of an integer >= minimum for the option ``field``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{field} must be an integer >= {minimum}, "
                                              f"got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{field} must be an integer >= {minimum}, "
                                              f"got {value}")
        return value
    return parse


def setting_value(text: str):
    """A setting's value as written on the command line: a TOML value (number,
    true/false, "string", [list] -> tuple), else the plain string; "none" is None."""
    import tomllib

    if text.strip().lower() == "none":
        return None
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text
    return tuple(value) if isinstance(value, list) else value


def settings_of(cls: type, args: argparse.Namespace) -> dict:
    """The experiment settings bench's options and --set NAME=VALUE give, each checked to be
    a setting (a dataclass field) of the experiment class; values read by
    ``setting_value`` (their types and ranges are checked when the experiment is made,
    ``campaign.experiment.validate_settings``). Records in args.setting_labels how each was
    written (--NAME, --set NAME), for the error that names it."""
    from aligngym.scenarios.config import ConfigError
    known = {f.name: f for f in fields(cls)}
    labels = getattr(args, "setting_labels", {})
    out = {}
    for f in cls.flagged_settings():
        given = getattr(args, f.name, None)
        if given is not None:
            out[f.name] = given if f.metadata["choices"] else setting_value(given)
            labels[f.name] = "--" + f.name.replace("_", "-")
    for item in args.set or ():
        name, sep, text = item.partition("=")
        name = name.strip().replace("-", "_")
        if not sep or name not in known:
            raise ConfigError(f"--set {item!r}: need NAME=VALUE with NAME a setting of "
                              f"{args.paper}: " + ", ".join(sorted(known)))
        out[name] = setting_value(text)
        labels[name] = f"--set {name}"
    args.setting_labels = labels
    return out


def check_writable(path_text: str, option: str) -> None:
    """Before any work: the output file can be written (its directory exists or can be
    made, and is writable; an existing file is writable)."""
    import os
    from pathlib import Path

    from aligngym.scenarios.config import ConfigError

    path = Path(path_text)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError:                  # a file (not a folder) on the way
        raise ConfigError(f"{option} {path}: cannot create {path.parent}: a file of that "
                          "name (or above it) is in the way, not a directory") from None
    except OSError as exc:
        raise ConfigError(f"{option} {path}: cannot create {path.parent} "
                          f"({exc.strerror})") from None
    if path.is_dir() or not os.access(path if path.exists() else path.parent, os.W_OK):
        raise ConfigError(f"{option} {path}: cannot write this file")


def option_labels(args: argparse.Namespace) -> dict[str, str]:
    """The scenario fields --duration and --imu-rate override, by option (errors name
    what the user wrote)."""
    return {field: option for field, option in (("duration", "--duration"),
                                                 ("imu_rate", "--imu-rate"))
            if getattr(args, field) is not None}
