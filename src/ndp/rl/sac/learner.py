"""SAC, chunked SAC and NDP-SAC: one learner (an :class:`ndp.rl.run.RLLearner`).

Data flow of one iteration (E envs, T decisions per env, k sub-steps, A actions, D DMP DoF,
P bounded parameters per decision, C the critic's action input)::

    obs [E, O], robot state y0, dy0 [E, D] --actor--> squashed Gaussian over u [E, P]
    u (random in the bounded space for the first random_steps) --head decode--> [E, k, A]
    --ChunkedEnv x E--> sub-rewards [E, k], mask [E, k] --> chunk return, bootstrap weight
    --> replay (one row per decision) --> updates_per_step x k gradient steps per decision:
        critics on the k-step soft target, actor on alpha log pi - min Q, temperature

The actor is the run's :class:`ndp.policies.ActorCritic` (its ``squashed`` or
``ndp-squashed`` head; its PPO critic is unused), so evaluation, rendering, ONNX export and
``ndp.load_policy`` read a SAC run like a PPO one; the twin critics, their targets, the
optimisers, the temperature and the replay buffer are saved under the checkpoint's ``sac`` key.
Observations are not normalised (SAC's usual setting; the identity statistics are saved as
every RL run's).
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import torch
from torch import nn

from ndp.policies.squashed import SquashedGaussian, SquashedNDPHead
from ndp.rl.config import TrainConfig
from ndp.rl.methods import section
from ndp.rl.offpolicy.critics import TwinQ as TwinQ  # re-exported (its old home)
from ndp.rl.offpolicy.loop import OffPolicyLearner, check_learning_budget, mean_of
from ndp.rl.offpolicy.state import Part
from ndp.rl.sac import SAC_METRICS
from ndp.rl.sac.config import SACConfig
from ndp.rl.sac.health import Q_RUNAWAY, q_runaway
from ndp.rl.sac.losses import (
    actor_loss,
    alpha_loss,
    critic_loss,
    critic_target,
    soft_update,
)
from ndp.runs.checkpoint import REAL, FiniteTensor, MayLack, Spec
from ndp.runs.session import RunSession, nonfinite_parameter


def scores_params(head: nn.Module, critic_input: str) -> bool:
    """Whether the critics score the bounded parameters ``tanh(u)`` (NDP-SAC with
    ``critic_input='params'``) rather than the k actions."""
    return isinstance(head, SquashedNDPHead) and critic_input == "params"


def critic_input(
    u: torch.Tensor,
    dist: SquashedGaussian,
    params: bool,
    low: torch.Tensor,
    high: torch.Tensor,
) -> torch.Tensor:
    """What the critics score with the state [B, C] for raw parameters ``u`` [B, P]: ``tanh(u)``
    (``params``, see :func:`scores_params`) or the k actions ``u`` gives, inside the bounds
    ``low``, ``high`` [A] (differentiable)."""
    if params:
        return torch.tanh(u)
    return torch.maximum(torch.minimum(dist.decode(u), high), low).flatten(1)


class SACLearner(OffPolicyLearner):
    """SAC over decisions of k env steps (see the module docstring), on the shared
    off-policy loop (:class:`ndp.rl.offpolicy.loop.OffPolicyLearner`).

    Args:
        cfg: the resolved config (``cfg.sac``: :class:`ndp.rl.sac.config.SACConfig`).
        session: the run's session (paths, the divergence message).
    """

    section = "sac"
    own_columns = SAC_METRICS

    def __init__(self, cfg: TrainConfig, session: RunSession) -> None:
        check_learning_budget(cfg, self.section)  # before any env is built
        s = self.settings = section(cfg, SACConfig)
        self._open_loop(cfg, session, s)
        self.P = self.model.head.n_params // 2
        self.is_ndp = isinstance(self.model.head, SquashedNDPHead)
        self.scores_params = scores_params(self.model.head, s.critic_input)
        c_dim = self.P if self.scores_params else self.k * self.spec.action_dim
        pol = cfg.policy
        assert pol.hidden is not None and pol.activation is not None  # resolve_config fills them
        self._open_critics(
            TwinQ(self.obs_dim, c_dim, tuple(pol.hidden), pol.activation, s.critic_layer_norm)
        )
        self.log_alpha = torch.tensor(math.log(s.init_alpha), requires_grad=True)
        # fused Adam: one kernel for all tensors (the per-tensor loop of the default CPU Adam
        # was a tenth of a gradient step); same numbers up to rounding
        self.actor_opt = torch.optim.Adam(self.model.actor.parameters(), lr=s.lr, fused=True)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=s.lr, fused=True)
        self.alpha_opt = torch.optim.Adam([self.log_alpha], lr=s.lr)
        self.target_entropy = float(-self.P if s.target_entropy is None else s.target_entropy)
        self._open_replay(s.buffer_size, {"u": self.P, "critic_in": c_dim})
        self.return_peak: float | None = None
        """The largest |mean training-episode return| of any update so far (None: no episode
        has ended yet); saved with the checkpoint (critic health, :mod:`ndp.rl.sac.health`)."""
        self._q_warned = False  # the runaway is said once per session

    # ----------------------------------------------------------------------- protocol
    def nonfinite(self) -> str | None:
        """The first actor or critic parameter (or the temperature) holding NaN / Inf."""
        return super().nonfinite() or nonfinite_parameter([("log_alpha", self.log_alpha)])

    def extra_parts(self) -> dict[str, Part]:
        """The temperature's optimiser (saved after the shared parts)."""
        return {"alpha_opt": self.alpha_opt}

    def extra_state(self) -> dict[str, object]:
        """The temperature and the critic-health peak."""
        return {"log_alpha": self.log_alpha.detach().clone(), "return_peak": self.return_peak}

    def extra_schema(self) -> dict[str, Spec]:
        """``return_peak`` may be absent (checkpoints before 2026-12-05 lack it)."""
        return {"log_alpha": FiniteTensor(self.log_alpha.detach()),
                "return_peak": MayLack((REAL, type(None)))}  # fmt: skip

    def load_extra_state(self, s: dict[str, Any]) -> None:
        """The temperature and the peak."""
        with torch.no_grad():
            self.log_alpha.copy_(s["log_alpha"])
        self.return_peak = s.get("return_peak")  # checkpoints before 2026-12-05 lack it

    # ----------------------------------------------------------------------- acting
    def _dist(self, obs: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor) -> SquashedGaussian:
        dist, _ = self.model.distribution(obs, y0, dy0)
        assert isinstance(dist, SquashedGaussian)  # the squashed heads
        return dist

    def critic_input(self, u: torch.Tensor, dist: SquashedGaussian) -> torch.Tensor:
        """What the critics score with the state [B, C] (:func:`critic_input`)."""
        return critic_input(u, dist, self.scores_params, self.low, self.high)

    def _random_u(self) -> torch.Tensor:
        """Raw parameters [E, P] uniform in the bounded space (tanh(u) ~ U(-1, 1)^P)."""
        p = self.rng.uniform(-1.0 + 1e-6, 1.0 - 1e-6, size=(self.E, self.P))
        return torch.as_tensor(np.arctanh(p), dtype=torch.float32)

    def act(
        self, obs: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor, explore: bool
    ) -> tuple[torch.Tensor, dict[str, np.ndarray]]:
        """A draw of the squashed Gaussian (uniform in the bounded space during the random
        steps): the actions [E, k, A] and the replay's ``u`` [E, P], ``critic_in`` [E, C]."""
        dist = self._dist(obs, y0, dy0)
        u = dist.sample() if explore else self._random_u()
        act = torch.maximum(torch.minimum(dist.actions(u), self.high), self.low)
        c = self.critic_input(u, dist)
        return act, {"u": u.numpy(), "critic_in": c.numpy()}

    # ----------------------------------------------------------------------- learning
    def iterate(self) -> dict[str, float]:
        """One iteration of the shared loop (:meth:`OffPolicyLearner.iterate`), then the
        critic's health is checked.

        Raises:
            TrainingDivergedError: NaN / Inf in a loss or parameter.
        """
        row = super().iterate()
        self._watch_critic(row)
        return row

    def _watch_critic(self, row: dict[str, float]) -> None:
        """Track the largest mean episode return and say once (stderr, RuntimeWarning) when the
        critics' estimate runs away from it (:func:`ndp.rl.sac.health.q_runaway`)."""
        ret = row.get("charts/episode_return", math.nan)
        if math.isfinite(ret):
            self.return_peak = max(self.return_peak or 0.0, abs(ret))
        q = row.get("sac/q", math.nan)
        if self._q_warned or self.return_peak is None or not q_runaway(q, self.return_peak):
            return
        self._q_warned = True
        warnings.warn(
            f"sac: at update {self.update} (env step {self.global_step:,}) the critics' mean "
            f"value estimate is {q:,.0f}, above {Q_RUNAWAY:g}x the largest mean episode return "
            f"so far ({self.return_peak:,.0f}): the critic is running away; numbers of this "
            "run are those of a diverged critic (docs/offpolicy.md, 'Critic health'; said once)",
            RuntimeWarning,
            stacklevel=3,
        )

    def gradient_step(self, b: dict[str, torch.Tensor]) -> dict[str, float]:
        """One step of the critics, the actor and the temperature on a replay batch ``b``."""
        s = self.settings
        alpha = self.log_alpha.detach().exp()
        with torch.no_grad():
            dist_n = self._dist(b["next_obs"], b["next_y0"], b["next_dy0"])
            u_n = dist_n.sample()
            q1_t, q2_t = self.critic_target(b["next_obs"], self.critic_input(u_n, dist_n))
            logp_n = dist_n.log_prob(u_n)[:, 0]
            y = critic_target(b["ret"][:, 0], b["discount"][:, 0], q1_t, q2_t, logp_n, alpha)
        q1, q2 = self.critic(b["obs"], b["critic_in"])
        lc = critic_loss(q1, q2, y)
        self._step(self.critic_opt, lc, "critic")
        dist = self._dist(b["obs"], b["y0"], b["dy0"])
        u = dist.rsample()
        logp = dist.log_prob(u)[:, 0]
        with self._critics_frozen():  # the actor's loss does not train the critics
            q1_pi, q2_pi = self.critic(b["obs"], self.critic_input(u, dist))
        la = actor_loss(logp, q1_pi, q2_pi, alpha)
        self._step(self.actor_opt, la, "actor")
        lt = alpha_loss(self.log_alpha, logp, self.target_entropy)
        self._step(self.alpha_opt, lt, "temperature")
        soft_update(self.critic_target, self.critic, s.tau)
        return {
            "critic": float(lc.detach()),
            "actor": float(la.detach()),
            "alpha": float(lt.detach()),
            "q": float(torch.minimum(q1, q2).detach().mean()),
        }

    def algorithm_metrics(self, losses: dict[str, list[float]]) -> dict[str, float]:
        """SAC's columns of the row: the shared ones and the temperature's."""
        return {
            **self.loop_metrics(losses, self.settings.lr),
            "sac/alpha": float(self.log_alpha.detach().exp()),
            "sac/alpha_loss": mean_of(losses, "alpha"),
        }
