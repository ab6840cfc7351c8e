"""The ``ndp`` console script's entry: a stop (SIGINT, SIGTERM) from the process's first instant
ends in one line and exit 130 / 143, never a traceback.

The console script imports this module, not ``ndp.cli``: importing the ``ndp`` package and its
command modules takes a few hundred milliseconds, and a Ctrl-C in that window used to end in a
``KeyboardInterrupt`` traceback (and a scripted ``kill -INT`` in it was reported as a crash).
This module sets its handlers before anything of ``ndp`` is imported; :func:`ndp.cli.main` then
installs its own (``ndp.runs.signals.stop_on_sigterm``), which stop commands cleanly. What is
left is the interpreter's own start-up before this module runs (tens of milliseconds), which no
Python code can cover.
"""

from __future__ import annotations

import os
import signal
import sys

_NAMES: dict[int, str] = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM"}


def _stop_before_start(signum: int, frame: object) -> None:
    """A stop while ``ndp`` is still being imported: nothing has been written yet, so the
    process ends at once with the shells' exit code (128 + the signal number)."""
    code = 128 + signum
    sys.stderr.write(f"ndp: stopped by {_NAMES.get(signum, str(signum))} (exit {code})\n")
    sys.stderr.flush()
    os._exit(code)


for _sig in _NAMES:  # at import: the console script imports this module first
    signal.signal(_sig, _stop_before_start)


def main() -> int:
    """Run the ``ndp`` command (:func:`ndp.cli.main`)."""
    from ndp.cli import main as ndp_main

    return ndp_main()
