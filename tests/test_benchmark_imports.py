"""Every name a benchmark script imports from the package exists (the scripts import lazily,
inside functions, so a moved name breaks them only when that path runs: benchmarks/
rl_throughput.py imported ``DyneConfig`` from ``ndp.rl.config`` after it moved to
``ndp.rl.dyne.config``, and every row of our own runs failed)."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

BENCHMARKS = sorted((Path(__file__).resolve().parents[1] / "benchmarks").glob("*.py"))
OPTIONAL = ("stable_baselines3", "envpool", "onnxruntime", "onnx", "ray", "wandb", "rliable")


def _imports(path: Path) -> list[tuple[int, str, str]]:
    """(line, module, name) of each ``from ndp... import name`` in a script, at any depth."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "ndp":
            out += [(node.lineno, node.module, a.name) for a in node.names]
    return out


@pytest.mark.parametrize("path", BENCHMARKS, ids=lambda p: p.name)
def test_every_package_name_a_benchmark_imports_exists(path):
    missing = []
    for line, module, name in _imports(path):
        try:
            mod = importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if exc.name and exc.name.split(".")[0] in OPTIONAL:
                continue  # an optional extra this environment lacks
            missing.append(f"{path.name}:{line}: {module} ({exc})")
            continue
        if hasattr(mod, name):
            continue
        try:
            importlib.import_module(f"{module}.{name}")  # a submodule
        except ModuleNotFoundError:
            missing.append(f"{path.name}:{line}: {module} has no {name}")
    assert not missing, "\n".join(missing)


def test_the_check_sees_a_moved_name(tmp_path):
    script = tmp_path / "bench.py"
    script.write_text("def f():\n    from ndp.rl.config import DyneConfig\n")
    assert _imports(script) == [(2, "ndp.rl.config", "DyneConfig")]
    assert not hasattr(importlib.import_module("ndp.rl.config"), "DyneConfig")
