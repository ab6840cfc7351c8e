"""Provenance of runs and generated results (a leaf module): commit, dirty flag, command line,
the environment fingerprint (package versions, CPU model), and whether a commit is in the
repository's history.

Nothing here imports the rest of the package, so every sub-package can record where its outputs
came from.
"""

from __future__ import annotations

import functools
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


@functools.lru_cache(maxsize=256)
def commit_in_history(commit: str, cwd: str | None = None) -> bool | None:
    """Whether ``commit`` (a full or abbreviated hash) is in the history of this checkout's
    repository: reachable from one of its refs (any branch or tag, as ``git log --all`` walks
    them); None outside a checkout. A run trained at a commit that was never pushed, or whose
    branch was lost, records a hash that is not: the report marks it lost."""
    if _git("rev-parse", "--git-dir", cwd=cwd) is None:
        return None
    out = _git("for-each-ref", "--count=1", "--format=%(refname)", "--contains", commit, cwd=cwd)
    return bool(out and out.strip())


def git_dirty(cwd: str | Path | None = None) -> bool | None:
    """Whether the checkout has uncommitted changes to tracked files (None outside a checkout)."""
    out = _git("status", "--porcelain", "--untracked-files=no", cwd=cwd)
    return None if out is None else bool(out.strip())


DISTRIBUTIONS = {
    "ndp": "neural-dynamic-policies",
    "torch": "torch",
    "numpy": "numpy",
    "gymnasium": "gymnasium",
    "mujoco": "mujoco",
    "metaworld": "metaworld",
}
"""The packages a run session records (key: the name in ``provenance.json``; value: the
distribution whose installed version it is)."""

FINGERPRINT_KEYS = ("python", "torch", "numpy", "mujoco", "metaworld", "cpu")
"""A run's environment fingerprint (:func:`fingerprint`): the versions that change what a
trainer computes, and the CPU model (floating-point results can differ between CPUs)."""


def versions() -> dict[str, str]:
    """Versions of Python and of the numerical packages, from their installed package metadata
    (nothing is imported; a package without a ``__version__``, such as Meta-World, still gets
    its version): ``"not installed"`` for a package that is not."""
    from importlib import metadata

    out = {"python": platform.python_version()}
    for key, dist in DISTRIBUTIONS.items():
        try:
            out[key] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            mod = sys.modules.get(key)  # a checkout on sys.path without metadata
            out[key] = str(getattr(mod, "__version__", "not installed"))
    return out


def cpu_model() -> str:
    """The CPU's model name (Linux: ``/proc/cpuinfo``'s ``model name``; elsewhere
    :func:`platform.processor`), or ``"unknown"``."""
    try:
        for line in Path("/proc/cpuinfo").read_text(errors="replace").splitlines():
            key, _, value = line.partition(":")
            if key.strip() in ("model name", "Model", "cpu model") and value.strip():
                return " ".join(value.split())
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def fingerprint(entry: dict[str, Any]) -> dict[str, str]:
    """The environment fingerprint of one ``provenance.json`` session (:data:`FINGERPRINT_KEYS`),
    with ``"not recorded"`` for what an older session lacks (sessions before the CPU was
    recorded; ``versions`` that listed only the packages already imported) and Meta-World's
    ``"unknown"`` (what sessions recorded before its version was read from its metadata) kept
    as it was written."""
    got = entry.get("versions")
    recorded: dict[str, Any] = got if isinstance(got, dict) else {}
    out = {k: str(recorded.get(k, "not recorded")) for k in FINGERPRINT_KEYS if k != "cpu"}
    out["cpu"] = str(entry.get("cpu") or "not recorded")
    return out


def fingerprint_text(fp: dict[str, str]) -> str:
    """A fingerprint on one line: ``python 3.11.7, torch 2.13.0+cpu, ..., CPU AMD EPYC``."""
    return ", ".join(f"{'CPU' if k == 'cpu' else k} {fp.get(k, 'not recorded')}"
                     for k in FINGERPRINT_KEYS)  # fmt: skip


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
    """Where a run session comes from: time, command line, commit, dirty flag, host, and its
    environment fingerprint (:func:`fingerprint`): the versions of Python and the numerical
    packages, and the CPU model."""
    return {
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "argv": list(sys.argv if argv is None else argv),
        "commit": git_commit(short=False),
        "dirty": git_dirty(),
        "host": platform.node(),
        "versions": versions(),
        "cpu": cpu_model(),
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


def user_command(argv: list[str]) -> list[str]:
    """A recorded command line as a user types it: the program, when it is the ``ndp`` entry
    point under any path (``.venv/bin/ndp``) or the module run as ``python -m ndp.cli`` /
    ``python -m ndp`` (whose ``sys.argv[0]`` is the module's file), becomes ``ndp``; every
    absolute path argument is made :func:`portable_path`."""
    if argv:
        head = Path(argv[0])
        if head.name == "ndp" or (
            head.parent.name == "ndp" and head.name in ("cli.py", "__main__.py")
        ):
            argv = ["ndp", *argv[1:]]
    return portable_command(argv)


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
