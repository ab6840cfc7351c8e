"""The run directory: file names, creation (never over an existing run), resume, provenance."""

from __future__ import annotations

import json
import os
import re
import shutil
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ndp.io import atomic_write_text, remove_stale_tmp
from ndp.provenance import fingerprint, provenance

CONFIG_NAME = "config.json"
"""The resolved config of the run."""
CHECKPOINT_NAME = "checkpoint.pt"
"""The latest good checkpoint."""
METRICS_NAME = "metrics.csv"
"""One row per update (RL) or epoch (imitation)."""
LEGACY_METRICS_NAMES = ("progress.csv",)
"""Earlier names of the metrics file (RL runs of version 0.1); read, and renamed on resume."""
PROVENANCE_NAME = "provenance.json"
"""A list with one entry per session of the run (see :func:`ndp.provenance.provenance`)."""
TB_DIR = "tb"
"""TensorBoard event folder."""
RUN_OUTPUTS = ("eval.json", "predictions.png", "video.mp4", "best.pt", "done.json")
"""Outputs that commands write from a run (removed with it by ``overwrite``)."""


class RunDir:
    """A run directory and the files every trainer writes into it.

    Args:
        path: the directory (created by :meth:`create`).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    @property
    def config(self) -> Path:
        return self.path / CONFIG_NAME

    @property
    def checkpoint(self) -> Path:
        return self.path / CHECKPOINT_NAME

    @property
    def metrics(self) -> Path:
        return self.path / METRICS_NAME

    @property
    def tensorboard(self) -> Path:
        return self.path / TB_DIR

    def held(self) -> str | None:
        """What in the directory belongs to an earlier run (None: nothing)."""
        if self.checkpoint.exists():
            return "a checkpoint"
        for name in (METRICS_NAME, *LEGACY_METRICS_NAMES):
            if (self.path / name).exists():
                return f"a run's {name}"
        return None

    def partial_start(self) -> bool:
        """The directory holds the files of a start that stopped before its first checkpoint
        (this version's metrics.csv, config.json and provenance.json) and nothing that could be
        resumed or that marks a finished run (a checkpoint, done.json, eval.json). Older
        layouts (a legacy metrics file alone) are not taken for one."""
        return (
            self.metrics.is_file()
            and self.config.is_file()
            and (self.path / PROVENANCE_NAME).is_file()
            and not self.checkpoint.exists()
            and not (self.path / "done.json").exists()
            and not (self.path / "eval.json").exists()
        )

    def run_files(self) -> list[Path]:
        """The files and folders of a run in the directory (what ``overwrite`` removes)."""
        names = (
            CONFIG_NAME,
            CHECKPOINT_NAME,
            METRICS_NAME,
            *LEGACY_METRICS_NAMES,
            PROVENANCE_NAME,
            TB_DIR,
            *RUN_OUTPUTS,
        )
        return [self.path / n for n in names if (self.path / n).exists()]

    def create(self, overwrite: bool = False, resumable: bool = True) -> list[Path]:
        """Make the directory for a new run; refuse one that holds an earlier run.

        Args:
            overwrite: remove the earlier run's files first (and say which on stderr); other
                files in the directory are left alone.
            resumable: the command can ``--resume`` (named in the refusal only then).

        Returns:
            The paths removed (empty without ``overwrite``).

        Raises:
            ValueError: the directory holds a checkpoint or a metrics file (one line).
            OSError: the directory cannot be made or written (a file in the way, no
                permission), one line naming the path.
        """
        if self.path.exists() and not self.path.is_dir():
            raise ValueError(f"run_dir: {self.path} exists and is not a directory")
        held = self.held()
        removed: list[Path] = []
        if held is not None and not overwrite and self.partial_start():
            # a start stopped before its first checkpoint: nothing of it can be resumed, and
            # the same command starts the run again; its files are kept aside, not deleted
            files = self.run_files()
            n = 1
            while (self.path / f"partial-start-{n}").exists():
                n += 1
            aside = self.path / f"partial-start-{n}"
            aside.mkdir()
            for p in files:
                p.rename(aside / p.name)
            print(
                f"ndp: {self.path} holds a start that stopped before its first checkpoint "
                f"(nothing to resume); starting the run again ({', '.join(p.name for p in files)}"
                f" moved to {aside.name}/)",
                file=sys.stderr,
            )
            held = None
        if held is not None and not overwrite:
            if resumable and self.checkpoint.is_file():  # never offer to delete what resumes
                raise ValueError(
                    f"run_dir: {self.path} already holds {held}; resume it (--resume "
                    f"{self.path}) or choose another run directory"
                )
            raise ValueError(
                f"run_dir: {self.path} already holds {held}; replace it (--overwrite) or "
                "choose another run directory"
            )
        if held is not None:
            removed = self.run_files()
            print(
                f"ndp: --overwrite: removing the earlier run in {self.path}: "
                + ", ".join(p.name for p in removed),
                file=sys.stderr,
            )
            for p in removed:
                shutil.rmtree(p) if p.is_dir() else p.unlink()
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except (FileExistsError, NotADirectoryError):  # a parent is a regular file
            raise OSError(f"run_dir: cannot create {self.path}: a parent is a file") from None
        self._check_writable()
        remove_stale_tmp(self.path)
        return removed

    def _check_writable(self) -> None:
        probe = self.path / f".write-test-{os.getpid()}"
        try:
            probe.write_bytes(b"")
            probe.unlink()
        except OSError as exc:
            raise OSError(
                exc.errno, f"run_dir: {self.path} is not writable ({exc.strerror or exc})"
            ) from None

    def open_for_resume(self) -> None:
        """Check that a run can be resumed here; rename a legacy metrics file to the new name.

        Raises:
            FileNotFoundError: no checkpoint in the directory.
        """
        if not self.checkpoint.is_file():
            if self.partial_start():
                raise FileNotFoundError(
                    f"resume: {self.path} stopped before its first checkpoint, so there is "
                    "nothing to resume: run the same command without --resume to start it again"
                )
            raise FileNotFoundError(
                f"resume: no checkpoint in {self.path} (not a run directory, or a run archived "
                "without its checkpoint)"
            )
        self._check_writable()
        remove_stale_tmp(self.path)  # left by a write that was killed
        if not self.metrics.exists():
            for name in LEGACY_METRICS_NAMES:
                old = self.path / name
                if old.is_file():
                    old.rename(self.metrics)
                    break

    def write_config(self, config: dict[str, Any]) -> None:
        """Write ``config.json`` atomically (sorted keys, one trailing newline)."""
        atomic_write_text(self.config, json.dumps(config, indent=2, sort_keys=True) + "\n")

    def read_config(self) -> dict[str, Any]:
        """Read ``config.json``.

        Raises:
            FileNotFoundError: no config in the directory.
            ValueError: the file is not JSON.
        """
        if not self.config.is_file():
            raise FileNotFoundError(f"config: no such file {self.config}")
        try:
            out = json.loads(self.config.read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"config: {self.config} is not valid JSON ({exc})") from None
        if not isinstance(out, dict):
            raise ValueError(f"config: {self.config} does not hold a JSON object")
        return out

    def record_session(self, event: str, argv: list[str] | None = None) -> dict[str, Any]:
        """Append one provenance entry (``event``: 'start' or 'resume') to provenance.json."""
        path = self.path / PROVENANCE_NAME
        sessions: list[dict[str, Any]] = []
        if path.is_file():
            try:
                loaded = json.loads(path.read_text())
                sessions = loaded if isinstance(loaded, list) else []
            except json.JSONDecodeError:
                sessions = []  # an unreadable record is replaced, never a reason to stop a run
        entry = {"event": event, **provenance(argv)}
        sessions.append(entry)
        atomic_write_text(path, json.dumps(sessions, indent=2) + "\n")
        return entry


RUN_KINDS: dict[str, tuple[str, str]] = {
    "rl": ("an RL run", "ndp rl eval / export / render RUN, ndp rl train --resume RUN"),
    "il": ("an imitation run", "ndp il eval RUN, ndp il train --resume RUN"),
    "sb3": (
        "a Stable-Baselines3 reference run",
        "stable_baselines3.PPO.load on its model.zip; ndp report RUN",
    ),
}
"""Run kind -> (what it is, the commands that read it), for errors that meet a run of another
kind (``bc`` runs are RL runs at update 0)."""


def kind_of_run(run_dir: str | Path) -> str | None:
    """The kind of the run in ``run_dir`` ('rl', 'il', 'sb3'), from its run.json, else from its
    config.json's shape (imitation configs hold ``model`` and ``data``); None when neither
    tells."""
    path = Path(run_dir)
    try:
        manifest = json.loads((path / "run.json").read_text())
        kind = manifest.get("kind") if isinstance(manifest, dict) else None
        if isinstance(kind, str):
            return "rl" if kind == "bc" else kind
    except (OSError, ValueError):
        pass
    try:
        config = json.loads((path / CONFIG_NAME).read_text())
    except (OSError, ValueError):
        return None
    if isinstance(config, dict) and "model" in config and "data" in config:
        return "il"
    if isinstance(config, dict) and "algo" in config and "ppo" in config:
        return "rl"
    return None


def wrong_kind(run_dir: str | Path, found: str, expected: str) -> str:
    """The one-line message for a run of kind ``found`` given to a reader of ``expected``."""
    what, readers = RUN_KINDS.get(found, (f"a {found!r} run", "its own tools"))
    want = RUN_KINDS.get(expected, (f"a {expected!r} run", ""))[0]
    return f"{run_dir} is {what}, not {want}; read it with {readers}".replace("RUN", str(run_dir))


def run_name(task: str, label: str, seed: int) -> str:
    """The one name of a run directory: ``<task>-<label>-s<seed>`` (``label``: the method for
    ``ndp rl train``'s default ``runs/<name>``, the arm for a sweep's runs); ``task`` is the
    task row's canonical name (an alias or a method's task variant resolved first)."""
    return f"{task}-{label}-s{int(seed)}"


def parse_run_name(name: str, tasks: Iterable[str] = ()) -> tuple[str, str, int] | None:
    """The inverse of :func:`run_name`: ``(task, label, seed)`` of a directory name, or None.
    Task names hold '-' too: with ``tasks`` (the known task names) the longest one that
    prefixes the name is the task; without, the label is taken as one '-'-free word after the
    task where the name allows nothing else."""
    m = re.match(r"^(?P<head>.+)-s(?P<seed>\d+)$", name)
    if m is None:
        return None
    head, seed = m.group("head"), int(m.group("seed"))
    for task in sorted(tasks, key=len, reverse=True):
        if head.startswith(task + "-") and len(head) > len(task) + 1:
            return task, head[len(task) + 1 :], seed
    if "-" not in head:
        return None
    task, label = head.rsplit("-", 1)
    return task, label, seed


def run_fingerprints(run_dir: str | Path) -> list[dict[str, str]]:
    """The environment fingerprints (:func:`ndp.provenance.fingerprint`: Python, torch, numpy,
    MuJoCo and Meta-World versions, the CPU model) of a run's sessions, each distinct one once,
    in session order; empty when provenance.json is missing or unreadable."""
    out: list[dict[str, str]] = []
    for e in provenance_sessions(run_dir):
        if isinstance(e, dict) and (fp := fingerprint(e)) not in out:
            out.append(fp)
    return out


def run_commits(run_dir: str | Path) -> list[str]:
    """The commits (7 hex digits, sorted) a run's sessions were trained at, from its
    provenance.json; empty when the file is missing or unreadable (runs older than it)."""
    return sorted(
        {
            str(e["commit"])[:7]
            for e in provenance_sessions(run_dir)
            if isinstance(e, dict) and e.get("commit")
        }
    )


def provenance_sessions(run_dir: str | Path) -> list[object]:
    """The session records of a run's provenance.json; empty when it is missing or
    unreadable."""
    try:
        sessions = json.loads((Path(run_dir) / PROVENANCE_NAME).read_text())
    except (OSError, json.JSONDecodeError):
        return []
    return sessions if isinstance(sessions, list) else []
