"""TD3's settings (``--algo td3``): one typed config, the section ``td3`` of
``ndp.rl.config.TrainConfig`` (registered by :mod:`ndp.rl.td3`), options ``--td3-*``.

Defaults are Stable-Baselines3 2.x's ``TD3`` defaults (``stable_baselines3/td3/td3.py``, the
values of Fujimoto et al. 2018): learning rate 1e-3 (actor and critics), buffer 1M, batch 256,
tau 0.005, policy delay 2, target policy noise 0.2 clipped at 0.5, one gradient step per env
step. Two values are not SB3's defaults: the exploration noise, N(0, 0.1^2) on the bounded
action (the paper's; SB3's default is no noise and its documentation's example passes
``NormalActionNoise(sigma=0.1)``), and the random steps, 5,000 (our SAC's convention; SB3's
``learning_starts`` is 100). The discount is the run's ``--gamma`` (per env step, every
method's); the networks are ``--hidden`` / ``--activation``, 400-300 ReLU for TD3 (SB3's default
``net_arch`` for TD3 and the paper's). docs/offpolicy.md, "TD3", has the maths and the sources.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Literal

from ndp.checks import check_choice, check_int, check_positive, plain_numbers
from ndp.runs.cli import cli


@dataclass(frozen=True)
class TD3Config:
    """TD3 (``ndp.rl.td3``); read only by ``--algo td3``."""

    buffer_size: Annotated[int, cli(name="td3-buffer-size")] = 1_000_000
    """TD3: replay capacity in env steps (decisions x k; saved with the checkpoint). SB3: 1M."""
    batch_size: Annotated[int, cli(name="td3-batch-size")] = 256
    """TD3: decisions per gradient step. SB3 2.x: 256 (the paper: 100 for TD3, 256 in its
    later code)."""
    lr: Annotated[float, cli(name="td3-lr")] = 1e-3
    """TD3: Adam learning rate of the actor and of the twin critics. SB3 / the paper: 1e-3."""
    tau: Annotated[float, cli(name="td3-tau")] = 0.005
    """TD3: soft update rate of the target actor and target critics (at each delayed actor
    update). SB3 / the paper: 0.005."""
    random_steps: Annotated[int, cli(name="td3-random-steps")] = 5000
    """TD3: env steps acting uniformly at random (in the bounded action space) before the
    actor acts and learning starts. Our SAC's 5,000 (SB3's learning_starts: 100; the paper:
    25,000 in its later code, 10,000 in the paper)."""
    updates_per_step: Annotated[float, cli(name="td3-updates-per-step")] = 1.0
    """TD3: critic gradient steps per env step (a decision of k env steps gets k of them).
    SB3: train_freq 1, gradient_steps 1."""
    policy_delay: Annotated[int, cli(name="td3-policy-delay")] = 2
    """TD3: critic steps per actor update; the targets are soft-updated with the actor (every
    policy_delay-th critic step, counted from 1). SB3 / the paper: 2."""
    expl_noise: Annotated[float, cli(name="td3-expl-noise")] = 0.1
    """TD3: std of the Gaussian exploration noise added to the actor's bounded action in
    [-1, 1] (then clipped to [-1, 1]). The paper: 0.1 (SB3: no noise unless given)."""
    target_noise: Annotated[float, cli(name="td3-target-noise")] = 0.2
    """TD3: std of the target policy smoothing noise on the target actor's bounded action.
    SB3 / the paper: 0.2."""
    target_noise_clip: Annotated[float, cli(name="td3-target-noise-clip")] = 0.5
    """TD3: the smoothing noise is clipped to +- this before it is added (and the sum to
    [-1, 1]). SB3 / the paper: 0.5."""
    init: Annotated[Literal["orthogonal", "torch"], cli(name="td3-init")] = "torch"
    """TD3: initialisation of the actor's and the critics' linear layers. torch: PyTorch's
    ``nn.Linear`` default (uniform in +-1/sqrt(fan_in)), what SB3's TD3 and the paper's code
    use; orthogonal: the other learners' (``ndp.nets.mlp.MLP``: hidden gain sqrt(2) for ReLU,
    the actor's output 0.01, the critics' 1), TD3's only one in the first check (035f40e),
    where two of three push-v3 runs saturated the actor at once (docs/offpolicy.md, "TD3")."""

    def __post_init__(self) -> None:
        plain_numbers(self)  # numpy scalars -> Python numbers; NaN, a non-bool flag refused
        for name, low in (("buffer_size", 1), ("batch_size", 1), ("random_steps", 0),
                          ("policy_delay", 1)):  # fmt: skip
            check_int(name, getattr(self, name), low)
        for name in ("lr", "updates_per_step"):
            check_positive(name, getattr(self, name))
        for name in ("expl_noise", "target_noise", "target_noise_clip"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {v!r}")
        check_choice("init", self.init, ("orthogonal", "torch"))
        if not (isinstance(self.tau, (int, float)) and 0 < self.tau <= 1):
            raise ValueError(f"tau: expected a number in (0, 1], got {self.tau!r}")
