"""Finding runs and saying what each is: :func:`find_run_dirs` (run directories under the
given paths, two levels down at most) and :func:`run_info` (task, method label, seed, budget
and whether the run finished, as a :class:`ndp.experiments.rows.RunInfo`).

Only finished runs count: the budget reached (``done.json``, or the checkpoint's update count;
an imitation run also evaluated) and the run's record (``metrics.csv``) reaching it too.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from ndp.experiments.rows import RunInfo, _json
from ndp.experiments.run_kinds import RUN_KINDS, kind_of_algo, run_kind
from ndp.experiments.study import is_finished
from ndp.il.config import data_task_name
from ndp.runs import metrics_path, read_metrics, run_commits, run_fingerprints
from ndp.runs.session import Manifest, read_manifest


def _is_run(path: Path) -> bool:
    return (path / "arm.json").is_file() or metrics_path(path).is_file()


def find_run_dirs(paths: Sequence[str | Path]) -> list[Path]:
    """Run directories in ``paths`` (each a run, or holding runs up to two levels down).

    Raises:
        FileNotFoundError: a path does not exist.
    """
    out: list[Path] = []
    for p in map(Path, paths):
        if not p.exists():
            raise FileNotFoundError(f"report: no such directory {p}")
        if _is_run(p):
            out.append(p)
            continue
        for child in sorted(q for q in p.iterdir() if q.is_dir()):
            if _is_run(child):
                out.append(child)
            else:
                out += [g for g in sorted(q for q in child.iterdir() if q.is_dir()) if _is_run(g)]
    seen, uniq = set(), []
    for p in out:
        if p.resolve() not in seen:
            seen.add(p.resolve())
            uniq.append(p)
    return uniq


def _manifest(path: Path) -> Manifest | None:
    """The run's run.json, None when it has none (older runs) or it is unreadable (the other
    records then identify the run)."""
    try:
        return read_manifest(path)
    except ValueError:
        return None


def _kind_of_method(algo: str) -> str:
    """The run kind of a method named by an older run; "rl" for one no longer registered."""
    try:
        return kind_of_algo(algo).name
    except ValueError:
        return "rl"


def run_info(path: Path) -> RunInfo | None:
    """Identify a run (None: not enough to say which task / method / seed it is)."""
    arm = _json(path / "arm.json") or {}
    cfg = _json(path / "config.json") or {}
    algo = arm.get("algo") or cfg.get("algo") or cfg.get("method")  # method: an SB3 run's
    label = arm.get("label") or algo
    is_il = "model" in cfg and "data" in cfg
    if is_il and not algo:
        algo = "il-" + str(cfg["model"].get("kind", "ndp"))
        label = str(cfg["model"].get("kind", "ndp"))
    if not label or not algo:
        return None
    manifest = _manifest(path)
    kind = arm.get("kind") or (manifest.kind if manifest is not None else None)
    if kind not in RUN_KINDS:  # older runs, or a cloning run ("bc": an RL run once cloned)
        kind = "il" if is_il else _kind_of_method(str(algo))
    task, seed = arm.get("task"), arm.get("seed")
    if (task is None or seed is None) and manifest is not None:
        task, seed = manifest.task, manifest.seed  # what the run says it is (run.json)
    if task is None or seed is None:  # runs written before run.json
        m = re.fullmatch(rf"(.+)-{re.escape(str(label))}-s(\d+)", path.name)
        if m:
            task, seed = m.group(1), int(m.group(2))
        elif run_kind(kind).task_is_dataset and cfg:
            task, seed = data_task_name(cfg.get("data", {})), cfg.get("seed")
        elif cfg:
            task, seed = cfg.get("task"), cfg.get("seed")
    if task is None or seed is None:
        return None
    steps = arm.get("steps") or cfg.get(run_kind(kind).budget_key)
    if not steps:
        return None
    info = RunInfo(path, str(task), str(label), str(algo), int(seed), int(steps), kind,
                   manifest=manifest)  # fmt: skip
    info.finished = _finished(info)
    info.commits = run_commits(path)
    info.fingerprints = run_fingerprints(path)
    return info


def _record_reaches_budget(info: RunInfo) -> bool:
    """The run's metrics.csv reaches its budget (RL: the last row's ``global_step`` >= the
    budget; imitation: the last ``epoch``); a file cut short records less than ran."""
    kind = run_kind(info.kind)
    log = info.path / kind.metrics_file if kind.metrics_file else metrics_path(info.path)
    if not log.is_file():
        return False
    rows = read_metrics(log)
    col = kind.progress_column
    last = rows[-1].get(col, 0) if rows else 0
    target = info.steps
    manifest = info.manifest
    if (
        manifest is not None
        and manifest.finished
        and manifest.unit == "env_steps"
        and 0 < manifest.done < target
        and manifest.budget >= target
    ):
        # the run trained every planned update but executed fewer env steps than its slots
        # (decisions cut by an episode's end): its record must reach what it executed
        target = info.executed = int(manifest.done)
    done = _json(info.path / "done.json") or {}
    if done.get("reason") == "early stop" and isinstance(done.get("epoch"), int):
        target = done["epoch"]  # stopped on its validation split before the maximum
    if not (rows and last >= target):
        unit = kind.unit.removesuffix("s")
        info.problem = f"{log.name} ends at {unit} {last:,.0f} of {info.steps:,}"
        return False
    return True


def _finished(info: RunInfo) -> bool:
    path = info.path
    if (path / "done.json").is_file() or (path / "checkpoint.pt").is_file():
        if not (path / "done.json").is_file():
            try:
                if not is_finished(path, kind=info.kind):
                    return False
            except Exception:  # an unreadable checkpoint: not a finished run
                info.problem = "its checkpoint is unreadable"
                return False
        # finished by its own account; the record must say so too (a cut metrics.csv does not)
        return _record_reaches_budget(info)
    if run_kind(info.kind).needs_eval and not (path / "eval.json").is_file():
        return False
    return _record_reaches_budget(info)
