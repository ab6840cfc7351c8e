"""One metrics logger for every trainer: a CSV with fixed columns and TensorBoard, kept in step.

Each trainer names its columns once (RL: :data:`ndp.rl.logger.METRICS`, one row per update;
imitation: :data:`ndp.il.train.METRICS`, one row per epoch); docs/metrics.md documents both.
On resume the CSV keeps exactly the rows up to the checkpoint and TensorBoard drops the events
after it, so a resumed run's curves equal an uninterrupted run's.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ndp.runs.layout import LEGACY_METRICS_NAMES, METRICS_NAME, TB_DIR
from ndp.runs.signals import deferred_stops
from ndp.runs.tracking import Tracker, finite_row


def metrics_path(run_dir: str | Path) -> Path:
    """The metrics CSV of a run directory (a legacy ``progress.csv`` when that is all it has)."""
    run_dir = Path(run_dir)
    path = run_dir / METRICS_NAME
    if not path.exists():
        for name in LEGACY_METRICS_NAMES:
            if (run_dir / name).exists():
                return run_dir / name
    return path


def read_metrics(run_dir: str | Path) -> list[dict[str, float]]:
    """The rows of a run's metrics CSV as floats (empty cells: NaN); a file path works too.

    Raises:
        FileNotFoundError: no metrics file.
        ValueError: a file that is not a metrics CSV (binary, a cell that is not a number),
            naming it.
    """
    path = Path(run_dir)
    if path.is_dir():
        path = metrics_path(path)
    if not path.is_file():
        raise FileNotFoundError(f"metrics: no such file {path}")
    try:
        with path.open(newline="") as f:
            return [
                {k: float(v) if v not in ("", None) else math.nan for k, v in r.items()}
                for r in csv.DictReader(f)
            ]
    except (UnicodeDecodeError, csv.Error) as exc:
        why = exc.reason if isinstance(exc, UnicodeDecodeError) else str(exc)
        raise ValueError(f"metrics: {path} is not a metrics CSV (not text: {why})") from None
    except (TypeError, ValueError) as exc:  # a cell that is not a number, a ragged row
        raise ValueError(f"metrics: {path} is not a metrics CSV ({exc})") from None


class MetricsLogger:
    """Write one row per update / epoch to ``metrics.csv`` and, optionally, TensorBoard.

    Args:
        run_dir: run directory.
        columns: CSV columns in order; the first is the row index (``update``, ``epoch``).
        step: the column used as TensorBoard's x axis (``global_step``, ``epoch``).
        tensorboard: also write TensorBoard events under ``run_dir/tb``.
        resume_index: when resuming, keep the CSV rows with index <= this and drop TensorBoard
            events with a step after ``resume_step``.
        resume_step: the x-axis value of the checkpoint resumed from.
        filename, tb_dir: the CSV's file name and the TensorBoard folder inside ``run_dir``
            (other than the defaults only for a second log, e.g. behaviour cloning before RL).
        trackers: where each row also goes (:mod:`ndp.runs.tracking`, e.g. W&B), at the
            ``step`` column's value; closed with the logger.
    """

    def __init__(
        self,
        run_dir: str | Path,
        columns: Sequence[str],
        step: str,
        tensorboard: bool = True,
        resume_index: int | None = None,
        resume_step: int | None = None,
        filename: str = METRICS_NAME,
        tb_dir: str = TB_DIR,
        trackers: Sequence[Tracker] = (),
    ) -> None:
        self.columns = tuple(columns)
        self._trackers = tuple(trackers)
        if step not in self.columns:
            raise ValueError(f"step: {step!r} is not one of the columns")
        self.index, self.step = self.columns[0], step
        self.path = Path(run_dir) / filename
        self.path.parent.mkdir(parents=True, exist_ok=True)
        rows: list[dict[str, str]] = []
        if resume_index is not None and self.path.is_file():
            with self.path.open(newline="") as f:
                rows = [
                    {c: r.get(c) or "" for c in self.columns}
                    for r in csv.DictReader(f)
                    if float(r[self.index]) <= resume_index
                ]
        self._file = self.path.open("w", newline="")
        self._csv = csv.DictWriter(self._file, fieldnames=list(self.columns))
        self._csv.writeheader()
        self._csv.writerows(rows)
        self._file.flush()
        self._tb = None
        if tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            purge = None if resume_step is None else int(resume_step) + 1
            self._tb = SummaryWriter(str(Path(run_dir) / tb_dir), purge_step=purge)

    def log(self, metrics: dict[str, Any]) -> None:
        """Write one row (unknown names raise ValueError; missing or NaN values stay empty)."""
        unknown = set(metrics) - set(self.columns)
        if unknown:
            raise ValueError(f"metrics: unknown names {sorted(unknown)}; see docs/metrics.md")
        row = {}
        for name in self.columns:
            v = metrics.get(name)
            if v is None or (isinstance(v, float) and math.isnan(v)):
                row[name] = ""
            else:
                row[name] = repr(float(v)) if isinstance(v, float) else str(v)
        # a stop (SIGTERM / Ctrl-C under stop_on_sigterm) waits until the row is written: raised
        # inside TensorBoard's writer it could leave its lock held and hang the close
        with deferred_stops():
            self._csv.writerow(row)
            self._file.flush()
            if self._tb is not None:
                x = int(metrics[self.step])
                for name, v in metrics.items():
                    if name in (self.index, self.step) or v is None:
                        continue
                    if not (isinstance(v, float) and math.isnan(v)):
                        self._tb.add_scalar(name, float(v), x)
                self._tb.flush()
            if self._trackers:
                values = finite_row(metrics, (self.index, self.step))
                for tracker in self._trackers:
                    tracker.log(values, int(metrics[self.step]))

    def close(self) -> None:
        """Flush and close (the trackers too)."""
        self._file.close()
        if self._tb is not None:
            self._tb.close()
        for tracker in self._trackers:
            tracker.close()

    def __enter__(self) -> MetricsLogger:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
