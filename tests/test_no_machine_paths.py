"""No committed table, figure, card or doc holds a machine's absolute path (issue "a user's
first day, part 2", item 7): results name their runs relative to a runs root."""

from __future__ import annotations

import os
import re
from pathlib import Path

from ndp.provenance import portable_command, portable_path, user_command

ROOT = Path(__file__).resolve().parents[1]
MACHINE = re.compile(rb"/(work|home|root|Users)/")
SKIP = {".gz", ".safetensors", ".pt", ".npz", ".onnx"}


def test_docs_results_and_zoo_hold_no_absolute_machine_path():
    bad = []
    for base in (ROOT / "docs", ROOT / "src" / "ndp" / "zoo"):
        for p in base.rglob("*"):
            if p.is_file() and p.suffix not in SKIP and MACHINE.search(p.read_bytes()):
                bad.append(str(p.relative_to(ROOT)))
    assert not bad, f"absolute machine paths in: {bad[:20]}"


def test_portable_paths(tmp_path, monkeypatch):
    work = tmp_path / "work"
    (work / "main").mkdir(parents=True)
    monkeypatch.chdir(work / "main")
    assert portable_path(work / "runs" / "study" / "r-s0") == os.path.join(
        "..", "runs", "study", "r-s0"
    )
    assert portable_path(work / "main" / "docs") == "docs"
    assert portable_path("runs/x") == "runs/x"
    assert portable_path("/elsewhere/deep/runs/x") == ".../runs/x"
    cmd = ["ndp", "report", str(work / "runs" / "s"), "--out=" + str(work / "main" / "o")]
    assert portable_command(cmd) == ["ndp", "report", "../runs/s", "--out=o"]


def test_a_recorded_command_reads_as_a_user_types_it():
    # the entry point under a venv, the module run with python -m, the package's __main__
    for head in ("/w/.venv/bin/ndp", "/w/wt/rg/src/ndp/cli.py", "/site/ndp/__main__.py"):
        assert user_command([head, "rl", "train", "--seed", "1"]) == [
            "ndp", "rl", "train", "--seed", "1",
        ]  # fmt: skip
    # anything else keeps its program (made portable): a script is not the ndp command
    assert user_command(["/w/benchmarks/zoo.py", "--out", "zoo"])[0] == ".../benchmarks/zoo.py"
    assert user_command(["/w/src/other/cli.py", "x"])[0] != "ndp"
    assert user_command([]) == []
