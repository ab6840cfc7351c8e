"""A sweep's progress lines: runs done / running / failed / busy and an ETA.

Part of :mod:`ndp.experiments.sweep` (its docstring describes the whole).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

from ndp.experiments.sweep.jobs import Job, Outcome
from ndp.runs import metrics_path

# ----------------------------------------------------------------------------- progress


def run_fraction(job: Job) -> float:
    """How much of its budget a run has done (from the last row of its metrics)."""
    path = metrics_path(job.run_dir)
    try:
        with path.open("rb") as fh:
            header = fh.readline().decode().strip().split(",")
            fh.seek(0, os.SEEK_END)
            size = fh.tell()
            fh.seek(max(0, size - 4096))
            tail = fh.read().decode(errors="replace").strip().splitlines()
    except OSError:
        return 0.0
    if not tail or "," not in tail[-1] or tail[-1].split(",")[0] == header[0]:
        return 0.0
    col = "global_step" if "global_step" in header else header[0]
    try:
        value = float(tail[-1].split(",")[header.index(col)])
    except (ValueError, IndexError):
        return 0.0
    return min(1.0, max(0.0, value / job.steps))


def _hms(seconds: float) -> str:
    s = round(seconds)
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


class Progress:
    """Progress lines: runs done / running / failed / queued, the share of the budget done and
    an ETA (the rate of this session's progress, in env steps or epochs)."""

    def __init__(self, jobs: Sequence[Job], out: TextIO | None = None, every: float = 30.0):
        self.jobs = list(jobs)
        self.out = out or sys.stdout
        self.every = max(0.5, float(every))
        self.t0 = time.time()
        self.last = self.t0
        self.start_frac = {j.run_dir: run_fraction(j) for j in self.jobs}
        self.work0 = sum(self.start_frac.values())
        self.status: dict[Path, str] = {}
        self.running: set[Path] = set()
        self.noted_busy: set[Path] = set()

    def started(self, job: Job) -> None:
        self.running.add(job.run_dir)
        if self.status.get(job.run_dir) == "busy":  # polled again: it is queued work, not busy
            del self.status[job.run_dir]

    def waiting(self, outcome: Outcome) -> None:
        """A run another process is training: noted once, counted as busy while it waits."""
        run = outcome.job.run_dir
        self.running.discard(run)
        self.status[run] = "busy"
        if run not in self.noted_busy:
            self.noted_busy.add(run)
            self.note(
                f"busy        {outcome.job.name}: {outcome.error}; waiting for it after this "
                "sweep's other runs",
                with_counts=True,
            )

    def finished(self, outcome: Outcome) -> None:
        self.running.discard(outcome.job.run_dir)
        self.status[outcome.job.run_dir] = outcome.status
        what = {"done": "finished", "skipped": "already finished"}.get(outcome.status)
        msg = f"{outcome.status:<11} {outcome.job.name}"
        if what == "finished":
            msg += f" ({_hms(outcome.seconds)})"
        if outcome.status in ("failed", "busy"):
            msg += f": {outcome.error}"
        self.note(msg, with_counts=True)

    def retry(self, outcome: Outcome, attempt: int, of: int) -> None:
        self.running.discard(outcome.job.run_dir)
        self.note(f"retrying   {outcome.job.name} (attempt {attempt}/{of}) after: {outcome.error}")

    def work(self) -> float:
        total = 0.0
        for j in self.jobs:
            st = self.status.get(j.run_dir)
            if st in ("done", "skipped"):
                total += 1.0
            elif j.run_dir in self.running or st == "busy":
                total += run_fraction(j)
            else:
                total += self.start_frac[j.run_dir]
        return total

    def counts(self) -> str:
        vals = list(self.status.values())
        done = sum(v in ("done", "skipped") for v in vals)
        failed = sum(v == "failed" for v in vals)
        busy = sum(v == "busy" for v in vals)
        queued = len(self.jobs) - len(vals) - len(self.running)
        work = self.work()
        elapsed = time.time() - self.t0
        gained = work - self.work0
        if work >= len(self.jobs) - 1e-9:
            eta = "0:00:00"
        elif gained > 1e-3 and elapsed > 0:
            eta = _hms(elapsed * (len(self.jobs) - work) / gained)
        else:
            eta = "?"
        return (
            f"{done}/{len(self.jobs)} done, {len(self.running)} running, {failed} failed, "
            + (f"{busy} busy elsewhere, " if busy else "")
            + f"{queued} queued; {100 * work / max(1, len(self.jobs)):.0f}% of the budget; "
            f"elapsed {_hms(elapsed)}, ETA {eta}"
        )

    def note(self, msg: str, with_counts: bool = False) -> None:
        stamp = time.strftime("%H:%M:%S")
        line = f"[{stamp}] {msg}" + (f" | {self.counts()}" if with_counts else "")
        print(line, file=self.out, flush=True)
        self.last = time.time()

    def tick(self) -> None:
        if time.time() - self.last >= self.every:
            self.note(self.counts())

    def timeout(self) -> float:
        return max(0.1, self.every - (time.time() - self.last))
