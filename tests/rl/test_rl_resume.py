"""Checkpoints: atomic writes, SIGKILL a training subprocess and resume it."""

from __future__ import annotations

import signal
import sys

import pytest
import torch

from ndp import runs as ck
from ndp.cli import main as ndp_main
from ndp.runs import read_metrics


def test_atomic_save_keeps_previous_file_on_crash(tmp_path, monkeypatch):
    path = tmp_path / "c.pt"
    ck.save_checkpoint(path, {"x": torch.ones(3)}, kind="rl")

    def boom(obj, f):
        f.write(b"partial")
        raise RuntimeError("disk full")

    monkeypatch.setattr(torch, "save", boom)
    with pytest.raises(RuntimeError):
        ck.save_checkpoint(path, {"x": torch.zeros(3)}, kind="rl")
    monkeypatch.undo()
    assert torch.equal(ck.load_checkpoint(path)["x"], torch.ones(3))
    assert [p.name for p in tmp_path.iterdir()] == ["c.pt"]  # no temporary file left


def test_sigkill_then_resume(tmp_path, kill_after_rows):
    run = tmp_path / "run"
    n_updates = 30
    cmd = [
        sys.executable,
        "-m",
        "ndp.cli",
        "rl",
        "train",
        "--task",
        "point-mass",
        "--algo",
        "ndp",
        "--steps",
        str(520 * n_updates),
        "--steps-per-update",
        "512",
        "--minibatches",
        "4",
        "--checkpoint-every",
        "2",
        "--run-dir",
        str(run),
        "--no-progress",
    ]
    csv_path = run / "metrics.csv"
    proc = kill_after_rows(cmd, run)
    assert proc.returncode == -signal.SIGKILL
    killed_rows = len(read_metrics(csv_path))
    assert killed_rows < n_updates
    saved = ck.load_checkpoint(run / "checkpoint.pt")
    assert saved["update"] % 2 == 0 and killed_rows - saved["update"] <= 2  # <= one interval lost

    assert ndp_main(["rl", "train", "--resume", str(run), "--no-progress"]) == 0
    rows = read_metrics(csv_path)
    assert [int(r["update"]) for r in rows] == list(range(1, n_updates + 1))
    steps = [r["global_step"] for r in rows]
    assert steps == sorted(steps) and len(set(steps)) == len(steps)
    final = ck.load_checkpoint(run / "checkpoint.pt")
    assert final["update"] == n_updates
    assert final["global_step"] == int(steps[-1])


def test_resume_errors(tmp_path):
    assert ndp_main(["rl", "train", "--resume", str(tmp_path / "nothing")]) == 2


def test_corrupt_checkpoint_and_leftover_progress_give_one_line_errors(tmp_path):
    from ndp.cli import main as ndp_main
    from ndp.runs import load_checkpoint

    run = tmp_path / "run"
    run.mkdir()
    for content in (b"", b"not a checkpoint at all", b"PK\x03\x04garbage"):
        (run / "checkpoint.pt").write_bytes(content)
        with pytest.raises(ValueError, match=r"checkpoint: (cannot read|.* not a checkpoint)"):
            load_checkpoint(run / "checkpoint.pt")
    assert ndp_main(["rl", "eval", str(run)]) == 2
    # a directory with a previous run's progress but no checkpoint is not silently replaced
    other = tmp_path / "other"
    other.mkdir()
    (other / "metrics.csv").write_text("update,global_step\n1,512\n")
    rc = ndp_main(
        [
            "rl",
            "train",
            "--task",
            "point-mass",
            "--steps",
            "520",
            "--run-dir",
            str(other),
            "--no-progress",
            "--no-tensorboard",
            "--vector",
            "sync",
        ]
    )
    assert rc == 2 and (other / "metrics.csv").read_text().startswith("update,global_step")


def test_resume_refuses_run_changing_options_and_extends_steps(tmp_path, capsys):
    run = tmp_path / "run"
    base = [
        "rl",
        "train",
        "--task",
        "point-mass",
        "--steps-per-update",
        "256",
        "--minibatches",
        "2",
        "--no-progress",
        "--no-tensorboard",
        "--vector",
        "sync",
    ]
    assert ndp_main([*base, "--steps", "512", "--run-dir", str(run)]) == 0
    # nothing left to do: said so, exit 0, nothing changed
    assert ndp_main(["rl", "train", "--resume", str(run)]) == 0
    assert "nothing to do" in capsys.readouterr().err
    # an option that would change the run is refused by name
    assert ndp_main(["rl", "train", "--resume", str(run), "--lr", "1e-2"]) == 2
    assert "['ppo.lr']" in capsys.readouterr().err
    # extending the budget continues the same run
    assert ndp_main(["rl", "train", "--resume", str(run), "--steps", "1024", "--no-progress"]) == 0
    state = ck.load_checkpoint(run / "checkpoint.pt")
    assert state["update"] == 4 and state["config"]["steps"] == 1024
