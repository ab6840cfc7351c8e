"""Provenance of runs and generated results (a leaf module): commit, dirty flag, command line.

Nothing here imports the rest of the package, so every sub-package can record where its outputs
came from.
"""

from __future__ import annotations

import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any


def _git(*args: str, cwd: str | Path | None = None) -> str | None:
    try:
        return subprocess.run(
            ["git", *args],
            capture_output=True,
            text=True,
            check=True,
            cwd=cwd or Path(__file__).parent,
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        return None


def git_commit(short: bool = True, cwd: str | Path | None = None) -> str:
    """The current git commit (short hash by default), or ``"unknown"`` outside a checkout."""
    out = _git("rev-parse", *(["--short"] if short else []), "HEAD", cwd=cwd)
    return (out or "").strip() or "unknown"


def git_dirty(cwd: str | Path | None = None) -> bool | None:
    """Whether the checkout has uncommitted changes to tracked files (None outside a checkout)."""
    out = _git("status", "--porcelain", "--untracked-files=no", cwd=cwd)
    return None if out is None else bool(out.strip())


def versions() -> dict[str, str]:
    """Versions of Python and of the numerical packages already imported (none is imported)."""
    out = {"python": platform.python_version()}
    for name in ("ndp", "torch", "numpy", "gymnasium", "mujoco", "metaworld"):
        mod = sys.modules.get(name)
        if mod is not None:
            out[name] = str(getattr(mod, "__version__", "unknown"))
    return out


def installed_versions() -> dict[str, str]:
    """Installed versions (package metadata, nothing imported) of the package and of what a
    trained policy needs to run or be rebuilt: torch, numpy and the simulators."""
    from importlib import metadata

    out = {}
    for name in (
        "neural-dynamic-policies",
        "torch",
        "numpy",
        "gymnasium",
        "mujoco",
        "metaworld",
        "dm_control",
    ):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def provenance(argv: list[str] | None = None) -> dict[str, Any]:
    """Where a run session comes from: time, command line, commit, dirty flag, host, versions."""
    return {
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "argv": list(sys.argv if argv is None else argv),
        "commit": git_commit(short=False),
        "dirty": git_dirty(),
        "host": platform.node(),
        "versions": versions(),
    }


def portable_path(path: str | Path) -> str:
    """``path`` as a committed file may record it: a relative path unchanged; an absolute one
    relative to the working directory when it lies under it or under its parent
    (``/work/runs/x`` from ``/work/main`` gives ``../runs/x``), else its last two parts
    (``.../runs/x``): no machine's absolute path is written into a table, card or export."""
    import os

    p = Path(path)
    if not p.is_absolute():
        return str(path)
    here = Path.cwd()
    if any(p.is_relative_to(base) for base in (here, here.parent)):
        return os.path.relpath(p, here)
    return ".../" + "/".join(p.parts[-2:])


def portable_command(argv: list[str]) -> list[str]:
    """A command line with every absolute path argument made :func:`portable_path`."""
    out = []
    for a in argv:
        if a.startswith("/"):
            out.append(portable_path(a))
        elif a.startswith("--") and "=/" in a:
            k, v = a.split("=", 1)
            out.append(f"{k}={portable_path(v)}")
        else:
            out.append(a)
    return out
