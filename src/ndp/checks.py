"""Checks shared by the typed configs.

:func:`plain_numbers` runs first in every config's ``__post_init__``: numpy (or any other
``numbers``) scalars become Python ``bool`` / ``int`` / ``float``, so ``DMPConfig(n_basis=
np.int64(5))`` is the same config as ``DMPConfig(n_basis=5)`` (equal, hashable, JSON-ready)
instead of being refused as "not an integer"; a ``bool`` field holds True or False, never a
truthy string. Nothing here imports numpy or torch.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import typing
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from _typeshed import DataclassInstance


def _numpy_bool(value: object) -> bool:
    """numpy's bool scalar (``numpy.bool_``, named ``numpy.bool`` from numpy 2), without
    importing numpy."""
    t = type(value)
    return t.__module__ == "numpy" and t.__name__ in ("bool_", "bool")


def check_flag(name: str, value: object) -> bool:
    """``value`` as a bool when it is True / False (numpy's bool too); anything else, such as
    the truthy string ``"no"``, is refused (ValueError naming ``name``): a flag of the Python
    API (``act(deterministic=)``, ``ChunkedEnv(stale_world=)``)."""
    if not (isinstance(value, bool) or _numpy_bool(value)):
        raise ValueError(f"{name}: expected True or False, got {value!r}")
    return bool(value)


def plain_number(value: object) -> object:
    """``value`` as a Python bool / int / float when it is a non-Python numeric scalar (numpy's
    ``bool_``, integers and floats); anything else unchanged."""
    if type(value) in (bool, int, float) or isinstance(value, (str, bytes)):
        return value
    if _numpy_bool(value):  # numpy.bool_ is not a numbers.Number
        return bool(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    return value


@functools.cache
def _flag_fields(cls: type) -> dict[str, bool]:
    """A dataclass's fields annotated ``bool`` (False) or ``bool | None`` (True: None allowed),
    from its resolved annotations (``Annotated[...]`` extras stripped); once per class."""
    out: dict[str, bool] = {}
    for name, t in typing.get_type_hints(cls).items():
        if t is bool:
            out[name] = False
        elif typing.get_origin(t) is not None and set(typing.get_args(t)) == {bool, type(None)}:
            out[name] = True
    return out


def plain_numbers(config: DataclassInstance) -> None:
    """Replace every numeric-scalar field of a (frozen) dataclass by its Python number
    (:func:`plain_number`); tuples of numbers too. A NaN or infinite number in any field is
    refused here, naming the field (no config field of the package takes one), and so is a
    field annotated ``bool`` holding anything but True / False (numpy's bool included): a
    truthy string such as ``"no"`` would otherwise read as True.

    Raises:
        ValueError: ``<field>: expected a finite number, got nan``; ``<field>: expected true
            or false, got 'no'``.
    """
    flags = _flag_fields(config.__class__)
    for f in dataclasses.fields(config):
        v = getattr(config, f.name)
        if f.name in flags and not (
            isinstance(v, bool) or _numpy_bool(v) or (flags[f.name] and v is None)
        ):
            raise ValueError(f"{f.name}: expected true or false, got {v!r}")
        for x in v if isinstance(v, tuple) else (v,):
            if isinstance(x, numbers.Real) and not isinstance(x, bool) and not math.isfinite(x):
                raise ValueError(f"{f.name}: expected a finite number, got {x!r}")
        if isinstance(v, tuple):
            items = tuple(plain_number(x) for x in v)
            if all(a is b for a, b in zip(items, v, strict=True)):
                continue
            new: object = items
        else:
            new = plain_number(v)
            if new is v:
                continue
        object.__setattr__(config, f.name, new)


def check_device_available(device: str) -> None:
    """Refuse a torch device this machine cannot use, before anything is built or written.

    Raises:
        ValueError: a CUDA device on a torch without CUDA or without that many GPUs, or MPS
            where it is not available (one line naming the device and what is available).
    """
    import torch

    d = torch.device(device)
    if d.type == "cuda":
        n = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if n == 0:
            raise ValueError(
                f"device: {device!r} is not available: this torch has no usable CUDA device "
                f"(torch {torch.__version__}, CUDA build: {torch.version.cuda or 'no'}); use 'cpu'"
            )
        if d.index is not None and d.index >= n:
            raise ValueError(f"device: {device!r} is not available: {n} CUDA device(s) here")
    elif d.type == "mps" and not torch.backends.mps.is_available():
        raise ValueError(f"device: {device!r} is not available on this machine; use 'cpu'")


def check_int(name: str, value: object, low: int = 0, note: str = "") -> int:
    """``value`` as an int >= ``low`` (numpy integers accepted, bools refused).

    Raises:
        ValueError: ``"<name>: expected an integer >= <low>[ <note>], got <value!r>"``.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
        more = f" {note}" if note else ""
        raise ValueError(f"{name}: expected an integer >= {low}{more}, got {value!r}")
    return int(value)


def check_choice(name: str, value: object, choices: Sequence[str]) -> str:
    """``value`` as one of ``choices`` (strings).

    Raises:
        ValueError: ``"<name>: expected one of <a, b, ...>, got <value!r>"``.
    """
    if value not in choices:
        raise ValueError(f"{name}: expected one of {', '.join(choices)}, got {value!r}")
    return str(value)


def check_positive(name: str, value: object) -> float:
    """``value`` as a finite float > 0 (bools refused).

    Raises:
        ValueError: ``"<name>: expected a finite number > 0, got <value!r>"``.
    """
    if (
        isinstance(value, bool)
        or not isinstance(value, numbers.Real)
        or not math.isfinite(value)
        or value <= 0
    ):
        raise ValueError(f"{name}: expected a finite number > 0, got {value!r}")
    return float(value)


def check_unit_interval(name: str, value: object) -> None:
    """``value`` is a number in [0, 1] (a discount, GAE's lambda).

    Raises:
        ValueError: ``"<name>: expected a number in [0, 1], got <value!r>"``.
    """
    if not (isinstance(value, (int, float)) and 0.0 <= value <= 1.0):
        raise ValueError(f"{name}: expected a number in [0, 1], got {value!r}")


def install_hint(extra: str) -> str:
    """The install line for an optional extra, as a user can run it: the package is not on
    PyPI yet, so from a clone of the repository, pinned by its constraints file."""
    return f"pip install -c constraints.txt '.[{extra}]' in a clone of the repository"
