"""One writer per run directory: an exclusive lock held for the whole life of a run.

Every trainer takes it when it creates, resumes or overwrites a run
(:meth:`ndp.runs.session.RunSession.open`) and keeps it until the run is closed, so a second
``ndp rl train`` / ``ndp il train`` / ``ndp bc train`` on the same directory, a second
``--resume`` of it, or an ``--overwrite`` of it while it trains, is refused in one line naming
the process that holds it. The lock is ``flock`` on ``<run>/.run.lock``: the kernel releases it
when its process dies, so the lock of a killed run is stale by construction and the next run
takes it over (the file's text, the last holder's pid and host, is only a message). Within one
process the lock is re-entrant (a counted registry), so a command that locks a run before it
overwrites it, then opens its session, holds it once.

A sweep's own lock (``.sweep.lock``, ``ndp.experiments.sweep``) is another file: it keeps two
sweeps from starting the same run, and this one keeps the trainer it starts from racing a
trainer started by hand.
"""

from __future__ import annotations

import contextlib
import errno
import os
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import IO

RUN_LOCK_NAME = ".run.lock"
"""The lock file in a run directory."""

_HELD: dict[Path, tuple[IO[str], int, bool]] = {}
"""This process's locks: resolved run path -> (open lock file, hold count, whether acquiring
made the directory)."""


class RunBusyError(ValueError):
    """Another process holds the run directory's lock (it is being trained now)."""


def _key(run_dir: str | Path) -> Path:
    return Path(run_dir).resolve()


def open_lock(path: str | Path, what: str = "run_dir") -> IO[str]:
    """Open (creating it if missing) the lock file ``path`` for :func:`try_flock`: never through
    a symbolic link (``O_NOFOLLOW``: a planted link would have its target truncated and
    overwritten), never a directory. The one way every lock of the package (a run's, a sweep's,
    an export's) is opened.

    Raises:
        OSError: one line naming ``what``, the file and how to clear it: a symbolic link, a
            directory, or not writable.
    """
    path = Path(path)
    if path.is_symlink():
        raise OSError(
            f"{what}: {path} is a symbolic link, not a lock file; nothing was written through "
            f"it (remove it: rm {path})"
        )
    if path.is_dir():
        raise OSError(f"{what}: {path} is a directory, not a lock file (remove it: rmdir {path})")
    flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as exc:
        if exc.errno in (errno.ELOOP, errno.EMLINK):  # a link planted after the check
            raise OSError(
                f"{what}: {path} is a symbolic link, not a lock file; nothing was written "
                f"through it (remove it: rm {path})"
            ) from None
        if exc.errno == errno.EISDIR:
            raise OSError(
                f"{what}: {path} is a directory, not a lock file (remove it: rmdir {path})"
            ) from None
        raise
    return os.fdopen(fd, "r+")


def try_flock(fh: IO[str]) -> str | None:
    """Take an exclusive, non-blocking flock on the open lock file ``fh`` and write this
    process's pid and host into it; where another process holds it, close ``fh`` and return
    what the file says of the holder (the one flock of this run lock and of the sweep's)."""
    import fcntl

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
    return None


def acquire(run_dir: str | Path) -> None:
    """Take the run's lock (re-entrant within the process; the directory is made if missing).

    Raises:
        RunBusyError: another process holds it; the message names the run and the holder.
        OSError: the directory cannot be made or the lock file written (one line).
    """
    key = _key(run_dir)
    if key in _HELD:
        fh, n, made = _HELD[key]
        _HELD[key] = (fh, n + 1, made)
        return
    if key.exists() and not key.is_dir():
        raise OSError(f"run_dir: {run_dir} exists and is not a directory")
    made = not key.exists()
    try:
        key.mkdir(parents=True, exist_ok=True)
        fh = open_lock(key / RUN_LOCK_NAME)
    except (FileExistsError, NotADirectoryError):
        raise OSError(f"run_dir: cannot create {run_dir}: a parent is a file") from None
    except PermissionError:
        raise OSError(f"run_dir: {run_dir} is not writable (permission denied)") from None
    holder = try_flock(fh)
    if holder is not None:
        _remove_if_bare(key, made)
        raise RunBusyError(
            f"run_dir: {run_dir} is being trained now ({holder}); wait for it to finish or "
            "stop it (Ctrl-C keeps its last checkpoint), or choose another run directory"
        )
    _HELD[key] = (fh, 1, made)


def _remove_if_bare(key: Path, made: bool) -> None:
    """Remove a directory that acquiring made and that holds nothing but the lock file (a run
    stopped before it wrote anything leaves no empty directory behind)."""
    if not made:
        return
    with contextlib.suppress(OSError):
        if {p.name for p in key.iterdir()} <= {RUN_LOCK_NAME}:
            (key / RUN_LOCK_NAME).unlink(missing_ok=True)
            key.rmdir()


def release(run_dir: str | Path, every: bool = False) -> None:
    """Give one hold of the run's lock back (``every``: all of this process's holds, as the
    outermost holder does when an exception unwinds past inner ones); the lock is released at
    the last; a run this process does not hold: nothing. A directory that acquiring made and
    that still holds nothing but the lock is removed."""
    key = _key(run_dir)
    if key not in _HELD:
        return
    fh, n, made = _HELD[key]
    if n > 1 and not every:
        _HELD[key] = (fh, n - 1, made)
        return
    del _HELD[key]
    _remove_if_bare(key, made)
    fh.close()  # closing the descriptor releases the flock


def holder(run_dir: str | Path) -> str | None:
    """Who holds the run's lock now (another process), or None (free, or held by this
    process)."""
    key = _key(run_dir)
    if key in _HELD or not (key / RUN_LOCK_NAME).is_file():
        return None
    try:
        acquire(key)
    except RunBusyError as exc:
        text = str(exc)
        return text[text.find("(") + 1 : text.find(")")] or "another process"
    except OSError:
        return None
    release(key)
    return None


@contextlib.contextmanager
def held(run_dir: str | Path) -> Iterator[None]:
    """Hold the run's lock for the ``with`` block; at its end every hold this process took
    inside it is given back too (a learner whose construction was interrupted never closes its
    session), so nothing stays locked and no bare directory stays behind."""
    acquire(run_dir)
    try:
        yield
    finally:
        release(run_dir, every=True)


@contextlib.contextmanager
def output_lock(out: str | Path, what: str = "out_dir") -> Iterator[None]:
    """One writer at a time for an output that is not a run directory (an export folder): an
    flock on ``<parent>/.<name>.lock`` beside it (in the nearest existing folder above it, so
    that nothing is created before the writer's checks, and the folder itself stays as the
    writer leaves it), taken with :func:`open_lock` and removed when the block ends, however it
    ends.

    Raises:
        RunBusyError: another process writes ``out`` now (one line naming it and the holder).
    """
    target = Path(out).absolute()
    # the lock lives in the nearest folder that exists (no folder is made before the writer's
    # own checks, so a refused write leaves nothing behind), named after the path below it
    base = target.parent
    while not base.exists() and base != base.parent:
        base = base.parent
    if not base.is_dir():  # a parent is a file: the writer's own checks name it
        yield
        return
    rel = target.relative_to(base).as_posix().replace("/", "__")
    lock_path = base / f".{rel}.lock"
    fh = open_lock(lock_path, what)
    holder_text = try_flock(fh)
    if holder_text is not None:
        raise RunBusyError(
            f"{what}: {out} is being written now by {holder_text}; wait for it to finish or "
            "choose another folder"
        )
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            lock_path.unlink()
        fh.close()
