"""Thin metrics logger: TensorBoard event files and a CSV with stable column names.

The names are documented in docs/metrics.md; :data:`METRICS` is the CSV's column order.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

METRICS: tuple[str, ...] = (
    "update",
    "global_step",
    "charts/episodes",
    "charts/success_any",
    "charts/success_final",
    "charts/episode_return",
    "charts/episode_return_live",
    "charts/episode_length",
    "charts/env_steps_per_s",
    "charts/learning_rate",
    "losses/policy",
    "losses/value",
    "losses/entropy",
    "losses/approx_kl",
    "losses/clipfrac",
    "losses/grad_norm",
    "losses/explained_variance",
    "policy/std",
    "dmp/goal_norm",
    "dmp/weight_norm",
    "time/rollout_s",
    "time/update_s",
)
"""CSV columns, in order. Values that do not apply (e.g. dmp/* for PPO) are left empty."""

TIME_METRICS = ("charts/env_steps_per_s", "time/rollout_s", "time/update_s")
"""Columns that depend on wall-clock time (excluded from determinism checks)."""


class Logger:
    """Write one row per update to ``progress.csv`` and, optionally, TensorBoard.

    Args:
        run_dir: run directory.
        tensorboard: also write TensorBoard events under ``run_dir/tb``.
        resume_update: when resuming, drop CSV rows after this update and purge TensorBoard
            events after ``resume_step``.
        resume_step: global step of the checkpoint resumed from.
    """

    def __init__(
        self,
        run_dir: Path,
        tensorboard: bool = True,
        resume_update: int | None = None,
        resume_step: int | None = None,
    ) -> None:
        self.path = Path(run_dir) / "progress.csv"
        self.path.parent.mkdir(parents=True, exist_ok=True)
        rows: list[dict[str, str]] = []
        if resume_update is not None and self.path.is_file():
            with self.path.open(newline="") as f:
                rows = [r for r in csv.DictReader(f) if int(r["update"]) <= resume_update]
        self._file = self.path.open("w", newline="")
        self._csv = csv.DictWriter(self._file, fieldnames=list(METRICS))
        self._csv.writeheader()
        self._csv.writerows(rows)
        self._file.flush()
        self._tb = None
        if tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            self._tb = SummaryWriter(str(Path(run_dir) / "tb"), purge_step=resume_step)

    def log(self, metrics: dict[str, Any]) -> None:
        """Write one row (unknown keys raise ValueError; missing or NaN values stay empty)."""
        unknown = set(metrics) - set(METRICS)
        if unknown:
            raise ValueError(f"metrics: unknown names {sorted(unknown)}; see docs/metrics.md")
        row = {}
        for name in METRICS:
            v = metrics.get(name)
            if v is None or (isinstance(v, float) and math.isnan(v)):
                row[name] = ""
            else:
                row[name] = repr(float(v)) if isinstance(v, float) else str(v)
        self._csv.writerow(row)
        self._file.flush()
        if self._tb is not None:
            step = int(metrics["global_step"])
            for name, v in metrics.items():
                if name in ("update", "global_step") or v is None:
                    continue
                if not (isinstance(v, float) and math.isnan(v)):
                    self._tb.add_scalar(name, float(v), step)

    def close(self) -> None:
        """Flush and close."""
        self._file.close()
        if self._tb is not None:
            self._tb.close()


def read_csv(path: Path) -> list[dict[str, float]]:
    """Read ``progress.csv`` as a list of dicts (empty cells become NaN)."""
    with Path(path).open(newline="") as f:
        return [
            {k: float(v) if v != "" else math.nan for k, v in r.items()} for r in csv.DictReader(f)
        ]
