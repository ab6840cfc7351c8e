"""The code-health counts of issue "the library and the lab", printed as JSON.

What it counts, over ``src/ndp`` (the package):

- ``lines``: lines of Python per top-level package, and the experiment layer's share;
- ``report_init_lines``: lines of ``ndp/experiments/report/__init__.py`` (target <= 300);
- ``long_functions``: functions (and methods) of 80 lines or more (target <= 8), and those over
  60 lines in ``ndp/experiments`` (target 0), each with its place;
- ``any_share``: the share of function signatures whose annotations name ``Any`` (target
  <= 15%), and ``spec: Any`` parameters;
- ``hand_checks``: hand-written ``"expected an integer >="`` messages outside ``ndp/checks.py``
  (the one ``check_int`` family);
- ``duplicates``: the pairs the ``duplicates`` command finds (target <= 15), when that command
  is on the PATH (a tool of the development machines, not a dependency; otherwise null);
- ``tests`` with ``--pytest``: the default test suite's wall time (target <= 720 s on 2 cores),
  its CPU seconds, the load average before and after and each xdist worker's share.

Example::

    python benchmarks/code_counts.py            # counts only (seconds)
    python benchmarks/code_counts.py --pytest   # and the default suite's wall / CPU time
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
PYTEST_ARGS = ("-n", "2", "--dist", "loadfile")  # as `make test`
SRC = ROOT / "src" / "ndp"


def _functions(tree: ast.AST) -> list[ast.FunctionDef | ast.AsyncFunctionDef]:
    return [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]


def _names_any(node: ast.AST | None) -> bool:
    if node is None:
        return False
    return any(
        (isinstance(n, ast.Name) and n.id == "Any")
        or (isinstance(n, ast.Attribute) and n.attr == "Any")
        or (isinstance(n, ast.Constant) and isinstance(n.value, str) and "Any" in n.value)
        for n in ast.walk(node)
    )


def counts() -> dict[str, Any]:
    """Every count but the test time."""
    per_pkg: dict[str, int] = {}
    long80: list[str] = []
    long60_exp: list[str] = []
    signatures = with_any = spec_any = 0
    hand_checks = 0
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC.parent).as_posix()
        text = path.read_text()
        n_lines = text.count("\n")
        parts = path.relative_to(SRC).parts
        pkg = parts[0] if len(parts) > 1 else "(top level)"
        per_pkg[pkg] = per_pkg.get(pkg, 0) + n_lines
        if path.name != "checks.py":
            hand_checks += len(re.findall(r"expected an integer >=", text))
        for fn in _functions(ast.parse(text)):
            size = (fn.end_lineno or fn.lineno) - fn.lineno + 1
            where = f"{rel}:{fn.lineno} {fn.name} ({size} lines)"
            if size >= 80:
                long80.append(where)
            if size > 60 and parts[0] == "experiments":
                long60_exp.append(where)
            args = [*fn.args.posonlyargs, *fn.args.args, *fn.args.kwonlyargs]
            args += [a for a in (fn.args.vararg, fn.args.kwarg) if a is not None]
            signatures += 1
            if any(_names_any(a.annotation) for a in args) or _names_any(fn.returns):
                with_any += 1
            spec_any += sum(a.arg == "spec" and _names_any(a.annotation) for a in args)
    total = sum(per_pkg.values())
    init = SRC / "experiments" / "report" / "__init__.py"
    return {
        "lines": {"total": total, "per_package": dict(sorted(per_pkg.items())),
                  "experiments_share": round(per_pkg.get("experiments", 0) / total, 3)},
        "report_init_lines": init.read_text().count("\n") if init.is_file() else None,
        "long_functions": {"80_or_more": len(long80), "experiments_over_60": len(long60_exp),
                           "places_80": long80, "places_experiments_60": long60_exp},
        "any_share": {"signatures": signatures, "naming_any": with_any,
                      "share": round(with_any / max(signatures, 1), 3), "spec_any": spec_any},
        "hand_checks": hand_checks,
        "duplicates": duplicates(),
    }  # fmt: skip


def duplicates() -> dict[str, Any] | None:
    """The ``duplicates`` command's pair count over ``src`` (None where it is not installed)."""
    exe = shutil.which("duplicates")
    if exe is None:
        return None
    res = subprocess.run([exe, "--most", "200", "--seconds", "300"], cwd=ROOT / "src",
                         capture_output=True, text=True, timeout=600)  # fmt: skip
    first = res.stdout.strip().splitlines()[0] if res.stdout.strip() else ""
    m = re.match(r"(\d+) pairs", first)
    return {"pairs": int(m.group(1)) if m else 0, "summary": first}


def tests_seconds() -> dict[str, Any]:
    """Wall and CPU time of the default suite as ``make test`` runs it (2 pytest-xdist workers),
    with the load average beside: on a machine shared with other work the wall time is not the
    quiet-machine one, the CPU seconds (the suite's processes and their subprocesses) are."""
    load_before = os.getloadavg()
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *PYTEST_ARGS]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    lines = res.stdout.strip().splitlines()
    workers = [line for line in lines if re.match(r"gw\d+: \d+ tests", line)]
    return {"seconds": round(wall, 1), "cpu_seconds": round(cpu, 1),
            "load_before": [round(x, 2) for x in load_before],
            "load_after": [round(x, 2) for x in os.getloadavg()],
            "workers": workers, "returncode": res.returncode,
            "summary": lines[-1] if lines else ""}  # fmt: skip


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pytest", action="store_true", help="also time the default test suite")
    args = ap.parse_args(argv)
    out = counts()
    if args.pytest:
        out["tests"] = tests_seconds()
    print(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
