"""Bad sweep input, refused before anything starts, and the plan of a sweep.

Part of :mod:`ndp.experiments.sweep` (its docstring describes the whole).
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import io
import shlex
import typing
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

from ndp.experiments.run_kinds import RUN_KINDS, config_class, il_data_args, run_kind
from ndp.experiments.study import Arm, arm_conflict, is_finished
from ndp.experiments.sweep.jobs import FAILED_NAME, Job
from ndp.experiments.sweep.runner import is_busy

# ----------------------------------------------------------------------------- bad input


def close_hint(value: str, known: Iterable[str], n: int = 4) -> str:
    """'; close matches: a, b' (or a short list of the known values when none is close)."""
    known = list(known)
    close = difflib.get_close_matches(value, known, n=n, cutoff=0.5)
    if close:
        return "; close matches: " + ", ".join(close)
    shown = ", ".join(known[:12]) + (", ..." if len(known) > 12 else "")
    return f"; known: {shown}"


def known_methods() -> list[str]:
    """Every method an arm may name: the trainer's registry, the SB3 reference, imitation."""
    return [algo for kind in RUN_KINDS.values() for algo in kind.algos()]


def check_methods(methods: Sequence[str]) -> list[str]:
    """The methods, each known (else ValueError naming it and the close matches)."""
    known = known_methods()
    for m in methods:
        if m not in known:
            raise ValueError(f"method: unknown method {m!r}{close_hint(m, known)}")
    return list(methods)


def check_tasks(tasks: Sequence[str], kind: str = "rl") -> list[str]:
    """Canonical task names ('rl': ndp.envs.TASKS; 'il': data sets, see
    :func:`ndp.experiments.run_kinds.il_data_args`); an unknown one is a ValueError naming it and
    the close matches."""
    out = []
    for t in tasks:
        if run_kind(kind).task_is_dataset:
            il_data_args(t)
            out.append(t)
            continue
        from ndp.envs import get_task_spec

        out.append(get_task_spec(t).name)  # unknown: ValueError "task: unknown task ..."
    return out


def _config_class(kind: str) -> type:
    return config_class(run_kind(kind))


def train_options(kind: str = "rl") -> dict[str, str]:
    """``--option`` -> field of the trainer's command line ('rl': ``ndp rl train``, 'il':
    ``ndp il train``), as tyro names them there (nested configs flattened, ``--no-x`` for
    booleans, annotated names and aliases)."""
    from ndp.runs.cli import HIDDEN

    out: dict[str, str] = {}

    def walk(cls: type) -> None:
        hints = typing.get_type_hints(cls, include_extras=True)
        for f in dataclasses.fields(cls):
            t = hints[f.name]
            meta: tuple[Any, ...] = ()
            if typing.get_origin(t) is typing.Annotated:
                meta, t = t.__metadata__, typing.get_args(t)[0]
            if HIDDEN is not None and any(m is HIDDEN for m in meta):
                continue
            if isinstance(t, type) and dataclasses.is_dataclass(t):
                walk(t)
                continue
            conf = next((m for m in meta if hasattr(m, "aliases") and hasattr(m, "name")), None)
            name = ((conf.name if conf is not None and conf.name else None) or f.name).replace(
                "_", "-"
            )
            out["--" + name] = f.name
            for alias in (conf.aliases or ()) if conf is not None else ():
                out[alias] = f.name
            if t is bool:
                out["--no-" + name] = f.name

    walk(_config_class(kind))
    return out


RESERVED = {name: kind.reserved for name, kind in RUN_KINDS.items() if kind.takes_options}
"""Options the sweep sets itself (per run: task / data set, method, seed, budget, directory;
:attr:`ndp.experiments.run_kinds.RunKind.reserved`)."""


class UnknownOptionError(ValueError):
    """An arm uses an option the trainer does not know (``option``: which)."""

    def __init__(self, message: str, option: str) -> None:
        super().__init__(message)
        self.option = option


def _option_names(args: Sequence[str]) -> list[str]:
    return [a.split("=", 1)[0] for a in args if a.startswith("--")]


def check_arms(arms: Sequence[Arm], tasks: Sequence[str] = (), study: str = "") -> None:
    """Refuse, before anything starts, an arm whose options the trainer does not know (the
    message names the arm, the option, what the arm needs and the close options), or whose
    values it refuses (the trainer's own message); RL arms are also resolved against every
    task (task presets: e.g. DMP steps that are not a multiple of k)."""
    where = f"{study}: " if study else ""
    opts_cache: dict[str, dict[str, str]] = {}
    for arm in arms:
        if not run_kind(arm.kind).takes_options:
            continue
        opts = opts_cache.setdefault(arm.kind, train_options(arm.kind))
        prog = run_kind(arm.kind).prog
        for name in _option_names(arm.args):
            if name in RESERVED[arm.kind]:
                raise ValueError(
                    f"{where}arm {arm.label!r}: {name} is set by the sweep for every run "
                    "(use the sweep's --tasks / --seeds / --steps / --runs-dir)"
                )
            if name not in opts:
                needs = (
                    f" (it needs {arm.requires}, which this version lacks)" if arm.requires else ""
                )
                raise UnknownOptionError(
                    f"{where}arm {arm.label!r} uses {name}, which `{prog}` does not know"
                    f"{needs}{close_hint(name, opts)}. Nothing was started: leave the arm out "
                    "(--skip-unavailable, or --arms with the others).",
                    name,
                )
    for arm in arms:
        if not run_kind(arm.kind).takes_options:
            continue
        for task in [t for t in tasks if arm.runs_on(t)] or ("point-mass",)[: not tasks]:
            _parse_arm(arm, task)


def _parse_arm(arm: Arm, task: str) -> None:
    from ndp.runs.cli import parse_config

    kind = run_kind(arm.kind)
    argv, prog = kind.argv(task, arm), kind.prog
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(err):
            cfg: object = parse_config(config_class(kind), argv, prog=prog)
        kind.check(cfg, task)
    except SystemExit:
        rows = [ln.strip(" │╭╰─╮╯|-") for ln in err.getvalue().splitlines()]
        text = " ".join(r for r in rows if r and not r.startswith("For full helptext"))
        raise ValueError(
            f"arm {arm.label!r} on {task}: `{prog}` refuses its options "
            f"{' '.join(arm.args)!r}: {text[-500:]}"
        ) from None
    except ValueError as exc:
        raise ValueError(f"arm {arm.label!r} on {task}: {exc}") from None


def parse_overrides(items: Sequence[str], kind: str = "rl") -> list[tuple[str, list[list[str]]]]:
    """``KEY=V1[,V2...]`` -> (``--key``, [argv of each value]); KEY is a field of the trainer's
    config as on its command line (``lr``, ``n-basis`` / ``n_basis``, ``k``, ...). A boolean
    takes true / false. One value applies to every run; several make a grid axis.

    Raises:
        ValueError: no '=', an unknown key (named, with the close keys), a key the sweep sets.
    """
    opts = train_options(kind)
    keys = sorted({o[2:] for o in opts if not o.startswith("--no-")})
    out = []
    for item in items:
        if "=" not in item:
            raise ValueError(f"override: expected KEY=VALUE[,VALUE...], got {item!r}")
        key, values = item.split("=", 1)
        key = key.strip().lstrip("-").replace("_", "-")
        if ("--" + key) not in opts or key.startswith("no-"):
            raise ValueError(f"override: unknown key {key!r}{close_hint(key, keys)}")
        if "--" + key in RESERVED[kind]:
            raise ValueError(
                f"override: {key!r} is set by the sweep itself (use --tasks, --methods, --seeds, "
                "--steps or --runs-dir)"
            )
        vals = [v.strip() for v in values.split(",")]
        if not vals or any(not v for v in vals):
            raise ValueError(f"override: {item!r} has an empty value")
        is_bool = ("--no-" + key) in opts
        argvs = []
        for v in vals:
            if is_bool:
                b = v.lower()
                if b not in ("true", "false", "1", "0", "yes", "no", "on", "off"):
                    raise ValueError(f"override: {key} is a boolean (true / false), got {v!r}")
                argvs.append([f"--{key}" if b in ("true", "1", "yes", "on") else f"--no-{key}"])
            else:
                argvs.append([f"--{key}", *v.split()])
        out.append(("--" + key, argvs))
    return out


def _label_part(key: str, argv: Sequence[str]) -> str:
    name = key[2:].replace("-", "")
    if len(argv) == 1:  # a boolean
        return name if not argv[0].startswith("--no-") else f"no{name}"
    value = "_".join(argv[1:])
    return name + "".join(
        c if c.isalnum() or c == "_" else {".": "p", "-": "m"}.get(c, "_") for c in value
    )


def apply_overrides(
    arms: Sequence[Arm], overrides: Sequence[tuple[str, list[list[str]]]], extra: Sequence[str] = ()
) -> list[Arm]:
    """Each arm with the overrides (and ``extra`` options) appended; an override with several
    values multiplies the arms (label suffix ``-<key><value>``, e.g. ``ndp-k3``)."""
    out = list(arms)
    for key, argvs in overrides:
        nxt = []
        for arm in out:
            if not run_kind(arm.kind).takes_options:
                nxt.append(arm)
                continue
            for argv in argvs:
                label = arm.label if len(argvs) == 1 else f"{arm.label}-{_label_part(key, argv)}"
                note = f"{arm.note}; {' '.join(argv)}".lstrip("; ")
                nxt.append(
                    dataclasses.replace(arm, label=label, args=(*arm.args, *argv), note=note)
                )
        out = nxt
    if extra:
        out = [
            dataclasses.replace(a, args=(*a.args, *extra)) if run_kind(a.kind).takes_options else a
            for a in out
        ]
    return out


def check_plan(jobs: Sequence[Job]) -> None:
    """Refuse, before anything starts, two jobs sharing a run directory, or a directory that
    holds another run (another arm, budget, task or seed)."""
    seen: dict[Path, Job] = {}
    bad = []
    for j in jobs:
        if j.run_dir in seen:
            raise ValueError(
                f"sweep: {seen[j.run_dir].name} and {j.name} share the run directory {j.run_dir} "
                "(two arms with one label?)"
            )
        seen[j.run_dir] = j
        why = arm_conflict(j.run_dir, j.arm, j.steps, j.task, j.seed)
        if why is not None:
            bad.append(f"{j.run_dir}: {why}")
    if bad:
        more = f" (and {len(bad) - 3} more)" if len(bad) > 3 else ""
        raise ValueError(
            "sweep: refused before starting: "
            + "; ".join(bad[:3])
            + more
            + ". Use another --runs-dir, or the same --steps as before."
        )


def job_state(job: Job) -> str:
    """'finished', 'resumable' (a checkpoint), 'running' (locked by another process), 'failed'
    (failed.json from an earlier sweep; will be retried) or 'new'."""
    if is_busy(job.run_dir):
        return "running"
    if is_finished(job.run_dir, job.arm):
        return "finished"
    if (job.run_dir / FAILED_NAME).is_file():
        return "failed"
    if (job.run_dir / "checkpoint.pt").is_file():
        return "resumable"
    return "new"


def plan_lines(jobs: Sequence[Job], state: Callable[[Job], str] = job_state) -> list[str]:
    """One line per job (``--dry-run``): its state, name, directory and command."""
    lines = []
    for j in jobs:
        st = state(j)
        cmd = "" if st == "finished" else "  $ " + shlex.join(j.command())
        lines.append(f"{st:<9} {j.name:<40} {j.run_dir}{cmd}")
    return lines
