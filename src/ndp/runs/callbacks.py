"""Training callbacks: code of yours called by the run driver after every update (epoch).

The habit of Stable-Baselines3's ``EvalCallback`` / ``CheckpointCallback``, for every learner
the driver runs (``ndp.rl.run.train(cfg, callbacks=[...])``, ``ndp.rl.run.resume``, the imitation
trainers): subclass :class:`Callback` and override what you need.

- :meth:`Callback.on_update` after each update's row is logged;
- :meth:`Callback.on_eval` after an update whose row holds a periodic evaluation
  (``eval/*`` columns: ``--eval-every``);
- :meth:`Callback.should_stop`: True ends the run after this update; the driver writes a
  checkpoint first, so ``ndp rl train --resume RUN`` (or ``ndp.rl.run.resume``) continues it.

Two ready ones: :class:`StopAtSuccess` (stop once the deterministic evaluation reaches a
success rate) and :class:`CheckpointEvery` (a checkpoint every N updates beside the run's own
cadence). Example::

    from ndp.rl.run import train
    from ndp.runs.callbacks import CheckpointEvery, StopAtSuccess

    train(cfg, callbacks=[StopAtSuccess(0.9), CheckpointEvery(5)])

A callback that raises stops the run as any error does (the last checkpoint stays).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ndp.checks import check_int

__all__ = ["Callback", "CallbackContext", "CheckpointEvery", "StopAtSuccess", "check_callbacks"]

EVAL_PREFIX = "eval/"
"""A row holds a periodic evaluation where one of its columns starts with this."""


@dataclass(frozen=True)
class CallbackContext:
    """What a callback may read of the run (and the one thing it may do: save now)."""

    step: int
    """The learner's step count (updates, or epochs) after this update."""
    budget: int
    """The run's budget in the same unit."""
    run_dir: Path
    """The run directory."""
    learner: Any
    """The learner (``.model`` is the actor-critic of the RL learners); read it, do not step
    it."""
    save: Callable[[], Path]
    """Write the checkpoint now (only from finite parameters); returns its path."""


class Callback:
    """Override any of the three; the defaults do nothing and never stop."""

    def on_update(self, row: dict[str, float], ctx: CallbackContext) -> None:
        """After every update's row is logged (``row``: the metrics.csv columns)."""

    def on_eval(self, row: dict[str, float], ctx: CallbackContext) -> None:
        """After an update whose row holds a periodic evaluation (``eval/*`` columns)."""

    def should_stop(self, row: dict[str, float], ctx: CallbackContext) -> bool:
        """True: end the run after this update (checkpointed first, resumable)."""
        return False


def has_eval(row: dict[str, float]) -> bool:
    """Whether ``row`` holds a periodic evaluation (a finite ``eval/*`` value)."""
    return any(
        k.startswith(EVAL_PREFIX) and isinstance(v, (int, float)) and math.isfinite(v)
        for k, v in row.items()
    )


class StopAtSuccess(Callback):
    """Stop once ``key`` (default the deterministic evaluation's success at any step) reaches
    ``threshold`` on ``patience`` consecutive evaluations.

    Raises:
        ValueError: ``threshold`` outside [0, 1] or ``patience`` < 1 (naming the argument).
    """

    def __init__(self, threshold: float, key: str = "eval/success_any", patience: int = 1) -> None:
        if not (isinstance(threshold, (int, float)) and 0.0 <= threshold <= 1.0):
            raise ValueError(f"threshold: expected a success rate in [0, 1], got {threshold!r}")
        check_int("patience", patience, 1)
        self.threshold, self.key, self.patience = float(threshold), str(key), patience
        self.streak = 0
        """Consecutive evaluations at or above the threshold so far."""

    def on_eval(self, row: dict[str, float], ctx: CallbackContext) -> None:
        value = row.get(self.key, math.nan)
        self.streak = self.streak + 1 if value >= self.threshold else 0

    def should_stop(self, row: dict[str, float], ctx: CallbackContext) -> bool:
        return self.streak >= self.patience


class CheckpointEvery(Callback):
    """Write the checkpoint every ``n`` updates (beside the run's own cadence); ``paths`` lists
    what it wrote.

    Raises:
        ValueError: ``n`` < 1 (naming the argument).
    """

    def __init__(self, n: int) -> None:
        check_int("n", n, 1, note="(updates)")
        self.n = n
        self.paths: list[Path] = []

    def on_update(self, row: dict[str, float], ctx: CallbackContext) -> None:
        if ctx.step % self.n == 0:
            self.paths.append(ctx.save())


def check_callbacks(callbacks: Sequence[object] | None) -> list[Callback]:
    """The callbacks as a list, each one checked.

    Raises:
        ValueError: one that is not a :class:`Callback` (naming ``callbacks`` and its index).
    """
    out: list[Callback] = []
    for i, cb in enumerate(callbacks or ()):
        if not isinstance(cb, Callback):
            raise ValueError(
                f"callbacks: expected ndp.runs.callbacks.Callback instances, got "
                f"{type(cb).__name__} at index {i}"
            )
        out.append(cb)
    return out
