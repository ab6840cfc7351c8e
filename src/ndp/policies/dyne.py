"""Dyn-E's action embedding (Whitney et al., "Dynamics-aware Embeddings", ICLR 2020) and its head.

Three networks over sequences of k actions [B, k, A] with a latent of size L (= A):

- :class:`SequenceEmbedding`: a VAE-style encoder ``q(e | a_1..a_k)`` (MLP 400-400 SELU ->
  mean and log-variance) and a state predictor ``f(s_0, e) -> whitened (s_k - s_0)`` (MLP
  400-400 SELU), trained together on random action sequences: whitened squared prediction error
  (mean over state dimensions) + ``kl_weight`` * KL(q || N(0, I)). The state is the robot's
  positions and velocities (the chunked env's ``robot_pos`` / ``robot_vel``); its whitening
  statistics and those of the encoder's latent are buffers of the module.
- :class:`ActionDecoder`: whitened latent -> k actions (MLP 400-400 SELU, tanh output scaled to
  the action bounds), trained after the VAE so that the encoder maps the decoded sequence back
  onto the latent it came from (the decoded sequence has the same predicted effect).
- :class:`DyneHead`: the action head of a Dyn-E policy. The actor's raw output [B, L] becomes
  the latent ``e = max_latent * tanh(raw)`` (the TD3 action) and is decoded into the decision's k
  actions; the deterministic action is the decoded sequence, a stochastic one adds a small fixed
  Gaussian (``EVAL_STD``) per action (Dyn-E itself explores in the latent, see ndp.rl.dyne).
"""

from __future__ import annotations

import math

import torch
from torch import nn
from torch.nn import functional as F

from ndp.policies.base import ActionHead, HeadOutput
from ndp.policies.distributions import SubActionGaussian

HIDDEN = 400
"""Width of every embedding network's hidden layers (the original's)."""
EVAL_STD = 0.1
"""Std of the Gaussian around each decoded action when a Dyn-E policy is sampled (evaluation
only: training explores in the latent)."""


def _mlp(in_dim: int, out_dim: int, hidden: int = HIDDEN, layers: int = 2) -> nn.Sequential:
    mods: list[nn.Module] = []
    d = in_dim
    for _ in range(layers):
        mods += [nn.Linear(d, hidden), nn.SELU()]
        d = hidden
    mods.append(nn.Linear(d, out_dim))
    return nn.Sequential(*mods)


class ActionDecoder(nn.Module):
    """Whitened latent [B, L] -> k actions [B, k, A] within ``[low, high]`` (tanh output).

    Args:
        k: actions per sequence.
        action_dim: A.
        latent_dim: L.
        low, high: action bounds [A].
    """

    # buffers registered in __init__
    centre: torch.Tensor
    half_range: torch.Tensor

    def __init__(
        self,
        k: int,
        action_dim: int,
        latent_dim: int,
        low: torch.Tensor | float = -1.0,
        high: torch.Tensor | float = 1.0,
    ) -> None:
        super().__init__()
        self.k, self.action_dim, self.latent_dim = int(k), int(action_dim), int(latent_dim)
        self.net = _mlp(self.latent_dim, self.k * self.action_dim)
        lo = torch.as_tensor(low, dtype=torch.float32).expand(self.action_dim).clone()
        hi = torch.as_tensor(high, dtype=torch.float32).expand(self.action_dim).clone()
        self.register_buffer("centre", (hi + lo) / 2, persistent=False)
        self.register_buffer("half_range", (hi - lo) / 2, persistent=False)

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        out = torch.tanh(self.net(z)).view(z.shape[0], self.k, self.action_dim)
        return self.centre + self.half_range * out


class SequenceEmbedding(nn.Module):
    """Encoder of k-action sequences and the state predictor that shapes its latent.

    Args:
        k: actions per sequence.
        action_dim: A.
        state_dim: S (robot positions and velocities, 2 D).
        latent_dim: L.

    Buffers (set by :meth:`set_state_stats` / :meth:`set_latent_stats`, saved): ``s_mean``,
    ``s_std`` [S] (the chunk's start state), ``d_mean``, ``d_std`` [S] (its change over the
    chunk), ``z_mean``, ``z_std`` [L] (the encoder's mean over the exploration data).
    """

    # buffers registered in __init__
    s_mean: torch.Tensor
    s_std: torch.Tensor
    d_mean: torch.Tensor
    d_std: torch.Tensor
    z_mean: torch.Tensor
    z_std: torch.Tensor

    def __init__(self, k: int, action_dim: int, state_dim: int, latent_dim: int) -> None:
        super().__init__()
        self.k, self.action_dim = int(k), int(action_dim)
        self.state_dim, self.latent_dim = int(state_dim), int(latent_dim)
        self.encoder = _mlp(self.k * self.action_dim, 2 * self.latent_dim)
        self.predictor = _mlp(self.state_dim + self.latent_dim, self.state_dim)
        for name, n in (("s", state_dim), ("d", state_dim), ("z", latent_dim)):
            self.register_buffer(f"{name}_mean", torch.zeros(n))
            self.register_buffer(f"{name}_std", torch.ones(n))

    @staticmethod
    def _stats(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        std = x.std(0)
        return x.mean(0), torch.where(std > 1e-6, std, torch.ones_like(std))

    def set_state_stats(self, s0: torch.Tensor, delta: torch.Tensor) -> None:
        """Whitening statistics of start states [N, S] and state changes [N, S] (a constant
        dimension gets std 1, as in the original)."""
        for name, x in (("s", s0), ("d", delta)):
            mean, std = self._stats(x)
            getattr(self, f"{name}_mean").copy_(mean)
            getattr(self, f"{name}_std").copy_(std)

    def encode(self, actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Actions [B, k, A] -> (mean, log-variance) [B, L] of q(e | actions) (not whitened)."""
        h = self.encoder(actions.reshape(actions.shape[0], -1))
        return h[:, : self.latent_dim], h[:, self.latent_dim :]

    def whiten_latent(self, z: torch.Tensor) -> torch.Tensor:
        """Encoder latent -> the whitened latent the decoder and TD3 use."""
        return (z - self.z_mean) / self.z_std

    def predict(self, s0: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """Whitened state change [B, S] from the raw start state [B, S] and a latent [B, L]."""
        s = (s0 - self.s_mean) / self.s_std
        change: torch.Tensor = self.predictor(torch.cat((s, z), dim=-1))
        return change

    def loss(
        self, s0: torch.Tensor, actions: torch.Tensor, delta: torch.Tensor, kl_weight: float
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(total, prediction, KL): prediction = whitened squared error, mean over dimensions
        and batch; KL summed over the latent, mean over the batch."""
        mu, logvar = self.encode(actions)
        z = mu + torch.randn_like(mu) * torch.exp(0.5 * logvar)
        target = (delta - self.d_mean) / self.d_std
        pred = F.mse_loss(self.predict(s0, z), target)
        kl = (-0.5 * (1 + logvar - mu.pow(2) - logvar.exp()).sum(-1)).mean()
        return pred + kl_weight * kl, pred, kl


class DyneHead(ActionHead):
    """Dyn-E action head: raw actor output [B, L] -> latent ``max_latent * tanh(raw)`` ->
    frozen decoder -> k actions [B, k, A] (see the module docstring).

    Args:
        k: sub-steps per decision.
        action_dim: A (= L, the latent size, as in the original).
        low, high: action bounds [A].

    State: the decoder's weights, ``max_latent`` (largest whitened latent magnitude seen in the
    exploration data: the TD3 action range) and ``log_std`` (fixed, not trained).
    """

    # buffer registered in __init__
    max_latent: torch.Tensor

    def __init__(
        self, k: int, action_dim: int, low: torch.Tensor | float, high: torch.Tensor | float
    ) -> None:
        super().__init__()
        self.k = int(k)
        self.action_dim = int(action_dim)
        self.latent_dim = self.action_dim
        self.n_params = self.latent_dim
        self.decoder = ActionDecoder(self.k, self.action_dim, self.latent_dim, low, high)
        self.register_buffer("max_latent", torch.tensor(1.0))
        self.log_std = nn.Parameter(
            torch.full((self.action_dim,), math.log(EVAL_STD)), requires_grad=False
        )

    def latent(self, raw: torch.Tensor) -> torch.Tensor:
        """The TD3 action: ``max_latent * tanh(raw)`` [B, L]."""
        return self.max_latent * torch.tanh(raw)

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        """Whitened latent [B, L] -> k actions [B, k, A]."""
        actions: torch.Tensor = self.decoder(z)
        return actions

    def distribution(
        self, raw: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> HeadOutput:
        return SubActionGaussian(self.decode(self.latent(raw)), self.log_std), {}

    def extra_repr(self) -> str:
        return f"k={self.k}, A={self.action_dim}, L={self.latent_dim}"
