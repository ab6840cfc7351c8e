"""Typed configs as command lines: one dataclass tree per command, parsed by tyro.

Every field of a command's frozen config dataclass becomes one ``--field-name`` option (nested
configs are flattened: no ``--ppo.`` prefixes), its docstring becomes the help text, and
``bool`` fields get ``--x / --no-x``. :data:`HIDDEN` and :func:`cli` are the two annotations the
config modules use (both are no-ops when tyro, an extra of the package, is not installed, so the
configs themselves import without it).

Resuming: :func:`parse_config` takes the saved config as the default, so the options given on
the command line are exactly the fields that differ (:func:`changed_fields`), and a trainer can
refuse the ones that would change the run.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, TypeVar

T = TypeVar("T")

try:  # tyro is needed only to parse command lines
    import tyro.conf as _conf

    HIDDEN: Any = _conf.Suppress
    """Annotation: a derived field that is not an option (e.g. the head, which follows algo)."""

    def cli(name: str | None = None, aliases: Sequence[str] = (), help: str | None = None) -> Any:
        """Annotation: the option's name (without ``--``), extra spellings (with ``--``) and
        help text (None: the field's docstring)."""
        return _conf.arg(name=name, aliases=tuple(aliases) or None, help=help)

except ImportError:  # pragma: no cover - the layer-only install
    HIDDEN = None

    def cli(name: str | None = None, aliases: Sequence[str] = (), help: str | None = None) -> Any:
        return None


def parse_config(
    cls: type[T],
    args: Sequence[str],
    *,
    prog: str,
    description: str | None = None,
    default: T | None = None,
) -> T:
    """Parse ``args`` into ``cls`` (flat options; ``--help`` prints them and exits).

    Bad values exit with status 2 and a message naming the option (tyro's errors; a
    ``__post_init__`` ValueError is shown the same way).
    """
    import tyro

    parsed = tyro.cli(
        cls,
        args=list(args),
        prog=prog,
        description=description,
        default=default,
        config=(tyro.conf.OmitArgPrefixes,),
    )
    assert parsed is not None  # tyro returns the parsed instance (or exits)
    return parsed


def changed_fields(old: Any, new: Any, prefix: str = "") -> list[str]:
    """Dotted names of the leaf fields whose values differ between two configs of one class."""
    out: list[str] = []
    for f in dataclasses.fields(old):
        a, b = getattr(old, f.name), getattr(new, f.name)
        if dataclasses.is_dataclass(a) and dataclasses.is_dataclass(b):
            out += changed_fields(a, b, f"{prefix}{f.name}.")
        elif a != b:
            out.append(prefix + f.name)
    return out


def pop_flag(args: Sequence[str], flag: str) -> tuple[bool, list[str]]:
    """Remove every ``flag`` from ``args``; returns (whether it was there, the rest)."""
    rest = [a for a in args if a != flag]
    return len(rest) != len(args), rest


def pop_option(args: Sequence[str], flag: str) -> tuple[str | None, list[str]]:
    """Remove ``flag VALUE`` / ``flag=VALUE`` from ``args``; returns (value or None, the rest).

    Raises:
        ValueError: the flag is given without a value, or more than once.
    """
    rest: list[str] = []
    value: str | None = None
    it = iter(args)
    for a in it:
        if a == flag or a.startswith(flag + "="):
            if value is not None:
                raise ValueError(f"{flag}: given more than once")
            if a == flag:
                value = next(it, None)
                if value is None or value.startswith("--"):
                    raise ValueError(f"{flag}: expected a run directory after {flag}")
            else:
                value = a.split("=", 1)[1]
        else:
            rest.append(a)
    return value, rest


try:
    POSITIONAL: Any = _conf.Positional
    """Annotation: a positional argument (e.g. the run directory of ``ndp il eval RUN``)."""
except NameError:  # pragma: no cover - the layer-only install
    POSITIONAL = None
