"""Studies as data: one TOML file per study (``data/<name>.toml``), read into the
:class:`~ndp.experiments.studies.base.Study`, :class:`~ndp.experiments.studies.base.ArmSpec` and
:class:`~ndp.experiments.studies.base.Condition` objects the sweep and the report read.

A file (every key but ``name``, ``title``, ``doc``, the tasks and ``arms`` may be left out; the
defaults are :class:`~ndp.experiments.studies.base.Study`'s)::

    name = "my-study"                    # ndp sweep my-study
    title = "One line for the tables"
    doc = "What the study measures and how to read it (its pre-registered readings)."
    tasks = ["push-v3", "throw"]         # or task_set = "metaworld" (a named task set)
    seeds = [0, 1, 2]
    steps = 300_000                      # budget per run: env steps (RL), epochs (imitation)
    kind = "rl"                          # the run kind: rl, il, sb3, bc
    budgets = [0.25, 0.5, 1.0]           # fractions of the budget the report reads
    summary = ["over-tasks"]             # extra report sections
    readings = "ndp.experiments.report.regimes:regimes_readings"   # an entry point

    [[arms]]                             # one table per arm, in the sweep's order
    label = "ndp-k10"
    algo = "ndp"
    args = ["--k", "10", "--minibatches", "16"]    # ndp rl train / ndp il train options
    note = "NDP, k = 10, white noise"
    requires = ""                        # trainer options it needs that may not exist yet
    pending_method = false               # true: left out where its method is not registered
    in_default = true                    # false: runs only when named with --arms
    tasks = []                           # the tasks it runs on; empty: every task

    [[conditions]]                       # the report's condition x method tables
    name = "white, k = 10"
    note = "what the condition is"
    methods = [["ndp", "ndp-k10"], ["ppo", "ppo"]]   # (method, arm label), in table order
    unequal = false
    overrides = [["throw", "ppo", "ppo-fixed"]]      # (task, method, arm label)

    [[selection]]                        # the report's model selection on validation
    model = "ndp"
    arms = ["ndp-lr3e-4", "ndp-lr1e-3"]

A malformed file is refused when the package is imported, with one line naming the file and
the key (``data/x.toml: arms[2].args: expected a list of strings, got str``; ``arms[N]`` counts
from 0): an unknown key (with the close names), a value of the wrong type, a missing key, a
study name defined twice, an arm label defined twice in one study, an unknown task set.

Task lists that need code (Meta-World's 50 names come from metaworld) are named task sets:
``task_set = "metaworld"`` is resolved through :data:`TASK_SETS` (an entry point
``"module:function"``, imported only when the sweep asks for the tasks, so reading the files
imports neither torch nor a simulator); :func:`register_task_set` adds one.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from ndp.experiments.studies.base import ArmSpec, Condition, Study, resolve

DATA_DIR = Path(__file__).resolve().parent / "data"
"""The shipped study files (``<name>.toml``, one per study)."""

TASK_SETS: dict[str, str | Callable[[], Sequence[str]]] = {
    "metaworld": "ndp.envs.metaworld_env:metaworld_env_names",
}
"""Named task lists (``task_set = NAME``): an entry point ``"module:function"`` (or the function)
giving the task names, resolved when the sweep asks for the study's tasks."""


def register_task_set(name: str, tasks: str | Callable[[], Sequence[str]]) -> None:
    """Name a task list for study files (``task_set = name``); ``tasks`` is an entry point
    ``"module:function"`` or the function. A name taken already: ValueError naming it."""
    if name in TASK_SETS:
        raise ValueError(f"task_set: {name!r} is registered already")
    TASK_SETS[name] = tasks


class _TaskSet:
    """The tasks of a named task set, looked up and built when called."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __call__(self) -> tuple[str, ...]:
        return tuple(resolve(TASK_SETS[self.name])())

    def __repr__(self) -> str:
        return f"task_set {self.name!r}"


class _Fixed:
    """A fixed tuple, returned when called (a study's ``tasks`` and ``arms`` are callables)."""

    def __init__(self, items: tuple[Any, ...]) -> None:
        self.items = items

    def __call__(self) -> tuple[Any, ...]:
        return self.items

    def __repr__(self) -> str:
        return repr(self.items)


# a key's type: its name in the error message and the check of one value
_Check = tuple[str, Callable[[Any], bool]]


def _strs(v: Any) -> bool:
    return isinstance(v, list) and all(isinstance(x, str) for x in v)


def _tuples_of_strs(n: int) -> Callable[[Any], bool]:
    return lambda v: isinstance(v, list) and all(_strs(x) and len(x) == n for x in v)


_STR: _Check = ("a string", lambda v: isinstance(v, str))
_STRS: _Check = ("a list of strings", _strs)
_BOOL: _Check = ("true or false", lambda v: isinstance(v, bool))
_INT: _Check = ("an integer", lambda v: isinstance(v, int) and not isinstance(v, bool))
_INTS: _Check = (
    "a list of integers",
    lambda v: isinstance(v, list) and all(_INT[1](x) for x in v),
)
_NUMBERS: _Check = (
    "a list of numbers",
    lambda v: (
        isinstance(v, list)
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
    ),
)
_TABLES: _Check = (
    "a list of tables ([[...]])",
    lambda v: isinstance(v, list) and all(isinstance(x, dict) for x in v),
)

_STUDY_KEYS: dict[str, _Check] = {
    "name": _STR,
    "title": _STR,
    "doc": _STR,
    "tasks": _STRS,
    "task_set": _STR,
    "seeds": _INTS,
    "steps": _INT,
    "kind": _STR,
    "budgets": _NUMBERS,
    "summary": _STRS,
    "readings": _STR,
    "arms": _TABLES,
    "conditions": _TABLES,
    "selection": _TABLES,
}
_ARM_KEYS: dict[str, _Check] = {
    "label": _STR,
    "algo": _STR,
    "args": _STRS,
    "note": _STR,
    "requires": _STR,
    "pending_method": _BOOL,
    "in_default": _BOOL,
    "tasks": _STRS,
}
_CONDITION_KEYS: dict[str, _Check] = {
    "name": _STR,
    "note": _STR,
    "methods": ("a list of [method, arm label] pairs", _tuples_of_strs(2)),
    "unequal": _BOOL,
    "overrides": ("a list of [task, method, arm label] triples", _tuples_of_strs(3)),
}
_SELECTION_KEYS: dict[str, _Check] = {"model": _STR, "arms": _STRS}


def _type_name(v: Any) -> str:
    return {dict: "a table", list: "a list", str: "a string", bool: "a boolean"}.get(
        type(v), type(v).__name__
    )


def _checked(
    table: dict[str, Any], keys: dict[str, _Check], required: Iterable[str], where: str
) -> dict[str, Any]:
    """``table`` once every key is known, of its type and the required ones are there
    (ValueError ``"<where><key>: ..."`` otherwise)."""
    for key, value in table.items():
        if key not in keys:
            close = difflib.get_close_matches(key, list(keys), n=2, cutoff=0.6)
            hint = f"; did you mean {' or '.join(close)}?" if close else ""
            raise ValueError(f"{where}{key}: unknown key (known: {', '.join(keys)}){hint}")
        what, ok = keys[key]
        if not ok(value):
            raise ValueError(f"{where}{key}: expected {what}, got {_type_name(value)}")
    for key in required:
        if key not in table:
            raise ValueError(f"{where}{key}: missing (required)")
    return table


def _arm(table: dict[str, Any], where: str) -> ArmSpec:
    t = _checked(table, _ARM_KEYS, ("label", "algo"), where)
    for key in ("args", "tasks"):
        if key in t:
            t[key] = tuple(t[key])
    return ArmSpec(**t)


def _condition(table: dict[str, Any], where: str) -> Condition:
    t = _checked(table, _CONDITION_KEYS, ("name", "note", "methods"), where)
    t["methods"] = tuple(tuple(p) for p in t["methods"])
    if "overrides" in t:
        t["overrides"] = tuple(tuple(p) for p in t["overrides"])
    return Condition(**t)


def _study(data: dict[str, Any]) -> Study:
    """The :class:`Study` of one parsed file (ValueError ``"<key>: ..."``)."""
    t = _checked(dict(data), _STUDY_KEYS, ("name", "title", "doc", "arms"), "")
    if ("tasks" in t) == ("task_set" in t):
        raise ValueError("tasks: give exactly one of tasks (a list) and task_set (a name)")
    if "task_set" in t:
        name = t.pop("task_set")
        if name not in TASK_SETS:
            raise ValueError(f"task_set: unknown task set {name!r} (known: {', '.join(TASK_SETS)})")
        t["tasks"] = _TaskSet(name)
    else:
        if not t["tasks"]:
            raise ValueError("tasks: empty (name at least one task)")
        t["tasks"] = _Fixed(tuple(t["tasks"]))
    if not t["arms"]:
        raise ValueError("arms: none (a study needs at least one [[arms]] table)")
    arms: list[ArmSpec] = []
    for i, table in enumerate(t["arms"]):
        arm = _arm(table, f"arms[{i}].")
        if any(a.label == arm.label for a in arms):
            raise ValueError(
                f"arms[{i}].label: arm {arm.label!r} is defined twice in study {t['name']!r}"
            )
        arms.append(arm)
    t["arms"] = _Fixed(tuple(arms))
    if "readings" in t:
        module, sep, fn = t["readings"].partition(":")
        if not (module and sep and fn):
            raise ValueError(f"readings: {t['readings']!r} is not 'package.module:function'")
    for key in ("seeds", "summary"):
        if key in t:
            t[key] = tuple(t[key])
    if "budgets" in t:
        t["budgets"] = tuple(float(b) for b in t["budgets"])
    if "conditions" in t:
        t["conditions"] = tuple(
            _condition(c, f"conditions[{i}].") for i, c in enumerate(t["conditions"])
        )
    if "selection" in t:
        sel = [_checked(s, _SELECTION_KEYS, ("model", "arms"), f"selection[{i}].")
               for i, s in enumerate(t["selection"])]  # fmt: skip
        t["selection"] = tuple((s["model"], tuple(s["arms"])) for s in sel)
    return Study(**t)


def _toml() -> ModuleType:
    """The TOML reader: the standard library's ``tomllib`` (Python >= 3.11), or ``tomli`` (the
    same API; on Python 3.10 the [rl] and [il] extras install it)."""
    import importlib

    try:
        reader: ModuleType = importlib.import_module("tomllib")
    except ModuleNotFoundError:  # Python 3.10
        reader = importlib.import_module("tomli")
    return reader


def load_study(path: str | Path) -> Study:
    """The study of one TOML file (malformed: ValueError ``"<path>: <key>: ..."``)."""
    path = Path(path)
    toml = _toml()
    try:
        with path.open("rb") as f:
            data = toml.load(f)
        return _study(data)
    except (toml.TOMLDecodeError, ValueError) as e:
        raise ValueError(f"{path}: {e}") from None


def load_studies(paths: Iterable[str | Path]) -> dict[str, Study]:
    """Name -> :class:`Study` of the files ``paths``, in their order (a name in two files:
    ValueError naming the second file and the first)."""
    found: dict[str, Study] = {}
    where: dict[str, Path] = {}
    for p in paths:
        study = load_study(p)
        if study.name in found:
            raise ValueError(
                f"{p}: name: study {study.name!r} is defined twice (also in {where[study.name]})"
            )
        found[study.name], where[study.name] = study, Path(p)
    return found


def study_files(folder: str | Path = DATA_DIR) -> list[Path]:
    """The study files of ``folder`` (``*.toml``), sorted by name."""
    return sorted(Path(folder).glob("*.toml"))
