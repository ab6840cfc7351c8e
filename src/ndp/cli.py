"""The ``ndp`` command: thin entry points over the library.

Each sub-package that has commands exposes ``add_subparser(subparsers)``; this module only wires.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import Any

# Sub-command modules, each with ``add_subparser(subparsers) -> None`` that registers a parser
# whose ``func(args) -> int`` runs the command.
_COMMAND_MODULES = ("ndp.experiments.demo", "ndp.il.cli", "ndp.rl.cli")
# The command and the extra of the modules that need one: without it installed, the command is
# still listed and says what to install instead of failing the whole ``ndp`` command.
_EXTRAS = {"ndp.il.cli": ("il", "il"), "ndp.rl.cli": ("rl", "rl")}


def _add_missing_extra(sub: Any, command: str, extra: str, missing: str) -> None:
    p = sub.add_parser(command, help=f"(needs the [{extra}] extra: not installed)")
    p.add_argument("args", nargs=argparse.REMAINDER)

    def func(args: argparse.Namespace) -> int:
        print(
            f"ndp {command}: needs the [{extra}] extra (missing module {missing!r}): "
            f"pip install 'neural-dynamic-policies[{extra}]'",
            file=sys.stderr,
        )
        return 2

    p.set_defaults(func=func)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ndp", description="Neural Dynamic Policies")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:  # a sub-package not present in this build
                continue
            missing = (exc.name or "").split(".")[0]
            if name not in _EXTRAS or missing in ("", "ndp"):
                raise
            _add_missing_extra(sub, *_EXTRAS[name], missing)
            continue
        module.add_subparser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ModuleNotFoundError as exc:
        if (exc.name or "ndp").split(".")[0] == "ndp":
            raise
        # a third-party package of an extra that is not installed (a core-only install)
        print(
            f"ndp: error: {exc}: install the extras this command needs "
            "(pip install 'neural-dynamic-policies[envs]', '[rl]', '[il]'; '[dev]' for all)",
            file=sys.stderr,
        )
        return 2
    except (ValueError, OSError) as exc:  # bad input, unreadable or unwritable files
        print(f"ndp: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
