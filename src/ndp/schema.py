"""The one task schema: what a task is, for a DMP, a policy and an export, without the
simulators.

:class:`TaskSchema` is declared once, here, at the bottom of the data flow: the DMP
coordinates, the action bounds and scale, the low-level controller, the clocks. The task table
(``ndp.envs.TaskSpec``, which imports gymnasium, MuJoCo and Meta-World) extends it with what
only the environments need (the Meta-World name, the NDP preset, aliases); a trained policy's
export (``policy.json``, field ``"spec"``) records exactly the schema's fields, and
``TaskSchema.from_record`` reads them back, so that ``ndp.load_policy(path).act(obs,
robot_state)`` runs with torch, numpy and safetensors only (:data:`PolicySpec`: the schema as
read from an export).

``spec_record(spec)`` writes the record; ``TaskSchema.from_record(record)`` reads it back.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import torch

from ndp.dmp.controllers import DeltaController

RECORD_FIELDS: dict[str, type | tuple[type, ...]] = {
    "name": str,
    "family": str,
    "env_id": str,
    "dmp_dofs": int,
    "dof_names": list,
    "dof_units": list,
    "y0_source": str,
    "action_dim": int,
    "action_low": list,
    "action_high": list,
    "action_scale": list,
    "action_absolute": list,
    "horizon": int,
    "control_dt": (int, float),
    "sim_dt": (int, float),
    "obs_dim": int,
    "actuation": str,
    "base_task": (str, type(None)),
}
"""Fields of ``policy.json``'s ``"spec"`` and their JSON types."""


class InverseController(Protocol):
    """Trajectory points [..., k+1, D] -> actions [..., k, A] (``ndp.dmp.controllers``)."""

    def __call__(
        self, traj: torch.Tensor, robot_pos: torch.Tensor | None = None, clip: bool = True
    ) -> torch.Tensor: ...


@dataclass(frozen=True)
class TaskSchema:
    """The fields of a task every layer reads: the task table's rows extend it
    (``ndp.envs.TaskSpec``), a trained policy acts with it and its export records it.

    ``controller`` is built from the action fields for position-actuated tasks where not given;
    torque-actuated rows of the task table hold their impedance controller, and a torque task
    read back from an export has none (its controller runs inside the env; its policies output
    its commands directly).
    """

    name: str
    """Canonical task name."""
    family: str
    """``"metaworld"``, ``"jaco"`` or ``"toy"``."""
    env_id: str
    """The gymnasium id of the task's per-step env."""
    dmp_dofs: int
    """D: coordinates a DMP drives (the length of the robot state ``y0`` / ``dy0``)."""
    dof_names: tuple[str, ...]
    """Name of each of the D coordinates."""
    dof_units: tuple[str, ...]
    """Unit of each of the D coordinates (``m``, ``rad``, ``cmd``)."""
    y0_source: str
    """Where the env reads the robot state, in words."""
    action_dim: int
    """A: size of one env action."""
    action_low: tuple[float, ...]
    """Lower action bounds [A]."""
    action_high: tuple[float, ...]
    """Upper action bounds [A]."""
    action_scale: tuple[float, ...]
    """Physical change per unit action, per DMP coordinate (0 where absolute)."""
    action_absolute: tuple[bool, ...]
    """True where the action is the trajectory value itself."""
    horizon: int
    """Default episode length in env steps."""
    control_dt: float
    """Seconds per env step (= per sub-step of a decision)."""
    sim_dt: float
    """Simulator step (s)."""
    obs_dim: int
    """Observation size."""
    actuation: Literal["position", "torque"] = "position"
    """``"position"`` or ``"torque"`` (VICES rows)."""
    base_task: str | None = None
    """Torque rows: the position-controlled task they vary; else None."""
    controller: InverseController | None = field(default=None, compare=False)
    """The low-level controller, trajectory points -> actions; None: a ``DeltaController``
    built from the ``action_*`` fields (position-actuated tasks)."""

    def __post_init__(self) -> None:
        if self.controller is None and self.actuation == "position":
            ctrl = DeltaController(
                scale=tuple(float(x) for x in self.action_scale),
                absolute=tuple(bool(x) for x in self.action_absolute),
                low=tuple(float(x) for x in self.action_low),
                high=tuple(float(x) for x in self.action_high),
            )
            object.__setattr__(self, "controller", ctrl)

    def inverse_controller(
        self, traj: torch.Tensor, robot_pos: torch.Tensor | None = None, clip: bool = True
    ) -> torch.Tensor:
        """Map DMP trajectory points to env actions with the task's controller.

        Args:
            traj: [..., k+1, D] trajectory points in physical units; ``traj[..., 0, :]`` is the
                robot's state at the decision.
            robot_pos: Optional [..., D] measured start replacing ``traj[..., 0, :]``.
            clip: Clip to the action bounds (False for a policy's mean).

        Returns:
            [..., k, A] actions, within ``[action_low, action_high]`` when ``clip``.
        """
        if self.controller is None:
            raise ValueError(
                f"spec: {self.name!r} is torque-actuated; its controller runs inside the env "
                "(install the [envs] extra to build it)"
            )
        return self.controller(traj, robot_pos, clip)

    @classmethod
    def from_record(cls, record: Any, source: str = "spec") -> TaskSchema:
        """The spec of a ``policy.json`` ``"spec"`` record.

        Raises:
            ValueError: a missing field or a value of the wrong type or length (one line naming
                ``source`` and the field).
        """
        check_record(record, source)
        kw = dict(record)
        for key in ("dof_names", "dof_units"):
            kw[key] = tuple(str(x) for x in kw[key])
        for key in ("action_low", "action_high", "action_scale"):
            kw[key] = tuple(float(x) for x in kw[key])
        kw["action_absolute"] = tuple(bool(x) for x in kw["action_absolute"])
        kw["control_dt"], kw["sim_dt"] = float(kw["control_dt"]), float(kw["sim_dt"])
        return cls(**{k: kw[k] for k in RECORD_FIELDS})


PolicySpec = TaskSchema
"""The schema as a trained policy's export records it (``TaskSchema.from_record``)."""


def spec_record(spec: TaskSchema) -> dict[str, Any]:
    """The ``"spec"`` record of ``policy.json`` for a task's schema (a ``TaskSpec`` row or a
    :class:`TaskSchema` read back): plain JSON values."""

    def floats(xs: Iterable[float]) -> list[float]:
        return [float(x) for x in xs]

    return {
        "name": str(spec.name),
        "family": str(spec.family),
        "env_id": str(spec.env_id),
        "dmp_dofs": int(spec.dmp_dofs),
        "dof_names": [str(x) for x in spec.dof_names],
        "dof_units": [str(x) for x in spec.dof_units],
        "y0_source": str(spec.y0_source),
        "action_dim": int(spec.action_dim),
        "action_low": floats(spec.action_low),
        "action_high": floats(spec.action_high),
        "action_scale": floats(spec.action_scale),
        "action_absolute": [bool(x) for x in spec.action_absolute],
        "horizon": int(spec.horizon),
        "control_dt": float(spec.control_dt),
        "sim_dt": float(spec.sim_dt),
        "obs_dim": int(spec.obs_dim),
        "actuation": str(spec.actuation),
        "base_task": None if spec.base_task is None else str(spec.base_task),
    }


def check_record(record: object, source: str = "spec") -> None:
    """Check a ``"spec"`` record's fields, types and lengths (``ValueError``, one line)."""
    if not isinstance(record, dict):
        raise ValueError(f"{source}: expected an object, got {type(record).__name__}")
    for key, types in RECORD_FIELDS.items():
        if key not in record:
            raise ValueError(f"{source}: missing field {key!r}")
        v = record[key]
        if isinstance(v, bool) or not isinstance(v, types):
            raise ValueError(f"{source}.{key}: expected {_names(types)}, got {type(v).__name__}")
    d, a = record["dmp_dofs"], record["action_dim"]
    if d < 1 or a < 1:
        raise ValueError(f"{source}: dmp_dofs and action_dim must be >= 1, got {d} and {a}")
    lengths = {
        "dof_names": d,
        "dof_units": d,
        "action_scale": d,
        "action_absolute": d,
        "action_low": a,
        "action_high": a,
    }
    for key, n in lengths.items():
        if len(record[key]) != n:
            raise ValueError(f"{source}.{key}: expected {n} values, got {len(record[key])}")
    for key in ("action_low", "action_high", "action_scale", "control_dt", "sim_dt"):
        vals = record[key] if isinstance(record[key], list) else [record[key]]
        if not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            for x in vals
        ):
            raise ValueError(f"{source}.{key}: expected finite numbers, got {record[key]!r}")
    if not all(isinstance(x, bool) for x in record["action_absolute"]):
        raise ValueError(f"{source}.action_absolute: expected true / false values")
    if record["actuation"] not in ("position", "torque"):
        raise ValueError(
            f"{source}.actuation: expected 'position' or 'torque', got {record['actuation']!r}"
        )


def _names(types: type | tuple[type, ...]) -> str:
    ts = types if isinstance(types, tuple) else (types,)
    return " or ".join("null" if t is type(None) else t.__name__ for t in ts)
