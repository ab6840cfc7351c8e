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
import json
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

T = TypeVar("T")

try:  # tyro is needed only to parse command lines
    import tyro.conf as _conf

    HIDDEN: Any = _conf.Suppress
    """Annotation: a derived field that is not an option (e.g. the head, which follows algo)."""

    def cli(
        name: str | None = None, aliases: Sequence[str] = (), help: str | None = None
    ) -> object:
        """Annotation: the option's name (without ``--``), extra spellings (with ``--``) and
        help text (None: the field's docstring)."""
        return _conf.arg(name=name, aliases=tuple(aliases) or None, help=help)

except ImportError:  # pragma: no cover - the layer-only install
    HIDDEN = None

    def cli(
        name: str | None = None, aliases: Sequence[str] = (), help: str | None = None
    ) -> object:
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


def read_config_file(path: str | Path) -> dict[str, Any]:
    """A config file as a dict: JSON (``.json``, e.g. a run's ``config.json``) or YAML
    (``.yaml`` / ``.yml``, rl-zoo's habit), either a whole config or some of its fields
    (sections nested: ``{"ppo": {"lr": 1e-4}, "policy": {"k": 5}}``).

    Raises:
        ValueError: a missing or unreadable file, another suffix, or a top level that is not
            a mapping (one line naming ``config`` and the file).
    """
    p = Path(path)
    if p.suffix.lower() not in (".json", ".yaml", ".yml"):
        raise ValueError(f"config: expected a .json, .yaml or .yml file, got {str(p)!r}")
    try:
        text = p.read_text()
    except OSError as exc:
        raise ValueError(f"config: cannot read {p} ({exc.strerror or exc})") from None
    try:
        if p.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            import yaml

            data = yaml.safe_load(text)
    except ImportError:
        raise ValueError("config: a YAML file needs PyYAML (the [rl] extra)") from None
    except Exception as exc:  # json / yaml parser errors, one line
        first = str(exc).splitlines()[0][:160] if str(exc) else type(exc).__name__
        raise ValueError(f"config: {p} is not valid {p.suffix[1:].upper()} ({first})") from None
    if not isinstance(data, dict):
        raise ValueError(f"config: {p}: expected a mapping of fields, got {type(data).__name__}")
    return data


def merge_config_dict(
    base: dict[str, Any], over: dict[str, Any], where: str = ""
) -> dict[str, Any]:
    """``base`` with ``over``'s values (nested dicts merged key by key).

    Raises:
        ValueError: a key of ``over`` that ``base`` does not have (naming its dotted path).
    """
    out = dict(base)
    for k, v in over.items():
        if k not in base:
            known = ", ".join(sorted(base))
            raise ValueError(f"config: unknown field {where + k!r} (known here: {known})")
        if isinstance(base[k], dict) and isinstance(v, dict):
            out[k] = merge_config_dict(base[k], v, f"{where}{k}.")
        else:
            out[k] = v
    return out


def changed_fields(
    old: DataclassInstance | type[DataclassInstance],
    new: DataclassInstance | type[DataclassInstance],
    prefix: str = "",
) -> list[str]:
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
