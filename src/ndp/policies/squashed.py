"""Squashed-Gaussian heads for the SAC family (``ndp.rl.sac``): a state-dependent Gaussian over
a decision's raw parameters ``u`` [B, P], bounded by tanh, and a deterministic map from ``u`` to
the decision's k sub-actions [B, k, A].

- ``"squashed"`` (SAC at k = 1, chunked SAC at k > 1): P = k * A; the sub-actions are
  ``low + (tanh(u) + 1) / 2 * (high - low)``, reshaped [B, k, A] (always inside the bounds).
- ``"ndp-squashed"`` (NDP-SAC): P = D (1 + N) DMP parameters; the sub-actions are the NDP
  head's decode of ``u`` (goal and forcing weights bounded by tanh inside it, the DMP
  integrated from the robot state, the inverse controller): :class:`ndp.policies.heads.NDPHead`
  as it is, in its parameter-space form.

The actor's last layer gives ``2 P`` numbers: the mean of ``u`` and its log std (clamped to
[:data:`LOG_STD_MIN`, :data:`LOG_STD_MAX`], SAC's usual range). The density of a decision is
that of the bounded parameters ``tanh(u)``::

    log pi(tanh(u) | s) = sum_p [ log N(u_p; mu_p, sigma_p) - log(1 - tanh(u_p)^2) ]

(one log-prob per decision), which is what SAC's entropy term and temperature read. The
deterministic policy (evaluation, export, ``ndp.load_policy``) is ``decode(mu)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import torch
from torch import nn

from ndp.policies.base import HEAD_BUILDERS, ActionHead, decision_k, register_head
from ndp.policies.distributions import ParamGaussian, gaussian_draw

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from ndp.policies.config import PolicyConfig
    from ndp.schema import TaskSchema

LOG_STD_MIN = -20.0
"""Smallest log std of the raw parameters (SAC's usual bound)."""
LOG_STD_MAX = 2.0
"""Largest log std of the raw parameters."""


def tanh_log_det(u: torch.Tensor) -> torch.Tensor:
    """``log(1 - tanh(u)^2)`` [..., P], computed stably as ``2 (log 2 - u - softplus(-2 u))``."""
    return 2.0 * (math.log(2.0) - u - torch.nn.functional.softplus(-2.0 * u))


class SquashedGaussian(ParamGaussian):
    """A state-dependent diagonal Gaussian over raw parameters ``u`` [B, P], bounded by tanh;
    one log-prob per decision (a :class:`ndp.policies.distributions.PolicyDistribution`;
    sampling, the mode and the actions are :class:`ndp.policies.distributions.ParamGaussian`'s).

    Args:
        mean: [B, P].
        log_std: [B, P] (already clamped).
        decode: ``u`` [B, P] -> sub-actions [B, k, A] (differentiable).
    """

    def decode(self, u: torch.Tensor) -> torch.Tensor:
        """Sub-actions [B, k, A] of raw parameters ``u`` [B, P], with the gradient (the actor's
        loss reaches the parameters through it)."""
        return self._decode(u)

    def rsample(self, generator: torch.Generator | None = None) -> torch.Tensor:
        """A reparameterised draw of ``u`` [B, P] (gradient to the mean and std)."""
        return gaussian_draw(self.mean, self.log_std, generator)

    def log_prob(self, u: torch.Tensor) -> torch.Tensor:
        """Log density of the bounded parameters ``tanh(u)`` [B, 1] (see the module docstring)."""
        var = (2.0 * self.log_std).exp()
        gauss = -((u - self.mean) ** 2) / (2.0 * var) - self.log_std - 0.5 * math.log(2 * math.pi)
        return (gauss - tanh_log_det(u)).sum(-1, keepdim=True)

    def entropy(self) -> torch.Tensor:
        """Entropy of the Gaussian over ``u`` [B, 1] (the bounded parameters' entropy has no
        closed form; SAC estimates it from :meth:`log_prob` of a sample)."""
        return (self.log_std + 0.5 * math.log(2 * math.pi * math.e)).sum(-1, keepdim=True)


def split_mean_log_std(raw: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The actor's output [B, 2P] -> mean [B, P] and clamped log std [B, P]."""
    mean, log_std = raw.chunk(2, dim=-1)
    return mean, log_std.clamp(LOG_STD_MIN, LOG_STD_MAX)


class SquashedHead(ActionHead):
    """A head whose actor output [B, 2P] is a squashed Gaussian's mean and log std over P raw
    parameters; a subclass says how raw parameters become the k sub-actions."""

    def decode(self, u: torch.Tensor) -> torch.Tensor:
        """``u`` [B, P] -> sub-actions [B, k, A] (heads that do not read the robot state)."""
        raise NotImplementedError

    def decoder(
        self, y0: torch.Tensor | None, dy0: torch.Tensor | None
    ) -> Callable[[torch.Tensor], torch.Tensor]:
        """``u`` [B, P] -> sub-actions [B, k, A] for the decision's robot state (default:
        :meth:`decode`, which does not read it)."""
        return self.decode

    def distribution(
        self, raw: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> tuple[SquashedGaussian, dict[str, torch.Tensor]]:
        mean, log_std = split_mean_log_std(raw)
        return SquashedGaussian(mean, log_std, self.decoder(y0, dy0)), {}


class SquashedActionHead(SquashedHead):
    """SAC's head: k actions per decision (k = 1: SAC; k > 1: chunked SAC), each inside the
    task's action bounds by ``tanh``.

    Args:
        k: sub-steps per decision.
        action_dim: A.
        low, high: the action bounds [A].
    """

    low: torch.Tensor
    high: torch.Tensor

    def __init__(
        self, k: int, action_dim: int, low: ArrayLike | torch.Tensor, high: ArrayLike | torch.Tensor
    ) -> None:
        super().__init__()
        self.k, self.action_dim = int(k), int(action_dim)
        self.n_params = 2 * self.k * self.action_dim
        self.register_buffer("low", torch.as_tensor(low, dtype=torch.float32), persistent=False)
        self.register_buffer("high", torch.as_tensor(high, dtype=torch.float32), persistent=False)

    def decode(self, u: torch.Tensor) -> torch.Tensor:
        """Raw parameters [B, k A] -> sub-actions [B, k, A] inside the bounds."""
        a = u.view(u.shape[0], self.k, self.action_dim)
        return self.low + (torch.tanh(a) + 1.0) * 0.5 * (self.high - self.low)


class DecodingHead(Protocol):
    """What NDP-SAC needs of the NDP head (:class:`ndp.policies.heads.NDPHead`)."""

    k: int
    action_dim: int
    n_params: int

    def decode(
        self, raw: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]: ...


class SquashedNDPHead(SquashedHead):
    """NDP-SAC's head: the NDP head's parameters (goal and forcing weights, bounded by tanh
    inside ``NDPHead.decode``) under a state-dependent squashed Gaussian.

    Args:
        ndp: the task's NDP head (its DMP, bounds and inverse controller as they are).
    """

    needs_robot_state = True

    def __init__(self, ndp: DecodingHead) -> None:
        super().__init__()
        assert isinstance(ndp, nn.Module)  # a head: its DMP buffers follow the model
        self.ndp: DecodingHead = ndp
        self.k, self.action_dim = ndp.k, ndp.action_dim
        self.n_params = 2 * ndp.n_params

    def decoder(
        self, y0: torch.Tensor | None, dy0: torch.Tensor | None
    ) -> Callable[[torch.Tensor], torch.Tensor]:
        if y0 is None or dy0 is None:
            raise ValueError("SquashedNDPHead: the robot state y0, dy0 [B, D] is required")
        ndp = self.ndp

        def decode(u: torch.Tensor) -> torch.Tensor:
            return ndp.decode(u, y0, dy0)[0]

        return decode


@register_head("squashed")
def _build_squashed(cfg: PolicyConfig, spec: TaskSchema) -> ActionHead:
    return SquashedActionHead(decision_k(cfg), spec.action_dim, spec.action_low, spec.action_high)


@register_head("ndp-squashed")
def _build_ndp_squashed(cfg: PolicyConfig, spec: TaskSchema) -> ActionHead:
    ndp = HEAD_BUILDERS["ndp"](cfg, spec)  # the NDP head as the "ndp" method builds it
    if not hasattr(ndp, "decode"):
        raise ValueError("head: the registered 'ndp' head has no decode(raw, y0, dy0)")
    return SquashedNDPHead(ndp)  # type: ignore[arg-type]  # checked: it decodes
