"""The ``aligngym`` command line: the parser and the dispatch to one module per command
(``scenarios.commands``: bench, regress, reproduce, ...).

Imports stay inside the commands: help, version and option errors answer without
loading MuJoCo, SciPy or the estimators.
"""
from __future__ import annotations

import argparse
import sys
from typing import Sequence

from aligngym.scenarios.commands import (bank, bench, fidelity, regress, render, report,
                                         reproduce, simulate)
from aligngym.scenarios.commands.options import Parser, Version

COMMANDS = {"simulate": simulate, "fidelity": fidelity, "bench": bench, "render": render,
            "report": report, "reproduce": reproduce, "bank": bank, "regress": regress}
"""The commands in the order --help lists them: each module's ``add_parser(sub)`` declares
its options, its ``run(args)`` does the work and returns the exit status."""


def build_parser(bench_details: bool = False, experiment: type | None = None
                 ) -> argparse.ArgumentParser:
    """The parser; bench_details: list the filters in ``bench --help`` (imports them);
    experiment: the Experiment class bench names, whose declared settings become options
    (imported only when bench names one)."""
    parser = Parser(prog="aligngym", description="SINS initial-alignment scenario testbed")
    parser.add_argument("--version", action=Version)
    parser.add_argument("--plugin", action="append", metavar="MODULE", default=[],
                        help="import MODULE (a module name, or a .py file) before the "
                        "command, so the sensors, worlds, experiments and filters it "
                        "registers are known; repeatable, before the command; the "
                        "environment variable ALIGNGYM_PLUGINS adds a comma-separated list")
    sub = parser.add_subparsers(dest="command", parser_class=Parser, metavar="COMMAND")
    for name, command in COMMANDS.items():
        if name == "bench":
            command.add_parser(sub, bench_details, experiment)
        else:
            command.add_parser(sub)
    return parser


def _interrupted(args: argparse.Namespace) -> str:
    """The one line for Ctrl-C: what was kept and how to continue."""
    from pathlib import Path

    if args.command != "bench":
        return "aligngym: interrupted; no output was written (an existing one is unchanged)"
    if not args.out:
        return "aligngym: interrupted; nothing was kept (bench without --out keeps no episodes)"
    kept = len(list(Path(args.out).glob("**/episodes/seed_*.npz")))
    again = [w for w in args.command_line if w not in ("--resume", "--force")] + ["--resume"]
    return (f"aligngym: interrupted; {kept} finished episode(s) kept in {args.out}; "
            f"continue with: {' '.join(again)}")


def plugin_names(argv: Sequence[str]) -> list[str]:
    """The plugins to import: ALIGNGYM_PLUGINS (comma-separated), then each --plugin
    MODULE (or --plugin=MODULE) before the command."""
    import os
    names = [n.strip() for n in os.environ.get("ALIGNGYM_PLUGINS", "").split(",")
             if n.strip()]
    words = list(argv)
    for i, word in enumerate(words):
        if word in COMMANDS:                       # the command: options before it only
            break
        if word == "--plugin" and i + 1 < len(words):
            names.append(words[i + 1])
        elif word.startswith("--plugin="):
            names.append(word.split("=", 1)[1])
    return names


def load_plugin(name: str) -> None:
    """Import a plugin: a module name (found from the working directory too) or a .py
    file's path; ValueError naming it if it cannot be imported."""
    import importlib
    import importlib.util
    import os
    from pathlib import Path

    try:
        if name.endswith(".py"):
            path = Path(name)
            spec = importlib.util.spec_from_file_location(path.stem, path)
            if spec is None or not path.is_file():
                raise FileNotFoundError(f"no file {name}")
            module = importlib.util.module_from_spec(spec)
            sys.modules[path.stem] = module
            spec.loader.exec_module(module)
        else:
            if os.getcwd() not in sys.path:
                sys.path.append(os.getcwd())
            importlib.import_module(name)
    except Exception as exc:      # any failure of the user's module: one line, its cause
        raise ValueError(f"--plugin {name}: cannot import it: {type(exc).__name__}: "
                         f"{exc}") from None


_EXIT_FROZEN = False
"""Whether ``_finish_collections`` is registered to run at exit."""


def _finish_collections() -> None:
    """At exit: the garbage there is now collected (its finalizers run), then every live
    object frozen out of the collector's reach (``gc.freeze``), so that the interpreter's
    shutdown frees them by their reference counts alone, without the full collections it
    runs as it clears each module, each of which traverses every object a campaign left
    (a ten-episode bench's exit: 0.34-0.42 s before, 0.13-0.15 s with this; the saving
    grows with the objects a command leaves). The cost: an object still alive at exit
    that sits in a reference cycle is freed without its ``__del__`` or weakref callbacks
    (a plugin that must clean up at exit registers ``atexit`` or ``weakref.finalize``
    handlers, which run)."""
    import gc
    gc.collect()
    gc.freeze()


def _no_collection_at_exit() -> None:
    """Register ``_finish_collections`` to run at this process's exit, once: the command
    line's process (``main``, also when a program calls it)."""
    global _EXIT_FROZEN
    if not _EXIT_FROZEN:
        import atexit
        atexit.register(_finish_collections)
        _EXIT_FROZEN = True


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        for name in plugin_names(argv):
            load_plugin(name)
    except ValueError as exc:
        print(f"aligngym: error: {exc}", file=sys.stderr)
        return 2
    parser = build_parser(bench_details="bench" in argv and ("-h" in argv or "--help" in argv),
                          experiment=bench.named_experiment(argv))
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        hint = (f" ('aligngym bench {args.paper} --help' lists its settings; any other is "
                "--set NAME=VALUE)" if args.command == "bench" else "")
        parser.error(f"unrecognized arguments: {' '.join(unknown)}{hint}")
    args.command_line = ["aligngym", *argv]
    if args.command is None:      # a usage error: the usage, and status 2
        parser.print_help()
        return 2
    from aligngym.scenarios.campaign.executors import keep_freed_memory
    from aligngym.scenarios.config import ConfigError, SettingError
    from aligngym.scenarios.interrupts import remember_interrupts

    keep_freed_memory()          # the command's process only: not a library caller's
    _no_collection_at_exit()

    try:
        with remember_interrupts():
            return COMMANDS[args.command].run(args)
    except ConfigError as exc:
        if isinstance(exc, SettingError):    # a setting: named as the user wrote it
            labels = getattr(args, "setting_labels", {})
            exc = exc.as_written(lambda name: labels.get(name, name))
        print(f"aligngym: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(_interrupted(args), file=sys.stderr)
        return 130
    except OSError as exc:         # a full disk, a file removed under us: path and cause
        where = exc.filename or "an output"
        print(f"aligngym: error: {where}: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
