"""The RL run: what every RL method's run shares, as a recipe of the one run driver
(:mod:`ndp.runs.driver`), and the ``train`` / ``resume`` entry points.

A method supplies only its learner (an :class:`RLLearner`: the shared on-policy
:class:`ndp.rl.onpolicy.trainer.Trainer` for PPO, PPO-multi, PPO-repeat, NDP and VICES; Dyn-E's
:class:`ndp.rl.dyne.DyneLearner`; any learner registered with
:attr:`ndp.rl.methods.Method.learner`). :class:`RLRecipe` gives the driver the rest: the run
plan from the resolved :class:`ndp.rl.config.TrainConfig` (kind ``rl``, counted in updates,
the resume rule :data:`ndp.rl.config.SAFE_ON_RESUME`), the budget check on resume, the
``run.json`` manifest in env steps, ``metrics.csv`` with its progress bar, and the checkpoint
cadence.
"""

from __future__ import annotations

import contextlib
import dataclasses
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from ndp.rl.config import SAFE_ON_RESUME, TrainConfig, load_config, resolve_config
from ndp.rl.methods import METHODS
from ndp.rl.onpolicy.trainer import Trainer
from ndp.rl.progress import TrainProgress
from ndp.runs import RunDir
from ndp.runs.driver import Checkpoint, Row, Run, RunPlan, run
from ndp.runs.session import Learner, Manifest, RunSession

if TYPE_CHECKING:
    from ndp.runs.callbacks import Callback

__all__ = [
    "RLLearner",
    "RLRecipe",
    "check_budget_not_below",
    "open_run",
    "resume",
    "resume_run",
    "rl_manifest",
    "say_budget",
    "train",
]


@runtime_checkable
class RLLearner(Learner, Protocol):
    """The :class:`ndp.runs.session.Learner` of an RL method: its step is the update, and it
    says how many env steps ran, which metrics columns it writes and when it may checkpoint."""

    @property
    def global_step(self) -> int:
        """Env steps executed (the budget's unit in run.json and the metrics' x axis)."""
        ...

    @property
    def columns(self) -> tuple[str, ...]:
        """``metrics.csv``'s columns, in order (``update`` first; docs/metrics.md)."""
        ...

    def checkpoint_due(self, every: int, last: int) -> bool:
        """Whether to checkpoint after the update just done (the default cadence is
        :func:`ndp.runs.session.checkpoint_due`; Dyn-E waits for its embedding)."""
        ...


RLLearnerBuilder = Callable[[TrainConfig, RunSession], RLLearner]
"""``(resolved config, run session) -> learner``: what :attr:`ndp.rl.methods.Method.learner`
names (the session gives paths and the divergence message)."""


def rl_manifest(cfg: TrainConfig, global_step: int, update: int = 0) -> Manifest:
    """The :class:`ndp.runs.session.Manifest` of an RL run at ``update``."""
    finished = update >= cfg.num_updates
    return Manifest(
        kind="rl",
        task=cfg.task,
        label=cfg.algo,
        seed=int(cfg.seed),
        budget=int(cfg.num_updates * cfg.env_steps_per_update),
        unit="env_steps",
        done=int(global_step),
        finished=finished,
        reason="budget" if finished else "",
    )


def say_budget(cfg: TrainConfig) -> None:
    """The one place an RL run's budget is rounded and said: ``steps`` rounds up to whole
    updates of ``env_steps_per_update`` (itself ``steps_per_update`` rounded up to
    ``k * num_envs``); where that changes the number, stderr says what will be trained."""
    trained = cfg.num_updates * cfg.env_steps_per_update
    if trained != cfg.steps or cfg.env_steps_per_update != cfg.steps_per_update:
        print(
            f"ndp: budget: --steps {cfg.steps:,} trains {trained:,} env steps: "
            f"{cfg.num_updates:,} update(s) of {cfg.env_steps_per_update:,} env steps "
            f"(--steps-per-update {cfg.steps_per_update:,} rounded up to whole decisions of "
            f"k={cfg.k} x num_envs={cfg.num_envs})"
            + (
                "; counted in sub-step slots: an episode that ends inside a decision executes "
                "fewer env steps (the report names such runs)"
                if cfg.k > 1
                else ""
            ),
            file=sys.stderr,
        )


def check_budget_not_below(done_updates: int, cfg: TrainConfig) -> None:
    """A resume may extend a run's budget, never cut it below what it has trained (its
    config.json and record would then claim less than ran).

    Raises:
        ValueError: ``steps`` gives fewer updates than the checkpoint's.
    """
    if cfg.num_updates < done_updates:
        raise ValueError(
            f"steps: the run has trained {done_updates} updates "
            f"({done_updates * cfg.env_steps_per_update:,} env steps); --steps {cfg.steps:,} "
            "would cut its budget below that (give at least that many, or start a new run)"
        )


class RLRecipe:
    """The driver's recipe of an RL run (see the module docstring).

    Args:
        cfg: the run's config, resolved (:func:`ndp.rl.config.resolve_config`) once, by the
            caller.
    """

    def __init__(self, cfg: TrainConfig) -> None:
        self.cfg = cfg
        self.method = METHODS[cfg.algo]
        self.plan = RunPlan.of_config(
            cfg,
            cfg.to_dict(),
            cfg.num_updates,
            run_dir=cfg.run_dir or ".",
            kind="rl",
            unit="update",
            safe_on_resume=tuple(SAFE_ON_RESUME),
            threads=int(cfg.torch_threads),
            hint=self.method.hint,
            checkpoint_every=int(cfg.checkpoint_every),
        )

    def check_checkpoint(self, ckpt: Checkpoint) -> None:
        check_budget_not_below(int(ckpt["update"]), self.cfg)

    def build(self, session: RunSession, fresh: bool) -> RLLearner:
        say_budget(self.cfg)
        learner: RLLearner | None = self.method.build_learner(self.cfg, session)
        return Trainer(self.cfg, session) if learner is None else learner

    def manifest(self, learner: RLLearner) -> Manifest:
        return rl_manifest(self.cfg, learner.global_step, learner.step)

    @contextlib.contextmanager
    def log(self, learner: RLLearner, session: RunSession) -> Iterator[Callable[[Row], None]]:
        with TrainProgress(session.run.path, learner.columns, self.cfg, learner.step,
                           learner.global_step, session.resumed) as progress:  # fmt: skip
            yield progress.log

    def checkpoint_due(self, learner: RLLearner) -> bool:
        return learner.checkpoint_due(self.cfg.checkpoint_every, self.cfg.num_updates)

    def summary(self, learner: RLLearner, last: Row, session: RunSession) -> Row:
        return last


def open_run(
    cfg: TrainConfig, resume: bool = False, overwrite: bool = False, resolved: bool = False
) -> Run[RLLearner, Row]:
    """The run of ``cfg``, opened (locked, created or resumed, seeded, built, restored,
    started): ``.learner`` is the method's learner, ``.train(max_steps)`` drives it and
    ``.close()`` (or ``with``) ends it. ``resolved``: ``cfg`` is already resolved."""
    if not resolved:
        cfg = resolve_config(cfg)
    return Run(RLRecipe(cfg), resume=resume, overwrite=overwrite)


def train(
    cfg: TrainConfig,
    max_updates: int | None = None,
    overwrite: bool = False,
    resolved: bool = False,
    callbacks: Sequence[Callback] | None = None,
) -> Row:
    """Train a fresh run through the run driver; returns the last update's metrics.

    ``callbacks``: :class:`ndp.runs.callbacks.Callback` instances called after every update
    (``on_update``, ``on_eval``, ``should_stop``: e.g. ``StopAtSuccess(0.9)``,
    ``CheckpointEvery(5)``); a stop writes a checkpoint first, and the run resumes from it.

    ``overwrite``: remove an earlier run in the run directory first (its files are named on
    stderr); without it such a directory is refused. ``resolved``: ``cfg`` is already
    :func:`ndp.rl.config.resolve_config`'s output (``ndp rl train`` resolves it to name the run
    directory).

    Raises:
        TrainingDivergedError: NaN / Inf in a loss, gradient or parameter.
    """
    if not resolved:
        cfg = resolve_config(cfg)  # once: the learner gets it resolved
    return run(RLRecipe(cfg), overwrite=overwrite, max_steps=max_updates, callbacks=callbacks)


def resume(
    run_dir: str | Path,
    max_updates: int | None = None,
    callbacks: Sequence[Callback] | None = None,
    **overrides: Any,
) -> Row:
    """Continue a run from its directory's checkpoint (at most one interval is lost).

    Args:
        run_dir: a directory written by :func:`train`.
        max_updates: stop after this many more updates.
        **overrides: fields of :data:`SAFE_ON_RESUME` (``steps`` extends the budget); any
            other field is refused (:func:`resume_run`).
    """
    run_dir = Path(run_dir)
    cfg = load_config(RunDir(run_dir).config)
    unknown = sorted(set(overrides) - {f.name for f in dataclasses.fields(cfg)})
    if unknown:
        raise ValueError(f"resume: no such options {unknown} (may change: {list(SAFE_ON_RESUME)})")
    changed = dataclasses.replace(cfg, run_dir=str(run_dir), **overrides)
    return resume_run(changed, max_updates, callbacks)


def resume_run(
    cfg: TrainConfig, max_updates: int | None = None, callbacks: Sequence[Callback] | None = None
) -> Row:
    """Continue the run in ``cfg.run_dir`` with ``cfg``: its saved config (``config.json``,
    read once by the caller) with what the resume changes. The run driver compares it with the
    checkpoint's config (:func:`ndp.runs.resume.check_resume`), the one check of a resume: a
    field outside :data:`SAFE_ON_RESUME` that differs is refused, naming each field with both
    values, before anything is built.

    Raises:
        ValueError: a refused change; FileNotFoundError: no checkpoint to resume from.
    """
    return run(RLRecipe(resolve_config(cfg)), resume=True, max_steps=max_updates,
               callbacks=callbacks)  # fmt: skip
