"""The sweep driver: run a list of jobs on a backend, retry a failure once, wait for busy
runs.

Part of :mod:`ndp.experiments.sweep` (its docstring describes the whole).
"""

from __future__ import annotations

import contextlib
import json
import sys
import time
from collections import deque
from collections.abc import Hashable, Sequence
from pathlib import Path
from typing import TextIO

from ndp.experiments.sweep.backends import Backend, make_backend
from ndp.experiments.sweep.checks import check_plan
from ndp.experiments.sweep.jobs import BUSY_POLL_S, FAILED_NAME, Job, Outcome, SweepResult
from ndp.experiments.sweep.progress import Progress, _hms
from ndp.io import atomic_write_text
from ndp.runs.signals import exit_code, stop_on_sigterm

# ----------------------------------------------------------------------------- the driver


def run_sweep(
    jobs: Sequence[Job],
    backend: str = "local",
    workers: int | None = None,
    address: str | None = None,
    retries: int = 1,
    progress_every: float = 30.0,
    out: TextIO | None = None,
    wait_busy: bool = True,
) -> SweepResult:
    """Execute ``jobs`` (see the module doc); returns when every job has an outcome or the sweep
    was interrupted (``result.interrupted``; every run resumable).

    A run that another process is training (its lock is held) is put aside; once nothing else
    is queued it is tried again every :data:`BUSY_POLL_S` seconds, so it ends 'skipped' when
    that process finished it, or is continued here from its checkpoint when that process
    stopped. ``wait_busy=False``: its outcome is 'busy' at once (exit code 1).

    Raises:
        ValueError: a run directory holds another run, or two jobs share one (nothing started).
    """
    jobs = list(jobs)
    check_plan(jobs)
    out = out or sys.stdout
    t0 = time.time()

    be = make_backend(backend, workers, address)
    progress = Progress(jobs, out, progress_every)
    st = _Loop(jobs, retries, wait_busy, progress)
    stop_code = 0
    try:
        with stop_on_sigterm():
            progress.note(f"sweep: {len(jobs)} runs on {be.describe()}; {progress.counts()}")
            while st.queue or st.inflight or st.aside:
                st.step(be)
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (ndp.runs.signals.Terminated)
        st.interrupted, stop_code = True, exit_code(exc)
        st.stop(be)
    finally:
        be.close()
    result = SweepResult(jobs, st.outcomes, st.interrupted, time.time() - t0)
    result.exit_code = stop_code or (1 if result.failed or result.busy else 0)
    _print_summary(result, progress)
    return result


class _Loop:
    """The state of a sweep's loop: the queue, the runs in flight, those busy elsewhere (put
    aside until their next poll), and each job's outcome."""

    def __init__(self, jobs: list[Job], retries: int, wait_busy: bool, progress: Progress) -> None:
        self.retries, self.wait_busy, self.progress = retries, wait_busy, progress
        self.index = {j.run_dir: i for i, j in enumerate(jobs)}
        self.outcomes: list[Outcome | None] = [None] * len(jobs)
        self.queue: deque[tuple[Job, int]] = deque((j, 1) for j in jobs)
        self.inflight: dict[Hashable, tuple[Job, int]] = {}
        self.aside: dict[Path, tuple[float, Job, int, Outcome]] = {}  # next poll time
        self.interrupted = False

    def settle(self, h: Hashable, res: Outcome | BaseException) -> None:
        """Record what the run of handle ``h`` came to: busy (put aside), failed (retried
        while attempts are left) or its outcome."""
        job, attempt = self.inflight.pop(h)
        if isinstance(res, BaseException):
            cancelled = type(res).__name__ in ("TaskCancelledError",) or self.interrupted
            res = Outcome(
                job,
                "interrupted" if cancelled else "failed",
                error="" if cancelled else f"{type(res).__name__}: {res}",
            )
        res.job, res.attempts = job, attempt
        if res.status == "busy" and self.wait_busy and not self.interrupted:
            self.aside[job.run_dir] = (time.time() + BUSY_POLL_S, job, attempt, res)
            self.progress.waiting(res)
            return
        if res.status == "failed" and attempt <= self.retries and not self.interrupted:
            self.progress.retry(res, attempt + 1, self.retries + 1)
            self.queue.appendleft((job, attempt + 1))
            return
        self.outcomes[self.index[job.run_dir]] = res
        if res.status == "failed":
            _write_failed(res)
        self.progress.finished(res)

    def step(self, be: Backend) -> None:
        """One turn: requeue the busy runs due for a poll (once the queue is out), submit while
        slots are free, settle what finished (or sleep until the next poll)."""
        if not self.queue:  # this sweep's own work is out: poll the runs others train
            now = time.time()
            for key, (due, job, attempt, _) in list(self.aside.items()):
                if due <= now:
                    del self.aside[key]
                    self.queue.append((job, attempt))
        while self.queue and len(self.inflight) < be.slots:
            job, attempt = self.queue.popleft()
            h = be.submit(job)
            self.inflight[h] = (job, attempt)
            self.progress.started(job)
        if self.inflight:
            for h, res in be.wait(list(self.inflight), self.progress.timeout()):
                self.settle(h, res)
        elif self.aside:
            next_due = min(due for due, *_ in self.aside.values())
            time.sleep(max(0.05, min(self.progress.timeout(), next_due - time.time())))
        self.progress.tick()

    def stop(self, be: Backend) -> None:
        """Interrupted: stop the running trainers at their last checkpoint; the runs busy
        elsewhere keep their 'busy' outcome (not ours to stop)."""
        self.progress.note(
            f"interrupted: stopping {len(self.inflight)} running trainers at their last checkpoint"
        )
        for h, res in be.interrupt(list(self.inflight)):
            if h in self.inflight:
                self.settle(h, res)
        for _, job, _attempt, res in self.aside.values():
            self.outcomes[self.index[job.run_dir]] = res


def _write_failed(outcome: Outcome) -> None:
    with contextlib.suppress(OSError):
        atomic_write_text(
            outcome.job.run_dir / FAILED_NAME,
            json.dumps(
                {
                    "error": outcome.error,
                    "attempts": outcome.attempts,
                    "returncode": outcome.returncode,
                    "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                    "log": str(outcome.job.run_dir / "train.log"),
                },
                indent=1,
            )
            + "\n",
        )


def _print_summary(result: SweepResult, progress: Progress) -> None:
    n = len(result.jobs)
    done = sum(o is not None and o.status == "done" for o in result.outcomes)
    skipped = sum(o is not None and o.status == "skipped" for o in result.outcomes)
    lines = [
        f"sweep: {done + skipped}/{n} finished ({done} trained now, {skipped} already finished), "
        f"{len(result.failed)} failed, "
        + (f"{len(result.busy)} busy elsewhere, " if result.busy else "")
        + _hms(result.seconds)
    ]
    for o in result.failed:
        lines.append(
            f"  FAILED {o.job.name} after {o.attempts} attempt(s): {o.error} "
            f"(log: {o.job.run_dir / 'train.log'})"
        )
    for o in result.busy:
        lines.append(f"  BUSY {o.job.name}: {o.error} (not trained by this sweep)")
    if result.interrupted:
        stopped = [o for o in result.outcomes if o is not None and o.status == "interrupted"]
        kept = sum((o.job.run_dir / "checkpoint.pt").is_file() for o in stopped)
        fresh = (
            f", {len(stopped) - kept} before their first (they start again)"
            if kept < len(stopped)
            else ""
        )
        lines.append(
            f"sweep: interrupted; {kept} runs stopped at their last checkpoint{fresh}. "
            "Run the same command again to continue (finished runs are skipped)."
        )
    print("\n".join(lines), file=progress.out, flush=True)
