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

from ndp.experiments.sweep.backends import LocalBackend, RayBackend, default_workers, make_backend
from ndp.experiments.sweep.checks import (
    RESERVED,
    UnknownOptionError,
    apply_overrides,
    check_arms,
    check_methods,
    check_plan,
    check_tasks,
    close_hint,
    job_state,
    known_methods,
    parse_overrides,
    plan_lines,
    train_options,
)
from ndp.experiments.sweep.driver import run_sweep
from ndp.experiments.sweep.jobs import (
    BUSY_POLL_S,
    FAILED_NAME,
    LOCK_NAME,
    RUN_ENV,
    STOP_GRACE_S,
    Job,
    Outcome,
    SweepResult,
    make_jobs,
)
from ndp.experiments.sweep.progress import Progress, run_fraction
from ndp.experiments.sweep.runner import (
    execute,
    is_busy,
)

__all__ = [
    "BUSY_POLL_S",
    "FAILED_NAME",
    "LOCK_NAME",
    "RESERVED",
    "RUN_ENV",
    "STOP_GRACE_S",
    "Job",
    "LocalBackend",
    "Outcome",
    "Progress",
    "RayBackend",
    "SweepResult",
    "UnknownOptionError",
    "apply_overrides",
    "check_arms",
    "check_methods",
    "check_plan",
    "check_tasks",
    "close_hint",
    "default_workers",
    "execute",
    "is_busy",
    "job_state",
    "known_methods",
    "make_backend",
    "make_jobs",
    "parse_overrides",
    "plan_lines",
    "run_fraction",
    "run_sweep",
    "train_options",
]
