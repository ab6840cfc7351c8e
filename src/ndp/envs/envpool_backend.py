"""The EnvPool simulator backend of the Meta-World tasks (``--backend envpool``).

EnvPool 1.2.5 ships a C++ port of Meta-World v3 (``envpool.mujoco.metaworld``: the same MJCF
models, MuJoCo stepping and v2 rewards in C++). :class:`EnvPoolMetaWorldEnv` puts one of its
envs (``num_envs=1``) behind the interface of :class:`ndp.envs.metaworld_env.MetaWorldEnv`, so
that the chunked wrapper, the vector envs and every trainer run on it unchanged.

What it serves (:func:`check_backend` refuses the rest with one line naming ``backend``):

- the Meta-World v3 tasks with position (mocap) actuation, except those the equivalence check
  found to differ (:data:`ndp.envs.envpool_tasks.ENVPOOL_DIFFERING`);
- the live reward only: k = 1, or ``stale_world=False`` (the stale-world rule recomputes the
  reward on a world snapshot, which needs the simulator's state; EnvPool does not expose it);
- the v2 reward (the one EnvPool implements), dense, sparse or smooth (the last two are
  wrappers over it); random goals only (``fixed_goal`` None), ``substeps=1``, no rendering.

Observation: as the metaworld path's (39 float64 values, the goal visible: EnvPool's
``partially_observable`` config set to False). Seeds: ``reset(seed=s)`` builds the EnvPool env
with config ``seed = s mod 2**31``; its task configurations are then drawn from
``std::mt19937(seed)`` (a uniform per reset-vector entry, libstdc++'s ``generate_canonical``),
not from numpy's generator, so a seed gives other episodes than under the metaworld backend
(same distribution). :class:`StdUniform` reproduces that stream in numpy, which is how the
equivalence check (:mod:`ndp.envs.envpool_equivalence`) starts both backends in the same state.

Robot state: hand position = observation[0:3] (the metaworld path's ``hand`` body position,
the same numbers); hand velocity = the finite difference of it over the env step (the metaworld
path reads MuJoCo's instantaneous body velocity: the two differ, by an amount the equivalence
table reports); the commanded state is tracked in Python (mocap target = the previous one plus
``action * 0.01`` clipped to the task's mocap box, as metaworld's ``set_xyz_action``).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike

from ndp.checks import check_choice, install_hint
from ndp.envs import envpool_tasks
from ndp.envs.base import NDPEnv

if TYPE_CHECKING:
    from ndp.envs.spec import TaskSpec

BACKENDS = ("metaworld", "envpool")
"""Values of ``backend`` (``ndp rl train --backend``): metaworld's Python envs (the default)
or EnvPool's C++ port of them."""
ENVPOOL_VERSION = "1.2.5"
"""The EnvPool release this backend is written and checked against (the ``[envpool]`` extra)."""
ENVPOOL_SEED_MOD = 2**31
"""EnvPool's config seed is a C int: a reset seed ``s`` becomes ``s % ENVPOOL_SEED_MOD``."""
ENVPOOL_INFO_KEYS = (
    "success",
    "near_object",
    "grasp_success",
    "grasp_reward",
    "in_place_reward",
    "obj_to_target",
    "unscaled_reward",
)
"""metaworld's info keys, as EnvPool reports them (floats in the step info)."""


def check_backend_name(value: object) -> str:
    """``backend`` checked (one of :data:`BACKENDS`).

    Raises:
        ValueError: anything else (named in the message).
    """
    return check_choice("backend", value, BACKENDS)


def envpool_task_id(task: str) -> str:
    """EnvPool's id of a Meta-World v3 task: ``"push-v3"`` -> ``"MetaWorld/Push-v3"``."""
    name, version = task.rsplit("-", 1)
    return "MetaWorld/" + "".join(p[:1].upper() + p[1:] for p in name.split("-")) + f"-{version}"


def import_envpool() -> ModuleType:
    """``import envpool`` with the install hint when it is missing.

    Raises:
        ImportError: one line naming ``backend`` and the install command.
    """
    try:
        import envpool
    except ImportError:
        raise ImportError(
            f"backend: 'envpool' needs EnvPool {ENVPOOL_VERSION} ({install_hint('envpool')})"
        ) from None
    return envpool


def envpool_available() -> bool:
    """Whether EnvPool imports here."""
    try:
        import_envpool()
    except ImportError:
        return False
    return True


def check_backend(
    backend: object,
    spec: TaskSpec,
    *,
    k: int = 1,
    stale_world: bool = False,
    reward_version: str = "v2",
    fixed_goal: object = None,
    substeps: int = 1,
    render_mode: str | None = None,
) -> str:
    """``backend`` checked against the task and the run's options (module docstring).

    Args:
        backend: one of :data:`BACKENDS`.
        spec: the task's row (``ndp.envs.TaskSpec``).
        k: sub-steps per decision of the run.
        stale_world: the run's stale-world rule (matters at k > 1).
        reward_version: Meta-World's reward function asked for.
        fixed_goal: the task options' ``fixed_goal``.
        substeps: env-step subdivision (``ndp rl eval --exec-k``).
        render_mode: None or ``"rgb_array"``.

    Returns:
        The backend name.

    Raises:
        ValueError: one line naming ``backend`` and what was expected.
    """
    name_ok: str = check_backend_name(backend)
    if name_ok == "metaworld":
        return name_ok

    name = spec.metaworld_name or spec.name
    if spec.family != "metaworld" or getattr(spec, "actuation", "position") != "position":
        raise ValueError(
            f"backend: 'envpool' serves the position-actuated Meta-World v3 tasks, got task "
            f"{spec.name!r}; use --backend metaworld"
        )
    if name in envpool_tasks.ENVPOOL_DIFFERING:  # the module attribute: the generated list
        raise ValueError(
            f"backend: 'envpool' differs from metaworld on {name} beyond the stated tolerances "
            "(docs/results/envpool_equivalence/); use --backend metaworld"
        )
    if stale_world and k > 1:
        raise ValueError(
            f"backend: 'envpool' serves the live reward only (the stale-world rule needs the "
            f"simulator's state), got stale_world=True at k={k}; add --no-stale-world or use "
            "--backend metaworld"
        )
    if reward_version != "v2":
        raise ValueError(
            f"backend: 'envpool' implements Meta-World's v2 reward, got reward_version="
            f"{reward_version!r}; use --reward-version v2 or --backend metaworld"
        )
    if fixed_goal is not None:
        raise ValueError(
            f"backend: 'envpool' draws a fresh task configuration every reset (goals 'random'), "
            f"got fixed_goal={fixed_goal!r}; use --goals random or --backend metaworld"
        )
    if substeps != 1:
        raise ValueError(
            f"backend: 'envpool' runs metaworld's env step (substeps=1), got substeps="
            f"{substeps!r}; use --backend metaworld"
        )
    if render_mode is not None:
        raise ValueError(
            f"backend: 'envpool' does not render here, got render_mode={render_mode!r}; "
            "use --backend metaworld to render"
        )
    return name_ok


class StdUniform:
    """numpy's view of EnvPool's reset draws: ``std::mt19937(seed)`` and
    ``std::uniform_real_distribution<double>`` as libstdc++ computes them (two 32-bit words
    ``lo, hi`` per double: ``u = (lo + hi * 2**32) / 2**64``, then ``low + u * (high - low)``).

    ``uniform(low, high, size)`` draws entry by entry in order, as EnvPool's ``SampleRandVec``
    and metaworld's ``_get_state_rand_vec`` both do, so a metaworld env whose ``np_random`` is
    this object draws the reset vectors an EnvPool env of the same seed draws (rejection loops
    included).
    """

    def __init__(self, seed: int) -> None:
        """Args: seed: the EnvPool env's seed (config seed + env index), 0 <= seed < 2**32."""
        self._bits = np.random.MT19937()
        self._bits._legacy_seeding(int(seed))  # init_genrand(seed), as std::mt19937(seed)
        self._mark = self._bits.state

    def mark(self) -> None:
        """Remember the stream's position (:meth:`rewind` returns to it)."""
        self._mark = self._bits.state

    def rewind(self) -> None:
        """Return to the position of the last :meth:`mark`."""
        self._bits.state = self._mark

    def random(self, n: int) -> np.ndarray:
        """The next ``n`` doubles in [0, 1) of the stream, [n] float64."""
        words = self._bits.random_raw(2 * int(n)).astype(np.float64)
        u = (words[0::2] + words[1::2] * 2.0**32) / 2.0**64
        return np.minimum(u, np.nextafter(1.0, 0.0))  # libstdc++'s rounding guard

    def uniform(
        self, low: ArrayLike = 0.0, high: ArrayLike = 1.0, size: int | Sequence[int] | None = None
    ) -> np.ndarray | float:
        """``low + u * (high - low)`` per entry (numpy's broadcasting of ``low`` / ``high``)."""
        lo, hi = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
        shape = (
            np.broadcast_shapes(lo.shape, hi.shape) if size is None else tuple(np.atleast_1d(size))
        )
        n = int(np.prod(shape))
        u = self.random(n).reshape(shape)
        out = np.broadcast_to(lo, shape) + u * (
            np.broadcast_to(hi, shape) - np.broadcast_to(lo, shape)
        )
        return out if shape else float(out)


class MetaWorldFacts(TypedDict):
    """What :func:`metaworld_facts` reads from metaworld's env of a task."""

    observation_space: spaces.Box
    hand_init_pos: np.ndarray
    mocap_low: np.ndarray
    mocap_high: np.ndarray
    action_scale: float
    control_dt: float


@functools.cache
def metaworld_facts(task: str) -> MetaWorldFacts:
    """What the adapter takes from metaworld's own env of ``task`` (built once per process):
    the goal-visible observation space, the hand's reset position, the mocap box, the action
    scale and the control period (s)."""
    from metaworld.env_dict import ALL_V3_ENVIRONMENTS

    env = ALL_V3_ENVIRONMENTS[task]()
    env._partially_observable = False
    del env.sawyer_observation_space
    box = env.sawyer_observation_space
    facts: MetaWorldFacts = {
        "observation_space": spaces.Box(box.low, box.high, dtype=np.float64),
        "hand_init_pos": np.asarray(env.hand_init_pos, dtype=np.float64).copy(),
        "mocap_low": np.asarray(env.mocap_low, dtype=np.float64).copy(),
        "mocap_high": np.asarray(env.mocap_high, dtype=np.float64).copy(),
        "action_scale": float(env.action_scale),
        "control_dt": float(env.model.opt.timestep * env.frame_skip),
    }
    env.close()  # type: ignore[no-untyped-call]
    return facts


class EnvPoolMetaWorldEnv(NDPEnv):
    """One Meta-World v3 task simulated by EnvPool, behind :class:`MetaWorldEnv`'s interface.

    Observation [39] float64 as the metaworld path's (goal visible); actions [4] in ``[-1, 1]``
    (clipped); step info: metaworld's keys (:data:`ENVPOOL_INFO_KEYS`, floats) with
    ``success`` (bool), ``robot_pos`` [4], ``robot_vel`` [4], ``sim_unstable``. The robot state
    and seeds: the module docstring. No stale-world reward (``world_snapshot`` /
    ``stale_reward`` are absent: the chunked wrapper then refuses ``stale_world=True``).
    """

    metadata: dict[str, Any] = {"render_modes": [], "render_fps": 80}  # noqa: RUF012

    def __init__(self, task: str = "reach-v3", horizon: int = 150) -> None:
        """Create the env (EnvPool itself is built at the first reset, with its seed).

        Args:
            task: A Meta-World v3 name, e.g. ``"push-v3"``.
            horizon: Env steps per episode.

        Raises:
            ValueError: unknown task or bad horizon. ImportError: EnvPool missing.
        """
        from metaworld.env_dict import ALL_V3_ENVIRONMENTS

        if task not in ALL_V3_ENVIRONMENTS:
            raise ValueError(f"task: expected a Meta-World v3 name, got {task!r}")
        self._envpool = import_envpool()
        self._setup(horizon, None, action_dim=4)
        self.task = task
        self.reward_version = "v2"
        self.substeps = 1
        facts = metaworld_facts(task)
        self.observation_space = facts["observation_space"]
        self._hand_init = facts["hand_init_pos"]
        self._mocap_low, self._mocap_high = facts["mocap_low"], facts["mocap_high"]
        self._scale = facts["action_scale"]
        self.control_dt = facts["control_dt"]
        self._pool: Any = None
        self._obs: np.ndarray | None = None
        self._steps = 0
        self._gripper = -1.0
        self._gripper_rate = 0.0
        self._mocap = self._hand_init.copy()
        self._mocap_vel = np.zeros(3)
        self._vel = np.zeros(3)

    def _build(self, seed: int) -> None:
        """(Re)build the EnvPool env with config ``seed`` (closing the previous one)."""
        if self._pool is not None:
            self._pool.close()
        self._pool = self._envpool.make_gymnasium(
            envpool_task_id(self.task),
            num_envs=1,
            seed=int(seed) % ENVPOOL_SEED_MOD,
            partially_observable=False,
            max_episode_steps=int(self.horizon),
        )

    # ------------------------------------------------------------------ state access
    def robot_state(self) -> tuple[np.ndarray, np.ndarray]:
        """``(pos [4], vel [4])``: hand xyz (m, observation[0:3]) and the last gripper command;
        hand velocity over the last env step (m/s, finite difference) and the command's rate
        (before the first reset: the hand's reset position, at rest)."""
        hand = self._hand_init if self._obs is None else self._obs[:3]
        return np.append(hand, self._gripper), np.append(self._vel, self._gripper_rate)

    def command_state(self) -> tuple[np.ndarray, np.ndarray]:
        """``(pos [4], vel [4])``: the mocap target xyz (tracked) and the last gripper command;
        the target's velocity over the last env step and the command's rate."""
        return np.append(self._mocap, self._gripper), np.append(self._mocap_vel, self._gripper_rate)

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset: a fresh task configuration from EnvPool's seeded stream (a given or deferred
        seed rebuilds the EnvPool env with it; none continues the stream)."""
        explicit = seed if seed is not None else self._pending_seed
        self._reset_rng(seed)
        if explicit is not None or self._pool is None:
            s = int(explicit) if explicit is not None else int(self.np_random.integers(2**31))
            self._build(s)
        obs, _ = self._pool.reset()
        self._obs = np.asarray(obs[0], dtype=np.float64)
        self._steps = 0
        self._unstable = False
        self._gripper, self._gripper_rate = -1.0, 0.0
        self._mocap = self._hand_init.copy()
        self._mocap_vel = np.zeros(3)
        self._vel = np.zeros(3)
        pos, vel = self.robot_state()
        return self._obs.copy(), self._state_info(False, pos, vel)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One env step (see the class docstring for the returned info).

        Raises:
            ValueError: wrong shape or non-finite values in ``action``.
        """
        a = self._check_action(action)
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        self._check_running(self._steps)
        a = np.clip(a, -1.0, 1.0).astype(np.float32)
        obs, reward, _, _, ep_info = self._pool.step(a[None])
        self._steps += 1
        new = np.asarray(obs[0], dtype=np.float64)
        mocap = np.clip(self._mocap + a[:3].astype(np.float64) * self._scale,
                        self._mocap_low, self._mocap_high)  # fmt: skip
        self._mocap_vel = (mocap - self._mocap) / self.control_dt
        self._mocap = mocap
        self._gripper_rate = (float(a[3]) - self._gripper) / self.control_dt
        self._gripper = float(a[3])
        info: dict[str, Any] = {k: float(np.asarray(ep_info[k])[0]) for k in ENVPOOL_INFO_KEYS}
        if not np.all(np.isfinite(new)):
            pos, vel = self.robot_state()
            return self._unstable_step(self._obs.copy(), pos, vel, info)
        self._vel = (new[:3] - self._obs[:3]) / self.control_dt
        self._obs = new
        pos, vel = self.robot_state()
        info.update(self._state_info(info["success"] > 0.5, pos, vel))
        truncated = self._steps >= self.horizon
        return self._obs.copy(), float(np.asarray(reward)[0]), False, truncated, info

    def close(self) -> None:
        """Close the EnvPool env."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None
