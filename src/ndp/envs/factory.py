"""One factory for every task, and gymnasium registration.

Ids: ``ndp/<name>`` for the per-step env (``ndp/push-v3``, ``ndp/throw``; the older
``ndp/JacoThrow-v0`` style ids are deprecated aliases) and
``ndp/<name>-k<k>`` for the chunked env with k sub-steps per decision (k in :data:`CHUNKED_KS`,
e.g. ``gymnasium.make("ndp/push-v3-k5")``). Each id has its ``max_episode_steps``: the task's
horizon in env steps (150), and ``ceil(horizon / k)`` decisions for the chunked ids, the same
length the env itself truncates at; a longer episode needs both ``horizon=`` (the env) and
``max_episode_steps=`` (gymnasium's ``TimeLimit``). The ids are registered when
:mod:`ndp.envs` is imported, and in an installed package already on ``import gymnasium`` (the
start-up hook described in :mod:`ndp.gym_ids`); ``gymnasium.make("ndp.envs:ndp/push-v3")``
(the module named in the id) works without the hook.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypedDict

import gymnasium as gym
import numpy as np

from ndp.checks import check_int
from ndp.envs.base import check_fixed_goal, defer_seed
from ndp.envs.chunked import ChunkedEnv
from ndp.envs.envpool_backend import EnvPoolMetaWorldEnv, check_backend
from ndp.envs.impedance import ImpedanceController
from ndp.envs.jaco import JacoEnv
from ndp.envs.metaworld_env import (
    V1_REWARD_BROKEN,
    MetaWorldEnv,
    check_reward_version,
    metaworld_env_names,
)
from ndp.envs.point_mass import PointMassEnv, PointMassOptions
from ndp.envs.release import RELEASE_GOAL_TASKS
from ndp.envs.rewards import RewardVariant, check_reward, check_smooth_lambda
from ndp.envs.spec import (
    TASKS,
    TORQUE_TASKS,
    TaskSpec,
    add_tasks,
    check_free,
    finer_spec,
    get_task_spec,
    jaco_spec,
    metaworld_spec,
    torque_rows,
    toy_spec,
)
from ndp.envs.torque import JacoTorqueEnv, MetaWorldTorqueEnv
from ndp.gym_ids import TABLE, expand, register
from ndp.io import atomic_write_text
from ndp.schema import TaskSchema, check_record, spec_record

if TYPE_CHECKING:
    from typing_extensions import Unpack


class _FrameOptions(TypedDict, total=False):
    """Env-class keywords every family takes (rendered frame size, the fixed goal)."""

    width: int
    height: int
    fixed_goal: int | str | None


class _MetaWorldTorqueOptions(_FrameOptions, total=False):
    camera_name: str
    reward_version: str


class _MetaWorldOptions(_MetaWorldTorqueOptions, total=False):
    substeps: int


class _JacoTorqueOptions(_FrameOptions, total=False):
    camera: str


class _JacoOptions(_JacoTorqueOptions, total=False):
    substeps: int


def _make_metaworld(
    spec: TaskSpec, horizon: int, render_mode: str | None, **kw: Unpack[_MetaWorldOptions]
) -> gym.Env:
    return MetaWorldEnv(
        spec.metaworld_name or spec.name, horizon=horizon, render_mode=render_mode, **kw
    )


def _make_jaco(
    spec: TaskSpec, horizon: int, render_mode: str | None, **kw: Unpack[_JacoOptions]
) -> gym.Env:
    return JacoEnv(spec.name, horizon=horizon, render_mode=render_mode, **kw)


def _make_toy(
    spec: TaskSpec, horizon: int, render_mode: str | None, **kw: Unpack[PointMassOptions]
) -> gym.Env:
    return PointMassEnv(dim=spec.dmp_dofs, horizon=horizon, render_mode=render_mode, **kw)


def _torque_metaworld(
    spec: TaskSpec, horizon: int, render_mode: str | None, **kw: Unpack[_MetaWorldTorqueOptions]
) -> gym.Env:
    task = spec.metaworld_name or spec.name
    return MetaWorldTorqueEnv(task, _impedance(spec), horizon, render_mode, **kw)


def _torque_jaco(
    spec: TaskSpec, horizon: int, render_mode: str | None, **kw: Unpack[_JacoTorqueOptions]
) -> gym.Env:
    if spec.base_task is None:
        raise ValueError(f"spec: the torque row {spec.name!r} names no base_task")
    return JacoTorqueEnv(spec.base_task, _impedance(spec), horizon, render_mode, **kw)


def _impedance(spec: TaskSpec) -> ImpedanceController | None:
    """The impedance controller of a torque-actuated row (None: the env's default); a position
    controller is refused, naming the row."""
    if spec.controller is not None and not isinstance(spec.controller, ImpedanceController):
        raise ValueError(f"spec: the torque row {spec.name!r} has no impedance controller")
    return spec.controller


FAMILIES: dict[str, Callable[..., gym.Env]] = {}
"""Task family -> ``(spec, horizon, render_mode, **kw) -> env``: filled by :func:`register_task`
(the built-in ``metaworld``, ``jaco`` and ``toy`` by :func:`register_builtin_families`)."""

TORQUE_FAMILIES: dict[str, Callable[..., gym.Env]] = {}
"""Task family -> env factory of its torque-actuated rows (``spec.actuation == "torque"``;
``register_task(..., torque=...)``)."""
CHUNKED_KS = (5,)
"""k of the registered chunked-env ids ``ndp/<name>-k<k>`` (any k: ``ndp.make_env``)."""


def make_env(
    name: str,
    *,
    seed: int | None = None,
    horizon: int | None = None,
    render_mode: str | None = None,
    substeps: int = 1,
    reward_version: str = "v2",
    fixed_goal: int | str | None = None,
    observation: str = "full",
    reward: str = "dense",
    smooth_lambda: float | None = None,
    backend: str = "metaworld",
    **kw: Any,
) -> gym.Env:
    """Create the plain per-step env of a task.

    Picklable factories work with ``gymnasium.vector.SyncVectorEnv`` / ``AsyncVectorEnv``, e.g.
    ``AsyncVectorEnv([lambda i=i: make_env("push-v3", seed=s + i) for i in range(n)])``.

    Args:
        name: Task name or alias (see :data:`ndp.envs.TASKS`).
        seed: Seed used by the first ``reset()`` that is not given one (object/goal sampling)
            and for the action space's sampler; None leaves both unseeded.
        horizon: Episode length in env steps; default ``spec.horizon`` (150) times
            ``substeps``. Meta-World's own is 500.
        render_mode: None or ``"rgb_array"``.
        substeps: m: each env step is ``1 / m`` of the task's (``ndp.envs.spec.finer_spec``:
            ``frame_skip / m`` simulator steps, ``action_scale / m`` per delta action); one of
            ``ndp.envs.spec.substep_factors(spec)`` (1 for the toy and torque-actuated rows).
        reward_version: ``"v2"`` (default) or ``"v1"``: Meta-World's reward function (v1: the
            shaped rewards the 2021 release trained on; success stays the v2 evaluation).
            Meta-World tasks only.
        fixed_goal: None (a fresh seeded task configuration every reset), the seed of the
            one configuration (objects, goal) every reset uses (:func:`fixed_goal_seed` derives
            it from a run's seed), or ``"release"``: the 2021 release's one hard-coded
            configuration (:mod:`ndp.envs.release`; push, soccer, faucet-open, Throw, Pick).
        observation: ``"full"`` (the task's observation) or ``"release9"`` (Meta-World only: the
            2021 release's 9 values, hand xyz, first object xyz, goal xyz; a
            :class:`ReleaseObservation` wrapper, the env's own state is unchanged).
        reward: ``"dense"`` (the env's own reward), ``"sparse"`` (1 at the first successful
            step, which ends the episode, else 0) or ``"smooth"`` (the env's reward minus
            ``smooth_lambda * ||a_t - a_{t-1}||^2``): :mod:`ndp.envs.rewards`. Success is the
            task's own under every variant.
        smooth_lambda: the smooth reward's price (None: ``ndp.envs.rewards.
            DEFAULT_SMOOTH_LAMBDA``); given with another reward: ValueError.
        backend: ``"metaworld"`` (default) or ``"envpool"``: the simulator of a Meta-World task
            (:mod:`ndp.envs.envpool_backend`; refused, naming ``backend``, for what it does not
            serve: other tasks, v1 rewards, fixed goals, substeps, rendering).
        **kw: Passed to the env class (``width``, ``height``, ``camera_name`` for Meta-World,
            ``camera`` for Jaco).

    Returns:
        A :class:`ndp.envs.metaworld_env.MetaWorldEnv` or :class:`ndp.envs.jaco.JacoEnv`
        (in a :class:`ndp.envs.rewards.RewardVariant` for a sparse or smooth reward).

    Raises:
        ValueError: unknown name (with close names), bad horizon, render mode, substeps,
            reward or smooth_lambda.
    """
    spec = get_task_spec(name)
    if substeps != 1:
        spec = finer_spec(spec, substeps)  # checks substeps against the task's factors
        kw["substeps"] = substeps
    horizon = _task_horizon(spec, horizon)
    kw.update(task_options(spec, reward_version, fixed_goal))
    release9 = check_observation(spec, observation) == "release9"
    reward = check_reward(reward)
    check_smooth_lambda(smooth_lambda, reward)  # before the env is built

    check_backend(backend, spec, reward_version=reward_version, fixed_goal=fixed_goal,
                  substeps=substeps, render_mode=render_mode)  # fmt: skip
    env = _build_env(spec, backend, horizon, render_mode, kw)
    defer_seed(env, seed)
    if reward != "dense":
        env = RewardVariant(env, reward, smooth_lambda)
    return ReleaseObservation(env) if release9 else env


def _task_horizon(spec: TaskSpec, horizon: int | None) -> int:
    """``horizon`` (None: the task's), refused unless a positive int."""
    if horizon is None:
        horizon = spec.horizon
    if isinstance(horizon, bool) or not isinstance(horizon, int) or horizon < 1:
        raise ValueError(f"horizon: expected a positive int, got {horizon!r}")
    return horizon


def _build_env(
    spec: TaskSpec, backend: str, horizon: int, render_mode: str | None, kw: dict[str, Any]
) -> gym.Env:
    """The task's env from its family's (or the envpool backend's) class, marked with its row."""
    families = TORQUE_FAMILIES if spec.actuation == "torque" else FAMILIES
    if spec.family not in families:
        raise ValueError(
            f"family: no env class for family {spec.family!r} of task {spec.name!r}"
            f" (known: {', '.join(families)})"
        )
    if backend == "envpool":
        if kw.keys() - {"reward_version"}:
            raise ValueError(f"backend: 'envpool' takes no env options, got {sorted(kw)}")
        env: gym.Env = EnvPoolMetaWorldEnv(spec.metaworld_name or spec.name, horizon)
    else:
        env = families[spec.family](spec, horizon, render_mode, **kw)
    env.unwrapped.ndp_task = spec.name  # type: ignore[attr-defined]  # the row (evaluation)
    return env


def task_options(
    spec: TaskSpec, reward_version: str = "v2", fixed_goal: object = None
) -> dict[str, Any]:
    """The env-class keywords of the task options, checked against the task's row.

    Raises:
        ValueError: a bad value, v1 rewards for a task that is not Meta-World's, or a Meta-World
            task whose v1 reward metaworld cannot run (named in the message).
    """
    reward_version = check_reward_version(reward_version)
    out: dict[str, Any] = {}
    if spec.family == "metaworld":
        if reward_version == "v1" and (spec.metaworld_name or spec.name) in V1_REWARD_BROKEN:
            raise ValueError(
                f"reward_version: {spec.name}'s v1 reward does not run in metaworld 3.1.1; use 'v2'"
            )
        out["reward_version"] = reward_version
    elif reward_version != "v2":
        raise ValueError(
            f"reward_version: 'v1' exists for Meta-World tasks only, got task {spec.name!r}"
        )
    goal = check_fixed_goal(fixed_goal)
    if goal == "release" and spec.name not in RELEASE_GOAL_TASKS:
        raise ValueError(
            f"fixed_goal: 'release' (the 2021 release's hard-coded configuration) exists for "
            f"{', '.join(RELEASE_GOAL_TASKS)}, not {spec.name!r}"
        )
    if goal is not None:
        out["fixed_goal"] = goal
    return out


OBSERVATIONS = ("full", "release9")
"""Observation filters of ``make_env(observation=...)``."""
RELEASE9 = (0, 1, 2, 4, 5, 6, 36, 37, 38)
"""Indices of the Meta-World observation the 2021 release's policies saw: hand xyz, the first
object's xyz, goal xyz."""


def check_observation(spec: TaskSchema, observation: object) -> str:
    """``observation`` checked against the task's row.

    Raises:
        ValueError: not one of :data:`OBSERVATIONS`, or ``release9`` for a task that is not
            Meta-World's.
    """
    if observation not in OBSERVATIONS:
        raise ValueError(f"observation: expected 'full' or 'release9', got {observation!r}")
    if observation == "release9" and spec.family != "metaworld":
        raise ValueError(
            f"observation: 'release9' exists for Meta-World tasks only, got task {spec.name!r}"
        )
    return str(observation)


class ReleaseObservation(gym.ObservationWrapper):
    """The 2021 release's 9-D Meta-World observation (:data:`RELEASE9`: hand, object, goal) in
    place of the 39 values; the env underneath, its rewards and the stale-world rule (which
    reads ``env.unwrapped``) are unchanged."""

    def __init__(self, env: gym.Env) -> None:
        import numpy as np
        from gymnasium import spaces

        super().__init__(env)
        box = env.observation_space
        assert isinstance(box, spaces.Box)  # the Meta-World observation
        idx = np.array(RELEASE9)
        self._idx = idx
        self.observation_space = spaces.Box(box.low[idx], box.high[idx], dtype=box.dtype)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        out: np.ndarray = observation[self._idx].copy()
        return out


def fixed_goal_seed(run_seed: int) -> int:
    """The ``fixed_goal`` of a run with ``goals="fixed"``: derived from the run's seed (distinct
    from its env reset seeds), so every env of the run, and its evaluation, share one goal and
    runs of other seeds have other goals."""
    import numpy as np

    return int(np.random.SeedSequence([int(run_seed), 0x6F41]).generate_state(1)[0])


GYM_ID_HORIZON = 10**9
"""The env's own horizon when it is made through a gymnasium id: gymnasium's ``TimeLimit``
(the registered horizon, or ``gymnasium.make(..., max_episode_steps=N)``) ends the episode.
gymnasium calls the entry point without N, so an env keeping the task's horizon (150 on
Meta-World) would end a longer episode early, silently."""


def _make_registered(name: str, deprecated_id: str | None = None, **kw: Any) -> gym.Env:
    """gymnasium entry point (per-step env); ``deprecated_id``: the id to use instead (the
    registration is an old name, said once per make). The env's own horizon is lifted
    (:data:`GYM_ID_HORIZON`) unless ``horizon`` is given."""
    if deprecated_id is not None:
        import warnings

        warnings.warn(
            f"this id is deprecated: use gymnasium.make({deprecated_id!r}) (ids are "
            "ndp/<task> and ndp/<task>-k<k>)",
            DeprecationWarning,
            stacklevel=3,
        )
    return make_env(name, **{"horizon": GYM_ID_HORIZON, **kw})


def _make_registered_chunked(name: str, k: int, stale_world: bool = True, **kw: Any) -> gym.Env:
    """gymnasium entry point (chunked env; its ``TimeLimit`` counts decisions of k env
    steps)."""
    env = make_env(name, **{"horizon": GYM_ID_HORIZON, **kw})
    return ChunkedEnv(env, k, stale_world=stale_world)


def register_torque_envs() -> list[str]:
    """Register the torque-actuated rows (``ndp/<name>``, per-step env only; idempotent).

    Returns:
        The registered ids, e.g. ``"ndp/push-v3-osc"``, ``"ndp/throw-joint"``.
    """
    return register(expand({}, (), {n: (s.env_id, s.horizon) for n, s in TORQUE_TASKS.items()}))


def register_envs() -> list[str]:
    """Register every task with gymnasium (idempotent), with its horizon as
    ``max_episode_steps`` (decisions for the chunked ids); :mod:`ndp.gym_ids` holds the rule.

    Returns:
        The registered ids, e.g. ``"ndp/push-v3"``, ``"ndp/throw"``.
    """
    return register(expand({n: (s.env_id, s.horizon) for n, s in TASKS.items()}, CHUNKED_KS))


def gym_id_table() -> dict[str, Any]:
    """The id table the task tables give, in the shape of the shipped one
    (:data:`ndp.gym_ids.TABLE`, which the start-up hook registers on ``import gymnasium``)."""
    return {
        "tasks": {n: [s.env_id, int(s.horizon)] for n, s in TASKS.items()},
        "chunked_ks": [int(k) for k in CHUNKED_KS],
        "torque": {n: [s.env_id, int(s.horizon)] for n, s in TORQUE_TASKS.items()},
    }


def write_gym_id_table() -> None:
    """Rewrite the shipped id table from the task tables (after adding a task)."""
    atomic_write_text(TABLE, json.dumps(gym_id_table(), indent=1) + "\n")


def register_task(
    spec: TaskSpec,
    make: Callable[..., gym.Env] | None = None,
    *,
    torque: Callable[..., gym.Env] | None = None,
    probe: bool = True,
) -> list[str]:
    """Add a task, and with ``make`` its robot family, so that everything built on the task
    table works on it: ``ndp.make_env(name, k)``, ``ndp rl train --task NAME`` (every method),
    evaluation, export, sweeps, and its gymnasium ids. A new robot family is one module that
    defines its env and calls this once per task; the built-in families are registered the same
    way (:func:`register_builtin_families`).

    Args:
        spec: the task's :class:`ndp.envs.spec.TaskSpec` row (its ``family`` names the family;
            ``ndp`` its NDP preset, else the default one).
        make: ``(spec, horizon, render_mode, **kw) -> env`` for a family not yet in
            :data:`FAMILIES` (the env: an :class:`ndp.envs.base.NDPEnv`, which the chunked env
            reads the robot state and the stale-world reward from); None: the family's
            existing factory.
        torque: the family's factory of torque-actuated envs (VICES; the rows of
            :func:`ndp.envs.spec.torque_rows`, which are then added with the task); None: the
            family's existing one, if any.
        probe: build the env once (reset with seed 0, one zero action) and check its
            observation, action and robot-state sizes against the row (the built-in tasks,
            registered at import, skip it; their tests build every one).

    Every field is checked (:func:`check_task_spec`) and the env probed before anything is
    added: a refused call leaves no trace (no task, alias, family or gymnasium id).

    Returns:
        The gymnasium ids registered (per-step and chunked; the torque rows' per-step ids).

    Raises:
        ValueError: a field of the row is malformed, the probed env disagrees with it, the
            name, an alias or the env id is taken, or the family has no factory (or already
            has another one); one line naming the field.
    """
    check_task_spec(spec)
    if make is None and spec.family not in FAMILIES:
        raise ValueError(
            f"make: family {spec.family!r} has no env factory yet ({', '.join(FAMILIES)}); "
            "pass make=(spec, horizon, render_mode, **kw) -> env"
        )
    for name, given, table in (("make", make, FAMILIES), ("torque", torque, TORQUE_FAMILIES)):
        if given is not None and table.get(spec.family, given) is not given:
            raise ValueError(f"{name}: family {spec.family!r} already has an env factory")
    family_torque = torque if torque is not None else TORQUE_FAMILIES.get(spec.family)
    rows = torque_rows(spec) if family_torque is not None else []
    if torque is not None and not rows:
        raise ValueError(
            f"torque: family {spec.family!r} has no torque-actuated rows (ndp.envs.spec."
            "torque_rows knows the impedance controllers of metaworld and jaco only)"
        )
    check_free([spec, *rows])  # before the probe builds anything
    if probe:
        probe_env(spec, make if make is not None else FAMILIES[spec.family])
    add_tasks([spec, *rows])  # all or none: a clash of any name adds nothing
    if make is not None:
        FAMILIES[spec.family] = make
    if torque is not None:
        TORQUE_FAMILIES[spec.family] = torque
    per_torque = {r.name: (r.env_id, r.horizon) for r in rows}
    return register(expand({spec.name: (spec.env_id, spec.horizon)}, CHUNKED_KS, per_torque))


_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
"""A task name, alias or family: what a command line, a file name and a gymnasium id take."""


def check_task_spec(spec: object) -> None:
    """Every field of a task row, before anything is registered.

    Raises:
        ValueError: one line naming ``spec.<field>``, the value and what was expected.
    """
    from gymnasium.envs.registration import parse_env_id

    if not isinstance(spec, TaskSpec):
        raise ValueError(f"spec: expected an ndp.envs.spec.TaskSpec row, got {type(spec).__name__}")
    for key in ("name", "family"):
        v = getattr(spec, key)
        if not (isinstance(v, str) and _NAME.match(v)):
            raise ValueError(
                f"spec.{key}: expected letters, digits, '.', '_' or '-' (not first), got {v!r}"
            )
    bad = [a for a in spec.aliases if not (isinstance(a, str) and _NAME.match(a))]
    if not isinstance(spec.aliases, tuple) or bad:
        raise ValueError(
            f"spec.aliases: expected a tuple of names like spec.name, got {spec.aliases!r}"
        )
    try:
        parse_env_id(spec.env_id)
    except Exception:  # gymnasium raises its own error kind
        raise ValueError(
            f"spec.env_id: expected a gymnasium id '[namespace/]name-vN', got {spec.env_id!r}"
        ) from None
    for key in ("horizon", "obs_dim", "dmp_dofs", "action_dim"):
        v = getattr(spec, key)
        check_int(f"spec.{key}", v, 1)
    try:
        record = spec_record(spec)
    except (TypeError, ValueError) as e:
        raise ValueError(f"spec: a field of {spec.name!r} is not of its type ({e})") from None
    check_record(record, "spec")  # types, lengths, finite numbers, actuation
    for key in ("control_dt", "sim_dt"):
        if not record[key] > 0:
            raise ValueError(f"spec.{key}: expected seconds > 0, got {record[key]!r}")
    if record["sim_dt"] > record["control_dt"]:
        raise ValueError(
            f"spec.sim_dt: expected at most control_dt ({record['control_dt']}), got "
            f"{record['sim_dt']}"
        )
    low, high = record["action_low"], record["action_high"]
    if any(lo >= hi for lo, hi in zip(low, high, strict=True)):
        raise ValueError(f"spec.action_low: expected below action_high, got {low} and {high}")


def probe_env(spec: TaskSpec, make: Callable[..., gym.Env]) -> None:
    """Build the row's env with its family's ``make``, reset it (seed 0), step it once with a
    zero action, and check what it returns against the row.

    Raises:
        ValueError: naming ``make`` (it failed) or the field the env disagrees with.
    """
    try:
        env = make(spec, spec.horizon, None)
    except Exception as e:  # a user's factory: any error is reported in one line
        raise ValueError(f"make: building {spec.name!r} failed ({type(e).__name__}: {e})") from None
    try:
        shapes = {}
        try:
            obs, _ = env.reset(seed=0)
            shapes["obs"] = np.shape(obs)
            shapes["action"] = tuple(env.action_space.shape or ())
            zero = np.zeros(shapes["action"], dtype=env.action_space.dtype)
            obs, *_ = env.step(zero)
            shapes["step obs"] = np.shape(obs)
            state = getattr(env.unwrapped, "robot_state", None)
            if callable(state):
                shapes["robot state"] = np.shape(state()[0])
        except Exception as e:
            raise ValueError(
                f"make: the env of {spec.name!r} fails on reset / step ({type(e).__name__}: {e})"
            ) from None
    finally:
        env.close()
    want = {
        "obs": ("obs_dim", (spec.obs_dim,)),
        "step obs": ("obs_dim", (spec.obs_dim,)),
        "action": ("action_dim", (spec.action_dim,)),
        "robot state": ("dmp_dofs", (spec.dmp_dofs,)),
    }
    for what, got in shapes.items():
        key, shape = want[what]
        if tuple(got) != shape:
            raise ValueError(
                f"spec.{key}: the row says {shape[0]}, but the env's {what} has shape {list(got)}"
            )


def register_builtin_families() -> None:
    """Register the built-in tasks through :func:`register_task`, as a user's family would: the
    50 Meta-World v3 tasks (with their ``-osc`` torque rows), Jaco ``throw`` / ``pick`` (with
    ``-joint`` / ``-osc``) and the toy point masses (2-D, 3-D). Called once, when
    :mod:`ndp.envs` is imported."""
    for name in metaworld_env_names():
        register_task(metaworld_spec(name), _make_metaworld, torque=_torque_metaworld, probe=False)
    for task in ("throw", "pick"):
        register_task(jaco_spec(task), _make_jaco, torque=_torque_jaco, probe=False)
    for dim in (2, 3):
        register_task(toy_spec(dim), _make_toy, probe=False)


register_builtin_families()
