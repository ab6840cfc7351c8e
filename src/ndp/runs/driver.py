"""The one run driver: the lifecycle of every run (RL, Dyn-E, replay learners, imitation,
behaviour cloning, the Stable-Baselines3 reference), written once.

A run is two objects:

- a :class:`Recipe` (one per kind of run: ``ndp.rl.run.RLRecipe``, ``ndp.il.train``'s, ...):
  the :class:`RunPlan` (where, what kind, seed, budget, resume rule), how to **build** the
  learner, the run's :class:`ndp.runs.session.Manifest`, its metrics log, its checkpoint
  cadence and what :func:`run` returns;
- a :class:`ndp.runs.session.Learner` (one per method): its state and one
  :meth:`ndp.runs.session.Learner.iterate` per update or epoch. A method supplies only what
  it computes.

:func:`run` does the rest, in this order, for every run::

    signals   SIGTERM / SIGINT raise inside the run (ndp.runs.signals); a checkpoint write
              finishes first
    open      lock the run directory; create it, or open it to resume (kind and config checked)
    check     recipe.check_checkpoint(ckpt): e.g. a budget cut below what already ran
    seed      torch threads, then python / numpy / torch seeded ONCE, from plan.seed
    build     recipe.build(session, fresh): nets, envs, optimisers
    restore   learner.load_state_dict(ckpt), then the global RNG state of the checkpoint
    start     config.json, provenance.json (one entry per session), run.json
    drive     iterate -> log -> checkpoint when due (never from non-finite parameters),
              until the budget, ``max_steps`` more, or the learner's own stop
    finish    run.json says where the run stands; recipe.summary(...) is returned
    close     learner.close(), then the run's lock (also on an error or a stop)

Example (the shape of every recipe; ``tests/runs/test_driver.py`` has a complete one)::

    class MyRecipe:
        plan = RunPlan(run_dir=..., kind="rl", unit="update", seed=0, budget=100,
                       config=cfg, config_dict=cfg.to_dict(),
                       config_from_dict=MyConfig.from_dict, safe_on_resume=("steps",))
        def build(self, session, fresh): return MyLearner(cfg, session)
        ...
    summary = run(MyRecipe(), resume=False)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, Protocol, TypeVar

from ndp.runs.callbacks import Callback, CallbackContext, check_callbacks, has_eval
from ndp.runs.session import (
    Learner,
    Manifest,
    RunSession,
    checkpoint_due,
    seed_everything,
)
from ndp.runs.signals import stop_on_sigterm

Row = dict[str, float]
"""One row of ``metrics.csv`` (column -> value)."""
Checkpoint = dict[str, Any]
"""A loaded ``checkpoint.pt``: the learner's state plus ``rng`` and ``config``."""

L = TypeVar("L", bound=Learner)
S = TypeVar("S", covariant=True)


@dataclass(frozen=True)
class RunPlan:
    """What the driver needs before any learner exists (resolved once, from the config)."""

    run_dir: Path
    """The run directory (``ndp.runs.layout.run_name`` names the default one)."""
    kind: str
    """The run kind, written into every checkpoint; a resume refuses another
    (``ndp.runs.layout.RUN_KINDS``: ``rl``, ``il``, ``sb3``)."""
    unit: str
    """What one :meth:`Learner.iterate` is: ``"update"`` or ``"epoch"`` (messages)."""
    seed: int
    """Seeds python's, numpy's and torch's global generators, once, before the build."""
    budget: int
    """The learner's :attr:`Learner.step` at which the run is finished."""
    config: Any
    """The resolved, typed config (a dataclass): compared with the checkpoint's on resume."""
    config_dict: dict[str, Any]
    """``config`` as written to ``config.json`` and into every checkpoint."""
    config_from_dict: Callable[[dict[str, Any]], Any]
    """The inverse of ``config_dict``: reads the checkpoint's config for the comparison."""
    safe_on_resume: tuple[str, ...] = ()
    """Fields a resume may change (``ndp.runs.resume.check_resume``; ``steps`` extends)."""
    threads: int | None = 1
    """torch's intra-op threads (None: leave torch's setting)."""
    hint: str = ""
    """What to try after a divergence (ends the error's message)."""
    resumable: bool = True
    """False: the run kind cannot resume (its interrupt message says so)."""
    checkpoint_every: int = 1
    """The default cadence (:func:`ndp.runs.session.checkpoint_due`): every this many steps and
    at the budget."""
    extra: dict[str, Any] = field(default_factory=dict)
    """Kind-specific facts a recipe keeps beside the plan (not read by the driver)."""

    @classmethod
    def of_config(
        cls, config: Any, config_dict: dict[str, Any], budget: int, **fields: Any
    ) -> RunPlan:
        """The plan of a typed config that holds its ``run_dir`` and ``seed`` and reads
        ``config_dict`` back with its class's ``from_dict`` (the RL, IL and cloning runs');
        ``fields``: the plan's other fields (``run_dir`` and ``seed`` override the config's)."""
        fields = {"run_dir": config.run_dir, "seed": config.seed, **fields}
        fields["run_dir"], fields["seed"] = Path(fields["run_dir"]), int(fields["seed"])
        return cls(
            budget=int(budget),
            config=config,
            config_dict=config_dict,
            config_from_dict=type(config).from_dict,
            **fields,
        )


class Recipe(Protocol[L, S]):
    """What one kind of run supplies to :func:`run` (see the module docstring)."""

    @property
    def plan(self) -> RunPlan:
        """Where the run lives, its kind, seed, budget and resume rule."""
        ...

    def check_checkpoint(self, ckpt: Checkpoint) -> None:
        """Refuse a resume before anything is built (e.g. a budget below what ran)."""
        ...

    def build(self, session: RunSession, fresh: bool) -> L:
        """The learner, built after seeding (nets, envs, optimisers); ``fresh``: no checkpoint
        will be restored into it."""
        ...

    def manifest(self, learner: L) -> Manifest:
        """``run.json`` where the learner stands."""
        ...

    def log(self, learner: L, session: RunSession) -> AbstractContextManager[Callable[[Row], None]]:
        """The metrics log (CSV, TensorBoard, a progress bar), continued on resume."""
        ...

    def checkpoint_due(self, learner: L) -> bool:
        """Whether to write the checkpoint after the step just done."""
        ...

    def summary(self, learner: L, last: Row, session: RunSession) -> S:
        """What :func:`run` returns, after the run's last row (empty when nothing ran)."""
        ...


def save(session: RunSession, learner: Learner, plan: RunPlan) -> Path:
    """Write the learner's checkpoint atomically, only from finite parameters.

    Raises:
        TrainingDivergedError: a parameter holds NaN / Inf (the last good checkpoint stays)."""
    bad = learner.nonfinite()
    if bad is not None:
        raise session.diverged(f"parameter {bad} holds NaN/Inf before saving a checkpoint",
                               learner.step)  # fmt: skip
    return session.save(learner.state_dict(), learner.step, plan.config_dict)


def stop_at(budget: int, step: int, max_steps: int | None) -> int:
    """The step at which a call of :func:`run` stops: the budget, or ``max_steps`` more."""
    return budget if max_steps is None else min(budget, step + int(max_steps))


class Run(Generic[L, S]):
    """One run, opened: the lifecycle of :func:`run` in its two halves, for callers that need
    the learner between them (tests, notebooks). Opening locks, creates or resumes, seeds,
    builds, restores and starts; :meth:`train` drives and finishes; :meth:`close` (or the
    ``with`` block) closes the learner and releases the lock.

    Args:
        recipe: the run's :class:`Recipe`.
        resume: continue from the directory's checkpoint (its kind and config checked).
        overwrite: remove an earlier run in the directory first (named on stderr).
    """

    def __init__(self, recipe: Recipe[L, S], *, resume: bool = False,
                 overwrite: bool = False) -> None:  # fmt: skip
        self.recipe = recipe
        plan = self.plan = recipe.plan
        self.session, ckpt = RunSession.open(
            plan.run_dir,
            kind=plan.kind,
            config=plan.config,
            config_from_dict=plan.config_from_dict,
            safe_on_resume=plan.safe_on_resume,
            resume=resume,
            unit=plan.unit,
            hint=plan.hint,
            overwrite=overwrite,
            resumable=plan.resumable,
        )
        self._closed = False
        try:
            if ckpt is not None:
                recipe.check_checkpoint(ckpt)
            seed_run(plan)
            self.learner: L = recipe.build(self.session, fresh=ckpt is None)
        except BaseException:
            self.session.close()
            raise
        try:
            if ckpt is not None:
                self.learner.load_state_dict(ckpt)
                self.session.restored(ckpt, self.learner.step)
            self.session.start(plan.config_dict, recipe.manifest(self.learner))
        except BaseException:
            self.close()
            raise

    def train(self, max_steps: int | None = None, callbacks: Sequence[Callback] | None = None) -> S:
        """Drive to the budget (or ``max_steps`` more steps, or until a callback stops it:
        :mod:`ndp.runs.callbacks`), rewrite run.json, and return the recipe's summary. May be
        called again to continue."""
        cbs = check_callbacks(callbacks)
        stop = stop_at(self.plan.budget, self.learner.step, max_steps)
        last = drive(self.recipe, self.learner, self.session, stop, cbs)
        self.session.finish(self.recipe.manifest(self.learner))
        return self.recipe.summary(self.learner, last, self.session)

    def save(self) -> Path:
        """Write the checkpoint now (only from finite parameters)."""
        return save(self.session, self.learner, self.plan)

    def close(self) -> None:
        """Close the learner, then release the run's lock (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            self.learner.close()
        finally:
            self.session.close()

    def __enter__(self) -> Run[L, S]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def run(
    recipe: Recipe[L, S],
    *,
    resume: bool = False,
    overwrite: bool = False,
    max_steps: int | None = None,
    callbacks: Sequence[Callback] | None = None,
) -> S:
    """Run ``recipe`` from its start, or from its checkpoint with ``resume``, to its budget
    (or ``max_steps`` more steps, or until a callback stops it); returns
    ``recipe.summary(...)``. ``callbacks``: :class:`ndp.runs.callbacks.Callback` instances,
    called after every update.

    ``overwrite``: remove an earlier run in the directory first (named on stderr); without it
    such a directory is refused.

    Raises:
        KeyboardInterrupt / ndp.runs.signals.Terminated: Ctrl-C or SIGTERM; the last good
            checkpoint stays.
        TrainingDivergedError: a non-finite loss or parameter (the message names the last
            good checkpoint).
        ValueError: a refused directory, resume or config (one line).
    """
    cbs = check_callbacks(callbacks)  # before the run directory is touched
    with stop_on_sigterm(), Run(recipe, resume=resume, overwrite=overwrite) as opened:
        return opened.train(max_steps, cbs)


def seed_run(plan: RunPlan) -> None:
    """The one place a run seeds: torch's threads, then every global generator."""
    if plan.threads is not None:
        import torch

        torch.set_num_threads(int(plan.threads))
    seed_everything(plan.seed)


def drive(
    recipe: Recipe[L, object],
    learner: L,
    session: RunSession,
    stop: int,
    callbacks: Sequence[Callback] = (),
) -> Row:
    """The loop: iterate until ``learner.step`` reaches ``stop`` (or the learner stops by its
    own rule, or a callback does), log each row, checkpoint when the recipe says (and before a
    callback's stop, so the run resumes from there); returns the last row."""
    last: Row = {}
    with recipe.log(learner, session) as log:
        while learner.step < stop and not learner.stopped:
            last = learner.iterate()
            log(last)
            due = recipe.checkpoint_due(learner)
            if due:
                save(session, learner, recipe.plan)
            if callbacks and _callbacks_stop(callbacks, last, recipe, learner, session):
                if not due:
                    save(session, learner, recipe.plan)
                break
    return last


def _callbacks_stop(
    callbacks: Sequence[Callback],
    row: Row,
    recipe: Recipe[L, object],
    learner: L,
    session: RunSession,
) -> bool:
    """Call every callback on this update's row; whether any asks to stop."""
    ctx = CallbackContext(
        step=int(learner.step),
        budget=int(recipe.plan.budget),
        run_dir=Path(recipe.plan.run_dir),
        learner=learner,
        save=lambda: save(session, learner, recipe.plan),
    )
    evaluated = has_eval(row)
    stop = False
    for cb in callbacks:
        cb.on_update(row, ctx)
        if evaluated:
            cb.on_eval(row, ctx)
        stop = cb.should_stop(row, ctx) or stop
    return stop


def default_cadence(learner: Learner, plan: RunPlan) -> bool:
    """Every ``plan.checkpoint_every`` steps and at the budget."""
    return checkpoint_due(learner.step, plan.checkpoint_every, plan.budget)
