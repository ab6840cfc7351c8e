"""The ``ndp`` command: thin entry points over the library.

Each sub-package that has commands exposes ``add_subparser(subparsers)`` (argparse commands) and
may expose ``CONFIG_COMMANDS``: ``{"rl train": run(argv) -> int}``, commands whose options are
the fields of a typed config (parsed by tyro in ``ndp.runs.cli``); those get the rest of the
command line as it is. This module only wires.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence
from types import ModuleType

# Sub-command modules, each with ``add_subparser(subparsers) -> None`` that registers a parser
# whose ``func(args) -> int`` runs the command.
_COMMAND_MODULES = ("ndp.experiments.demo", "ndp.il.cli", "ndp.rl.cli")


def _modules() -> list[ModuleType]:
    out = []
    for name in _COMMAND_MODULES:
        try:
            out.append(importlib.import_module(name))
        except ModuleNotFoundError as exc:  # a sub-package not present in this build
            if exc.name != name:
                raise
    return out


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ndp", description="Neural Dynamic Policies")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for module in _modules():
        module.add_subparser(sub)
    return parser


def _config_command(argv: list[str]) -> Callable[[list[str]], int] | None:
    for module in _modules():
        for words, run in getattr(module, "CONFIG_COMMANDS", {}).items():
            n = len(words.split())
            if argv[:n] == words.split():
                return lambda rest, run=run, n=n: run(rest[n:])
    return None


def main(argv: Sequence[str] | None = None) -> int:
    args_list = list(sys.argv[1:] if argv is None else argv)
    try:
        run = _config_command(args_list)
        if run is not None:
            try:
                return int(run(args_list) or 0)
            except SystemExit as exc:  # --help (0) or a bad option (2), message already shown
                return exc.code if isinstance(exc.code, int) else 2
        parser = build_parser()
        args = parser.parse_args(args_list)
        return int(args.func(args) or 0)
    except (ValueError, OSError) as exc:  # bad input, unreadable or unwritable files
        print(f"ndp: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
