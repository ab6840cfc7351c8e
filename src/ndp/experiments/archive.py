"""Finished runs as a small archive: a study that outlives the machine its runs were made on.

A study's runs live outside the repository (``--runs-dir``). When a study takes more than one
session and the next session may start on a fresh machine, ``ndp sweep STUDY --pack OUT``
writes the study's **finished** runs to ``OUT`` (a ``.tar.gz``) without their checkpoints: the
files a report and a sweep read (``arm.json``, ``config.json``, ``run.json``, ``metrics.csv``,
``provenance.json``, ``train.log``, ``eval*.json``) and a ``done.json`` that marks the run
finished (a sweep skips it, a report counts it). Runs already in ``OUT`` are kept, so the
archive grows across sessions. ``ndp sweep STUDY --unpack OUT`` restores them into the runs
directory before the sweep starts; a run directory that already exists there is left as it
is. What an archived run cannot do: resume (it is finished), evaluate or export its policy (no
checkpoint).

Member names are ``<run name>/<file>``; anything else (absolute paths, ``..``, links, other
files) is refused when unpacking.
"""

from __future__ import annotations

import io
import json
import re
import tarfile
from collections.abc import Sequence
from pathlib import Path

from ndp.runs import metrics_path, read_metrics

FILES = (
    "arm.json",
    "config.json",
    "metrics.csv",
    "provenance.json",
    "train.log",
    "done.json",
    "run.json",
)
"""The files of a run that an archive keeps (besides ``eval*.json``)."""
_NAME = re.compile(r"[A-Za-z0-9._-]+")


def _members(run: Path) -> list[Path]:
    out = [run / f for f in FILES if (run / f).is_file()]
    out += sorted(p for p in run.glob("eval*.json") if p.is_file())
    return out


def _done_record(run: Path) -> bytes:
    rows = read_metrics(run) if metrics_path(run).is_file() else []
    last = rows[-1] if rows else {}
    rec = {
        "finished": True,
        "archived": True,
        "update": last.get("update"),
        "global_step": last.get("global_step"),
        "epoch": last.get("epoch"),
        "note": "archived without its checkpoint (ndp.experiments.archive)",
    }
    return (json.dumps(rec, indent=1) + "\n").encode()


def pack(runs: Sequence[Path], out: Path) -> list[str]:
    """Write the given finished run directories to ``out`` (merged with the runs ``out``
    already holds; written atomically). Returns the names of the runs in the archive."""
    out = Path(out)
    keep: dict[str, list[tuple[tarfile.TarInfo, bytes]]] = {}
    if out.is_file():
        with tarfile.open(out, "r:gz") as tf:
            for m in tf.getmembers():
                name = _check_member(m, out)
                f = tf.extractfile(m)
                assert f is not None
                keep.setdefault(name, []).append((m, f.read()))
    for run in map(Path, runs):
        entries = []
        for p in _members(run):
            data = p.read_bytes()
            info = tarfile.TarInfo(f"{run.name}/{p.name}")
            info.size, info.mtime = len(data), int(p.stat().st_mtime)
            entries.append((info, data))
        if not (run / "done.json").is_file():
            data = _done_record(run)
            info = tarfile.TarInfo(f"{run.name}/done.json")
            info.size = len(data)
            entries.append((info, data))
        keep[run.name] = entries
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    with tarfile.open(tmp, "w:gz") as tf:
        for name in sorted(keep):
            for info, data in keep[name]:
                tf.addfile(info, io.BytesIO(data))
    tmp.replace(out)
    return sorted(keep)


def _check_member(m: tarfile.TarInfo, archive: Path) -> str:
    parts = m.name.split("/")
    if not m.isfile() or len(parts) != 2 or not all(_NAME.fullmatch(p) for p in parts):
        raise ValueError(f"archive: {archive} holds {m.name!r}, not a run file <run>/<file>")
    if parts[1] not in FILES and not re.fullmatch(r"eval[A-Za-z0-9._-]*\.json", parts[1]):
        raise ValueError(f"archive: {archive} holds {m.name!r}, not one of a run's files")
    return parts[0]


def unpack(archive: Path, runs_dir: Path) -> tuple[list[str], list[str]]:
    """Restore the runs of ``archive`` into ``runs_dir``: (restored, left as they were because
    a directory of that name exists).

    Raises:
        FileNotFoundError: no such archive.
        ValueError: the archive holds something that is not a run's file (nothing written).
    """
    archive, runs_dir = Path(archive), Path(runs_dir)
    if not archive.is_file():
        raise FileNotFoundError(f"unpack: no such archive {archive}")
    with tarfile.open(archive, "r:gz") as tf:
        members = tf.getmembers()
        names: dict[str, list[tarfile.TarInfo]] = {}
        for m in members:
            names.setdefault(_check_member(m, archive), []).append(m)
        restored, kept = [], []
        for name, ms in sorted(names.items()):
            target = runs_dir / name
            if target.exists():
                kept.append(name)
                continue
            tmp = runs_dir / f".{name}.unpack"
            tmp.mkdir(parents=True, exist_ok=True)
            for m in ms:
                f = tf.extractfile(m)
                assert f is not None
                (tmp / m.name.split("/")[1]).write_bytes(f.read())
            tmp.replace(target)
            restored.append(name)
    return restored, kept
