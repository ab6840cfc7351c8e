"""Deterministic evaluation during training, for every RL learner.

Training-episode success measures the policy *with its exploration noise*; a method whose noise
decays slowly looks worse on it than its mean policy is. :class:`PeriodicEvaluator` runs, every
``TrainConfig.eval_every`` env steps and after the last update, ``eval_episodes`` episodes of the
policy's mode (no noise) on the fixed evaluation seeds ``EVAL_SEED, EVAL_SEED + 1, ...``, which
no training episode uses (training resets draw 32-bit seeds from ``SeedSequence([seed, epoch])``),
in an env of its own built like the run's (task options, k, stale-world rule, execution).

It does not change the training stream: it draws no random number from the learner's generators
(the mode is deterministic, the env has its own seeded generator), it restores the global torch,
NumPy and Python random states around each evaluation anyway, and it never updates the
observation normaliser. ``tests/rl/test_periodic_eval.py`` checks that a run's training columns
are identical with evaluation on and off.

Columns (:data:`EVAL_METRICS`, NaN in rows without an evaluation): ``eval/success_any`` (success
at any step), ``eval/success_final`` (at the final step), ``eval/return`` (mean return),
``eval/episodes`` and ``time/eval_s``.
"""

from __future__ import annotations

import math
import random
import time
from typing import TYPE_CHECKING

import numpy as np
import torch

if TYPE_CHECKING:
    from ndp.envs.chunked import ChunkedEnv
    from ndp.rl.config import TrainConfig
    from ndp.rl.normalize import ObsNormalizer
    from ndp.schema import TaskSchema

EVAL_METRICS = (
    "eval/success_any",
    "eval/success_final",
    "eval/return",
    "eval/episodes",
    "time/eval_s",
)
"""metrics.csv columns of the periodic deterministic evaluation (docs/metrics.md)."""


def eval_due(every: int, before: int, after: int, last: bool) -> bool:
    """Whether an evaluation is due after an update that took the run from ``before`` to
    ``after`` env steps: ``after`` crossed a multiple of ``every``, or it was the run's last
    update; never when ``every`` is 0 (off)."""
    if every <= 0:
        return False
    return last or after // every > before // every


class PeriodicEvaluator:
    """Evaluate a learner's current policy deterministically (see the module docstring).

    Args:
        cfg: the run's resolved :class:`ndp.rl.config.TrainConfig` (``eval_every``,
            ``eval_episodes``, the task options and chunked-env options).
        spec: the task spec the run's model was built for.
    """

    def __init__(self, cfg: TrainConfig, spec: TaskSchema) -> None:
        self.cfg = cfg
        self.spec = spec
        self.every = int(cfg.eval_every)
        self.episodes = int(cfg.eval_episodes)
        self._env: ChunkedEnv | None = None

    @property
    def enabled(self) -> bool:
        """Whether this run evaluates at all (``eval_every`` and ``eval_episodes`` > 0)."""
        return self.every > 0 and self.episodes > 0

    def maybe(
        self, before: int, after: int, last: bool, model: torch.nn.Module, obs_norm: ObsNormalizer
    ) -> dict[str, float]:
        """The :data:`EVAL_METRICS` of this update: an evaluation where one is due
        (:func:`eval_due`), else NaN."""
        if not (self.enabled and eval_due(self.every, before, after, last)):
            return dict.fromkeys(EVAL_METRICS, math.nan)
        return self.evaluate(model, obs_norm)

    def evaluate(self, model: torch.nn.Module, obs_norm: ObsNormalizer) -> dict[str, float]:
        """``eval_episodes`` deterministic episodes of ``model`` (an actor-critic of
        :func:`ndp.policies.build_actor_critic`) with ``obs_norm``'s statistics as they are."""
        from ndp.rl.config import EVAL_SEED
        from ndp.rl.evaluate import run_episode
        from ndp.rl.policy import Policy

        t0 = time.perf_counter()
        # the legacy global NumPy state is what seeding sets and what must come back unchanged
        states = (torch.get_rng_state(), np.random.get_state(), random.getstate())  # noqa: NPY002
        was_training = model.training
        try:
            model.eval()
            pol = Policy(self.cfg, self.spec, model, obs_norm)
            if self._env is None:
                self._env = pol.make_env()
            with torch.no_grad():
                rows = [
                    run_episode(pol, self._env, EVAL_SEED + i, True) for i in range(self.episodes)
                ]
        finally:
            model.train(was_training)
            torch.set_rng_state(states[0])
            np.random.set_state(states[1])  # noqa: NPY002
            random.setstate(states[2])
        return {
            "eval/success_any": float(np.mean([r["success_any"] for r in rows])),
            "eval/success_final": float(np.mean([r["success_final"] for r in rows])),
            "eval/return": float(np.mean([r["episode_return"] for r in rows])),
            "eval/episodes": float(len(rows)),
            "time/eval_s": time.perf_counter() - t0,
        }

    def close(self) -> None:
        """Close the evaluation env (if one was built)."""
        if self._env is not None:
            self._env.close()
            self._env = None
