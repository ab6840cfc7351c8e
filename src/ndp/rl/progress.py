"""What every RL learner's training loop shares: the metrics log, the progress bar, the
episode charts and where the loop stops (the PPO trainer and Dyn-E write one ``metrics.csv``
format through this)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

import numpy as np

from ndp.runs import MetricsLogger
from ndp.runs.tracking import make_trackers

if TYPE_CHECKING:
    from ndp.rl.config import TrainConfig


def episode_charts(episodes: Sequence[Sequence[float]]) -> dict[str, float]:
    """``charts/*`` of one iteration from its finished episodes' rows (``EpisodeTracker``:
    success_any, success_final, return, length, return_live); NaN means when none ended."""
    col = np.array(episodes) if len(episodes) else np.full((1, 5), math.nan)
    return {
        "charts/episodes": len(episodes),
        "charts/success_any": float(col[:, 0].mean()),
        "charts/success_final": float(col[:, 1].mean()),
        "charts/episode_return": float(col[:, 2].mean()),
        "charts/episode_return_live": float(col[:, 4].mean()),
        "charts/episode_length": float(col[:, 3].mean()),
    }


def last_update(num_updates: int, update: int, max_updates: int | None) -> int:
    """The update count at which a ``train(max_updates)`` call stops."""
    return num_updates if max_updates is None else min(num_updates, update + max_updates)


class TrainProgress:
    """The run's metrics log (CSV + TensorBoard, continued on resume) and a progress bar in env
    steps; a context manager that closes both.

    Args:
        run_dir: the run directory.
        columns: the metrics columns.
        cfg: the run's ``TrainConfig`` (steps, algo, task, progress, tensorboard).
        update, global_step: where the run stands.
        resumed: whether it continues from a checkpoint (its later rows are dropped).
    """

    def __init__(
        self,
        run_dir: str | Path,
        columns: Sequence[str],
        cfg: TrainConfig,
        update: int,
        global_step: int,
        resumed: bool,
    ) -> None:
        from tqdm import tqdm

        # the env steps the run trains (``--steps`` rounded up to whole updates: say_budget)
        self.steps = int(cfg.num_updates * cfg.env_steps_per_update)
        self.logger = MetricsLogger(
            run_dir,
            columns,
            step="global_step",
            tensorboard=cfg.tensorboard,
            resume_index=update if resumed else None,
            resume_step=global_step if resumed else None,
            trackers=make_trackers(cfg.track, run_dir, cfg.to_dict()),
        )
        self.bar = tqdm(
            total=self.steps,
            initial=min(global_step, self.steps),
            unit="step",
            disable=not cfg.progress,
            dynamic_ncols=True,
            desc=f"{cfg.algo} {cfg.task}",
        )

    def log(self, metrics: dict[str, float]) -> None:
        """Write one iteration's row and advance the bar to its ``global_step``."""
        self.logger.log(metrics)
        self.bar.update(min(int(metrics["global_step"]), self.steps) - self.bar.n)
        self.bar.set_postfix(  # a learner may leave either out (NaN: none ended)
            success=f"{metrics.get('charts/success_any', math.nan):.2f}",
            ret=f"{metrics.get('charts/episode_return', math.nan):.1f}",
        )

    def close(self) -> None:
        self.bar.close()
        self.logger.close()

    def __enter__(self) -> TrainProgress:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
