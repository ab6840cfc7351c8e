"""SAC's settings (``--algo sac``, ``sac-chunk``, ``ndp-sac``): one typed config, a field of
``ndp.rl.config.TrainConfig`` (``TrainConfig.sac``). Defaults are SAC's standard ones (Haarnoja
et al. 2018, as Stable-Baselines3 ships them) except the random steps (5,000 instead of SB3's
100, "a few thousand random steps first"). The discount is the run's ``--gamma`` (per env step,
every method's); the networks are ``--hidden`` / ``--activation`` (256-256 ReLU for these
methods)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

from ndp.checks import check_int, check_positive, plain_numbers
from ndp.runs.cli import cli

CRITIC_INPUTS = ("params", "actions")
"""What NDP-SAC's critic scores beside the state: the bounded DMP parameters ``tanh(u)`` or
the executed chunk of k actions."""


@dataclass(frozen=True)
class SACConfig:
    """SAC, chunked SAC and NDP-SAC (``ndp.rl.sac``); read only by those methods."""

    buffer_size: Annotated[int, cli(name="sac-buffer-size")] = 1_000_000
    """SAC: replay capacity in env steps (decisions x k; saved with the checkpoint)."""
    batch_size: Annotated[int, cli(name="sac-batch-size")] = 256
    """SAC: decisions per gradient step."""
    lr: Annotated[float, cli(name="sac-lr")] = 3e-4
    """SAC: Adam learning rate of the actor, the critics and the temperature."""
    tau: Annotated[float, cli(name="sac-tau")] = 0.005
    """SAC: soft target-update rate of the critics' targets."""
    random_steps: Annotated[int, cli(name="sac-random-steps")] = 5000
    """SAC: env steps acting uniformly at random (in the bounded parameter space) before the
    actor acts and learning starts."""
    updates_per_step: Annotated[float, cli(name="sac-updates-per-step")] = 1.0
    """SAC: gradient steps per env step (a decision of k env steps gets k of them)."""
    init_alpha: Annotated[float, cli(name="sac-init-alpha")] = 1.0
    """SAC: the entropy temperature at the start (tuned automatically towards the target
    entropy)."""
    target_entropy: Annotated[float | None, cli(name="sac-target-entropy")] = None
    """SAC: the temperature's target entropy per decision; None: minus the number of the
    actor's bounded parameters (k A for SAC / chunked SAC, D (1 + N) for NDP-SAC)."""
    critic_layer_norm: Annotated[bool, cli(name="sac-critic-layer-norm")] = False
    """SAC: a LayerNorm after each hidden layer's linear map in both critics (and their
    targets), the normalisation RLPD and BRO use against a critic's extrapolation; off is
    SAC's plain critic (the study's arms)."""
    critic_input: Annotated[str, cli(name="sac-critic-input")] = "params"
    """NDP-SAC: what the critic scores beside the state, 'params' (the bounded DMP parameters)
    or 'actions' (the k actions the DMP gives); SAC and chunked SAC always score actions."""

    def __post_init__(self) -> None:
        plain_numbers(self)  # numpy scalars -> Python numbers; NaN, a non-bool flag refused
        for name, low in (("buffer_size", 1), ("batch_size", 1), ("random_steps", 0)):
            check_int(name, getattr(self, name), low)
        for name in ("lr", "init_alpha", "updates_per_step"):
            check_positive(name, getattr(self, name))
        if not (isinstance(self.tau, (int, float)) and 0 < self.tau <= 1):
            raise ValueError(f"tau: expected a number in (0, 1], got {self.tau!r}")
        te = self.target_entropy
        if te is not None and not (isinstance(te, (int, float)) and math.isfinite(te)):
            raise ValueError(f"target_entropy: expected a finite number or None, got {te!r}")
        if self.critic_input not in CRITIC_INPUTS:
            raise ValueError(
                f"critic_input: expected one of {', '.join(CRITIC_INPUTS)}, got "
                f"{self.critic_input!r}"
            )
