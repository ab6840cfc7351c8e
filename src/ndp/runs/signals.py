"""Clean stops: SIGTERM becomes an exception, so a run stops like on Ctrl-C.

Both unwind the trainer (the last good checkpoint stays: checkpoint writes are atomic and a
killed write removes its temporary file), and the command prints one line with the command that
resumes and exits 130 (SIGINT) or 143 (SIGTERM). Inside :func:`deferred_stops` (every checkpoint
write) a stop waits until the block ends: raised in the middle of ``torch.save``, it would be
replaced by the zip writer's own error on unwinding.
"""

from __future__ import annotations

import contextlib
import signal
import sys
from collections.abc import Iterator
from pathlib import Path
from types import FrameType


class Terminated(KeyboardInterrupt):
    """Raised in the main thread when the process receives SIGTERM."""


_deferring = 0
_pending: KeyboardInterrupt | None = None


@contextlib.contextmanager
def deferred_stops() -> Iterator[None]:
    """Hold a stop (SIGTERM, SIGINT under :func:`stop_on_sigterm`) that arrives in the block
    and raise it when the block ends; an error raised by the block itself propagates unchanged
    and the stop stays pending until the next such block ends."""
    global _deferring, _pending
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
    if _deferring == 0 and _pending is not None:
        exc, _pending = _pending, None
        raise exc


def _stop(exc: KeyboardInterrupt) -> None:
    global _pending
    if _deferring:
        _pending = _pending or exc
        return
    raise exc


def exit_code(exc: KeyboardInterrupt) -> int:
    """130 for Ctrl-C (SIGINT), 143 for SIGTERM: 128 + the signal number, as shells report."""
    return 143 if isinstance(exc, Terminated) else 130


@contextlib.contextmanager
def stop_on_sigterm() -> Iterator[None]:
    """Within the block, SIGTERM raises :class:`Terminated` and SIGINT ``KeyboardInterrupt``
    (also where SIGINT was ignored at start-up, as for a shell's background jobs: a run is
    stopped by ``kill -INT`` as by Ctrl-C); the previous handlers are restored afterwards."""

    def on_term(signum: int, frame: FrameType | None) -> None:
        _stop(Terminated(signum))

    def on_int(signum: int, frame: FrameType | None) -> None:
        _stop(KeyboardInterrupt())

    try:
        old_term = signal.signal(signal.SIGTERM, on_term)
        old_int = signal.signal(signal.SIGINT, on_int)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old_term)
        signal.signal(signal.SIGINT, old_int)


def report_stop(
    exc: KeyboardInterrupt, resume_command: str, run_dir: str | Path | None = None
) -> int:
    """Print the one line a stopped run gives; returns the exit code.

    With ``run_dir``, a run stopped before its first checkpoint says that there is nothing to
    resume and that the same command starts it again (instead of pointing to ``--resume``)."""
    what = "terminated" if isinstance(exc, Terminated) else "interrupted"
    if run_dir is not None and not (Path(run_dir) / "checkpoint.pt").is_file():
        print(
            f"ndp: {what} before the first checkpoint: nothing to resume; the same command "
            "starts the run again",
            file=sys.stderr,
        )
        return exit_code(exc)
    print(
        f"ndp: {what}; the last checkpoint is kept. Continue with: {resume_command}",
        file=sys.stderr,
    )
    return exit_code(exc)
