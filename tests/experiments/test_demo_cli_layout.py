"""The quick-start command, atomic writes, and the one-way import rule of the layout."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

from ndp.cli import main
from ndp.io import atomic_write_text

SRC = Path(__file__).resolve().parents[2] / "src" / "ndp"


def test_demo_dmp_part_writes_figure_and_summary(tmp_path):
    assert main(["demo", "--out", str(tmp_path), "--skip", "il", "rl"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    png = Path(summary["dmp"]["figure"])
    assert png.is_file() and png.stat().st_size > 10_000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert summary["dmp"]["fit_mse_px2"] < 1e-2
    (tmp_path / "a-file").write_text("mine\n")  # --out naming a file: one line, file kept
    assert main(["demo", "--out", str(tmp_path / "a-file"), "--skip", "il", "rl"]) == 2
    assert (tmp_path / "a-file").read_text() == "mine\n"


def test_console_script_runs_and_rejects_unknown_command():
    exe = Path(sys.executable).with_name("ndp")
    r = subprocess.run([str(exe), "--help"], capture_output=True, text=True, check=False)
    assert r.returncode == 0 and "demo" in r.stdout
    r = subprocess.run([str(exe), "fly"], capture_output=True, text=True, check=False)
    assert r.returncode == 2 and "invalid choice" in r.stderr


def test_atomic_write_keeps_old_file_on_failure(tmp_path):
    target = tmp_path / "a.json"
    atomic_write_text(target, "old")

    class Boom(str):
        def encode(self, *a, **k):
            raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        atomic_write_text(target, Boom("new"))
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


# Which sub-packages each sub-package may import (imports point one way along the data flow).
ALLOWED = {
    "dmp": set(),
    "nets": set(),
    "runs": set(),  # run infrastructure (run dirs, metrics, checkpoints, typed CLIs)
    "envs": {"dmp", "schema"},
    "policies": {"dmp", "nets", "envs", "runs", "schema"},
    "il": {"dmp", "nets", "runs"},
    "rl": {"dmp", "nets", "envs", "policies", "runs", "schema"},
    "bc": {"dmp", "nets", "envs", "policies", "rl", "runs", "schema"},
    "experiments": {
        "dmp",
        "nets",
        "envs",
        "policies",
        "rl",
        "il",
        "bc",
        "sb3",
        "runs",
        "schema",
    },
}
LEAVES = {
    "io",
    "provenance",
    "checks",
    "chunk_info",
    "act_inputs",
    "gym_ids",
    "hub",
}  # leaf helper modules anyone may import (hub: the Hugging Face Hub, ndp.checks only)


def _ndp_imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    found = set()
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        for n in names:
            parts = n.split(".")
            if parts[0] == "ndp" and len(parts) > 1:
                found.add(parts[1])
    return found


@pytest.mark.parametrize("pkg", sorted(ALLOWED))
def test_imports_point_one_way(pkg):
    bad = {}
    for f in (SRC / pkg).rglob("*.py"):
        extra = _ndp_imports(f) - ALLOWED[pkg] - LEAVES - {pkg}
        if extra:
            bad[str(f.relative_to(SRC))] = sorted(extra)
    assert not bad, f"imports against the data flow: {bad}"


def test_atomic_write_gives_usual_file_mode(tmp_path):
    import os
    import stat

    target = tmp_path / "b.txt"
    atomic_write_text(target, "x")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask


@pytest.mark.parametrize(
    "argv",
    [["--help"], ["rl", "train", "--help"], ["il", "train", "--help"], ["il", "eval", "--help"],
     ["rl", "train", "--lr", "abc"], ["il", "train", "--bogus"], ["rl", "eval", "--help"],
     ["sweep", "--help"], ["report", "--help"], ["sweep", "--bogus"], ["report"]],
)  # fmt: skip
def test_help_and_argument_errors_import_no_heavy_module(argv):
    """Help and argument errors never import torch, scipy or the simulators (they answer in a
    fraction of a second; benchmarks/cli_startup.py measures it)."""
    code = (
        "import sys\nfrom ndp.cli import main\n"
        "try:\n    rc = main(sys.argv[1:])\nexcept SystemExit as e:\n    rc = e.code\n"
        "heavy = [m for m in ('torch', 'scipy', 'gymnasium', 'mujoco', 'metaworld') "
        "if m in sys.modules]\n"
        "print('HEAVY', heavy, 'RC', rc)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=120
    ).stdout
    assert "HEAVY [] RC" in out, out[-500:]
    assert out.strip().endswith("RC 0") == ("--help" in argv)
