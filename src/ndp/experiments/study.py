"""Learning studies: named arms x tasks x seeds, resumable, run in parallel, summarised.

An :class:`Arm` is one configuration: a method (``ndp``, ``ppo``, ``ppo-multi``, or ``sb3-ppo``,
Stable-Baselines3's PPO, see :mod:`ndp.sb3.runs`) plus extra ``ndp rl train`` options;
or an imitation model (``il-ndp``, ``il-cnn``, ``il-cnn-dmp``: ``ndp il train --model ...`` on the
data set the "task" names, see :data:`ndp.experiments.run_kinds.IL_METHODS` and
:func:`ndp.experiments.run_kinds.il_data_args`).
Every (task, arm, seed) is one ordinary run in ``<runs_dir>/<task>-<label>-s<seed>``:

- a finished run is reused, an interrupted ``ndp rl train`` run is resumed from its checkpoint
  (an interrupted SB3 run is restarted), so a study can be killed and re-run at any time, and a
  later session extends it;
- ``arm.json`` in each run directory records the arm; a directory that holds another arm's run
  is refused (no silent mixing);
- ``jobs`` runs go at once (one torch thread each; at most one per core); the runs themselves
  are executed by :mod:`ndp.experiments.sweep` (local process pool or Ray, retries, progress).

:func:`summarise` reads every run's ``metrics.csv`` (``charts/success_any`` per update: the
training episodes' success at any step, stochastic policy) and computes per run the **success
area** (the success curve averaged over the whole budget: the area under it divided by the
budget, the sample-efficiency number) and the **final success** (mean of the last 10% of
updates), then mean +- std over seeds.
"""

from __future__ import annotations

import json
import math
import subprocess
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ndp.experiments.rows import final_success, smooth, success_area
from ndp.experiments.run_kinds import kind_of_algo, run_kind
from ndp.io import atomic_savefig, atomic_write_text
from ndp.runs import metrics_path, read_metrics
from ndp.runs.layout import run_name
from ndp.runs.session import read_manifest


@dataclass(frozen=True)
class Arm:
    """One configuration of a study."""

    label: str
    """Name in run directories and tables (letters, digits, '-', '_')."""
    algo: str
    """'ndp', 'ppo', 'ppo-multi' or 'sb3-ppo'."""
    args: tuple[str, ...] = field(default=())
    """Extra ``ndp rl train`` options (not for 'sb3-ppo')."""
    note: str = ""
    """What the arm changes, for the tables."""
    requires: str = ""
    """What the arm needs that the trainer may not have yet (e.g. "the learned-a_z option of
    the RL NDP head"): named when its options are refused (ndp.experiments.sweep.check_arms)."""
    tasks: tuple[str, ...] = field(default=())
    """The tasks this arm runs on (its options exist only there, e.g. v1 rewards on Meta-World);
    empty: every task of the sweep."""

    def runs_on(self, task: str) -> bool:
        """Whether the arm has a run on ``task`` (:attr:`tasks` empty: every task)."""
        return not self.tasks or task in self.tasks

    def __post_init__(self) -> None:
        kind_of_algo(self.algo)  # a ValueError naming the known methods
        if not self.label or not all(c.isalnum() or c in "-_" for c in self.label):
            raise ValueError(f"label: expected letters, digits, '-' or '_', got {self.label!r}")
        if self.args and not run_kind(self.kind).takes_options:
            raise ValueError(f"args: the {self.algo!r} arm takes no ndp options")

    @property
    def kind(self) -> str:
        """The run kind that trains it (:func:`ndp.experiments.run_kinds.kind_of_algo`): 'rl'
        (``ndp rl train``), 'sb3' (the SB3 reference) or 'il' (``ndp il train``)."""
        return kind_of_algo(self.algo).name


def run_dir(runs_dir: Path, task: str, arm: Arm, seed: int) -> Path:
    """Directory of one run: ``<runs_dir>/<task>-<label>-s<seed>``
    (:func:`ndp.runs.layout.run_name`)."""
    return Path(runs_dir) / run_name(task, arm.label, seed)


_ARM_KEYS = ("label", "algo", "args", "steps")
"""The arm.json keys that identify a run (``note`` is a description; ``task`` / ``seed`` are
recorded for reports and compared when both records have them)."""


def arm_record(
    arm: Arm, steps: int, task: str | None = None, seed: int | None = None
) -> dict[str, Any]:
    """What ``arm.json`` holds: the arm, its budget, and (newer records) the task and seed."""
    rec: dict[str, Any] = {
        "label": arm.label,
        "algo": arm.algo,
        "args": list(arm.args),
        "note": arm.note,
        "steps": steps,
    }
    if task is not None:
        rec.update(task=task, seed=seed, kind=arm.kind)
    return rec


def arm_conflict(run: Path, arm: Arm, steps: int, task: str | None = None,
                 seed: int | None = None) -> str | None:  # fmt: skip
    """Why ``run`` cannot hold this arm's run (another arm, budget, task or seed), or None."""
    budget = _config_budget(run, arm)
    if budget is not None and budget != steps:
        unit = run_kind(arm.kind).unit
        return (
            f"its config.json trains {budget:,} {unit} where this sweep has {steps:,}; a "
            "run is counted only at its own budget"
        )
    rec = run / "arm.json"
    if not rec.is_file():
        return None
    try:
        have = json.loads(rec.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        return f"its arm.json is unreadable ({exc})"
    want = arm_record(arm, steps, task, seed)
    keys = [*_ARM_KEYS, *(k for k in ("task", "seed") if k in have and k in want)]
    diff = {k: (have.get(k), want.get(k)) for k in keys if have.get(k) != want.get(k)}
    if not diff:
        return None
    return "it holds another run (" + ", ".join(
        f"{k} {a!r} where this sweep has {b!r}" for k, (a, b) in diff.items()
    ) + ")"  # fmt: skip


def _config_budget(run: Path, arm: Arm) -> int | None:
    """The budget the run's config.json records (RL: ``steps``; imitation: ``epochs``), or None
    where there is no readable config (a run not started yet) or nothing that counts: a start
    that failed before its first checkpoint is restarted at the sweep's budget, so its config's
    budget is no conflict."""
    if not (run / "checkpoint.pt").exists() and not (run / "done.json").exists():
        return None
    try:
        cfg = json.loads((run / "config.json").read_text())
    except (OSError, json.JSONDecodeError):
        return None
    if not isinstance(cfg, dict):
        return None
    v = cfg.get(run_kind(arm.kind).budget_key)
    return int(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def _check_arm(run: Path, arm: Arm, steps: int, task: str | None = None,
               seed: int | None = None) -> None:  # fmt: skip
    why = arm_conflict(run, arm, steps, task, seed)
    if why is not None:
        raise ValueError(f"runs_dir: {run}: {why}. Use another --runs-dir or label.")
    rec = run / "arm.json"
    if not rec.is_file():  # an existing record is never rewritten (older study code reads it)
        run.mkdir(parents=True, exist_ok=True)
        atomic_write_text(rec, json.dumps(arm_record(arm, steps, task, seed), indent=1) + "\n")


def is_finished(run: Path, arm: Arm | None = None, kind: str | None = None) -> bool:
    """Whether a run completed its budget (an imitation run: trained and evaluated); ``kind``
    ('rl', 'sb3', 'il') stands for the arm where only that is known."""
    run = Path(run)
    kind = kind or (arm.kind if arm is not None else "rl")
    if run_kind(kind).needs_eval and not (run / "eval.json").is_file():
        return False  # e.g. an imitation run counts once trained and evaluated

    try:
        manifest = read_manifest(run)
    except ValueError:
        manifest = None  # unreadable: the other records decide
    if manifest is not None:
        return manifest.finished  # what the run says (run.json, written by its session)
    # runs written before run.json
    if (run / "done.json").is_file():
        return True
    ckpt = run / "checkpoint.pt"
    if not ckpt.is_file() or not (run / "config.json").is_file():
        return False
    return run_kind(kind).checkpoint_finished(run)


def train_command(
    task: str, arm: Arm, seed: int, steps: int, run: Path, num_envs: int = 4, vector: str = "auto"
) -> list[str]:
    """The command that trains (or resumes) one run (``vector``: its vector env kind): the
    arm's run kind builds it (:attr:`ndp.experiments.run_kinds.RunKind.command`).

    An imitation arm's ``steps`` is its budget in epochs and ``task`` its data set."""
    return run_kind(arm.kind).command(task, arm, seed, steps, run, num_envs, vector)


def prepare_run(run: Path, arm: Arm) -> None:
    """Before (re)starting a run: remove a partial log that nothing can resume from (an SB3 run,
    or a run killed before its first checkpoint), so the trainer starts it afresh."""
    log_file = metrics_path(run)
    resumable = run_kind(arm.kind).resumable
    if log_file.is_file() and (not resumable or not (run / "checkpoint.pt").is_file()):
        log_file.unlink()


def run_one(
    task: str,
    arm: Arm,
    seed: int,
    steps: int,
    runs_dir: Path,
    num_envs: int = 4,
    vector: str = "auto",
) -> Path:
    """Train, resume or reuse one run in this process's foreground; returns its directory.

    (:func:`ndp.experiments.sweep.grid.run_grid` and ``ndp sweep`` run many at once with retries:
    :mod:`ndp.experiments.sweep`.)"""
    run = run_dir(runs_dir, task, arm, seed)
    _check_arm(run, arm, steps, task, seed)
    if is_finished(run, arm):
        return run
    prepare_run(run, arm)
    t0 = time.time()
    log = run / "train.log"
    with log.open("a") as fh:
        subprocess.run(
            train_command(task, arm, seed, steps, run, num_envs, vector),
            check=True,
            stdout=fh,
            stderr=subprocess.STDOUT,
        )
    print(f"[{task} {arm.label} s{seed}] {time.time() - t0:.0f}s", flush=True)
    return run


def default_vector(jobs: int) -> str:
    """The vector env of each run when ``jobs`` run at once: with one job a run uses the env
    workers (``auto``); with several, each run is a single process (``sync``) unless the machine
    has cores to spare for workers too."""
    from ndp.envs.vector import default_workers

    return "auto" if jobs <= 1 or default_workers(64) >= 2 * jobs else "sync"


def load_curve(run: Path, key: str = "charts/success_any") -> tuple[np.ndarray, np.ndarray]:
    """(global_step [U], metric [U]) of a run; updates without finished episodes dropped."""
    rows = read_metrics(run)
    x = np.array([r["global_step"] for r in rows])
    y = np.array([r.get(key, math.nan) for r in rows])
    keep = ~np.isnan(y)
    return x[keep], y[keep]


def summarise(
    tasks: Sequence[str], arms: Sequence[Arm], seeds: Sequence[int], steps: int, runs_dir: Path
) -> dict[str, Any]:
    """Per task and arm: area and final success per seed, mean +- std, mean curve.

    Only finished runs count (a run still training is listed under ``running``).
    """
    grid = np.linspace(0, steps, 51)
    out: dict[str, Any] = {"steps": steps, "seeds": list(seeds), "tasks": {}}
    for task in tasks:
        out["tasks"][task] = {}
        for arm in arms:
            areas, finals, curves, used, running = [], [], [], [], []
            for seed in seeds:
                run = run_dir(runs_dir, task, arm, seed)
                if not metrics_path(run).is_file():
                    continue
                if not is_finished(run, arm):
                    running.append(seed)
                    continue
                x, y = load_curve(run)
                if len(x) == 0:
                    continue
                areas.append(success_area(x, y, steps))
                finals.append(final_success(y))
                curves.append(np.interp(grid, x, smooth(y, max(1, len(y) // 20)), left=np.nan))
                used.append(seed)
            if not areas and not running:
                continue
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                mean = np.nanmean(curves, 0) if curves else np.full(len(grid), np.nan)
                std = np.nanstd(curves, 0) if curves else np.full(len(grid), np.nan)
            out["tasks"][task][arm.label] = {
                "algo": arm.algo,
                "args": list(arm.args),
                "note": arm.note,
                "seeds": used,
                "running": running,
                "areas": areas,
                "finals": finals,
                "area_mean": float(np.mean(areas)) if areas else math.nan,
                "area_std": float(np.std(areas)) if areas else math.nan,
                "final_mean": float(np.mean(finals)) if finals else math.nan,
                "final_std": float(np.std(finals)) if finals else math.nan,
                "curve_steps": grid.tolist(),
                "curve_mean": mean.tolist(),
                "curve_std": std.tolist(),
            }
    return out


def cell(r: dict[str, Any] | None, key: str) -> str:
    """``mean +- std (n)`` of a summary entry's ``key`` ('area' or 'final')."""
    if r is None or not r[f"{key}s"]:
        return "-" if r is None or not r["running"] else "(running)"
    return f"{r[f'{key}_mean']:.2f} +- {r[f'{key}_std']:.2f} (n={len(r[f'{key}s'])})"


def markdown_table(summary: dict[str, Any], arms: Sequence[Arm], key: str) -> list[str]:
    """Rows of a task x arm table of ``key`` ('area' or 'final')."""
    labels = [a.label for a in arms]
    lines = ["| task | " + " | ".join(labels) + " |", "|---" * (len(labels) + 1) + "|"]
    for task, res in summary["tasks"].items():
        lines.append(f"| {task} | " + " | ".join(cell(res.get(lb), key) for lb in labels) + " |")
    return lines


def plot(summary: dict[str, Any], arms: Sequence[Arm], path: Path) -> None:
    """Success curves (mean +- std over seeds), one panel per task."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tasks = list(summary["tasks"])
    fig, axes = plt.subplots(1, len(tasks), figsize=(4.2 * len(tasks), 3.4), squeeze=False)
    for ax, task in zip(axes[0], tasks, strict=True):
        for arm in arms:
            r = summary["tasks"][task].get(arm.label)
            if r is None or not r["seeds"]:
                continue
            x, m, s = (np.array(r[k]) for k in ("curve_steps", "curve_mean", "curve_std"))
            ax.plot(x, m, label=f"{arm.label} (n={len(r['seeds'])})")
            ax.fill_between(x, m - s, m + s, alpha=0.15)
        ax.set_title(task)
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("env steps")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("success (any step, training)")
    axes[0][-1].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, path, dpi=60)
    plt.close(fig)
