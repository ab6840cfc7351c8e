"""One run of a sweep: its lock, its trainer process (one torch thread), stopping it,
its outcome.

Part of :mod:`ndp.experiments.sweep` (its docstring describes the whole).
"""

from __future__ import annotations

import contextlib
import os
import shlex
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO

from ndp.experiments.study import (
    _check_arm,
    is_finished,
    prepare_run,
)
from ndp.experiments.sweep.jobs import FAILED_NAME, LOCK_NAME, RUN_ENV, STOP_GRACE_S, Job, Outcome
from ndp.runs.lock import holder as run_lock_holder
from ndp.runs.lock import open_lock, try_flock

# ----------------------------------------------------------------------------- one run

_LIVE: dict[int, subprocess.Popen[bytes]] = {}
_LIVE_LOCK = threading.Lock()
_STOP = threading.Event()


class _RunLock:
    """An exclusive, non-blocking flock on ``<run>/.sweep.lock`` (None from :meth:`take` when
    another process holds it); the trainer process inherits the descriptor, so the lock stays
    held while it runs even if the sweep dies."""

    def __init__(self, fh: IO[str]) -> None:
        self.fh = fh

    @staticmethod
    def take(run: Path) -> _RunLock | str:
        run.mkdir(parents=True, exist_ok=True)
        fh = open_lock(run / LOCK_NAME)
        holder = try_flock(fh)
        return _RunLock(fh) if holder is None else holder

    def fileno(self) -> int:
        return self.fh.fileno()

    def note(self, line: str) -> None:
        self.fh.write(line + "\n")
        self.fh.flush()

    def close(self) -> None:
        self.fh.close()


def is_busy(run: Path) -> str | None:
    """Who holds the run (another sweep's trainer, or a trainer started by hand), or None."""
    by_hand = run_lock_holder(run)
    if by_hand is not None:
        return by_hand
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


def _stop_child(proc: subprocess.Popen[bytes], grace: float = STOP_GRACE_S) -> None:
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
    by_hand = run_lock_holder(run)  # a trainer started outside any sweep holds the run's lock
    if by_hand is not None:
        lock.close()
        return Outcome(job, "busy", error=f"{run} is being trained by {by_hand} (not a sweep)")
    t0 = time.time()
    try:
        _check_arm(run, job.arm, job.steps, job.task, job.seed)
        if is_finished(run, job.arm):
            (run / FAILED_NAME).unlink(missing_ok=True)
            return Outcome(job, "skipped")
        prepare_run(run, job.arm)
        cmd = job.command()
        log = run / "train.log"
        with log.open("ab") as fh:
            fh.seek(0, os.SEEK_END)
            start = fh.tell()
            stamp = time.strftime("%Y-%m-%dT%H:%M:%S")
            fh.write(f"# {stamp} ndp sweep on {socket.gethostname()}: {shlex.join(cmd)}\n".encode())
            fh.flush()
            proc = _spawn(cmd, fh, lock)
            if proc is None:
                return Outcome(job, "interrupted", error="not started (interrupted)")
            lock.note(f"trainer pid {proc.pid}")
            rc = _wait_trainer(proc)
            if rc is None:  # Ray's cancel (or Ctrl-C where this runs in the main thread)
                return Outcome(job, "interrupted", time.time() - t0, returncode=proc.returncode)
        return _ended(job, rc, time.time() - t0, log, start)
    except Exception as exc:  # a broken run directory, an unreadable checkpoint, ...
        return Outcome(job, "failed", time.time() - t0, f"{type(exc).__name__}: {exc}")
    finally:
        lock.close()


def _spawn(cmd: list[str], fh: IO[bytes], lock: _RunLock) -> subprocess.Popen[bytes] | None:
    """Start the trainer in its own session, its output to ``fh``, holding the run's lock
    (registered for :func:`_stop_all`); None when the sweep is stopping (nothing started)."""
    with _LIVE_LOCK:
        if _STOP.is_set():
            return None
        proc = subprocess.Popen(
            _stoppable(cmd),
            stdout=fh,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env={**os.environ, **RUN_ENV},
            start_new_session=True,
            pass_fds=(lock.fileno(),),
        )
        _LIVE[proc.pid] = proc
    return proc


def _wait_trainer(proc: subprocess.Popen[bytes]) -> int | None:
    """The trainer's exit status; None when a KeyboardInterrupt stopped it here. The trainer is
    never left behind (any exception stops it)."""
    try:
        while True:
            try:
                return proc.wait(timeout=0.5)
            except subprocess.TimeoutExpired:
                continue
    except KeyboardInterrupt:  # Ray's cancel (or Ctrl-C where this runs in the main thread)
        _stop_child(proc)
        return None
    finally:
        if proc.poll() is None:  # any other exception: never leave a trainer behind
            _stop_child(proc)
        with _LIVE_LOCK:
            _LIVE.pop(proc.pid, None)


def _ended(job: Job, rc: int, secs: float, log: Path, start: int) -> Outcome:
    """The outcome of a trainer that exited with ``rc``: done (the run finished), interrupted
    (the sweep stopped it), or failed with the tail of its log since ``start``."""
    run = job.run_dir
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


def _stop_all(sig: int = signal.SIGINT) -> None:
    """Local backend: no new trainer starts; every live one gets ``sig`` once."""
    with _LIVE_LOCK:
        _STOP.set()
        procs = list(_LIVE.values())
    for p in procs:
        if p.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                p.send_signal(sig)
