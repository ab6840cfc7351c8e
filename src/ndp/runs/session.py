"""The pieces of a run that are not learning, which the run driver (:mod:`ndp.runs.driver`)
puts together for every trainer.

- the one learner protocol, :class:`Learner` (its state, one :meth:`Learner.iterate` per update
  or epoch, its own metrics, its finite-parameter check);
- create-or-resume: a new run refuses a directory that holds one (:meth:`RunDir.create`); a
  resume loads the checkpoint of the expected ``kind`` and refuses a config that differs outside
  the fields the config class declares safe (:func:`ndp.runs.resume.check_resume`);
- seeding and the global RNG state (python, numpy, torch), saved in every checkpoint and
  restored on resume (:func:`seed_everything`, :func:`global_rng_state`);
- ``config.json``, one provenance entry per session, and ``run.json`` (:class:`Manifest`: what
  the run is and whether it finished, which sweeps and reports read instead of inferring it);
- checkpoints: atomic, only from finite parameters, on a cadence (:func:`checkpoint_due`);
- one divergence error, :class:`TrainingDivergedError`, that names the last good checkpoint.

Trainers do not call these themselves: a trainer is a recipe and a learner given to
:func:`ndp.runs.driver.run` (its docstring shows the order).
"""

from __future__ import annotations

import dataclasses
import json
import random
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypedDict, runtime_checkable

from ndp.io import atomic_write_text
from ndp.runs import lock
from ndp.runs.checkpoint import load_checkpoint, save_checkpoint
from ndp.runs.layout import RunDir
from ndp.runs.resume import check_resume

if TYPE_CHECKING:
    import numpy as np
    import torch
    from _typeshed import DataclassInstance
    from numpy.typing import NDArray
    from torch import Tensor

MANIFEST_NAME = "run.json"
"""The run's manifest (:class:`Manifest`)."""


class TrainingDivergedError(FloatingPointError):
    """A loss, gradient or parameter became NaN / Inf; training stopped and the last good
    checkpoint is kept (the message names it)."""


def seed_everything(seed: int) -> None:
    """Seed python's, numpy's global and torch's generators (third-party code may use any)."""
    import numpy as np
    import torch

    random.seed(seed)
    np.random.seed(seed)  # noqa: NPY002
    torch.manual_seed(seed)


class RngState(TypedDict):
    """The global generators' state, as saved in every checkpoint."""

    torch: Tensor
    numpy: dict[str, Any] | tuple[str, NDArray[np.uint32], int, int, float]
    python: tuple[object, ...]


def global_rng_state() -> RngState:
    """The global generators' state: ``{"torch", "numpy", "python"}`` (saved per checkpoint)."""
    import numpy as np
    import torch

    return {
        "torch": torch.get_rng_state(),
        "numpy": np.random.get_state(),  # noqa: NPY002
        "python": random.getstate(),
    }


def set_global_rng_state(state: RngState) -> None:
    """Restore :func:`global_rng_state`'s output."""
    import numpy as np
    import torch

    torch.set_rng_state(state["torch"])
    np.random.set_state(state["numpy"])  # noqa: NPY002
    random.setstate(state["python"])


def checkpoint_due(step: int, every: int, last: int) -> bool:
    """The default cadence: every ``every`` steps and at the budget's ``last`` step."""
    return step % max(int(every), 1) == 0 or step == last


@dataclass(frozen=True)
class Manifest:
    """What a run is, in ``run.json``: written when the run starts, rewritten when it stops.

    Sweeps and reports read this instead of inferring a run's identity from its folder name.
    """

    kind: str
    """The trainer: ``"rl"`` (PPO, NDP, PPO-multi, VICES, Dyn-E), ``"il"`` (digit writing),
    ``"bc"`` (behaviour cloning) or ``"sb3"`` (the Stable-Baselines3 reference)."""
    task: str
    """The task (``push-v3``) or, for imitation, the data set (``synthetic``)."""
    label: str
    """The method as run (``ndp``, ``ppo-multi``, ``cnn-dmp``)."""
    seed: int
    """The run's seed."""
    budget: int
    """The budget, in ``unit``."""
    unit: str
    """``"env_steps"`` (RL, BC on robot tasks) or ``"epochs"`` (imitation)."""
    done: int = 0
    """How much of the budget has run, in ``unit``."""
    finished: bool = False
    """The run reached its budget, or stopped early by its own rule (imitation's patience)."""
    reason: str = ""
    """Why it finished: ``"budget"``, ``"early stop"``; empty while it has not."""

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Manifest:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ValueError(f"run.json: unknown fields {unknown}")
        return cls(**d)


def read_manifest(run_dir: str | Path) -> Manifest | None:
    """The run's :class:`Manifest`, or None for runs written before run.json existed.

    Raises:
        ValueError: run.json exists but is not a manifest (one line naming the file).
    """
    path = Path(run_dir) / MANIFEST_NAME
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
        if not isinstance(data, dict):
            raise ValueError("not a JSON object")
        return Manifest.from_dict(data)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"run.json: {path} is not a run manifest ({exc})") from None


def write_manifest(run_dir: str | Path, manifest: Manifest) -> None:
    """Write ``run.json`` atomically."""
    atomic_write_text(
        Path(run_dir) / MANIFEST_NAME, json.dumps(manifest.to_dict(), indent=1) + "\n"
    )


@runtime_checkable
class Learner(Protocol):
    """The one learner protocol: what a method computes. The run driver
    (:func:`ndp.runs.driver.run`) does the rest: open, seed, build, restore, drive,
    checkpoint, signals, finish."""

    @property
    def step(self) -> int:
        """Updates (RL) or epochs (imitation) done; the budget is counted in it."""
        ...

    @property
    def stopped(self) -> bool:
        """The learner stopped by its own rule before the budget (imitation's patience)."""
        ...

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to continue (the session adds the global RNG state and config)."""
        ...

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state_dict`'s output."""
        ...

    def iterate(self) -> dict[str, float]:
        """One update or epoch; advances :attr:`step` and returns its metrics row.

        Raises:
            TrainingDivergedError: a loss or gradient became NaN / Inf."""
        ...

    def nonfinite(self) -> str | None:
        """The name of a parameter holding NaN / Inf, else None (checked before every
        checkpoint: a checkpoint is only ever written from finite parameters)."""
        ...

    def close(self) -> None:
        """Release environments and workers (called once, also after an error)."""
        ...


class LearnerDefaults:
    """Defaults of :class:`Learner` members most learners do not need: never stops early,
    nothing to check before a checkpoint."""

    @property
    def stopped(self) -> bool:
        """False: the learner runs to its budget."""
        return False

    def nonfinite(self) -> str | None:
        """None (override where the learner has parameters)."""
        return None


class CountsUpdates(LearnerDefaults):
    """Mixin of RL learners that count ``update`` and keep a :class:`RunSession` as
    ``session``: the :class:`Learner` counter and the last good checkpoint's update."""

    session: RunSession
    update: int

    @property
    def step(self) -> int:
        """Updates done (the :class:`Learner` counter)."""
        return self.update

    @property
    def last_ckpt_update(self) -> int | None:
        """The update of the last good checkpoint (None: none yet)."""
        return self.session.last_saved

    def checkpoint_due(self, every: int, last: int) -> bool:
        """The default cadence (:func:`checkpoint_due`) at the current update."""
        return checkpoint_due(self.update, every, last)


class RunSession:
    """One run directory's session: create-or-resume, checkpoints, divergence, manifest.

    Args:
        run: the run directory.
        kind: the checkpoint's trainer (``"rl"``, ``"il"``); a resume refuses another.
        unit: what one :meth:`Learner.iterate` is, ``"update"`` or ``"epoch"`` (messages).
        hint: what to try after a divergence (ends :meth:`diverged`'s message).
    """

    def __init__(self, run: RunDir, kind: str, unit: str = "update", hint: str = "") -> None:
        self.run = run
        self.kind = kind
        self.unit = unit
        self.hint = hint
        self.last_saved: int | None = None
        self.resumed = False
        self._locked = False

    @classmethod
    def open(
        cls,
        run_dir: str | Path,
        *,
        kind: str,
        config: DataclassInstance,
        config_from_dict: Callable[[dict[str, Any]], DataclassInstance],
        safe_on_resume: Iterable[str],
        resume: bool,
        unit: str = "update",
        hint: str = "",
        overwrite: bool = False,
        resumable: bool = True,
    ) -> tuple[RunSession, dict[str, Any] | None]:
        """Create the run directory, or open it to resume; returns the session and the
        checkpoint to continue from (None for a new run).

        A resume refuses a checkpoint of another ``kind`` and a ``config`` that differs from
        the checkpoint's outside ``safe_on_resume`` (one line naming each field).
        """
        session = cls(RunDir(run_dir), kind, unit, hint)
        if session.run.path.exists() and not session.run.path.is_dir():
            raise ValueError(f"run_dir: {session.run.path} exists and is not a directory")
        if resume and not session.run.path.is_dir():
            session.run.open_for_resume()  # its one-line error; the lock would make the folder
        lock.acquire(session.run.path)  # one writer for the run's whole life (ndp.runs.lock)
        session._locked = True
        try:
            if not resume:
                session.run.create(overwrite=overwrite, resumable=resumable)
                return session, None
            session.run.open_for_resume()
            ckpt = load_checkpoint(session.run.checkpoint, kind=kind)
            check_resume(config_from_dict(ckpt["config"]), config, safe_on_resume, session.run.path)
        except BaseException:
            session.close()
            raise
        return session, ckpt

    def close(self) -> None:
        """Release the run's lock (idempotent; the process's exit releases it too)."""
        if self._locked:
            self._locked = False
            lock.release(self.run.path)

    def restored(self, ckpt: dict[str, Any], step: int) -> None:
        """The learner continues from ``ckpt`` at ``step``: restore the global RNG state."""
        if "rng" in ckpt:
            set_global_rng_state(ckpt["rng"])
        self.last_saved = int(step)
        self.resumed = True

    def start(self, config: dict[str, Any], manifest: Manifest | None = None) -> None:
        """Write config.json (and run.json), and record the session in provenance.json."""
        self.run.write_config(config)
        self.run.record_session("resume" if self.resumed else "start")
        if manifest is not None:
            write_manifest(self.run.path, manifest)

    def save(self, state: dict[str, Any], step: int, config: dict[str, Any]) -> Path:
        """Write the checkpoint atomically: ``state`` plus the global RNG state and config."""
        save_checkpoint(
            self.run.checkpoint, {**state, "rng": global_rng_state(), "config": config}, self.kind
        )
        self.last_saved = int(step)
        return self.run.checkpoint

    def diverged(self, what: str, step: int) -> TrainingDivergedError:
        """The error for a non-finite value during ``unit`` ``step + 1``."""
        last = (
            f"{self.run.checkpoint} ({self.unit} {self.last_saved})"
            if self.last_saved is not None
            else "none written yet"
        )
        return TrainingDivergedError(
            f"training stopped at {self.unit} {step + 1}: {what}. The last good checkpoint is "
            f"kept: {last}.{' ' + self.hint if self.hint else ''}"
        )

    def finish(self, manifest: Manifest) -> None:
        """Rewrite run.json with where the run stands."""
        write_manifest(self.run.path, manifest)


def nonfinite_parameter(named: Iterable[tuple[str, torch.Tensor]]) -> str | None:
    """The name of the first parameter holding NaN / Inf, else None."""
    import torch

    for name, prm in named:
        if not bool(torch.isfinite(prm).all()):
            return str(name)
    return None
