"""The on-policy trainer's settings (``--algo ppo``, ``ppo-multi``, ``ppo-repeat``, ``ndp``,
``vices`` and its ablations): :class:`PPOConfig`, the section ``ppo`` of
``ndp.rl.config.TrainConfig`` (``TrainConfig.ppo``, ``config.json`` key ``"ppo"``).

The class lives with its learner, as SAC's and TD3's do (``ndp.rl.sac.config``,
``ndp.rl.td3.config``), and ``ndp.rl.config`` re-exports it (``from ndp.rl.config import
PPOConfig`` keeps working). Unlike theirs, the section is not registered with
``ndp.rl.methods.register_learner``: it is one of the run's reserved sections
(``ndp.rl.methods.RESERVED_SECTIONS``), a field of ``ndp.rl.config.RunConfig``, because its
options carry no learner prefix (``--lr``, ``--epochs``, ``--clip``: the names runs and
configs have used from the start, which ``Settings`` would refuse) and every on-policy method
reads it by default (``Method.reads``). Nothing here imports torch.
"""

from __future__ import annotations

from dataclasses import dataclass

from ndp.checks import check_int, check_positive, check_unit_interval, plain_numbers


@dataclass(frozen=True)
class PPOConfig:
    """PPO with GAE; defaults from the paper's supplement. Only the on-policy methods read this
    section; the discount, the update's size and the observation normaliser are the run's
    (:class:`ndp.rl.config.RunConfig`), read by every learner."""

    lr: float = 3e-4
    """Adam learning rate."""
    adam_eps: float = 1e-5
    """Adam epsilon."""
    gae_lambda: float = 0.95
    """GAE lambda per env step (sub-step)."""
    ent_coef: float = 0.0
    """Entropy bonus coefficient."""
    vf_coef: float = 0.5
    """Value loss coefficient."""
    max_grad_norm: float = 0.5
    """Global gradient-norm clip."""
    epochs: int = 10
    """Passes over each rollout."""
    minibatches: int = 32
    """Mini-batches per epoch (over decisions; each decision carries its k sub-steps)."""
    clip: float = 0.1
    """PPO ratio clip epsilon."""
    clip_value_loss: bool = False
    """Clip the value update around the rollout's values with ``clip`` (the release's PPO code
    base does; the supplement does not list it and SB3 does not use it; it slows learning)."""
    norm_return: bool = True
    """Scale rewards by the running std of the discounted return."""
    norm_adv: bool = True
    """Normalise advantages (to mean 0, std 1 over executed sub-steps)."""
    adv_norm_scope: str = "rollout"
    """Where advantages are normalised: over the whole 'rollout' or per 'minibatch' (SB3)."""
    clip_reward: float = 10.0
    """Clip normalised rewards to +- this."""
    anneal_lr: bool = False
    """Decay the learning rate linearly to 0 over the run."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        for name in (
            "lr",
            "adam_eps",
            "vf_coef",
            "max_grad_norm",
            "clip",
            "clip_reward",
        ):
            check_positive(name, getattr(self, name))
        check_unit_interval("gae_lambda", self.gae_lambda)
        if not (isinstance(self.ent_coef, (int, float)) and self.ent_coef >= 0):
            raise ValueError(f"ent_coef: expected a number >= 0, got {self.ent_coef!r}")
        for name in ("epochs", "minibatches"):
            check_int(name, getattr(self, name), 1)
        if self.adv_norm_scope not in ("rollout", "minibatch"):
            raise ValueError(
                f"adv_norm_scope: expected 'rollout' or 'minibatch', got {self.adv_norm_scope!r}"
            )
