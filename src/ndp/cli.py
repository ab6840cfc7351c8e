"""The ``ndp`` command: thin entry points over the library.

Each sub-package that has commands exposes ``add_subparser(subparsers)``; this module only wires.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

# Sub-command modules, each with ``add_subparser(subparsers) -> None`` that registers a parser
# whose ``func(args) -> int`` runs the command.
_COMMAND_MODULES = ("ndp.experiments.demo", "ndp.il.cli", "ndp.rl.cli")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ndp", description="Neural Dynamic Policies")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:  # a sub-package not present in this build
            if exc.name != name:
                raise
            continue
        module.add_subparser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, OSError) as exc:  # bad input, unreadable or unwritable files
        print(f"ndp: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
