"""Checks shared by the typed configs.

:func:`plain_numbers` runs first in every config's ``__post_init__``: numpy (or any other
``numbers``) scalars become Python ``bool`` / ``int`` / ``float``, so ``DMPConfig(n_basis=
np.int64(5))`` is the same config as ``DMPConfig(n_basis=5)`` (equal, hashable, JSON-ready)
instead of being refused as "not an integer"; a ``bool`` field holds True or False, never a
truthy string. Nothing here imports numpy or torch.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any


def _numpy_bool(value: Any) -> bool:
    """numpy's bool scalar (``numpy.bool_``, named ``numpy.bool`` from numpy 2), without
    importing numpy."""
    t = type(value)
    return t.__module__ == "numpy" and t.__name__ in ("bool_", "bool")


def plain_number(value: Any) -> Any:
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


def bool_field(field: dataclasses.Field[Any]) -> tuple[bool, bool]:
    """``(is a bool field, None allowed)`` from a dataclass field's annotation: ``bool``,
    ``bool | None`` or ``Optional[bool]``, bare or inside ``Annotated[...]`` (a string
    annotation under ``from __future__ import annotations`` or the type itself)."""
    t = field.type
    if t is bool:
        return True, False
    if not isinstance(t, str):
        return False, False
    t = t.replace(" ", "")
    if t.startswith("Annotated["):
        depth, end = 0, len(t)
        for i, ch in enumerate(t[len("Annotated[") :], start=len("Annotated[")):
            depth += ch == "["
            depth -= ch == "]"
            if ch == "," and depth == 0:
                end = i
                break
        t = t[len("Annotated[") : end]
    if t == "bool":
        return True, False
    return t in ("bool|None", "None|bool", "Optional[bool]"), True


def plain_numbers(config: Any) -> None:
    """Replace every numeric-scalar field of a (frozen) dataclass by its Python number
    (:func:`plain_number`); tuples of numbers too. A NaN or infinite number in any field is
    refused here, naming the field (no config field of the package takes one), and so is a
    field annotated ``bool`` holding anything but True / False (numpy's bool included): a
    truthy string such as ``"no"`` would otherwise read as True.

    Raises:
        ValueError: ``<field>: expected a finite number, got nan``; ``<field>: expected true
            or false, got 'no'``.
    """
    for f in dataclasses.fields(config):
        v = getattr(config, f.name)
        is_bool, optional = bool_field(f)
        if is_bool and not (isinstance(v, bool) or _numpy_bool(v) or (optional and v is None)):
            raise ValueError(f"{f.name}: expected true or false, got {v!r}")
        for x in v if isinstance(v, tuple) else (v,):
            if isinstance(x, numbers.Real) and not isinstance(x, bool) and not math.isfinite(x):
                raise ValueError(f"{f.name}: expected a finite number, got {x!r}")
        if isinstance(v, tuple):
            new: Any = tuple(plain_number(x) for x in v)
            if all(a is b for a, b in zip(new, v, strict=True)):
                continue
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
