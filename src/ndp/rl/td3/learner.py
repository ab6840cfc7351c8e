"""TD3 (Fujimoto et al. 2018) on the shared off-policy loop (:mod:`ndp.rl.offpolicy.loop`).

Data flow of one decision (E envs, P = k A bounded action values, k = 1 for ``--algo td3``)::

    obs [E, O] --actor--> p = tanh(mean) [E, P] --+ N(0, expl_noise^2), clip [-1, 1]--> p
    (uniform in [-1, 1]^P for the first random_steps) --affine to the bounds--> actions
    [E, k, A] --env--> reward, next obs --> replay (one row per decision)

and of one gradient step on a batch of B decisions::

    a~ = clip(p'(s') + clip(N(0, target_noise^2), +-target_noise_clip), -1, 1)      [B, P]
    y = R + w min(Q1'(s', a~), Q2'(s', a~))                                          [B]
    critics: mse(Q1(s, p), y) + mse(Q2(s, p), y)
    every policy_delay-th critic step: actor on -mean Q1(s, pi(s)), then the target actor and
    the target critics move tau of the way (soft update)

The actor is the run's :class:`ndp.policies.ActorCritic` with the ``squashed`` head, used
deterministically: its action is the head's mean through tanh (the head's log std is unused),
which is also the head's mode, so ``ndp rl eval / render / export`` and ``ndp.load_policy`` act
as TD3 does without noise. The critics score the bounded action p in [-1, 1]^P (SB3's
normalised action). The actor's and the critics' linear layers start from PyTorch's default
initialisation (``--td3-init torch``, SB3's; ``orthogonal``: the other learners').
Observations are not normalised (identity statistics are saved as every RL run's). The twin
critics, the targets, the optimisers and the replay are saved under the checkpoint's ``td3``
key.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from ndp.policies.squashed import SquashedGaussian
from ndp.rl.config import TrainConfig
from ndp.rl.methods import section
from ndp.rl.offpolicy.critics import TwinQ
from ndp.rl.offpolicy.loop import OffPolicyLearner, check_learning_budget
from ndp.rl.optim import soft_update
from ndp.rl.td3 import TD3_METRICS
from ndp.rl.td3.config import TD3Config
from ndp.rl.td3.losses import (
    actor_loss,
    actor_update_due,
    critic_loss,
    exploration_action,
    smoothed_target_action,
    td3_target,
)
from ndp.runs.checkpoint import INT, Spec
from ndp.runs.session import RunSession

if TYPE_CHECKING:
    from ndp.policies import ActorCritic


def torch_default_init(*modules: torch.nn.Module) -> None:
    """Re-initialise every ``nn.Linear`` in ``modules`` with PyTorch's default
    (``reset_parameters``: weights and biases uniform in +-1/sqrt(fan_in)), drawing from the
    global generator in module order."""
    for module in modules:
        for m in module.modules():
            if isinstance(m, torch.nn.Linear):
                m.reset_parameters()


class TD3Learner(OffPolicyLearner):
    """TD3 (see the module docstring).

    Args:
        cfg: the resolved config (``cfg.td3``: :class:`ndp.rl.td3.config.TD3Config`).
        session: the run's session (paths, the divergence message).
    """

    section = "td3"
    own_columns = TD3_METRICS
    actor_target: ActorCritic

    def __init__(self, cfg: TrainConfig, session: RunSession) -> None:
        check_learning_budget(cfg, self.section)  # before any env is built
        s = self.settings = section(cfg, TD3Config)
        self._open_loop(cfg, session, s)
        self.P = self.model.head.n_params // 2
        pol = cfg.policy
        assert pol.hidden is not None and pol.activation is not None  # resolve_config fills them
        critic = TwinQ(self.obs_dim, self.P, tuple(pol.hidden), pol.activation)
        if s.init == "torch":  # before the targets copy them
            torch_default_init(self.model.actor, critic)
        self._open_critics(critic, actor_target=self.model)
        self.actor_opt = torch.optim.Adam(self.model.actor.parameters(), lr=s.lr)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=s.lr)
        self._open_replay(s.buffer_size, {"u": self.P, "critic_in": self.P})
        self.actor_updates = 0

    # ----------------------------------------------------------------------- protocol
    def extra_state(self) -> dict[str, object]:
        """The count of actor updates."""
        return {"actor_updates": self.actor_updates}

    def extra_schema(self) -> dict[str, Spec]:
        """``actor_updates``: an integer."""
        return {"actor_updates": INT}

    def load_extra_state(self, s: dict[str, Any]) -> None:
        """The count of actor updates."""
        self.actor_updates = int(s["actor_updates"])

    # ----------------------------------------------------------------------- acting
    def policy_action(
        self, model: ActorCritic, obs: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor
    ) -> torch.Tensor:
        """The deterministic bounded action ``tanh(mean)`` [B, P] of ``model`` (the actor or
        its target), with the gradient."""
        dist, _ = model.distribution(obs, y0, dy0)
        assert isinstance(dist, SquashedGaussian)  # the squashed head
        return torch.tanh(dist.mean)

    def to_actions(self, p: torch.Tensor) -> torch.Tensor:
        """Bounded actions p [B, P] in [-1, 1] -> env actions [B, k, A] in the task's bounds
        (the squashed head's affine map)."""
        a = p.reshape(p.shape[0], self.k, -1)
        return self.low + (a + 1.0) * 0.5 * (self.high - self.low)

    def act(
        self, obs: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor, explore: bool
    ) -> tuple[torch.Tensor, dict[str, np.ndarray]]:
        """The actor's action plus Gaussian noise, clipped (uniform in [-1, 1]^P during the
        random steps): the env actions [E, k, A] and the replay's ``u`` = ``critic_in`` = the
        bounded action [E, P]."""
        if explore:
            p = self.policy_action(self.model, obs, y0, dy0)
            noise = self.rng.normal(0.0, self.settings.expl_noise, size=(self.E, self.P))
            p = exploration_action(p, torch.as_tensor(noise, dtype=torch.float32))
        else:
            p = torch.as_tensor(self.rng.uniform(-1.0, 1.0, size=(self.E, self.P)),
                                dtype=torch.float32)  # fmt: skip
        return self.to_actions(p), {"u": p.numpy(), "critic_in": p.numpy()}

    # ----------------------------------------------------------------------- learning
    def gradient_step(self, b: dict[str, torch.Tensor]) -> dict[str, float]:
        """One critic step; the actor and the targets every ``policy_delay``-th one."""
        s = self.settings
        with torch.no_grad():
            p_next = self.policy_action(self.actor_target, b["next_obs"], b["next_y0"],
                                        b["next_dy0"])  # fmt: skip
            noise = torch.randn_like(p_next) * s.target_noise
            a_next = smoothed_target_action(p_next, noise, s.target_noise_clip)
            q1_t, q2_t = self.critic_target(b["next_obs"], a_next)
            y = td3_target(b["ret"][:, 0], b["discount"][:, 0], q1_t, q2_t)
        q1, q2 = self.critic(b["obs"], b["critic_in"])
        lc = critic_loss(q1, q2, y)
        self._step(self.critic_opt, lc, "critic")
        out = {"critic": float(lc.detach()), "q": float(torch.minimum(q1, q2).detach().mean())}
        if actor_update_due(self.grad_steps + 1, s.policy_delay):  # the loop counts after
            with self._critics_frozen():  # the actor's loss does not train the critics
                p_pi = self.policy_action(self.model, b["obs"], b["y0"], b["dy0"])
                q1_pi, _ = self.critic(b["obs"], p_pi)
            la = actor_loss(q1_pi)
            self._step(self.actor_opt, la, "actor")
            soft_update(self.critic_target, self.critic, s.tau)
            soft_update(self.actor_target, self.model, s.tau)
            self.actor_updates += 1
            out["actor"] = float(la.detach())
        return out

    def algorithm_metrics(self, losses: dict[str, list[float]]) -> dict[str, float]:
        """TD3's columns of the row: the shared ones and the count of actor updates."""
        return {**self.loop_metrics(losses, self.settings.lr),
                "td3/actor_updates": float(self.actor_updates)}  # fmt: skip
