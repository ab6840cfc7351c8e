"""File helpers shared by every sub-package (a leaf module): atomic writes.

A reader never sees a half-written file, and a crash (even SIGKILL) mid-write leaves the previous
version intact: data goes to a temporary file in the same folder, is flushed and fsynced, and is
then renamed over the target with ``os.replace``.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

_UMASK = os.umask(0)
os.umask(_UMASK)


def atomic_write(path: str | os.PathLike[str], write: Callable[[BinaryIO], object]) -> None:
    """Call ``write(f)`` on a temporary binary file, then atomically rename it to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)  # mkstemp creates 0600; give the usual file mode
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.filename is None:
            # e.g. a full disk inside torch.save: name the file and the cause in one line
            raise OSError(exc.errno, f"cannot write {path}: {exc.strerror or exc}") from exc
        raise


TMP_GLOB = ".*.tmp"
"""Pattern of the temporary files :func:`atomic_write` creates (``.<name>.<random>.tmp``)."""


def remove_stale_tmp(folder: str | os.PathLike[str]) -> list[Path]:
    """Delete temporary files a killed :func:`atomic_write` left in ``folder``; returns them."""
    folder = Path(folder)
    removed = []
    if folder.is_dir():
        for p in folder.glob(TMP_GLOB):
            if p.is_file():
                p.unlink()
                removed.append(p)
    return removed


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes | memoryview) -> None:
    """Atomic binary write; see :func:`atomic_write`."""
    atomic_write(path, lambda f: f.write(data))


def atomic_savefig(fig: Any, path: str | os.PathLike[str], **kwargs: Any) -> Path:
    """Save a matplotlib figure atomically as PNG (``fig.savefig(..., format='png',
    **kwargs)`` into memory, then :func:`atomic_write_bytes`): a full disk or an interrupt
    leaves the earlier file or none, never a truncated image. Returns the path."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", **kwargs)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Atomic text write (UTF-8); see :func:`atomic_write`."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_torch_save(obj: object, path: str | os.PathLike[str]) -> None:
    """``torch.save(obj)`` atomically; see :func:`atomic_write`.

    The object is serialised in memory first and then written: a full disk then fails in the
    write itself, as an ``OSError`` naming the file (``torch.save`` straight to a file on a full
    disk raises its zip writer's ``RuntimeError: ... unexpected pos`` instead)."""
    import io

    import torch

    buf = io.BytesIO()
    torch.save(obj, buf)
    atomic_write_bytes(path, buf.getbuffer())


def atomic_save_npz(path: str | os.PathLike[str], **arrays: Any) -> None:
    """``numpy.savez_compressed`` atomically; see :func:`atomic_write`."""
    import io

    import numpy as np

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)  # in memory first, as atomic_torch_save
    atomic_write_bytes(path, buf.getbuffer())


def check_output_path(
    path: str | os.PathLike[str],
    name: str = "path",
    folder: bool = False,
    create: bool = True,
    overwrite: bool | None = None,
) -> Path:
    """The one check of a path a command is about to write, before any expensive work: a file
    (``folder`` False: the file's folder is made if ``create``) or a folder (``folder`` True: made
    if ``create``). Without ``create`` nothing is made (a dry run) and the same problems are
    found. ``overwrite`` False: an existing file at ``path`` (one the user named) is refused;
    None: not checked (the command's own outputs, regenerated in place).

    Raises:
        OSError: one line naming ``name`` and the path: a part of the path is a file; a folder
            where a file is to be written, or a file where a folder is; not writable.
        FileExistsError: ``overwrite`` False and the file exists (``--overwrite`` replaces it).
    """
    path = Path(path)
    target_dir = path if folder else path.parent
    if folder and path.exists() and not path.is_dir():
        raise OSError(f"{name}: {path} is a file, not a folder")
    if not folder and path.is_dir():
        raise OSError(f"{name}: {path} is a folder; give a file name")
    if overwrite is False and not folder and path.exists():
        raise FileExistsError(
            f"{name}: {path} exists; choose another path or pass --overwrite to replace it"
        )
    # the deepest part of the path that exists must be a writable folder
    probe = target_dir
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise OSError(f"{name}: cannot write {path}: a part of that path ({probe}) is a file")
    if not os.access(probe, os.W_OK):
        raise OSError(f"{name}: cannot write {path}: {probe} is not writable")
    if create:
        try:
            target_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OSError(f"{name}: cannot create {target_dir}: {exc.strerror or exc}") from None
    return path
