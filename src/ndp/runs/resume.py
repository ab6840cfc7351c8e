"""What a resume may change: one comparison of a run's saved config with the resuming one.

A run's identity is what its folder holds (its config, checkpoint and metrics), never the
spelling of its path: ``run_dir`` is where the run is now, so a run created as ``r/base`` resumes
as ``/abs/path/r/base``, from another working directory or after the folder moved to another
disk or machine. Every other field must match the checkpoint's unless the trainer's config
declares it safe on resume; a refused resume names each differing field with both values.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

    DataclassLike = DataclassInstance | type[DataclassInstance]
    """What ``dataclasses.fields`` takes: a dataclass instance or class."""

LOCATION_FIELDS = ("run_dir",)
"""Fields that say where the run is, not what it is: never compared on resume."""


def config_differences(
    saved: DataclassInstance, new: DataclassInstance, ignore: Iterable[str] = ()
) -> list[tuple[str, object, object]]:
    """``(dotted field, saved value, new value)`` for every field of two config dataclasses that
    differs, nested configs walked (``ppo.lr``), fields named in ``ignore`` (top level or
    dotted) and :data:`LOCATION_FIELDS` left out."""
    skip = set(ignore) | set(LOCATION_FIELDS)
    out: list[tuple[str, object, object]] = []

    def walk(a: DataclassLike, b: DataclassLike, prefix: str) -> None:
        for f in dataclasses.fields(a):
            name = prefix + f.name
            if name in skip:
                continue
            va, vb = getattr(a, f.name), getattr(b, f.name)
            if dataclasses.is_dataclass(va) and dataclasses.is_dataclass(vb):
                walk(va, vb, name + ".")
            elif va != vb:
                out.append((name, va, vb))

    walk(saved, new, "")
    return out


def check_resume(
    saved: DataclassInstance, new: DataclassInstance, safe: Iterable[str], where: object
) -> None:
    """Refuse a resume whose config differs from the checkpoint's outside ``safe`` fields.

    Raises:
        ValueError: one line naming the run, each differing field with the checkpoint's value
            and the requested one, and the fields that may change.
    """
    safe = tuple(safe)
    diff = config_differences(saved, new, ignore=safe)
    if diff:
        fields = "; ".join(f"{n}: {a!r} in the checkpoint, {b!r} now" for n, a, b in diff)
        raise ValueError(
            f"resume: {where}: the config differs from the checkpoint's in {fields} (only "
            f"{', '.join(safe)} may change on resume, and the run's location; start a new run "
            "for the others)"
        )
