"""Whether two versions of the study registry give the same sweeps: byte for byte, the output
of ``ndp sweep --list`` and of ``ndp sweep NAME --dry-run`` for every study (its default arms,
every arm named with ``--arms``, and every registered arm named with ``--skip-unavailable``),
plus every field of every :class:`ndp.experiments.studies.Study` as JSON (conditions,
selection, readings, budgets and summary, which the sweep does not print).

Made for the move of the studies from Python literals to data files (issue "the library and
the lab"): save the outputs with the old version, then compare with the new one.

Example::

    python benchmarks/studies_equivalence.py --save /tmp/hs-before      # old version
    python benchmarks/studies_equivalence.py --compare /tmp/hs-before   # new version: exit 1
                                                                        # on any difference

Each command runs as ``python -m ndp.cli sweep ...`` with this checkout's ``src`` first on
``PYTHONPATH`` (about 70 commands; minutes on a loaded machine). The dry runs use the empty
runs folder ``--runs-dir`` (default /tmp/hs-empty; nothing is written there).
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT / "src") + os.pathsep + env.get("PYTHONPATH", "")
    env.setdefault("OMP_NUM_THREADS", "1")
    return env


def _fields(obj: Any) -> Any:
    """A study (or its parts) as JSON-able data, the task and arm lists built."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {}
        for f in dataclasses.fields(obj):
            v = getattr(obj, f.name)
            if f.name == "tasks" and callable(v):
                v = obj.task_list()  # type: ignore[attr-defined]
            elif f.name == "arms" and callable(v):
                v = obj.arm_specs()  # type: ignore[attr-defined]
            out[f.name] = _fields(v)
        return out
    if isinstance(obj, (tuple, list)):
        return [_fields(v) for v in obj]
    if callable(obj):
        return f"{obj.__module__}:{obj.__qualname__}"
    return obj


def study_data() -> dict[str, Any]:
    """Every study's fields (in registry order) and the arms of each command."""
    sys.path.insert(0, str(ROOT / "src"))
    from ndp.experiments.studies import STUDIES

    data = {name: _fields(s) for name, s in STUDIES.items()}
    return data


def commands(runs_dir: str) -> list[tuple[str, list[str]]]:
    """(file name, sweep arguments) of every command compared."""
    sys.path.insert(0, str(ROOT / "src"))
    from ndp.experiments.studies import STUDIES

    out = [("list.txt", ["--list"])]
    for name, s in STUDIES.items():
        base = [name, "--dry-run", "--runs-dir", runs_dir]
        labels = [a.label for a in s.arm_specs()]
        keep, _ = s.available()
        out.append((f"{name}.txt", base))
        out.append((f"{name}-all-arms.txt", [*base, "--arms", *labels]))
        out.append(
            (f"{name}-registered-arms.txt",
             [*base, "--arms", *[a.label for a in keep], "--skip-unavailable"])
        )  # fmt: skip
    return out


def run_all(runs_dir: str) -> dict[str, str]:
    """File name -> the command line, its exit status, stdout and stderr."""
    results = {}
    for fname, argv in commands(runs_dir):
        p = subprocess.run(
            [sys.executable, "-m", "ndp.cli", "sweep", *argv],
            capture_output=True,
            text=True,
            env=_env(),
            cwd=ROOT,
        )
        results[fname] = (
            f"$ ndp sweep {' '.join(argv)}\n[rc {p.returncode}]\n"
            f"--- stdout\n{p.stdout}--- stderr\n{p.stderr}"
        )
    results["studies.json"] = json.dumps(study_data(), indent=1) + "\n"
    return results


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--save", type=Path, help="write the outputs into this folder")
    g.add_argument("--compare", type=Path, help="compare with the outputs saved in this folder")
    p.add_argument("--runs-dir", default="/tmp/hs-empty", help="the dry runs' (empty) folder")
    args = p.parse_args(argv)
    if Path(args.runs_dir).exists() and any(Path(args.runs_dir).iterdir()):
        p.error(f"--runs-dir: {args.runs_dir} is not empty")
    results = run_all(args.runs_dir)
    if args.save is not None:
        args.save.mkdir(parents=True, exist_ok=True)
        for fname, text in results.items():
            (args.save / fname).write_text(text)
        print(f"saved {len(results)} outputs in {args.save}")
        return 0
    saved = {f.name: f.read_text() for f in sorted(args.compare.iterdir()) if f.is_file()}
    differ = 0
    for fname in sorted(set(saved) | set(results)):
        a, b = saved.get(fname), results.get(fname)
        if a == b:
            continue
        differ += 1
        print(f"DIFFERS: {fname}")
        diff = difflib.unified_diff(
            (a or "").splitlines(), (b or "").splitlines(), "saved", "now", lineterm="", n=1
        )
        print("\n".join(list(diff)[:40]))
    print(f"{len(results)} outputs compared with {args.compare}: {differ} differ")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
