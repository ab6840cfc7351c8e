"""Runs as a small archive: a study that outlives the machine its runs were made on.

A study's runs live outside the repository (``--runs-dir``). When a study takes more than one
session and the next session may start on a fresh machine, ``ndp sweep STUDY --pack OUT``
writes the study's **finished** runs to ``OUT`` (a ``.tar.gz``) without their checkpoints: the
files a report and a sweep read (``arm.json``, ``config.json``, ``run.json``, ``metrics.csv``,
``provenance.json``, ``train.log``, ``eval*.json``) and a ``done.json`` that marks the run
finished (a sweep skips it, a report counts it). Runs already in ``OUT`` are kept, so the
archive grows across sessions. ``ndp sweep STUDY --unpack OUT`` restores them into the runs
directory before the sweep starts; a run directory that already exists there is left as it
is. What an archived finished run cannot do: resume (it is finished), evaluate or export its
policy (no checkpoint).

With ``--pack-unfinished`` the archive also takes the **unfinished** runs that have a
checkpoint, with their ``checkpoint.pt`` and without a ``done.json``: unpacked on the next
machine they are runs killed at their last checkpoint, and the sweep resumes them there (the
resume truncates ``metrics.csv`` to the checkpoint; the checkpoint is read before the metrics
so that the metrics never end before it). A session that must stop mid-run so loses at most
one checkpoint interval instead of the whole run. When the run has finished, packing it again
replaces its entry by the finished one (no checkpoint). A checkpoint is a torch pickle of this
package's trainer: unpack only archives you made or trust, as you would run their code.

Member names are ``<run name>/<file>``; anything else (absolute paths, ``..``, links, other
files) is refused when unpacking.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
import tarfile
import zlib
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
CHECKPOINT = "checkpoint.pt"
"""The checkpoint an unfinished run is archived with (``pack(..., unfinished=...)``)."""
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
        "note": "archived without its checkpoint (ndp.experiments.sweep.archive)",
    }
    return (json.dumps(rec, indent=1) + "\n").encode()


def _entry(name: str, data: bytes, mtime: float = 0.0) -> tuple[tarfile.TarInfo, bytes]:
    info = tarfile.TarInfo(name)
    info.size, info.mtime = len(data), int(mtime)
    return info, data


def pack(runs: Sequence[Path], out: Path, unfinished: Sequence[Path] = ()) -> list[str]:
    """Write the given finished run directories, and the ``unfinished`` ones with their
    checkpoint, to ``out`` (merged with the runs ``out`` already holds, a run's entry replaced
    by the new one; written atomically). Returns the names of the runs in the archive.

    Raises:
        FileNotFoundError: an unfinished run without ``checkpoint.pt`` (nothing to resume).
        ValueError: ``out`` exists and is not a run archive (a folder, another file, a tar
            holding other files): nothing is written and ``out`` is left as it is.
    """
    out = Path(out)
    for run in map(Path, unfinished):
        if not (run / CHECKPOINT).is_file():
            raise FileNotFoundError(f"pack: {run} has no {CHECKPOINT} to resume from")
    keep: dict[str, list[tuple[tarfile.TarInfo, bytes]]] = {}
    if out.exists() and not out.is_file():
        raise ValueError(f"pack: {out} is a folder, not an archive file (.tar.gz)")
    if out.is_file():  # merged with: it must be a run archive (anything else is left alone)
        try:
            with tarfile.open(out, "r:gz") as tf:
                for m in tf.getmembers():
                    name = _check_member(m, out)
                    f = tf.extractfile(m)
                    assert f is not None
                    keep.setdefault(name, []).append((m, f.read()))
        except (tarfile.TarError, EOFError, OSError, zlib.error) as exc:
            raise ValueError(
                f"pack: {out} exists and is not a readable .tar.gz run archive "
                f"({type(exc).__name__}: {str(exc)[:120]}); choose another file (it is left "
                f"as it is)"
            ) from None
    for run in map(Path, runs):
        entries = [
            _entry(f"{run.name}/{p.name}", p.read_bytes(), p.stat().st_mtime) for p in _members(run)
        ]
        if not (run / "done.json").is_file():
            entries.append(_entry(f"{run.name}/done.json", _done_record(run)))
        keep[run.name] = entries
    for run in map(Path, unfinished):
        ck = run / CHECKPOINT
        first = _entry(f"{run.name}/{CHECKPOINT}", ck.read_bytes(), ck.stat().st_mtime)
        rest = [  # read after the checkpoint: metrics at least as far as it
            _entry(f"{run.name}/{p.name}", p.read_bytes(), p.stat().st_mtime)
            for p in _members(run)
            if p.name != "done.json"
        ]
        keep[run.name] = [first, *rest]
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
    # exactly <run>/<file>: no '.', '..' or empty part, no leading dot (./x, ../x, .hidden)
    plain = all(p not in ("", ".", "..") and not p.startswith(".") for p in parts)
    if not m.isfile() or len(parts) != 2 or not plain or not all(_NAME.fullmatch(p) for p in parts):
        raise ValueError(f"archive: {archive} holds {m.name!r}, not a run file <run>/<file>")
    allowed = parts[1] in FILES or parts[1] == CHECKPOINT
    if not allowed and not re.fullmatch(r"eval[A-Za-z0-9._-]*\.json", parts[1]):
        raise ValueError(f"archive: {archive} holds {m.name!r}, not one of a run's files")
    return parts[0]


def unpack(archive: Path, runs_dir: Path) -> tuple[list[str], list[str]]:
    """Restore the runs of ``archive`` into ``runs_dir``: (restored, left as they were because
    a directory of that name exists). An unfinished run comes back with its checkpoint.

    Raises:
        FileNotFoundError: no such archive.
        ValueError: the archive holds something that is not a run's file (nothing written).
    """
    archive, runs_dir = Path(archive), Path(runs_dir)
    if not archive.is_file():
        raise FileNotFoundError(f"unpack: no such archive {archive}")
    try:
        tf = tarfile.open(archive, "r:gz")
        members = tf.getmembers()  # reads the whole index: a damaged archive fails here
    except (tarfile.TarError, EOFError, OSError, zlib.error) as exc:
        raise ValueError(
            f"unpack: {archive} is not a readable .tar.gz archive ({type(exc).__name__}: "
            f"{str(exc)[:120]})"
        ) from None
    # the folders this call makes (runs_dir and missing parents), removed again on failure
    made = [p for p in (runs_dir, *runs_dir.parents) if not p.exists()]
    with tf:
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
            try:
                tmp.mkdir(parents=True, exist_ok=True)
                for m in ms:
                    f = tf.extractfile(m)
                    assert f is not None
                    (tmp / m.name.split("/")[1]).write_bytes(f.read())
                tmp.replace(target)
            except (tarfile.TarError, EOFError, OSError, zlib.error) as exc:
                shutil.rmtree(tmp, ignore_errors=True)  # a failed unpack leaves nothing behind
                for folder in made:  # innermost first; only while empty (restored runs stay)
                    with contextlib.suppress(OSError):
                        folder.rmdir()
                raise ValueError(
                    f"unpack: cannot restore {name} from {archive} ({type(exc).__name__}: "
                    f"{str(exc)[:120]})"
                ) from None
            restored.append(name)
    return restored, kept
