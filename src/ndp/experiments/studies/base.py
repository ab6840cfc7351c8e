"""What a study is: :class:`ArmSpec`, :class:`Condition`, :class:`Study` (the entries of
:mod:`ndp.experiments.studies`), and :func:`resolve`, which turns an entry point
``"module:function"`` into the function when it is called.

A :class:`Study` names its tasks, its arms (:class:`ndp.experiments.study.Arm`: a method and
``ndp rl train`` / ``ndp il train`` options), its seeds and its budget; ``ndp sweep`` runs the
grid (``--tasks``, ``--arms``, ``--seeds``, ``--steps`` narrow or change it) and ``ndp report``
tabulates it. Importing this module imports neither torch nor a simulator: the arms and the
task lists are built when a sweep asks for them (:meth:`Study.arm_specs`, :meth:`Study.task_list`).

The named studies are data: one TOML file each, ``data/<name>.toml``, read into these classes
by :mod:`ndp.experiments.studies.loader` (tests and plugins may still build a :class:`Study`
in Python, with callables for its tasks and arms). Every arm is written out in its file, one
``[[arms]]`` table each, also where a loop generated the arms before (the regimes' k values,
the ablations' values, the digit studies' model x head x learning-rate grids): the file is
then the grid that runs, option for option, a changed arm is a changed line in a review, and
there is no second language (a generator form and its expansion rules) to learn and to check.
The longest lists (ndp-regimes, 23 arms; digits-head, 18) stay readable as tables. The values
that generated them are named in :mod:`ndp.experiments.studies.constants`, and
``tests/experiments/studies/test_data.py`` rebuilds those grids from them and compares them
with the files. Only a task list that needs code (Meta-World's 50 names, asked of metaworld)
is not written out: it is a named task set (``task_set = "metaworld"``,
:data:`ndp.experiments.studies.loader.TASK_SETS`), built when the sweep asks for the tasks.

Arms that need something this version may lack:

- ``pending_method`` arms (VICES, Dyn-E and their ablations, registered now) join their study
  only where their method is registered (``ndp.rl.methods.METHODS``); elsewhere the sweep
  leaves them out and says so;
- ``in_default=False`` arms run only when named with ``--arms``;
- arms with ``requires`` use trainer options (``--learn-az``, ``--only-g``); where
  ``ndp rl train`` does not know them, the sweep refuses the study before anything starts,
  naming the arm and the option (``--skip-unavailable`` leaves them out).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

if TYPE_CHECKING:
    from ndp.experiments.study import Arm


@dataclass(frozen=True)
class ArmSpec:
    """An arm as data (the :class:`ndp.experiments.study.Arm` is built on demand)."""

    label: str
    algo: str
    args: tuple[str, ...] = ()
    note: str = ""
    requires: str = ""
    """Trainer options the arm needs that may not exist yet (named when they are refused)."""
    pending_method: bool = False
    """The arm's method may not be registered yet: then the arm is left out (with a note)."""
    in_default: bool = True
    """Part of a plain ``ndp sweep STUDY``; False: only when named with ``--arms``."""
    tasks: tuple[str, ...] = ()
    """The tasks the arm runs on (``Arm.tasks``); empty: every task of the study."""

    def arm(self) -> Arm:
        """The :class:`ndp.experiments.study.Arm` of this spec."""
        from ndp.experiments.study import Arm

        return Arm(self.label, self.algo, self.args, self.note, self.requires, self.tasks)


Readings = Callable[[Sequence[Any], Sequence[int]], tuple[list[str], list[dict[str, Any]]]]
"""A study's readings: (the report's RL cells, the seeds) -> (Markdown lines, CSV rows)."""


def resolve(entry: str | Callable[..., Any]) -> Callable[..., Any]:
    """The function an entry point ``"package.module:function"`` names (imported now, so a
    study module never imports the report or the sweep); a callable is returned as is.

    Raises ValueError (naming ``entry``) for a malformed entry point or a missing function.
    """
    if callable(entry):
        return entry
    module, sep, name = str(entry).partition(":")
    if not sep or not module or not name:
        raise ValueError(f"entry: {entry!r} is not 'package.module:function'")
    try:
        fn: Any = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as e:
        raise ValueError(f"entry: {entry!r} does not name a function ({e})") from None
    if not callable(fn):
        raise ValueError(f"entry: {entry!r} names {type(fn).__name__}, not a function")
    return cast("Callable[..., Any]", fn)


@dataclass(frozen=True)
class Condition:
    """A named setting of a study whose arms are shared between conditions: which arm (run
    label) stands for each method under it (``ndp report --conditions``)."""

    name: str
    note: str
    """What the condition is, for the tables."""
    methods: tuple[tuple[str, str], ...]
    """(method, arm label) pairs, in table order."""
    unequal: bool = False
    """The methods do not see the same task distribution or settings on purpose (a condition
    reproduced from the 2021 release): the report labels it so."""
    overrides: tuple[tuple[str, str, str], ...] = ()
    """(task, method, arm label): on that task the method's arm is this one instead (a
    condition that the release ran differently per task, e.g. its goal rule)."""


@dataclass(frozen=True)
class Study:
    """A named grid: tasks x arms x seeds at one budget."""

    name: str
    title: str
    doc: str
    """What the study measures and how to read it (docs/experiments.md has the same)."""
    tasks: Callable[[], tuple[str, ...]]
    arms: Callable[[], tuple[ArmSpec, ...]]
    seeds: tuple[int, ...] = (0, 1, 2)
    steps: int = 300_000
    """Budget per run: env steps (RL), epochs (imitation)."""
    kind: str = "rl"
    """'rl' (``ndp rl train`` runs) or 'il' (``ndp il train`` runs)."""
    budgets: tuple[float, ...] = (0.25, 0.5, 1.0)
    """Fractions of the budget at which the report gives the success."""
    summary: tuple[str, ...] = field(default=())
    """Extra report sections: 'over-tasks' (mean over tasks, NDP >= PPO count)."""
    conditions: tuple[Condition, ...] = field(default=())
    """Conditions over shared arms (the report's condition x method tables); empty: every
    arm is its own column."""
    selection: tuple[tuple[str, tuple[str, ...]], ...] = field(default=())
    """(model, candidate arm labels): the report picks per task the candidate with the lowest
    mean validation MSE and reports its test MSE (``ndp.experiments.report.selection``)."""
    readings: str | Readings | None = None
    """The study's pre-registered readings, applied by code to the report's RL cells and seeds
    (Markdown lines and CSV rows): an entry point ``"module:function"`` (e.g.
    ``"ndp.experiments.report.regimes:regimes_readings"``) resolved when the report calls it
    (:meth:`readings_fn`), or the function itself; the report adds them after its condition
    tables (``<out>-readings.csv``)."""

    def task_list(self) -> tuple[str, ...]:
        """The study's tasks (built now: Meta-World's list imports metaworld)."""
        return tuple(self.tasks())

    def readings_fn(self) -> Readings | None:
        """The readings function (:attr:`readings` resolved), or None."""
        return None if self.readings is None else resolve(self.readings)

    def arm_specs(self) -> tuple[ArmSpec, ...]:
        """The study's arms as data, in their order."""
        return tuple(self.arms())

    def available(self) -> tuple[list[ArmSpec], list[tuple[ArmSpec, str]]]:
        """(the arms whose method is registered, [(arm, why it is left out)])."""
        from ndp.experiments.sweep import known_methods

        known = set(known_methods())
        keep, out = [], []
        for a in self.arm_specs():
            if a.algo in known:
                keep.append(a)
            elif a.pending_method:
                out.append((a, f"method {a.algo!r} is not registered in this version yet"))
            else:
                raise ValueError(
                    f"study {self.name}: arm {a.label!r} names unknown method {a.algo!r}"
                )
        return keep, out
