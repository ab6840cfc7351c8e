"""Experiment tracking beyond the CSV and TensorBoard: Weights & Biases, offline by default.

``ndp rl train --track wandb`` (``RunConfig.track``) adds a :class:`WandbTracker` to the run's
metrics log (:class:`ndp.runs.MetricsLogger`): every ``metrics.csv`` row is logged to a W&B run
at its ``global_step``, with the resolved config as the run's config. The W&B run lives in
``RUN/wandb/``; its id is kept in ``RUN/wandb/ndp-run-id`` so a resumed run continues the same
W&B run.

Mode: ``WANDB_MODE`` as W&B reads it; unset, **offline** (nothing leaves the machine; upload
later with ``wandb sync RUN/wandb/offline-run-*``). ``WANDB_PROJECT`` names the project
(default ``ndp``). W&B refuses a step lower than one it has logged, so after a resume from a
checkpoint the rows between the checkpoint and the interruption keep their first values in
W&B, while ``metrics.csv`` and TensorBoard hold the resumed ones.

wandb is optional (the ``[track]`` extra); asking for it without it installed is refused with
the command that installs it.
"""

from __future__ import annotations

import math
import os
import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import Literal, Protocol, cast

from ndp.io import atomic_write_text

__all__ = ["TRACKERS", "Tracker", "WandbTracker", "check_track", "make_trackers"]

TRACKERS = ("none", "wandb")
"""The values of ``--track``."""

MODES = ("offline", "online", "disabled")
"""The ``WANDB_MODE`` values a run accepts (unset: offline)."""

ID_FILE = "ndp-run-id"
"""Inside ``RUN/wandb/``: the W&B run id, so a resume continues the same W&B run."""


class Tracker(Protocol):
    """Where a metrics row goes besides the CSV (:class:`ndp.runs.MetricsLogger`)."""

    def log(self, metrics: Mapping[str, float], step: int) -> None:
        """One row at x-axis value ``step`` (NaN values already left out)."""
        ...

    def close(self) -> None:
        """Flush and finish."""
        ...


def check_track(track: str) -> None:
    """Refuse a ``track`` value that is not one of :data:`TRACKERS` (one line, naming it)."""
    if track not in TRACKERS:
        raise ValueError(f"track: expected one of {', '.join(TRACKERS)}, got {track!r}")


class WandbTracker:
    """A W&B run in ``RUN/wandb`` (offline unless ``WANDB_MODE`` says otherwise).

    Args:
        run_dir: the run directory.
        name: the W&B run's display name (the run directory's name).
        config: the run's resolved config (JSON-ready), the W&B run's config.

    Raises:
        ValueError: wandb is not installed (one line with the install command).
    """

    def __init__(self, run_dir: str | Path, name: str, config: Mapping[str, object]) -> None:
        try:
            import wandb
        except ImportError:
            raise ValueError(
                "track: --track wandb needs wandb: pip install 'wandb>=0.19' (or the [track] "
                "extra: pip install -e '.[track]')"
            ) from None
        folder = Path(run_dir) / "wandb"
        folder.mkdir(parents=True, exist_ok=True)
        id_file = folder / ID_FILE
        if id_file.is_file():
            run_id = id_file.read_text().strip()
        else:
            run_id = uuid.uuid4().hex[:12]  # W&B ids: lowercase letters and digits
            atomic_write_text(id_file, run_id + "\n")
        mode = os.environ.get("WANDB_MODE", "offline")
        if mode not in MODES:
            raise ValueError(f"track: WANDB_MODE must be one of {', '.join(MODES)}, got {mode!r}")
        self._run = wandb.init(
            dir=str(run_dir),
            project=os.environ.get("WANDB_PROJECT", "ndp"),
            name=name,
            id=run_id,
            resume="allow",
            mode=cast(Literal["online", "offline", "disabled"], mode),
            config=dict(config),
            settings=wandb.Settings(silent=True, console="off"),
        )

    def log(self, metrics: Mapping[str, float], step: int) -> None:
        """Log one row at ``step`` (the run's ``global_step``)."""
        self._run.log(dict(metrics), step=int(step))

    def close(self) -> None:
        """Finish the W&B run (its files are complete after this)."""
        self._run.finish()


def make_trackers(track: str, run_dir: str | Path, config: Mapping[str, object]) -> list[Tracker]:
    """The trackers ``--track`` asks for (none for ``'none'``)."""
    check_track(track)
    if track == "wandb":
        return [WandbTracker(run_dir, Path(run_dir).name, config)]
    return []


def finite_row(metrics: Mapping[str, object], skip: tuple[str, ...]) -> dict[str, float]:
    """The numeric, non-NaN values of a metrics row, without the ``skip`` columns."""
    return {
        name: float(v)
        for name, v in metrics.items()
        if name not in skip and isinstance(v, (int, float)) and not math.isnan(float(v))
    }
