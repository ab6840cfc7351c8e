"""The gymnasium ids of every task, as data, so they can be registered without importing the
simulators.

Two roads register the same ids: importing :mod:`ndp.envs` (which derives them from the task
tables, :func:`ndp.envs.factory.register_envs`), and, in an installed package, importing
``gymnasium`` alone: the start-up hook ``_ndp_gymnasium`` (loaded by ``_ndp_gymnasium.pth``)
calls :func:`register_shipped` once gymnasium has loaded, from the table shipped beside this
module (``gym_ids.json``). Entry points are strings, so registering imports no env class; the
first ``gymnasium.make("ndp/...")`` imports :mod:`ndp.envs`.

This module imports nothing heavy (gymnasium only inside :func:`register`), because the hook runs
inside ``import gymnasium``. ``tests/envs/test_gym_registration.py`` checks that the shipped table
equals the one the task tables give; after adding a task, rewrite it with
``python -c "from ndp.envs.factory import write_gym_id_table; write_gym_id_table()"``.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

TABLE = Path(__file__).with_name("gym_ids.json")
"""The shipped table: ``{"tasks": {name: [env_id, horizon]}, "chunked_ks": [k, ...],
"torque": {name: [env_id, horizon]}}``."""

LEGACY_IDS = frozenset({"ndp/JacoThrow-v0", "ndp/JacoPick-v0", "ndp/PointMass2D-v0",
                        "ndp/PointMass3D-v0"})  # fmt: skip
"""The built-in rows' older ids: each stays registered as a deprecated alias of ``ndp/<name>``
(a task a user registers keeps the id it gives, alone)."""

PER_STEP = "ndp.envs.factory:_make_registered"
CHUNKED = "ndp.envs.factory:_make_registered_chunked"


@dataclass(frozen=True)
class GymId:
    """One registration: the arguments of ``gymnasium.register``."""

    id: str
    """``ndp/<name>`` (per-step env) or ``ndp/<name>-k<k>`` (chunked env); a task row's older
    id (``ndp/JacoThrow-v0``) as a deprecated alias of ``ndp/<name>``."""
    entry_point: str
    """:data:`PER_STEP` or :data:`CHUNKED` (a string: registering imports no env class)."""
    kwargs: dict[str, Any] = field(default_factory=dict)
    """Passed to the entry point: ``{"name": task}``, plus ``"k"`` for a chunked id."""
    max_episode_steps: int = 0
    """The task's horizon in env steps; ``ceil(horizon / k)`` decisions for a chunked id."""
    disable_env_checker: bool = False
    """True for chunked ids (their info dict carries arrays the checker does not expect)."""


def expand(
    tasks: Mapping[str, tuple[str, int]],
    chunked_ks: Iterable[int] = (),
    torque: Mapping[str, tuple[str, int]] | None = None,
) -> list[GymId]:
    """The ids of a task table.

    Args:
        tasks: task name -> ``(env_id, horizon)``; each gets its per-step id and one chunked id
            per k in ``chunked_ks``.
        chunked_ks: k of the chunked ids.
        torque: torque-actuated rows, name -> ``(env_id, horizon)`` (per-step ids only).

    Returns:
        Per task its per-step id then its chunked ids, then the torque rows.
    """
    ks = [int(k) for k in chunked_ks]
    out: list[GymId] = []
    for name, (env_id, horizon) in tasks.items():
        # one scheme: ndp/<task name> and ndp/<task name>-k<k>; a task row's older id
        # (ndp/JacoThrow-v0, ndp/PointMass2D-v0) stays registered as a deprecated alias
        canonical = f"ndp/{name}"
        if env_id in LEGACY_IDS:
            out.append(GymId(canonical, PER_STEP, {"name": name}, int(horizon)))
            out.append(
                GymId(env_id, PER_STEP, {"name": name, "deprecated_id": canonical}, int(horizon))
            )
        else:
            out.append(GymId(env_id, PER_STEP, {"name": name}, int(horizon)))
        for k in ks:
            out.append(
                GymId(
                    f"ndp/{name}-k{k}", CHUNKED, {"name": name, "k": k}, -(-int(horizon) // k), True
                )
            )
    for name, (env_id, horizon) in (torque or {}).items():
        out.append(GymId(env_id, PER_STEP, {"name": name}, int(horizon)))
    return out


def shipped() -> list[GymId]:
    """The ids of the shipped table (:data:`TABLE`)."""
    data = json.loads(TABLE.read_text())
    return expand(
        {n: (e, h) for n, (e, h) in data["tasks"].items()},
        data["chunked_ks"],
        {n: (e, h) for n, (e, h) in data["torque"].items()},
    )


def register(ids: Iterable[GymId]) -> list[str]:
    """Register each id not yet registered (idempotent); returns every id given."""
    import gymnasium

    out = []
    for g in ids:
        if g.id not in gymnasium.registry:
            gymnasium.register(
                id=g.id,
                entry_point=g.entry_point,
                kwargs=dict(g.kwargs),
                max_episode_steps=g.max_episode_steps,
                disable_env_checker=g.disable_env_checker,
            )
        out.append(g.id)
    return out


def register_shipped() -> list[str]:
    """Register the shipped table's ids (what the start-up hook calls)."""
    return register(shipped())


def as_dicts(ids: Iterable[GymId]) -> list[dict[str, Any]]:
    """The ids as plain dicts (for comparisons and printing)."""
    return [asdict(g) for g in ids]
