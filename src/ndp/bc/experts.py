"""Scripted experts for demonstrations: Meta-World's own policies, the Jaco Throw / Pick scripts
and the toy task's straight line.

An expert is an object with ``reset(env, obs, info)`` and ``act(env, obs, info) -> action [A]``
in [-1, 1]; ``env`` is the unwrapped task env, an :class:`ndp.envs.base.NDPEnv` (scripts may
read its simulator, as a human demonstrator sees the scene), ``obs`` and ``info`` what the
per-step env returned last.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Protocol, cast

import numpy as np

if TYPE_CHECKING:
    from metaworld.policies.policy import Policy

    from ndp.envs.base import NDPEnv
    from ndp.envs.jaco import JacoEnv
    from ndp.envs.spec import TaskSpec


class Expert(Protocol):
    """A per-step demonstrator."""

    def reset(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> None: ...

    def act(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> np.ndarray: ...


class MetaWorldExpert:
    """Meta-World's scripted policy of the task (``metaworld.policies.ENV_POLICY_MAP``)."""

    def __init__(self, name: str) -> None:
        from metaworld.policies import ENV_POLICY_MAP

        if name not in ENV_POLICY_MAP:
            raise ValueError(f"task: Meta-World ships no scripted policy for {name!r}")
        # (the map's values are concrete policies; mypy infers the abstract base's constructor)
        make: Callable[[], Policy] = ENV_POLICY_MAP[name]
        self.policy = make()

    def reset(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> None:
        pass

    def act(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> np.ndarray:
        return np.clip(np.asarray(self.policy.get_action(obs), dtype=np.float64), -1.0, 1.0)


class PointMassExpert:
    """Straight to the goal at full speed (the toy task: obs = position, velocity, goal)."""

    def reset(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> None:
        pass

    def act(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> np.ndarray:
        from ndp.envs.point_mass import ACTION_SCALE

        d = len(obs) // 3
        a: np.ndarray = np.clip((obs[2 * d :] - obs[:d]) / ACTION_SCALE, -1.0, 1.0)
        return a


class ThrowExpert:
    """Swing the grip site along a 40-degree line at ``speed`` m/s by resolved-rate control (arm
    Jacobian pseudo-inverse on the joint targets), open the hand at step ``release``."""

    def __init__(self, speed: float = 3.2, release: int = 17) -> None:
        self.speed, self.release, self.t = float(speed), int(release), 0

    def reset(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> None:
        self.t = 0

    def act(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> np.ndarray:
        import mujoco

        from ndp.envs import jaco as J

        jaco = cast("JacoEnv", env)  # the Throw task's env (registered for the family)
        m, d = jaco.model, jaco.data
        if self.t < self.release:
            jacp = np.zeros((3, m.nv))
            mujoco.mj_jacSite(m, d, jacp, None, m.site("jaco/hand/gripsite").id)
            arm_v = [m.joint(j).dofadr[0] for j in J.ARM_JOINTS]
            ramp = min(1.0, (self.t + 1) / 5)
            v = self.speed * np.array([0.0, np.cos(0.7), np.sin(0.7)]) * ramp
            dq = np.linalg.pinv(jacp[:, arm_v]) @ v * J.CONTROL_DT
            a = np.r_[dq / J.ARM_DELTA, 1.0]
        else:
            a = np.r_[np.zeros(6), -1.0]
        self.t += 1
        out: np.ndarray = np.clip(a, -1.0, 1.0)
        return out


class PickExpert:
    """Above the cube, down, close the fingers, lift: joint-target waypoints from the arm's
    inverse kinematics, approached at half the action bound."""

    def __init__(self) -> None:
        self.plan: list[tuple[np.ndarray, float, int]] = []

    def reset(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> None:
        from ndp.envs import jaco as J

        cube = np.asarray(obs[18:21], dtype=np.float64).copy()
        model = cast("JacoEnv", env).model  # the Pick task's env (registered for the family)
        above = J.jaco_ik(model, cube + np.array([0, 0, 0.15]), q0=J.PICK_HOME)
        grasp = J.jaco_ik(model, cube + np.array([0, 0, 0.03]), q0=above)
        lift = J.jaco_ik(model, cube + np.array([0, 0, 0.25]), q0=grasp)
        self.plan = [(above, -1.0, 30), (grasp, -1.0, 30), (grasp, 1.0, 25), (lift, 1.0, 40)]

    def act(self, env: NDPEnv, obs: np.ndarray, info: Mapping[str, object]) -> np.ndarray:
        from ndp.envs import jaco as J

        while self.plan and self.plan[0][2] <= 0:
            self.plan.pop(0)
        if not self.plan:
            hold: np.ndarray = np.r_[np.zeros(6), 1.0]
            return hold
        q, fingers, steps = self.plan[0]
        self.plan[0] = (q, fingers, steps - 1)
        a = np.clip((q - cast("JacoEnv", env).joint_targets[:6]) / J.ARM_DELTA, -1.0, 1.0) * 0.5
        out: np.ndarray = np.r_[a, fingers]
        return out


EXPERTS: dict[str, Callable[[TaskSpec], Expert]] = {}
"""Task name or robot family -> ``(task spec) -> a new expert``; a task's own entry wins over
its family's (:func:`register_expert`)."""


def register_expert(name: str, build: Callable[[TaskSpec], Expert]) -> None:
    """Give a task (its canonical name) or a whole robot family (``TaskSpec.family``) a scripted
    expert, so ``ndp il collect``, ``ndp il bc`` and the ``bc`` run kind work on it.

    Raises:
        ValueError: ``name`` has an expert already.
    """
    if name in EXPERTS:
        raise ValueError(f"name: {name!r} already has a scripted expert")
    EXPERTS[name] = build


def _point_mass(spec: TaskSpec) -> Expert:
    return PointMassExpert()


def _throw(spec: TaskSpec) -> Expert:
    return ThrowExpert()


def _pick(spec: TaskSpec) -> Expert:
    return PickExpert()


def _metaworld(spec: TaskSpec) -> Expert:
    return MetaWorldExpert(spec.name)


register_expert("toy", _point_mass)
register_expert("throw", _throw)
register_expert("pick", _pick)
register_expert("metaworld", _metaworld)


def expert_builder(task: str) -> Callable[[TaskSpec], Expert]:
    """The factory of a task's scripted expert (canonical name or alias): its own, else its
    family's.

    Raises:
        ValueError: the task has no expert (one line naming it and those that have one).
    """
    from ndp.envs.spec import get_task_spec

    spec = get_task_spec(task)
    build = EXPERTS.get(spec.name) or EXPERTS.get(spec.family)
    if build is None:
        raise ValueError(
            f"task: {spec.name} has no scripted expert (tasks or families with one: "
            + ", ".join(EXPERTS)
            + ")"
        )
    return build


def expert_for(task: str) -> Expert:
    """A new scripted expert of a task (:func:`expert_builder`).

    Raises:
        ValueError: the task has no expert (one line naming it).
    """
    from ndp.envs.spec import get_task_spec

    return expert_builder(task)(get_task_spec(task))
