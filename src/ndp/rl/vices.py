"""VICES (Martin-Martin et al., IROS 2019) and its two ablations as methods of the shared trainer.

VICES is PPO with another action space and another low-level controller: the policy acts on the
torque-actuated variant of the task (``ndp.envs.TORQUE_TASKS``), choosing a target displacement
and per-axis stiffness (and optionally damping) of the impedance controller of
``ndp.envs.impedance``, which computes torques at every simulator step.

- ``vices``: one decision per env step (the ``step`` head, k = 1); end-effector space (OSC) on
  Meta-World, joint space on Throw / Pick (the paper's default there).
- ``vices-pos``: as ``vices`` but in end-effector space on every task (Throw / Pick in OSC).
- ``vices-low-freq``: as ``vices`` but one decision per k = 5 env steps (as NDP decides): the
  ``hold`` head draws one action per decision (one log-prob) and the torque row with
  ``period`` 5 holds its target and gains for the k env steps.

The requested task may be a position-controlled row (``--task push-v3``: its torque variant is
used) or a torque row (``--task throw-joint-zeta``: learned damping; the method's space and
period still apply).
"""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from ndp.policies.distributions import ParamGaussian
from ndp.policies.heads import ActionHead, register_head
from ndp.rl.methods import Method, no_dmp, register_method

LOW_FREQ_K = 5
"""Env steps per decision of ``vices-low-freq`` (NDP's k)."""


class HoldHead(ActionHead):
    """One raw action per decision, executed for the k sub-steps (the env holds its target).

    A diagonal Gaussian over the action [A] with a learned, state-independent log std; one
    log-prob per decision (``per_decision``); the k sub-actions [B, k, A] are the sample
    repeated.
    """

    def __init__(self, k: int, action_dim: int, init_log_std: float = 0.0) -> None:
        super().__init__()
        self.k = int(k)
        self.action_dim = int(action_dim)
        self.n_params = self.action_dim
        self.log_std = nn.Parameter(torch.full((self.action_dim,), float(init_log_std)))

    def distribution(self, raw, y0=None, dy0=None):
        k = self.k

        def repeat(z: torch.Tensor) -> torch.Tensor:
            return z.unsqueeze(1).expand(-1, k, -1).contiguous()

        return ParamGaussian(raw, self.log_std, repeat), {}


@register_head("hold")
def _build_hold(cfg: Any, spec: Any) -> ActionHead:
    return HoldHead(cfg.k, spec.action_dim, cfg.init_log_std)


def _variant(space: str | None = None, period: int = 1) -> Any:
    def variant(spec: Any) -> Any:
        from ndp.envs import torque_variant

        return torque_variant(spec, space=space, period=period)

    return variant


def _resolve_low_freq(policy: Any, spec: Any) -> dict[str, Any]:
    """``k`` = the torque row's decision period (5)."""
    return {**no_dmp(policy, spec), "k": int(spec.controller.period)}


register_method(
    Method(
        "vices",
        "step",
        "VICES: PPO on the torque-actuated task, actions = target displacement + stiffness "
        "of an impedance controller at the simulator rate (OSC on Meta-World, joint space on "
        "Throw / Pick)",
        task_variant=_variant(None, 1),
        metrics=("ctrl/gains_clipped", "ctrl/torque_saturated", "ctrl/nonfinite"),
    )
)
register_method(
    Method(
        "vices-pos",
        "step",
        "VICES in end-effector space on every task (OSC; the Throw / Pick ablation)",
        task_variant=_variant("osc", 1),
        metrics=("ctrl/gains_clipped", "ctrl/torque_saturated", "ctrl/nonfinite"),
    )
)
register_method(
    Method(
        "vices-low-freq",
        "hold",
        f"VICES deciding once per k = {LOW_FREQ_K} env steps (as NDP), target and gains held",
        resolve=_resolve_low_freq,
        task_variant=_variant(None, LOW_FREQ_K),
        metrics=("ctrl/gains_clipped", "ctrl/torque_saturated", "ctrl/nonfinite"),
    )
)
