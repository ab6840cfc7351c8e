"""Dyn-E's settings (``--algo dyne``): one typed config, the section ``dyne`` of
``ndp.rl.config.TrainConfig`` (registered by :mod:`ndp.rl.dyne`); its options have no prefix
(``--actor-lr``, ``--explore-steps``: older than the ``--sac-`` / ``--td3-`` convention)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ndp.checks import check_int, check_positive, plain_numbers


@dataclass(frozen=True)
class DyneConfig:
    """Dyn-E (Whitney et al., ICLR 2020): TD3 acting in a learned embedding of k-action sequences.

    Only read by ``--algo dyne``. Defaults follow the original code (``embedding/main.py``,
    ``rl/main_dyne.py``, ``rl/EmbeddedTD3.py`` of willwhitney/dynamics-aware-embeddings) and
    TD3 (Fujimoto et al., 2018); docs/dyne.md lists each value with its source and every
    deviation. The discount is the run's ``--gamma`` (per env step, every method's); the TD3
    actor and critics use ``--hidden`` / ``--activation`` (400-300 ReLU for Dyn-E, see
    docs/dyne.md).
    """

    explore_steps: int | None = None
    """Dyn-E: env steps of uniformly random k-action sequences collected first to train the
    embedding (counted in --steps, rounded up to whole iterations); None: the task's preset
    (ndp.rl.dyne.DYNE_EXPLORE_STEPS)."""
    embed_updates: int = 4000
    """Dyn-E: gradient steps of the embedding VAE (encoder + state predictor)."""
    decoder_updates: int = 10000
    """Dyn-E: gradient steps of the action decoder (trained after the VAE, encoder frozen)."""
    embed_batch: int = 128
    """Dyn-E: batch size (action sequences) of the VAE and decoder steps."""
    embed_lr: float = 1e-4
    """Dyn-E: Adam learning rate of the VAE (amsgrad) and of the decoder."""
    kl_weight: float = 1e-4
    """Dyn-E: weight of the VAE's KL term against the whitened state-prediction error."""
    norm_weight: float = 1e-4
    """Dyn-E: decoder penalty on the L2 norm of each decoded action (summed over the batch)."""
    replay_size: int = 200_000
    """Dyn-E: replay buffer capacity in decisions (k env steps each; saved in the checkpoint,
    about 4 * (2 * obs_dim + latent + 2 k + 2) bytes per decision)."""
    start_steps: int = 0
    """Dyn-E: env steps (after the exploration data) acting with uniformly random latents
    instead of the actor (the original used 0)."""
    updates_per_step: float = 1.0
    """Dyn-E: TD3 gradient steps per env step (the original: 1, run at episode ends)."""
    batch_size: int = 100
    """Dyn-E: TD3 batch size (decisions)."""
    actor_lr: float = 1e-3
    """Dyn-E: Adam learning rate of the TD3 actor."""
    critic_lr: float = 1e-3
    """Dyn-E: Adam learning rate of the TD3 twin critics."""
    tau: float = 0.005
    """Dyn-E: soft target-update rate of the TD3 target nets."""
    policy_delay: int = 2
    """Dyn-E: critic steps per actor (and target) update."""
    expl_noise: float = 0.1
    """Dyn-E: std of the Gaussian exploration noise on the latent, times the latent range."""
    target_noise: float = 0.2
    """Dyn-E: std of the target-policy smoothing noise, times the latent range (the original
    divides it further by k)."""
    target_noise_clip: float = 0.5
    """Dyn-E: clip of the target-policy smoothing noise, times the latent range."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        if self.explore_steps is not None:
            check_int("explore_steps", self.explore_steps, 1)
        for name in ("embed_updates", "decoder_updates", "start_steps"):
            check_int(name, getattr(self, name), 0)
        for name in ("embed_batch", "replay_size", "batch_size", "policy_delay"):
            check_int(name, getattr(self, name), 1)
        for name in ("embed_lr", "actor_lr", "critic_lr", "updates_per_step"):
            check_positive(name, getattr(self, name))
        for name in ("kl_weight", "norm_weight", "expl_noise", "target_noise", "target_noise_clip"):
            v = getattr(self, name)
            if (
                isinstance(v, bool)
                or not isinstance(v, (int, float))
                or not math.isfinite(v)
                or v < 0
            ):
                raise ValueError(f"{name}: expected a finite number >= 0, got {v!r}")
        if not (isinstance(self.tau, (int, float)) and 0.0 < self.tau <= 1.0):
            raise ValueError(f"tau: expected a number in (0, 1], got {self.tau!r}")
        if self.batch_size > self.replay_size:
            raise ValueError(
                f"batch_size: expected at most replay_size={self.replay_size}, "
                f"got {self.batch_size}"
            )
