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

from ndp import version
from ndp.checks import install_hint

# Sub-command modules, each with ``add_subparser(subparsers) -> None`` that registers a parser
# whose ``func(args) -> int`` runs the command.
_COMMAND_MODULES = (
    "ndp.experiments.demo",
    "ndp.il.cli",
    "ndp.bc.cli",
    "ndp.rl.cli",
    "ndp.experiments.sweep.cli",
)
# The command and the extra of the modules that need one: without it installed, the command is
# still listed and says what to install instead of failing the whole ``ndp`` command.
_EXTRAS = {"ndp.il.cli": ("il", "il"), "ndp.bc.cli": ("il", "rl"), "ndp.rl.cli": ("rl", "rl")}


def _missing_extra_message(command: str, extra: str, missing: str) -> str:
    return (
        f"ndp {command}: needs the [{extra}] extra (missing module {missing!r}): "
        f"{install_hint(extra)}"
    )


def _add_missing_extra(
    sub: argparse._SubParsersAction[argparse.ArgumentParser], command: str, extra: str, missing: str
) -> None:
    p = sub.add_parser(command, help=f"(needs the [{extra}] extra: not installed)")
    p.add_argument("args", nargs=argparse.REMAINDER)

    def func(args: argparse.Namespace) -> int:
        print(_missing_extra_message(command, extra, missing), file=sys.stderr)
        return 2

    p.set_defaults(func=func)


def _modules() -> list[tuple[str, ModuleType | str]]:
    """(name, module) per command module, or (name, missing third-party module) for a module
    whose extra is not installed."""
    out: list[tuple[str, ModuleType | str]] = []
    for name in _COMMAND_MODULES:
        try:
            out.append((name, importlib.import_module(name)))
        except ModuleNotFoundError as exc:
            if exc.name == name:  # a sub-package not present in this build
                continue
            missing = (exc.name or "").split(".")[0]
            if name not in _EXTRAS or missing in ("", "ndp"):
                raise
            out.append((name, missing))
    return out


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ndp", description="Neural Dynamic Policies")
    parser.add_argument(
        "--version", action="store_true", help="print the installed version and exit"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, module in _modules():
        if isinstance(module, str):
            _add_missing_extra(sub, *_EXTRAS[name], module)
        else:
            module.add_subparser(sub)
    return parser


def _config_command(argv: list[str]) -> tuple[str, Callable[[list[str]], int]] | None:
    """(module name, runner) of the typed-config command that ``argv`` names, if any."""
    for name, module in _modules():
        if isinstance(module, str):
            continue
        for words, run in getattr(module, "CONFIG_COMMANDS", {}).items():
            n = len(words.split())
            if argv[:n] == words.split():
                return name, lambda rest, run=run, n=n: run(rest[n:])
    return None


def version_line() -> str:
    """``ndp --version``'s line: the installed distribution's version (``ndp.version``)."""
    return f"ndp {version()}"


def main(argv: Sequence[str] | None = None) -> int:
    """The ``ndp`` command. SIGINT and SIGTERM stop it from its first instant (before any heavy
    import; also where SIGINT was ignored at start-up, as for a shell's background job): one
    line on stderr and exit 130 / 143, however far the command got."""
    from ndp.runs.signals import exit_code, stop_on_sigterm

    try:
        with stop_on_sigterm():
            return _main(argv)
    except KeyboardInterrupt as exc:  # a stop no command turned into its own message
        code = exit_code(exc)
        name = "SIGTERM" if code == 143 else "SIGINT"
        print(f"ndp: stopped by {name} (exit {code})", file=sys.stderr)
        return code


def _main(argv: Sequence[str] | None = None) -> int:
    args_list = list(sys.argv[1:] if argv is None else argv)
    if args_list[:1] == ["--version"]:  # before the sub-command modules are imported
        print(version_line())
        return 0
    try:
        found = _config_command(args_list)
        if found is not None:
            name, run = found
            try:
                return int(run(args_list) or 0)
            except SystemExit as exc:  # --help (0) or a bad option (2), message already shown
                return exc.code if isinstance(exc.code, int) else 2
            except ModuleNotFoundError as exc:
                missing = (exc.name or "ndp").split(".")[0]
                if missing == "ndp" or name not in _EXTRAS:
                    raise
                print(_missing_extra_message(*_EXTRAS[name], missing), file=sys.stderr)
                return 2
        parser = build_parser()
        args = parser.parse_args(args_list)
        return int(args.func(args) or 0)
    except ModuleNotFoundError as exc:
        if (exc.name or "ndp").split(".")[0] == "ndp":
            raise
        # a third-party package of an extra that is not installed (a core-only install)
        print(
            f"ndp: error: {exc}: install the extras this command needs "
            f"({install_hint('rl')}; [envs], [il], [dev] for all)",
            file=sys.stderr,
        )
        return 2
    except (ValueError, OSError) as exc:  # bad input, unreadable or unwritable files
        print(f"ndp: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
