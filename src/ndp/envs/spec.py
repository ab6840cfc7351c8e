"""Per-task spec table: what a DMP drives, in which units, and how trajectories become actions.

No code anywhere should branch on task-name strings; it reads a :class:`TaskSpec` instead.

Inverse controllers (``TaskSpec.controller``, data of the row: ``ndp.envs.controllers``; pure
torch, batched, differentiable up to the optional clip), today all ``DeltaController``:

- Meta-World (D = 4, A = 4): for sub-step ``t`` of a trajectory ``p`` [..., k+1, 4] in physical
  units, ``a[t, :3] = clip((p[t+1, :3] - p[t, :3]) / 0.01, -1, 1)`` (metaworld moves the hand
  target 0.01 m per unit action per step) and ``a[t, 3] = clip(p[t+1, 3], -1, 1)``: the DMP's
  fourth coordinate IS the absolute gripper command, so its ``y0`` is the last command sent
  (-1 = open after reset).
- Jaco (D = 7, A = 7): ``a[t] = clip((p[t+1] - p[t]) / scale, -1, 1)`` with ``scale`` =
  0.1 rad for the 6 arm joints and 0.1 rad for the tied finger coordinate (the env adds
  ``a * scale`` to its joint-position targets).

If ``robot_pos`` [..., D] is given it replaces ``p[..., 0, :]`` (the measured start).
A task with another actuation gets another controller in its row (``CONTROLLERS``).

Torque-actuated rows (:data:`TORQUE_TASKS`, the VICES baseline; ``ndp.envs.torque``): each is
its position-controlled row (``base_task``) with ``actuation="torque"`` and an
``ImpedanceController`` (``ndp.envs.impedance``) whose action layout sets ``action_dim``. Names:
``<task>-<space>[-zeta][-k<period>]`` with space ``osc`` (end-effector; every task) or ``joint``
(Jaco only), ``-zeta`` when the policy also chooses the damping ratio, ``-k5`` when it decides
once per 5 env steps (VICES low-frequency). Clocks: ``sim_dt`` is the controller's rate,
``control_dt`` the env step, ``controller.period * control_dt`` the policy's decision period.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import (
    Literal,  # noqa: F401  # the inherited fields' annotations resolve here
    TypeVar,
)

from ndp.dmp.controllers import DeltaController
from ndp.envs import jaco, point_mass, torque
from ndp.envs.base import divisors
from ndp.envs.impedance import ImpedanceController
from ndp.envs.metaworld_env import METAWORLD_POS_SCALE, REWARD_FROM_OBS
from ndp.envs.presets import DEFAULT as DEFAULT_PRESET
from ndp.envs.presets import NDP_PRESETS, NDPPreset
from ndp.schema import TaskSchema

SpecT = TypeVar("SpecT", bound=TaskSchema)
"""A task schema or a task-table row (:func:`finer_spec` keeps the type it is given)."""

Family = str
"""A robot family: ``"metaworld"``, ``"jaco"``, ``"toy"``, or one added with
:func:`ndp.envs.factory.register_task`."""


@dataclass(frozen=True)
class TaskSpec(TaskSchema):
    """A row of the task table: the task's schema (:class:`ndp.schema.TaskSchema`: DMP
    coordinates, actions, controller, clocks; what a policy and its export see), plus what
    only the environments and the trainer's presets need."""

    metaworld_name: str | None = None
    """The metaworld v3 name for Meta-World tasks, else None."""
    reward_from_obs: bool = False
    """The reward reads the world only through the observation, so the stale-world reward is
    the reward of the observation with the snapshot's world part (no kinematics pass);
    measured per task (``ndp.envs.metaworld_env.REWARD_FROM_OBS``)."""
    aliases: tuple[str, ...] = field(default=())
    """Other names :func:`get_task_spec` accepts for this task."""
    ndp: NDPPreset | None = None
    """The NDP head's per-task DMP settings (``ndp.envs.presets``); None: the task's row of
    ``NDP_PRESETS`` (or its ``DEFAULT``)."""
    controller: DeltaController | ImpedanceController | None = None
    """The low-level controller, trajectory points -> actions (``ndp.envs.controllers``); None:
    a :class:`DeltaController` built from the ``action_*`` fields. Torque-actuated rows hold an
    :class:`ndp.envs.impedance.ImpedanceController` (their action layout and gains)."""

    def __post_init__(self) -> None:
        if self.ndp is None:
            object.__setattr__(self, "ndp", NDP_PRESETS.get(self.name, DEFAULT_PRESET))
        super().__post_init__()


def metaworld_spec(name: str) -> TaskSpec:
    return TaskSpec(
        name=name,
        family="metaworld",
        env_id=f"ndp/{name}",
        dmp_dofs=4,
        dof_names=("hand_x", "hand_y", "hand_z", "gripper"),
        dof_units=("m", "m", "m", "cmd"),
        y0_source=(
            "hand body position (m) and its linear velocity (m/s) from MuJoCo; gripper: the last "
            "gripper command sent (-1 after reset) and its rate (1/s)"
        ),
        action_dim=4,
        action_low=(-1.0,) * 4,
        action_high=(1.0,) * 4,
        action_scale=(METAWORLD_POS_SCALE,) * 3 + (0.0,),
        action_absolute=(False, False, False, True),
        horizon=150,
        control_dt=0.0125,
        sim_dt=0.0025,
        obs_dim=39,
        metaworld_name=name,
        reward_from_obs=name in REWARD_FROM_OBS,
        aliases=(name.removesuffix("-v3"), f"metaworld-{name}"),
    )


def jaco_spec(task: str) -> TaskSpec:
    return TaskSpec(
        name=task,
        family="jaco",
        env_id=f"ndp/Jaco{task.capitalize()}-v0",
        dmp_dofs=7,
        dof_names=(*(j.split("/")[-1] for j in jaco.ARM_JOINTS), "fingers"),
        dof_units=("rad",) * 7,
        y0_source=(
            "arm joint angles (rad) and velocities (rad/s) from MuJoCo qpos/qvel; fingers: the "
            "mean of the three finger joint angles and velocities (the fingers are tied)"
        ),
        action_dim=7,
        action_low=(-1.0,) * 7,
        action_high=(1.0,) * 7,
        action_scale=(jaco.ARM_DELTA,) * 6 + (jaco.FINGER_DELTA,),
        action_absolute=(False,) * 7,
        horizon=150,
        control_dt=jaco.CONTROL_DT,
        sim_dt=jaco.SIM_DT,
        obs_dim=34,
        aliases=(f"jaco-{task}", f"Jaco{task.capitalize()}-v0", f"jaco_{task}"),
    )


def toy_spec(dim: int = 2, horizon: int | None = None) -> TaskSpec:
    """The toy point-mass task's row (``dim`` 2 or 3; ``ndp.envs.point_mass``)."""
    if dim not in (2, 3):
        raise ValueError(f"dim: expected 2 or 3, got {dim!r}")
    name = "point-mass" if dim == 2 else "point-mass-3d"
    return TaskSpec(
        name=name,
        family="toy",
        env_id=f"ndp/PointMass{dim}D-v0",
        dmp_dofs=dim,
        dof_names=("x", "y", "z")[:dim],
        dof_units=("m",) * dim,
        y0_source="the point's position (m) and velocity (m/s)",
        action_dim=dim,
        action_low=(-1.0,) * dim,
        action_high=(1.0,) * dim,
        action_scale=(point_mass.ACTION_SCALE,) * dim,
        action_absolute=(False,) * dim,
        horizon=int(point_mass.DEFAULT_HORIZON if horizon is None else horizon),
        control_dt=point_mass.CONTROL_DT,
        sim_dt=point_mass.CONTROL_DT,
        obs_dim=3 * dim,
        metaworld_name=None,
        aliases=(name.replace("-", "_"),),
    )


def ndp_preset(task: str) -> NDPPreset:
    """The NDP preset of a task (name or alias), as its task-table row holds it."""
    preset = get_task_spec(task).ndp
    assert preset is not None  # every row gets one in TaskSpec.__post_init__
    return preset


def frame_skip(spec: TaskSchema) -> int:
    """Simulator steps per env step, ``control_dt / sim_dt``: Meta-World 5, Jaco 10, the toy
    point mass 1 (it has no finer simulator step).

    Raises:
        ValueError: ``control_dt`` is not a whole multiple of ``sim_dt``.
    """
    ratio = float(spec.control_dt) / float(spec.sim_dt)
    n = round(ratio)
    if n < 1 or abs(ratio - n) > 1e-6 * n:
        raise ValueError(
            f"spec: control_dt={spec.control_dt} is not a whole multiple of sim_dt={spec.sim_dt}"
        )
    return n


def substep_factors(spec: TaskSchema) -> tuple[int, ...]:
    """The m a task's env step can be cut into (``finer_spec``, ``make_env(substeps=m)``): the
    divisors of its :func:`frame_skip` (Meta-World (1, 5), Jaco (1, 2, 5, 10), toy (1,)), so
    that every shorter env step is still a whole number of simulator steps; (1,) for
    torque-actuated rows, whose controller already acts at every simulator step."""
    if spec.actuation != "position":
        return (1,)
    return divisors(frame_skip(spec))


def finer_spec(spec: SpecT, m: int) -> SpecT:
    """The row of the same task with each env step cut into ``m`` shorter ones.

    One env step lasts ``control_dt / m`` s (``frame_skip / m`` simulator steps), the default
    horizon is ``horizon * m`` env steps (the same seconds), a delta DoF moves
    ``action_scale / m`` per unit action and env step (the same speed per second) and an
    absolute DoF (the Meta-World gripper) is unchanged; the inverse controller is rebuilt from
    these fields. ``m = 1`` gives a row equal to ``spec``.

    Args:
        spec: a position-controlled row.
        m: one of :func:`substep_factors` ``(spec)``.

    Raises:
        ValueError: ``m`` is not one of the task's factors (the message lists them).
    """
    allowed = substep_factors(spec)
    if isinstance(m, bool) or not isinstance(m, int) or m not in allowed:
        raise ValueError(
            f"m (substeps): expected one of {', '.join(map(str, allowed))} for {spec.name!r} "
            f"(divisors of its {frame_skip(spec)} simulator steps per env step), got {m!r}"
        )
    return dataclasses.replace(
        spec,
        control_dt=float(spec.control_dt) / m,
        horizon=int(spec.horizon) * m,
        action_scale=tuple(float(s) / m for s in spec.action_scale),
        controller=None,  # rebuilt from the action_* fields in __post_init__
    )


def torque_task_name(base: str, space: str, learn_damping: bool = False, period: int = 1) -> str:
    """Name of a torque-actuated row: ``<base>-<space>[-zeta][-k<period>]``."""
    return (
        f"{base}-{space}"
        + ("-zeta" if learn_damping else "")
        + (f"-k{period}" if period > 1 else "")
    )


TORQUE_PERIODS = (1, 5)
"""Decision periods (env steps) of the torque-actuated rows: every step (VICES) and 5 (VICES
low-frequency, one decision per k = 5 env steps as NDP decides)."""


def _torque_spec(base: TaskSpec, space: str, learn_damping: bool, period: int) -> TaskSpec:
    if base.family == "metaworld":
        ctrl = torque.sawyer_controller(learn_damping, period)
    else:
        ctrl = torque.jaco_controller(space, learn_damping, period)
    name = torque_task_name(base.name, space, learn_damping, period)
    a = ctrl.action_dim
    return dataclasses.replace(
        base,
        name=name,
        env_id=f"ndp/{name}",
        action_dim=a,
        action_low=(-1.0,) * a,
        action_high=(1.0,) * a,
        controller=ctrl,
        actuation="torque",
        base_task=base.name,
        aliases=(),
    )


def torque_rows(base: TaskSpec) -> list[TaskSpec]:
    """The torque-actuated rows of a position-controlled row: every space of its family
    (Meta-World: ``osc``; Jaco: ``joint`` and ``osc``), with and without a learnt damping ratio,
    at each of :data:`TORQUE_PERIODS`; none for a family without an impedance controller."""
    spaces = {"metaworld": ("osc",), "jaco": ("joint", "osc")}.get(base.family, ())
    if base.actuation != "position":
        return []
    return [
        _torque_spec(base, space, damping, period)
        for space in spaces
        for damping in (False, True)
        for period in TORQUE_PERIODS
    ]


TASKS: dict[str, TaskSpec] = {}
"""name -> TaskSpec of every position-controlled task: the 50 Meta-World v3 tasks,
``"throw"`` / ``"pick"``, the toy ``"point-mass"`` / ``"point-mass-3d"``, and any task a user
added. Filled by :func:`ndp.envs.factory.register_task` only, the built-in families included
(:func:`ndp.envs.factory.register_builtin_families`, when :mod:`ndp.envs` is imported)."""

TORQUE_TASKS: dict[str, TaskSpec] = {}
"""name -> TaskSpec of the torque-actuated variants (VICES): ``push-v3-osc``, ``throw-joint``,
``throw-osc``, ... (see the module docstring; :func:`torque_rows`); looked up by
:func:`get_task_spec` like :data:`TASKS`, added with their position row by ``register_task``."""

_ALIASES: dict[str, str] = {}


def torque_variant(
    spec: TaskSpec,
    space: str | None = None,
    learn_damping: bool | None = None,
    period: int | None = None,
) -> TaskSpec:
    """The torque-actuated row of a task (a torque row maps to its sibling).

    Args:
        spec: any row with a torque variant (Meta-World, Jaco; or a torque row).
        space: ``"osc"`` or ``"joint"``; None: the row's own (torque rows), else ``"osc"`` for
            Meta-World and ``"joint"`` for the Jaco tasks (VICES's defaults).
        learn_damping: None: the row's own (False for position rows).
        period: decision period in env steps; None: the row's own (1 for position rows).

    Raises:
        ValueError: the task has no such variant (e.g. the toy point mass).
    """
    ctrl = spec.controller if isinstance(spec.controller, ImpedanceController) else None
    base = spec.base_task or spec.name
    if space is None:
        if ctrl is not None:
            space = "osc" if ctrl.space == "ee" else "joint"
        else:
            space = "osc" if spec.family == "metaworld" else "joint"
    if learn_damping is None:
        learn_damping = bool(ctrl.learn_damping) if ctrl is not None else False
    if period is None:
        period = ctrl.period if ctrl is not None else 1
    name = torque_task_name(base, space, learn_damping, period)
    if name not in TORQUE_TASKS:
        raise ValueError(f"task: {spec.name!r} has no torque-actuated variant {name!r}")
    return TORQUE_TASKS[name]


def add_task(spec: TaskSpec) -> TaskSpec:
    """Add a row to :data:`TASKS` or, for a torque-actuated row, :data:`TORQUE_TASKS` (and its
    names to the lookup of :func:`get_task_spec`); :func:`ndp.envs.factory.register_task` is
    the public way, which also gives the family its env factory, adds the row's torque variants
    and registers the gymnasium ids.

    Raises:
        ValueError: the name, an alias or the env id already names a task.
    """
    return add_tasks([spec])[0]


def check_free(specs: Sequence[TaskSpec]) -> None:
    """Every name, alias and env id of ``specs`` is free (in the tables and among the rows).

    Raises:
        ValueError: naming the first one taken (``name: ...``).
    """
    seen: dict[str, str] = {}
    for spec in specs:
        for n in dict.fromkeys((spec.name, *spec.aliases, spec.env_id)):
            if n in TASKS or n in TORQUE_TASKS or n in _ALIASES:
                raise ValueError(f"name: {n!r} already names a task ({_ALIASES.get(n, n)})")
            if n in seen:
                raise ValueError(f"name: {n!r} names two of the new rows ({seen[n]}, {spec.name})")
            seen[n] = spec.name


def add_tasks(specs: Sequence[TaskSpec]) -> list[TaskSpec]:
    """Add several rows as one: every name, alias and env id is checked (against the tables
    and against each other) before any row is added, so a clash adds none of them.

    Raises:
        ValueError: a name, an alias or an env id already names a task, or two of the rows
            share one; nothing was added.
    """
    check_free(specs)
    for spec in specs:
        table = TORQUE_TASKS if spec.actuation == "torque" else TASKS
        table[spec.name] = spec
        _ALIASES.update({a: spec.name for a in (*spec.aliases, spec.env_id)})
    return list(specs)


def get_task_spec(name: str) -> TaskSpec:
    """Look up a task by name or alias.

    Args:
        name: e.g. ``"push-v3"``, ``"throw"``, ``"jaco-pick"``.

    Returns:
        The task's :class:`TaskSpec`.

    Raises:
        ValueError: unknown name; the message lists the closest known names.
    """
    if not isinstance(name, str):
        raise ValueError(f"task: expected a task name string, got {type(name).__name__}")
    if name in TASKS:
        return TASKS[name]
    if name in TORQUE_TASKS:
        return TORQUE_TASKS[name]
    if name in _ALIASES:
        key = _ALIASES[name]
        return TASKS[key] if key in TASKS else TORQUE_TASKS[key]
    close = difflib.get_close_matches(name, list(TASKS) + list(_ALIASES), n=5, cutoff=0.5)
    hint = ", ".join(close) if close else "see ndp.envs.TASKS"
    raise ValueError(f"task: unknown task {name!r}; close names: {hint}")
