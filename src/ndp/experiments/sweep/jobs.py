"""The jobs of a sweep: one (task, arm, seed) each, their outcomes and the sweep's result.

Part of :mod:`ndp.experiments.sweep` (its docstring describes the whole).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ndp.experiments.study import (
    Arm,
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
    """Every (task, arm, seed), seed-major (all tasks and arms of the first seed first); an
    arm restricted to some tasks (``Arm.tasks``) only on those."""
    return [
        Job(t, a, int(s), int(steps), run_dir(Path(runs_dir), t, a, s), num_envs, vector)
        for s in seeds
        for t in tasks
        for a in arms
        if a.runs_on(t)
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
