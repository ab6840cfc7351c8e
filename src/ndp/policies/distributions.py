"""Exploration distributions of the actor: Gaussian around each sub-action, or over DMP params.

Both expose the same small interface (:class:`PolicyDistribution`) so that the trainer never
branches on the method:

- ``sample()`` / ``mode()`` -> ``z``, what the rollout buffer stores (the sub-actions themselves
  [B, k, A], or the DMP parameters [B, P] for parameter-space exploration);
- ``log_prob(z)`` -> [B, L] with L = k (one log-prob per sub-action) or L = 1 (one per decision);
- ``entropy()`` -> [B, L];
- ``actions(z)`` -> the k sub-actions [B, k, A] the env should run (the trainer clips them to the
  task's bounds before they reach the simulator).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import torch

from ndp.dmp.integrate import recording

_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


def diag_gaussian_log_prob(
    x: torch.Tensor, mean: torch.Tensor, log_std: torch.Tensor
) -> torch.Tensor:
    """Log-density of a diagonal Gaussian, summed over the last dimension.

    Args:
        x: samples [..., A].
        mean: means [..., A].
        log_std: log standard deviations broadcastable to [..., A].

    Returns:
        [...]: ``sum_a -0.5 ((x - mean) / std)^2 - log std - 0.5 log(2 pi)``.
    """
    z = (x - mean) * torch.exp(-log_std)
    if torch.is_grad_enabled() or recording():
        return (-0.5 * z.pow(2) - log_std - _HALF_LOG_2PI).sum(-1)
    # no autograd (rollouts): the same operations, the numbers as tensors (z * z is pow(z, 2))
    q = scalar_like(-0.5, z) * (z * z) - log_std
    return (q - scalar_like(_HALF_LOG_2PI, q)).sum(-1)


_SCALARS: dict[tuple[float, torch.dtype, torch.device], torch.Tensor] = {}


def scalar_like(value: float, like: torch.Tensor) -> torch.Tensor:
    """``value`` as a 0-dim tensor of ``like``'s dtype and device (cached, not to be written):
    the number a Python scalar operand of an operation on ``like`` becomes, without that
    conversion on every call. Not while ``torch.export`` / ``torch.compile`` record."""
    key = (value, like.dtype, like.device)
    t = _SCALARS.get(key)
    if t is None:
        t = _SCALARS[key] = torch.tensor(value, dtype=like.dtype, device=like.device)
    return t


def diag_gaussian_entropy(log_std: torch.Tensor, shape: torch.Size) -> torch.Tensor:
    """Entropy of a diagonal Gaussian with ``log_std`` [A], broadcast to ``shape`` = [..., A].

    Returns:
        [...]: ``sum_a log std + 0.5 log(2 pi e)``.
    """
    ent = (log_std + 0.5 + _HALF_LOG_2PI).expand(shape)
    return ent.sum(-1)


class PolicyDistribution(Protocol):
    """What the trainer needs from an exploration distribution (see the module docstring)."""

    per_decision: bool
    """True when there is one log-prob per decision (L = 1), False for one per sub-action."""

    def sample(
        self, generator: torch.Generator | None = None, noise: torch.Tensor | None = None
    ) -> torch.Tensor: ...
    def mode(self) -> torch.Tensor: ...
    def log_prob(self, z: torch.Tensor) -> torch.Tensor: ...
    def entropy(self) -> torch.Tensor: ...
    def actions(self, z: torch.Tensor) -> torch.Tensor: ...


def gaussian_draw(
    mean: torch.Tensor,
    log_std: torch.Tensor,
    generator: torch.Generator | None = None,
    noise: torch.Tensor | None = None,
) -> torch.Tensor:
    """``mean + exp(log_std) * N(0, I)`` [shape of ``mean``], reparameterised (the gradient
    reaches ``mean`` and ``log_std``; ``log_std`` broadcasts). ``noise``: the N(0, I) draw
    itself, drawn by the caller (e.g. for more rows at once); None: drawn here."""
    if noise is None:
        noise = torch.randn(mean.shape, generator=generator, dtype=mean.dtype, device=mean.device)
    return mean + noise * log_std.exp()


class _DiagGaussian:
    """A diagonal Gaussian over ``z`` (sub-actions or raw parameters) with its ``mean`` and a
    broadcast ``log_std``: the draw and the mode of both exploration spaces."""

    def __init__(self, mean: torch.Tensor, log_std: torch.Tensor) -> None:
        self.mean = mean
        self.log_std = log_std

    def sample(
        self, generator: torch.Generator | None = None, noise: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Draw ``z`` [shape of ``mean``] (no gradient); ``noise``: the standard normal draw
        [shape of ``mean``] to use (None: drawn here)."""
        return gaussian_draw(self.mean, self.log_std, generator, noise).detach()

    def mode(self) -> torch.Tensor:
        """The means [shape of ``mean``]."""
        return self.mean.detach()


class SubActionGaussian(_DiagGaussian):
    """Independent diagonal Gaussians around each of the k sub-actions of a decision.

    Args:
        mean: [B, k, A].
        log_std: [A], learned and state-independent (shared by the k sub-actions).
    """

    per_decision = False

    def log_prob(self, z: torch.Tensor) -> torch.Tensor:
        """Per-sub-action log-probs [B, k] of ``z`` [B, k, A]."""
        return diag_gaussian_log_prob(z, self.mean, self.log_std)

    def entropy(self) -> torch.Tensor:
        """Per-sub-action entropies [B, k]."""
        return diag_gaussian_entropy(self.log_std, self.mean.shape)

    def actions(self, z: torch.Tensor) -> torch.Tensor:
        """The sub-actions are the samples themselves: [B, k, A]."""
        return z


class ParamGaussian(_DiagGaussian):
    """A diagonal Gaussian over the raw (pre-squashing) DMP parameters of a decision.

    One log-prob per decision; the k sub-actions are a deterministic function of the sample
    (bound, integrate the DMP, inverse controller).

    Args:
        mean: raw parameter means [B, P].
        log_std: [P], learned and state-independent.
        decode: raw parameters [B, P] -> sub-actions [B, k, A].
    """

    per_decision = True

    def __init__(
        self,
        mean: torch.Tensor,
        log_std: torch.Tensor,
        decode: Callable[[torch.Tensor], torch.Tensor],
    ) -> None:
        super().__init__(mean, log_std)
        self._decode = decode

    def log_prob(self, z: torch.Tensor) -> torch.Tensor:
        """Log-prob of the decision [B, 1] for parameters ``z`` [B, P]."""
        return diag_gaussian_log_prob(z, self.mean, self.log_std).unsqueeze(-1)

    def entropy(self) -> torch.Tensor:
        """Entropy of the decision [B, 1]."""
        return diag_gaussian_entropy(self.log_std, self.mean.shape).unsqueeze(-1)

    def actions(self, z: torch.Tensor) -> torch.Tensor:
        """Sub-actions [B, k, A] for raw parameters ``z`` [B, P]."""
        with torch.no_grad():
            return self._decode(z)


NOISES = ("white", "ar1")
"""Exploration noise of the per-sub-action Gaussian heads: independent per sub-step ('white'),
or an AR(1) process over env steps, continued across decisions ('ar1': the discretised
Ornstein-Uhlenbeck process; :class:`AR1SubActionGaussian`)."""


class AR1SubActionGaussian:
    """Gaussian sub-actions whose noise is an AR(1) process over env steps (temporally
    correlated exploration: the discretised Ornstein-Uhlenbeck process).

    ``z_j = mean_j + std * e_j`` with unit-variance noise ``e_j = rho e_{j-1} + sqrt(1 - rho^2)
    xi_j``, ``xi_j ~ N(0, I)``, for the sub-steps j = 0..k-1 of a decision; ``e_{-1}`` is the
    ``carry``: the last noise of the env's previous decision (a fresh N(0, I) draw at an
    episode's start, so every ``e_j`` is N(0, I) and corr(e_j, e_{j+l}) = rho^l).

    The log-prob of sub-action j is its density given the decision's earlier sub-actions and the
    carry: ``log N(xi_j; 0, I) - sum_a log(std sqrt(1 - rho^2))`` with ``xi_j = (e_j - rho
    e_{j-1}) / sqrt(1 - rho^2)`` and ``e_j = (z_j - mean_j) / std`` recomputed from the current
    parameters; the carry is part of the condition (stored with the decision), so the policy is
    a proper density over the decision given (observation, carry), the PPO ratio of sub-step j is
    exact, and the per-sub-step factorisation keeps the causal pairing with the advantage A_j
    (docs/rl-regimes.md). ``rho = 0`` is :class:`SubActionGaussian`.

    Args:
        mean: [B, k, A].
        log_std: [A].
        carry: [B, A] the previous noise ``e_{-1}``.
        rho: correlation of consecutive env steps' noise, in [0, 1).
    """

    per_decision = False

    def __init__(
        self, mean: torch.Tensor, log_std: torch.Tensor, carry: torch.Tensor, rho: float
    ) -> None:
        self.mean = mean
        self.log_std = log_std
        self.carry = carry.to(mean.dtype)
        self.rho = float(rho)
        self._s = math.sqrt(1.0 - self.rho * self.rho)

    def noise(self, z: torch.Tensor) -> torch.Tensor:
        """The unit noise ``e`` [B, k, A] of sub-actions ``z`` under the current parameters."""
        return (z - self.mean) * torch.exp(-self.log_std)

    def sample(
        self, generator: torch.Generator | None = None, noise: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Draw sub-actions [B, k, A] (no gradient); ``noise``: the innovations ``xi``
        [B, k, A] to use (None: drawn here)."""
        xi = noise
        if xi is None:
            xi = torch.randn(
                self.mean.shape,
                generator=generator,
                dtype=self.mean.dtype,
                device=self.mean.device,
            )
        e = torch.empty_like(xi)
        prev = self.carry
        for j in range(xi.shape[1]):
            prev = self.rho * prev + self._s * xi[:, j]
            e[:, j] = prev
        return (self.mean + e * self.log_std.exp()).detach()

    def mode(self) -> torch.Tensor:
        """The means [B, k, A] (the noise has mean 0 whatever the carry's value; the mode of
        the conditional density is shifted by ``rho^(j+1) std carry``, but a deterministic
        policy does not carry noise)."""
        return self.mean.detach()

    def log_prob(self, z: torch.Tensor) -> torch.Tensor:
        """Per-sub-action conditional log-probs [B, k] of ``z`` [B, k, A]."""
        e = self.noise(z)
        prev = torch.cat([self.carry.unsqueeze(1), e[:, :-1]], dim=1)
        xi = (e - self.rho * prev) / self._s
        log_scale = self.log_std + math.log(self._s)
        return (-0.5 * xi.pow(2) - log_scale - _HALF_LOG_2PI).sum(-1)

    def entropy(self) -> torch.Tensor:
        """Per-sub-action conditional entropies [B, k]."""
        return diag_gaussian_entropy(self.log_std + math.log(self._s), self.mean.shape)

    def actions(self, z: torch.Tensor) -> torch.Tensor:
        """The sub-actions are the samples themselves: [B, k, A]."""
        return z

    def last_noise(self, z: torch.Tensor) -> torch.Tensor:
        """The carry of the env's next decision: the noise of the last sub-action [B, A]."""
        return self.noise(z)[:, -1].detach()


def correlate(dist: PolicyDistribution, carry: torch.Tensor, rho: float) -> AR1SubActionGaussian:
    """``dist`` (a :class:`SubActionGaussian`) with AR(1) noise continued from ``carry`` [B, A].

    Raises:
        ValueError: ``dist`` is not a per-sub-action Gaussian (parameter noise, the hold head).
    """
    if not isinstance(dist, SubActionGaussian):
        raise ValueError(
            "noise: 'ar1' needs a Gaussian around each sub-action (ppo, ppo-multi, ndp without "
            f"--param-noise), got {type(dist).__name__}"
        )
    return AR1SubActionGaussian(dist.mean, dist.log_std, carry, rho)
