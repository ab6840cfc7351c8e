"""Inference at a higher control rate: ``ndp rl eval RUN_DIR --exec-k K2``.

The NDP supplement notes that "at inference time, one can sample arbitrarily high value for k".
Here a policy trained with k sub-steps per decision runs each decision, of the SAME duration
``k * control_dt`` seconds, as ``K2 = k * m`` sub-steps of a finer env whose env step lasts
``control_dt / m`` seconds.

Clocks (docs/policies.md "Inference at a higher rate"):

- simulator step ``sim_dt``: unchanged;
- env step: ``control_dt / m`` s = ``frame_skip / m`` simulator steps, so m must divide the
  task's frame skip ``control_dt / sim_dt`` (:func:`ndp.envs.spec.substep_factors`:
  Meta-World 5 -> m in {1, 5}; Jaco 10 -> {1, 2, 5, 10}; the toy point mass has no simulator
  step below its env step -> {1}); at most one sub-step per simulator step;
- decision: ``K2 = k * m`` env steps, ``k * control_dt`` s as trained; the episode horizon is
  ``horizon * m`` env steps, the same seconds.

The finer env (:func:`ndp.envs.spec.finer_spec`, ``make_env(..., substeps=m)``) moves a delta
DoF ``action_scale / m`` per unit action and env step (the same speed per second), leaves
absolute commands (the Meta-World gripper) as they are, and on Meta-World keeps the
observation's previous-frame block one trained env step (m env steps) back.

What each method does at K2:

- NDP: the same network outputs (goal, weights, DMP start y0 / dy0 read at the decision start)
  and the same DMP over the decision, reported at K2 + 1 evenly spaced times instead of k + 1;
  the finer inverse controller maps these points to K2 actions. The trajectory is integrated
  with ``lcm(dmp_steps, K2)`` Euler steps (:func:`dmp_steps_at`): the smallest refinement of
  the trained Euler grid that holds every report time. Where K2 divides ``dmp_steps`` that IS
  the trained integration (the coarse points are unchanged); otherwise (35 steps, K2 = 25: 175)
  the Euler step shrinks and the points at the coarse times move by the difference of the two
  Euler discretisations of the same ODE (measured in tests/rl/test_exec_k.py).
- PPO-multi, PPO (k = 1) and Dyn-E: each of the k raw (decoded, for Dyn-E) actions is held for
  m env steps of the finer env, so a delta DoF moves 1/m of that action's displacement per env
  step (the same displacement per trained env step) and an absolute DoF keeps its command.
- VICES (torque-actuated rows): refused; its impedance controller already computes torques at
  every simulator step, so no finer control step exists.

Metrics: success (``success_any``, ``success_final``) is comparable across m (success is
checked at every env step, so at m > 1 at m times as many instants). The return is NOT: the
rewards of m times as many env steps are summed (and the stale-world rule takes its snapshot
after the first, shorter, sub-step). Stochastic NDP draws independent noise per finer sub-step.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ndp.policies.base import ActionHead
    from ndp.rl.policy import Policy
    from ndp.schema import TaskSchema


REFUSED_ACTUATION = {
    "torque": (
        "its impedance controller already computes torques at every simulator step, so there "
        "is no finer control step to run it at"
    ),
}
"""``TaskSpec.actuation`` -> why ``--exec-k`` is refused for policies on such rows (VICES)."""


def exec_k_values(policy: Policy) -> tuple[int, ...]:
    """The K2 a trained policy accepts: ``k * m`` for every m of
    :func:`ndp.envs.spec.substep_factors` of its task, ascending (``(k,)`` where refused)."""
    from ndp.envs.spec import substep_factors

    if policy.spec.actuation in REFUSED_ACTUATION:
        return (policy.cfg.k,)
    return tuple(policy.cfg.k * m for m in substep_factors(policy.spec))


def substeps_for(policy: Policy, exec_k: object) -> int:
    """m = ``exec_k / k`` after checking ``exec_k`` against :func:`exec_k_values`.

    Raises:
        ValueError: one line naming ``exec_k`` / ``--exec-k``: a refused method (VICES, with
            the reason), or a value that is not ``k * m`` with m a divisor of the task's frame
            skip (the allowed values listed).
    """
    from ndp.envs.spec import frame_skip

    cfg = policy.cfg
    reason = REFUSED_ACTUATION.get(policy.spec.actuation)
    if reason is not None:
        raise ValueError(f"exec_k (--exec-k): not available for {cfg.algo} runs: {reason}")
    allowed = exec_k_values(policy)
    if isinstance(exec_k, bool) or not isinstance(exec_k, int) or exec_k not in allowed:
        raise ValueError(
            f"exec_k (--exec-k): expected one of {', '.join(map(str, allowed))} for this "
            f"{cfg.algo} run on {policy.spec.name} (k={cfg.k} times a divisor of its "
            f"{frame_skip(policy.spec)} simulator steps per env step), got {exec_k!r}"
        )
    return exec_k // cfg.k


def dmp_steps_at(dmp_steps: int, exec_k: int) -> int:
    """Euler steps per decision of the NDP head at ``exec_k`` sub-steps: ``lcm(dmp_steps,
    exec_k)``, the smallest multiple of the trained steps that ``exec_k`` divides (equal to
    ``dmp_steps`` where ``exec_k`` already divides it: the trained integration unchanged)."""
    return math.lcm(int(dmp_steps), int(exec_k))


def ndp_head_at(policy: Policy, exec_k: int, spec: TaskSchema) -> ActionHead:
    """A new NDP head reporting the trained head's DMP at ``exec_k`` + 1 points per decision.

    Built with the run's policy config (k = ``exec_k``, ``dmp_steps`` = :func:`dmp_steps_at`)
    on the finer task row ``spec`` (``finer_spec(policy.spec, m)``: its inverse controller
    works in the finer env step's displacement ``action_scale / m``); the goal bound
    (``exec_k * action_scale / m`` = ``k * action_scale``), weight bound and decision duration
    (``exec_k * control_dt / m``) equal the trained ones, and the trained head's state (its log
    std) is loaded. The trained head is not touched.

    Returns:
        ``ndp.policies.heads.NDPHead`` with ``k == exec_k``, in eval mode: raw [B, D (1 + N)]
        and y0, dy0 [B, D] -> actions [B, exec_k, A].
    """
    from ndp.policies.heads import build_head

    pcfg = policy.cfg.policy
    if pcfg.head != "ndp" or pcfg.ndp.dmp_steps is None:
        raise ValueError(f"policy: expected a resolved NDP head, got head {pcfg.head!r}")
    cfg = pcfg.updated(k=exec_k, dmp_steps=dmp_steps_at(pcfg.ndp.dmp_steps, exec_k))
    head = build_head(cfg, spec)
    head.load_state_dict(policy.model.head.state_dict())
    return head.eval()


def at_exec_k(policy: Policy, exec_k: int, hold: bool = False) -> Policy:
    """An evaluation copy of ``policy`` executing each decision as ``exec_k`` sub-steps.

    The copy's ``spec`` is the finer row, ``substeps`` is m and ``make_env()`` builds the finer
    chunked env (``exec_k`` env steps per decision, ``horizon * m`` per episode). NDP gets a
    copy of the actor-critic whose head is :func:`ndp_head_at` (same weights; the critic, which
    evaluation does not use, keeps its k value heads); the other methods keep the model and
    hold each sub-action for m env steps (:meth:`Policy.act`). ``exec_k = k`` (m = 1) builds
    the same env and the same actions as the trained policy.

    Args:
        policy: a trained policy (``substeps == 1``).
        exec_k: K2, one of :func:`exec_k_values`.
        hold: every method, NDP included, holds its k trained sub-actions for m env steps (a
            diagnostic: for NDP it separates the finer env from the DMP's finer sampling).

    Raises:
        ValueError: see :func:`substeps_for`; or ``policy`` is already an exec-k copy.
    """
    from ndp.envs.spec import finer_spec

    if policy.substeps != 1:
        raise ValueError("policy: already an exec-k copy; call at_exec_k on the trained policy")
    m = substeps_for(policy, exec_k)
    spec = finer_spec(policy.spec, m)
    model = policy.model
    if policy.cfg.policy.head == "ndp" and not hold:
        model = copy.deepcopy(policy.model)
        model.head = ndp_head_at(policy, exec_k, spec)
        model.eval()
    return dataclasses.replace(policy, spec=spec, model=model, substeps=m)
