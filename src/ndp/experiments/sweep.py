"""Sweeps: a grid of runs (tasks x arms x seeds), on a local process pool or on Ray.

A :class:`Job` is one (task, arm, seed) of a study (:mod:`ndp.experiments.study`): an ordinary
run directory ``<runs_dir>/<task>-<label>-s<seed>`` trained by its own ``ndp rl train`` (or
``ndp il train``, or the SB3 reference) process, pinned to one torch thread. :func:`run_sweep`
executes a list of jobs:

- **local** backend (default): at most ``workers`` runs at once (default: the cores this
  process may use), each its own trainer process;
- **ray** backend: every run is a Ray task (one CPU) that starts the same trainer process and
  writes the same run directory; ``address`` joins an existing cluster (whose nodes must share
  the runs directory and have this package installed), no address starts a local Ray instance
  that is shut down at the end.

Resumable: a finished run is skipped, an interrupted run continues from its checkpoint, a run
directory is locked (``.sweep.lock``, held by the trainer process too) so two sweeps never train
one run at once: a run another process is training is left to it and, once this sweep's own work
is done, polled until that process ends (then it is skipped as finished, or, when that process
died, continued here), so several sweeps over one directory share its runs and each returns when
all are finished (``wait_busy=False``: report them as busy instead). A failed run is retried
once (from its checkpoint where it has one) and then reported with its error (the last lines of
its ``train.log``; ``failed.json`` in its directory).
Ctrl-C (or SIGTERM) stops every running trainer at its last checkpoint (each gets one SIGINT)
and leaves everything resumable: the same command continues. Progress lines show the runs done /
running / failed / busy and an ETA from the env steps (epochs) done so far.

Bad input is refused before anything starts (:func:`check_tasks`, :func:`check_methods`,
:func:`parse_overrides`, :func:`check_arms`, :func:`check_plan`): the message names the bad
value and the close matches.
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import io
import json
import os
import shlex
import signal
import socket
import subprocess
import sys
import threading
import time
import typing
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from concurrent import futures
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from ndp.experiments.run_kinds import RUN_KINDS, config_class, run_kind
from ndp.experiments.study import (
    EXTERNAL_METHODS,
    IL_METHODS,
    Arm,
    _check_arm,
    arm_conflict,
    il_data_args,
    is_finished,
    prepare_run,
    run_dir,
    train_command,
)

LOCK_NAME = ".sweep.lock"
"""Lock file of a run directory (flock; held by the sweep's worker and the trainer process)."""
FAILED_NAME = "failed.json"
"""Written into a run directory whose run failed twice: the error and the attempts."""
RUN_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
"""Environment of every trainer process: one thread per math library (the trainers also set
torch to one thread: ``--torch-threads 1`` / ``--threads 1``)."""
BUSY_POLL_S = 15.0
"""Seconds between checks of a run that another process is training (see :func:`run_sweep`)."""
STOP_GRACE_S = 120.0
"""Seconds a trainer gets to stop after its SIGINT before it is killed (a second Ctrl-C kills at
once); either way the run resumes from its last checkpoint."""


# ----------------------------------------------------------------------------- jobs


@dataclass(frozen=True)
class Job:
    """One run of a sweep."""

    task: str
    """Task name (canonical), or the data set of an imitation arm."""
    arm: Arm
    """The configuration."""
    seed: int
    """Seed of the run."""
    steps: int
    """Budget: env steps (RL), epochs (imitation)."""
    run_dir: Path
    """The run directory."""
    num_envs: int = 4
    """Parallel envs of an RL run."""
    vector: str = "sync"
    """Vector env of an RL run ('sync': one process)."""

    @property
    def name(self) -> str:
        """``task label sSEED``, for progress lines and errors."""
        return f"{self.task} {self.arm.label} s{self.seed}"

    def command(self) -> list[str]:
        """The trainer command that starts (or resumes) the run."""
        return train_command(
            self.task, self.arm, self.seed, self.steps, self.run_dir, self.num_envs, self.vector
        )


def make_jobs(
    tasks: Sequence[str],
    arms: Sequence[Arm],
    seeds: Sequence[int],
    steps: int,
    runs_dir: Path,
    num_envs: int = 4,
    vector: str = "sync",
) -> list[Job]:
    """Every (task, arm, seed), seed-major (all tasks and arms of the first seed first)."""
    return [
        Job(t, a, int(s), int(steps), run_dir(Path(runs_dir), t, a, s), num_envs, vector)
        for s in seeds
        for t in tasks
        for a in arms
    ]


@dataclass
class Outcome:
    """What became of one job."""

    job: Job
    status: str
    """'done' (trained to the end now), 'skipped' (already finished), 'failed', 'interrupted'
    (stopped by Ctrl-C at its last checkpoint; resumable) or 'busy' (another process holds it)."""
    seconds: float = 0.0
    error: str = ""
    attempts: int = 1
    returncode: int | None = None


@dataclass
class SweepResult:
    """Outcomes of a sweep (one per job, in the jobs' order; None: never started)."""

    jobs: list[Job]
    outcomes: list[Outcome | None]
    interrupted: bool
    seconds: float
    exit_code: int = 0
    """130 after Ctrl-C, 143 after SIGTERM, 1 when runs failed or were left busy, else 0."""

    def _with(self, *status: str) -> list[Outcome]:
        return [o for o in self.outcomes if o is not None and o.status in status]

    @property
    def failed(self) -> list[Outcome]:
        return self._with("failed")

    @property
    def busy(self) -> list[Outcome]:
        """Runs another process was training when this sweep ended (not finished here)."""
        return self._with("busy")

    @property
    def finished(self) -> list[Outcome]:
        return self._with("done", "skipped")


# ----------------------------------------------------------------------------- one run

_LIVE: dict[int, subprocess.Popen] = {}
_LIVE_LOCK = threading.Lock()
_STOP = threading.Event()


class _RunLock:
    """An exclusive, non-blocking flock on ``<run>/.sweep.lock`` (None from :meth:`take` when
    another process holds it); the trainer process inherits the descriptor, so the lock stays
    held while it runs even if the sweep dies."""

    def __init__(self, fh: io.TextIOWrapper) -> None:
        self.fh = fh

    @staticmethod
    def take(run: Path) -> _RunLock | str:
        import fcntl

        run.mkdir(parents=True, exist_ok=True)
        fh = (run / LOCK_NAME).open("a+")
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            holder = fh.read().strip() or "another process"
            fh.close()
            return holder
        fh.seek(0)
        fh.truncate()
        fh.write(f"pid {os.getpid()} on {socket.gethostname()}\n")
        fh.flush()
        return _RunLock(fh)

    def fileno(self) -> int:
        return self.fh.fileno()

    def note(self, line: str) -> None:
        self.fh.write(line + "\n")
        self.fh.flush()

    def close(self) -> None:
        self.fh.close()


def is_busy(run: Path) -> str | None:
    """Who holds the run's lock (another sweep's trainer), or None."""
    if not (Path(run) / LOCK_NAME).is_file():
        return None
    lock = _RunLock.take(Path(run))
    if isinstance(lock, str):
        return lock
    lock.close()
    return None


def _log_tail(log: Path, start: int, lines: int = 3) -> str:
    """The error of an attempt: its 'ndp: error' line, or its last lines."""
    try:
        with log.open("rb") as fh:
            fh.seek(start)
            text = fh.read().decode("utf-8", "replace")
    except OSError:
        return ""
    rows = []
    for r in text.splitlines():
        # the box a command-line parser draws around its message (tyro): keep the text only
        r = r.strip().strip("│╭╮╰╯─ ").strip()
        if r and not r.startswith("# ") and not set(r) <= set("─━═-"):
            rows.append(r)
    errors = [r for r in rows if r.startswith("ndp: error") or r.startswith("ndp: ")]
    parse = [r for r in rows if r.startswith("Error parsing") or "error" in r.lower()[:40]]
    picked = errors[-1:] if errors else parse[-2:] if parse else rows[-lines:]
    return " | ".join(picked)[-600:]


def _stop_child(proc: subprocess.Popen, grace: float = STOP_GRACE_S) -> None:
    """One SIGINT (the trainer stops at its last checkpoint), then SIGKILL after ``grace``."""
    if proc.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=grace)
    except (subprocess.TimeoutExpired, KeyboardInterrupt):
        with contextlib.suppress(ProcessLookupError):
            proc.kill()
        proc.wait()


_UNBLOCK = (
    "import os, signal, sys; "
    "signal.pthread_sigmask(signal.SIG_UNBLOCK, (signal.SIGINT, signal.SIGTERM)); "
    "signal.signal(signal.SIGINT, signal.SIG_DFL); signal.signal(signal.SIGTERM, signal.SIG_DFL); "
    "os.execv(sys.argv[1], sys.argv[1:])"
)


def _stoppable(cmd: list[str]) -> list[str]:
    """``cmd``, started through a launcher that unblocks SIGINT / SIGTERM where this thread
    blocks them (a Ray worker does, and a child inherits its signal mask: its trainer would
    never see the SIGINT that stops it)."""
    if not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - not POSIX
        return cmd
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    # an ignored SIGINT (a shell's background job, nohup'ed CI) is inherited across exec too
    ignored = signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    if not {signal.SIGINT, signal.SIGTERM} & set(blocked) and not ignored:
        return cmd
    return [sys.executable, "-S", "-c", _UNBLOCK, *cmd]


def execute(job: Job) -> Outcome:
    """Run one job to its end in a trainer process (one attempt): skip it when finished,
    resume it from its checkpoint when it has one, start it otherwise.

    The trainer runs in its own session (a terminal's Ctrl-C reaches only the sweep, which
    forwards exactly one SIGINT); its output goes to ``<run>/train.log``. A KeyboardInterrupt
    here (Ray's cancel) stops the trainer the same way.
    """
    if threading.current_thread() is threading.main_thread():
        # a Ray worker started where SIGINT was ignored would never see Ray's cancel
        if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
            signal.signal(signal.SIGINT, signal.default_int_handler)
    run = job.run_dir
    lock = _RunLock.take(run)
    if isinstance(lock, str):
        return Outcome(job, "busy", error=f"{run} is being trained by {lock}")
    t0 = time.time()
    try:
        _check_arm(run, job.arm, job.steps, job.task, job.seed)
        if is_finished(run, job.arm):
            (run / FAILED_NAME).unlink(missing_ok=True)
            return Outcome(job, "skipped")
        prepare_run(run, job.arm)
        cmd = job.command()
        log = run / "train.log"
        env = {**os.environ, **RUN_ENV}
        with log.open("ab") as fh:
            fh.seek(0, os.SEEK_END)
            start = fh.tell()
            stamp = time.strftime("%Y-%m-%dT%H:%M:%S")
            fh.write(f"# {stamp} ndp sweep on {socket.gethostname()}: {shlex.join(cmd)}\n".encode())
            fh.flush()
            with _LIVE_LOCK:
                if _STOP.is_set():
                    return Outcome(job, "interrupted", error="not started (interrupted)")
                proc = subprocess.Popen(
                    _stoppable(cmd),
                    stdout=fh,
                    stderr=subprocess.STDOUT,
                    stdin=subprocess.DEVNULL,
                    env=env,
                    start_new_session=True,
                    pass_fds=(lock.fileno(),),
                )
                _LIVE[proc.pid] = proc
            lock.note(f"trainer pid {proc.pid}")
            try:
                while True:
                    try:
                        rc = proc.wait(timeout=0.5)
                        break
                    except subprocess.TimeoutExpired:
                        continue
            except KeyboardInterrupt:  # Ray's cancel (or Ctrl-C where this runs in the main thread)
                _stop_child(proc)
                return Outcome(job, "interrupted", time.time() - t0, returncode=proc.returncode)
            finally:
                if proc.poll() is None:  # any other exception: never leave a trainer behind
                    _stop_child(proc)
                with _LIVE_LOCK:
                    _LIVE.pop(proc.pid, None)
        secs = time.time() - t0
        if rc == 0 and is_finished(run, job.arm):
            (run / FAILED_NAME).unlink(missing_ok=True)
            return Outcome(job, "done", secs, returncode=0)
        if _STOP.is_set() and rc in (130, 143, -signal.SIGINT, -signal.SIGKILL):
            return Outcome(job, "interrupted", secs, returncode=rc)
        if rc == 0:
            error = "the trainer exited 0 but the run has not finished its budget"
        else:
            error = _log_tail(log, start) or f"exit status {rc}"
        return Outcome(job, "failed", secs, f"exit {rc}: {error}", returncode=rc)
    except Exception as exc:  # a broken run directory, an unreadable checkpoint, ...
        return Outcome(job, "failed", time.time() - t0, f"{type(exc).__name__}: {exc}")
    finally:
        lock.close()


def _stop_all(sig: int = signal.SIGINT) -> None:
    """Local backend: no new trainer starts; every live one gets ``sig`` once."""
    with _LIVE_LOCK:
        _STOP.set()
        procs = list(_LIVE.values())
    for p in procs:
        if p.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                p.send_signal(sig)


# ----------------------------------------------------------------------------- backends


class LocalBackend:
    """At most ``workers`` trainer processes at once (threads of this process wait on them)."""

    name = "local"

    def __init__(self, workers: int | None = None) -> None:
        self.slots = max(1, workers or default_workers())
        self.pool = futures.ThreadPoolExecutor(max_workers=self.slots, thread_name_prefix="sweep")
        _STOP.clear()

    def describe(self) -> str:
        return f"local, {self.slots} at once"

    def submit(self, job: Job) -> Any:
        return self.pool.submit(execute, job)

    def wait(self, handles: Sequence[Any], timeout: float) -> list[tuple[Any, Any]]:
        done, _ = futures.wait(handles, timeout=timeout, return_when=futures.FIRST_COMPLETED)
        out = []
        for h in done:
            try:
                out.append((h, h.result()))
            except Exception as exc:
                out.append((h, exc))
        return out

    def interrupt(self, handles: Sequence[Any]) -> list[tuple[Any, Any]]:
        _stop_all(signal.SIGINT)
        try:
            futures.wait(handles, timeout=STOP_GRACE_S + 10)
        except KeyboardInterrupt:  # a second Ctrl-C: kill (the checkpoints stay)
            _stop_all(signal.SIGKILL)
            futures.wait(handles)
        return self.wait(handles, 0) if handles else []

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)
        _STOP.clear()


class RayBackend:
    """Every run a Ray task with one CPU; at most ``workers`` in flight (default: the cluster's
    CPUs). Starts (and at the end shuts down) a local Ray instance unless ``address`` is given
    or Ray is already initialised in this process."""

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None) -> None:
        try:
            import ray
        except ModuleNotFoundError:
            raise ValueError(
                "--backend ray: needs Ray (pip install 'neural-dynamic-policies[ray]')"
            ) from None
        self.ray = ray
        self.started = False
        if not ray.is_initialized():
            kw: dict[str, Any] = {"include_dashboard": False, "logging_level": "WARNING"}
            if address:
                ray.init(address=address, **kw)
            else:
                ray.init(num_cpus=max(1, workers or default_workers()), **kw)
            self.started = True
        self.remote = ray.remote(num_cpus=1, max_retries=0)(execute)
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.slots = max(1, workers or cpus)
        self.where = address or ("a local Ray instance" if self.started else "the running Ray")

    def describe(self) -> str:
        return f"ray ({self.where}), {self.slots} at once"

    def submit(self, job: Job) -> Any:
        # the task may run on another node, in another directory: an absolute run directory
        return self.remote.remote(dataclasses.replace(job, run_dir=job.run_dir.absolute()))

    def _get(self, h: Any) -> Any:
        try:
            return self.ray.get(h)
        except Exception as exc:  # TaskCancelledError, WorkerCrashedError, RayTaskError, ...
            return exc

    def wait(self, handles: Sequence[Any], timeout: float) -> list[tuple[Any, Any]]:
        if not handles:
            return []
        ready, rest = self.ray.wait(list(handles), num_returns=1, timeout=timeout)
        if ready and rest:
            more, _ = self.ray.wait(rest, num_returns=len(rest), timeout=0)
            ready += more
        return [(h, self._get(h)) for h in ready]

    def interrupt(self, handles: Sequence[Any]) -> list[tuple[Any, Any]]:
        for h in handles:
            self.ray.cancel(h)  # KeyboardInterrupt in the task: its trainer gets one SIGINT
        try:
            self.ray.wait(list(handles), num_returns=len(handles), timeout=STOP_GRACE_S + 10)
        except KeyboardInterrupt:
            for h in handles:
                self.ray.cancel(h, force=True)
        return [(h, self._get(h)) for h in handles]

    def close(self) -> None:
        if self.started:
            self.ray.shutdown()


def default_workers() -> int:
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def make_backend(backend: str, workers: int | None = None, address: str | None = None) -> Any:
    """'local' or 'ray' (``address``: an existing cluster)."""
    if backend == "local":
        if address:
            raise ValueError("--address: only with --backend ray")
        return LocalBackend(workers)
    if backend == "ray":
        return RayBackend(address, workers)
    raise ValueError(f"backend: expected 'local' or 'ray', got {backend!r}")


# ----------------------------------------------------------------------------- progress


def run_fraction(job: Job) -> float:
    """How much of its budget a run has done (from the last row of its metrics)."""
    from ndp.runs import metrics_path

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
    from ndp.runs.signals import exit_code, stop_on_sigterm

    be = make_backend(backend, workers, address)
    progress = Progress(jobs, out, progress_every)
    index = {j.run_dir: i for i, j in enumerate(jobs)}
    outcomes: list[Outcome | None] = [None] * len(jobs)
    queue: deque[tuple[Job, int]] = deque((j, 1) for j in jobs)
    inflight: dict[Any, tuple[Job, int]] = {}
    aside: dict[Path, tuple[float, Job, int, Outcome]] = {}  # busy elsewhere: next poll time
    interrupted = False
    stop_code = 0

    def settle(h: Any, res: Any) -> None:
        job, attempt = inflight.pop(h)
        if isinstance(res, BaseException):
            cancelled = type(res).__name__ in ("TaskCancelledError",) or interrupted
            res = Outcome(
                job,
                "interrupted" if cancelled else "failed",
                error="" if cancelled else f"{type(res).__name__}: {res}",
            )
        res.job, res.attempts = job, attempt
        if res.status == "busy" and wait_busy and not interrupted:
            aside[job.run_dir] = (time.time() + BUSY_POLL_S, job, attempt, res)
            progress.waiting(res)
            return
        if res.status == "failed" and attempt <= retries and not interrupted:
            progress.retry(res, attempt + 1, retries + 1)
            queue.appendleft((job, attempt + 1))
            return
        outcomes[index[job.run_dir]] = res
        if res.status == "failed":
            _write_failed(res)
        progress.finished(res)

    try:
        with stop_on_sigterm():
            progress.note(f"sweep: {len(jobs)} runs on {be.describe()}; {progress.counts()}")
            while queue or inflight or aside:
                if not queue:  # this sweep's own work is out: poll the runs others train
                    now = time.time()
                    for key, (due, job, attempt, _) in list(aside.items()):
                        if due <= now:
                            del aside[key]
                            queue.append((job, attempt))
                while queue and len(inflight) < be.slots:
                    job, attempt = queue.popleft()
                    h = be.submit(job)
                    inflight[h] = (job, attempt)
                    progress.started(job)
                if inflight:
                    for h, res in be.wait(list(inflight), progress.timeout()):
                        settle(h, res)
                elif aside:
                    next_due = min(due for due, *_ in aside.values())
                    time.sleep(max(0.05, min(progress.timeout(), next_due - time.time())))
                progress.tick()
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (ndp.runs.signals.Terminated)
        interrupted, stop_code = True, exit_code(exc)
        progress.note(
            f"interrupted: stopping {len(inflight)} running trainers at their last checkpoint"
        )
        for h, res in be.interrupt(list(inflight)):
            if h in inflight:
                settle(h, res)
        for _, job, _attempt, res in aside.values():  # still busy elsewhere: not ours to stop
            outcomes[index[job.run_dir]] = res
    finally:
        be.close()
    result = SweepResult(jobs, outcomes, interrupted, time.time() - t0)
    result.exit_code = stop_code or (1 if result.failed or result.busy else 0)
    _print_summary(result, progress)
    return result


def _write_failed(outcome: Outcome) -> None:
    from ndp.io import atomic_write_text

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


# ----------------------------------------------------------------------------- bad input


def close_hint(value: str, known: Iterable[str], n: int = 4) -> str:
    """'; close matches: a, b' (or a short list of the known values when none is close)."""
    known = list(known)
    close = difflib.get_close_matches(value, known, n=n, cutoff=0.5)
    if close:
        return "; close matches: " + ", ".join(close)
    shown = ", ".join(known[:12]) + (", ..." if len(known) > 12 else "")
    return f"; known: {shown}"


def known_methods() -> list[str]:
    """Every method an arm may name: the trainer's registry, the SB3 reference, imitation."""
    from ndp.rl.methods import METHODS

    return [*METHODS, *EXTERNAL_METHODS, *IL_METHODS]


def check_methods(methods: Sequence[str]) -> list[str]:
    """The methods, each known (else ValueError naming it and the close matches)."""
    known = known_methods()
    for m in methods:
        if m not in known:
            raise ValueError(f"method: unknown method {m!r}{close_hint(m, known)}")
    return list(methods)


def check_tasks(tasks: Sequence[str], kind: str = "rl") -> list[str]:
    """Canonical task names ('rl': ndp.envs.TASKS; 'il': data sets, see
    :func:`ndp.experiments.study.il_data_args`); an unknown one is a ValueError naming it and
    the close matches."""
    out = []
    for t in tasks:
        if run_kind(kind).task_is_dataset:
            il_data_args(t)
            out.append(t)
            continue
        from ndp.envs import get_task_spec

        try:
            out.append(get_task_spec(t).name)
        except ValueError as exc:
            raise ValueError(f"task: {str(exc).removeprefix('name: ')}") from None
    return out


def _config_class(kind: str) -> type:
    return config_class(run_kind(kind))


def train_options(kind: str = "rl") -> dict[str, str]:
    """``--option`` -> field of the trainer's command line ('rl': ``ndp rl train``, 'il':
    ``ndp il train``), as tyro names them there (nested configs flattened, ``--no-x`` for
    booleans, annotated names and aliases)."""
    from ndp.runs.cli import HIDDEN

    out: dict[str, str] = {}

    def walk(cls: type) -> None:
        hints = typing.get_type_hints(cls, include_extras=True)
        for f in dataclasses.fields(cls):
            t, meta = hints[f.name], ()
            if typing.get_origin(t) is typing.Annotated:
                meta, t = t.__metadata__, typing.get_args(t)[0]
            if HIDDEN is not None and any(m is HIDDEN for m in meta):
                continue
            if isinstance(t, type) and dataclasses.is_dataclass(t):
                walk(t)
                continue
            conf = next((m for m in meta if hasattr(m, "aliases") and hasattr(m, "name")), None)
            name = ((conf.name if conf is not None and conf.name else None) or f.name).replace(
                "_", "-"
            )
            out["--" + name] = f.name
            for alias in (conf.aliases or ()) if conf is not None else ():
                out[alias] = f.name
            if t is bool:
                out["--no-" + name] = f.name

    walk(_config_class(kind))
    return out


RESERVED = {name: kind.reserved for name, kind in RUN_KINDS.items() if kind.takes_options}
"""Options the sweep sets itself (per run: task / data set, method, seed, budget, directory;
:attr:`ndp.experiments.run_kinds.RunKind.reserved`)."""


class UnknownOptionError(ValueError):
    """An arm uses an option the trainer does not know (``option``: which)."""

    def __init__(self, message: str, option: str) -> None:
        super().__init__(message)
        self.option = option


def _option_names(args: Sequence[str]) -> list[str]:
    return [a.split("=", 1)[0] for a in args if a.startswith("--")]


def check_arms(arms: Sequence[Arm], tasks: Sequence[str] = (), study: str = "") -> None:
    """Refuse, before anything starts, an arm whose options the trainer does not know (the
    message names the arm, the option, what the arm needs and the close options), or whose
    values it refuses (the trainer's own message); RL arms are also resolved against every
    task (task presets: e.g. DMP steps that are not a multiple of k)."""
    where = f"{study}: " if study else ""
    opts_cache: dict[str, dict[str, str]] = {}
    for arm in arms:
        if not run_kind(arm.kind).takes_options:
            continue
        opts = opts_cache.setdefault(arm.kind, train_options(arm.kind))
        prog = run_kind(arm.kind).prog
        for name in _option_names(arm.args):
            if name in RESERVED[arm.kind]:
                raise ValueError(
                    f"{where}arm {arm.label!r}: {name} is set by the sweep for every run "
                    "(use the sweep's --tasks / --seeds / --steps / --runs-dir)"
                )
            if name not in opts:
                needs = (
                    f" (it needs {arm.requires}, which this version lacks)" if arm.requires else ""
                )
                raise UnknownOptionError(
                    f"{where}arm {arm.label!r} uses {name}, which `{prog}` does not know"
                    f"{needs}{close_hint(name, opts)}. Nothing was started: leave the arm out "
                    "(--skip-unavailable, or --arms with the others).",
                    name,
                )
    for arm in arms:
        if not run_kind(arm.kind).takes_options:
            continue
        for task in tasks or ("point-mass",):
            _parse_arm(arm, task)


def _parse_arm(arm: Arm, task: str) -> None:
    from ndp.runs.cli import parse_config

    if arm.kind == "il":
        argv = [*il_data_args(task), "--model", IL_METHODS[arm.algo], *arm.args]
        prog = "ndp il train"
    else:
        argv = ["--task", task, "--algo", arm.algo, *arm.args]
        prog = "ndp rl train"
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(err):
            cfg = parse_config(_config_class(arm.kind), argv, prog=prog)
        if arm.kind == "rl":
            from ndp.rl.config import resolve_config

            resolve_config(cfg)
        elif cfg.config.data.source == "pendigits":
            from ndp.il.train import DEFAULT_PENDIGITS

            given = cfg.config.data.pendigits_path
            path = Path(given) if given else DEFAULT_PENDIGITS / "pendigits-train"
            if not path.is_file():
                raise ValueError(
                    f"data: the Pendigits file {path} does not exist (give its path with "
                    "-o pendigits_path=FILE)"
                )
    except SystemExit:
        rows = [ln.strip(" │╭╰─╮╯|-") for ln in err.getvalue().splitlines()]
        text = " ".join(r for r in rows if r and not r.startswith("For full helptext"))
        raise ValueError(
            f"arm {arm.label!r} on {task}: `{prog}` refuses its options "
            f"{' '.join(arm.args)!r}: {text[-500:]}"
        ) from None
    except ValueError as exc:
        raise ValueError(f"arm {arm.label!r} on {task}: {exc}") from None


def parse_overrides(items: Sequence[str], kind: str = "rl") -> list[tuple[str, list[list[str]]]]:
    """``KEY=V1[,V2...]`` -> (``--key``, [argv of each value]); KEY is a field of the trainer's
    config as on its command line (``lr``, ``n-basis`` / ``n_basis``, ``k``, ...). A boolean
    takes true / false. One value applies to every run; several make a grid axis.

    Raises:
        ValueError: no '=', an unknown key (named, with the close keys), a key the sweep sets.
    """
    opts = train_options(kind)
    keys = sorted({o[2:] for o in opts if not o.startswith("--no-")})
    out = []
    for item in items:
        if "=" not in item:
            raise ValueError(f"override: expected KEY=VALUE[,VALUE...], got {item!r}")
        key, values = item.split("=", 1)
        key = key.strip().lstrip("-").replace("_", "-")
        if ("--" + key) not in opts or key.startswith("no-"):
            raise ValueError(f"override: unknown key {key!r}{close_hint(key, keys)}")
        if "--" + key in RESERVED[kind]:
            raise ValueError(
                f"override: {key!r} is set by the sweep itself (use --tasks, --methods, --seeds, "
                "--steps or --runs-dir)"
            )
        vals = [v.strip() for v in values.split(",")]
        if not vals or any(not v for v in vals):
            raise ValueError(f"override: {item!r} has an empty value")
        is_bool = ("--no-" + key) in opts
        argvs = []
        for v in vals:
            if is_bool:
                b = v.lower()
                if b not in ("true", "false", "1", "0", "yes", "no", "on", "off"):
                    raise ValueError(f"override: {key} is a boolean (true / false), got {v!r}")
                argvs.append([f"--{key}" if b in ("true", "1", "yes", "on") else f"--no-{key}"])
            else:
                argvs.append([f"--{key}", *v.split()])
        out.append(("--" + key, argvs))
    return out


def _label_part(key: str, argv: Sequence[str]) -> str:
    name = key[2:].replace("-", "")
    if len(argv) == 1:  # a boolean
        return name if not argv[0].startswith("--no-") else f"no{name}"
    value = "_".join(argv[1:])
    return name + "".join(
        c if c.isalnum() or c == "_" else {".": "p", "-": "m"}.get(c, "_") for c in value
    )


def apply_overrides(
    arms: Sequence[Arm], overrides: Sequence[tuple[str, list[list[str]]]], extra: Sequence[str] = ()
) -> list[Arm]:
    """Each arm with the overrides (and ``extra`` options) appended; an override with several
    values multiplies the arms (label suffix ``-<key><value>``, e.g. ``ndp-k3``)."""
    out = list(arms)
    for key, argvs in overrides:
        nxt = []
        for arm in out:
            if not run_kind(arm.kind).takes_options:
                nxt.append(arm)
                continue
            for argv in argvs:
                label = arm.label if len(argvs) == 1 else f"{arm.label}-{_label_part(key, argv)}"
                note = f"{arm.note}; {' '.join(argv)}".lstrip("; ")
                nxt.append(
                    dataclasses.replace(arm, label=label, args=(*arm.args, *argv), note=note)
                )
        out = nxt
    if extra:
        out = [
            dataclasses.replace(a, args=(*a.args, *extra)) if run_kind(a.kind).takes_options else a
            for a in out
        ]
    return out


def check_plan(jobs: Sequence[Job]) -> None:
    """Refuse, before anything starts, two jobs sharing a run directory, or a directory that
    holds another run (another arm, budget, task or seed)."""
    seen: dict[Path, Job] = {}
    bad = []
    for j in jobs:
        if j.run_dir in seen:
            raise ValueError(
                f"sweep: {seen[j.run_dir].name} and {j.name} share the run directory {j.run_dir} "
                "(two arms with one label?)"
            )
        seen[j.run_dir] = j
        why = arm_conflict(j.run_dir, j.arm, j.steps, j.task, j.seed)
        if why is not None:
            bad.append(f"{j.run_dir}: {why}")
    if bad:
        more = f" (and {len(bad) - 3} more)" if len(bad) > 3 else ""
        raise ValueError(
            "sweep: refused before starting: "
            + "; ".join(bad[:3])
            + more
            + ". Use another --runs-dir, or the same --steps as before."
        )


def job_state(job: Job) -> str:
    """'finished', 'resumable' (a checkpoint), 'running' (locked by another process), 'failed'
    (failed.json from an earlier sweep; will be retried) or 'new'."""
    if is_busy(job.run_dir):
        return "running"
    if is_finished(job.run_dir, job.arm):
        return "finished"
    if (job.run_dir / FAILED_NAME).is_file():
        return "failed"
    if (job.run_dir / "checkpoint.pt").is_file():
        return "resumable"
    return "new"


def plan_lines(jobs: Sequence[Job], state: Callable[[Job], str] = job_state) -> list[str]:
    """One line per job (``--dry-run``): its state, name, directory and command."""
    lines = []
    for j in jobs:
        st = state(j)
        cmd = "" if st == "finished" else "  $ " + shlex.join(j.command())
        lines.append(f"{st:<9} {j.name:<40} {j.run_dir}{cmd}")
    return lines
