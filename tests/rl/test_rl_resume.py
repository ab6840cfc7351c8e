"""Checkpoints: atomic writes, SIGKILL a training subprocess and resume it."""

from __future__ import annotations

import dataclasses
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
    assert "ppo.lr: 0.0003 in the checkpoint, 0.01 now" in capsys.readouterr().err
    # extending the budget continues the same run
    assert ndp_main(["rl", "train", "--resume", str(run), "--steps", "1024", "--no-progress"]) == 0
    state = ck.load_checkpoint(run / "checkpoint.pt")
    assert state["update"] == 4 and state["config"]["steps"] == 1024


def _tiny(run_dir: str) -> list[str]:
    return ["rl", "train", "--task", "point-mass", "--steps-per-update", "256",
            "--minibatches", "2", "--no-progress", "--no-tensorboard", "--vector", "sync",
            "--steps", "512", "--run-dir", run_dir]  # fmt: skip


def test_a_run_resumes_from_any_spelling_of_its_path_and_after_a_move(tmp_path, monkeypatch):
    """A run's identity is its folder's contents: created as a relative path, it resumes from
    its absolute path, from another working directory, and after the folder was moved (another
    disk, a cluster's mount point)."""
    import shutil

    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert ndp_main(_tiny("r/base")) == 0
    extend = ["--steps", "1024", "--no-progress"]
    assert ndp_main(["rl", "train", "--resume", str(work / "r" / "base"), *extend]) == 0
    assert ck.load_checkpoint(work / "r" / "base" / "checkpoint.pt")["update"] == 4
    moved = tmp_path / "elsewhere" / "base"
    shutil.move(work / "r" / "base", moved)
    monkeypatch.chdir(tmp_path)
    assert ndp_main(["rl", "train", "--resume", "elsewhere/base", "--steps", "1536",
                     "--no-progress"]) == 0  # fmt: skip
    state = ck.load_checkpoint(moved / "checkpoint.pt")
    assert state["update"] == 6 and state["config"]["run_dir"] == "elsewhere/base"
    assert [int(r["update"]) for r in read_metrics(moved)] == [1, 2, 3, 4, 5, 6]


def test_a_refused_resume_names_each_field_and_both_values(tmp_path):
    """Another instance of the class: a config edited under a run (or a checkpoint of another
    run copied in) is refused naming the fields, never 'config differs' alone."""
    from ndp.rl.config import TrainConfig, load_config
    from ndp.rl.run import open_run
    from ndp.runs.resume import config_differences

    run = tmp_path / "run"
    assert ndp_main(_tiny(str(run))) == 0
    cfg = load_config(run / "config.json")
    changed = dataclasses.replace(cfg, seed=7, ppo=dataclasses.replace(cfg.ppo, lr=1e-2))
    assert config_differences(cfg, changed) == [("seed", 0, 7), ("ppo.lr", 3e-4, 1e-2)]
    assert config_differences(cfg, dataclasses.replace(cfg, run_dir="/x")) == []
    with pytest.raises(ValueError, match=r"seed: 0 in the checkpoint, 7 now; ppo\.lr: 0\.0003"):
        open_run(TrainConfig.from_dict(changed.to_dict()), resume=True)


def test_ctrl_c_before_the_first_checkpoint_says_so_and_the_same_command_restarts(tmp_path):
    """Interrupted before its first checkpoint: the stop line says there is nothing to resume,
    --resume says to rerun the command, and the plain rerun starts the run again (replacing the
    partial files, named on stderr) instead of refusing the folder."""
    import os
    import subprocess
    import time

    run = tmp_path / "run"
    argv = [*_tiny(str(run)), "--checkpoint-every", "1000", "--steps", "100000"]
    proc = subprocess.Popen([sys.executable, "-m", "ndp.cli", *argv], stderr=subprocess.PIPE)
    deadline = time.time() + 120
    while time.time() < deadline and not (
        (run / "metrics.csv").is_file() and len(read_metrics(run)) >= 1
    ):
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "before the first checkpoint: nothing to resume" in err.decode()
    assert not (run / "checkpoint.pt").exists() and (run / "metrics.csv").exists()
    with pytest.raises(FileNotFoundError, match="stopped before its first checkpoint"):
        ck.RunDir(run).open_for_resume()
    res = subprocess.run([sys.executable, "-m", "ndp.cli", *_tiny(str(run))],
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "stopped before its first checkpoint (nothing to resume); starting the run again" in (
        res.stderr
    )
    assert [int(r["update"]) for r in read_metrics(run)] == [1, 2]
    assert (run / "partial-start-1" / "metrics.csv").is_file()  # kept aside, not deleted


def test_a_finished_archived_run_is_never_taken_for_a_partial_start(tmp_path):
    """A run archived without its checkpoint (done.json) holds metrics but no checkpoint: a new
    run in its folder is refused, not started over it."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.csv").write_text("update,global_step\n1,100\n")
    (run / "done.json").write_text("{}")
    (run / "config.json").write_text("{}")
    (run / "provenance.json").write_text("[]")
    with pytest.raises(ValueError, match=r"already holds a run's metrics\.csv"):
        ck.RunDir(run).create()
    assert (run / "metrics.csv").exists()


def test_an_unfinished_run_archived_with_its_checkpoint_resumes_on_a_fresh_machine(
    tmp_path, kill_after_rows, capsys
):
    """``ndp sweep --pack A --pack-unfinished`` keeps a killed run's checkpoint: unpacked into
    an empty runs directory (the next session's machine) it resumes at that checkpoint and
    completes every update; packed again once finished, its entry loses the checkpoint."""
    import tarfile

    from ndp.experiments.sweep.archive import pack, unpack

    run = tmp_path / "runs" / "point-mass-ndp-s0"
    n_updates = 12
    cmd = [sys.executable, "-m", "ndp.cli", "rl", "train", "--task", "point-mass", "--algo",
           "ndp", "--steps", str(520 * n_updates), "--steps-per-update", "512", "--minibatches",
           "4", "--checkpoint-every", "2", "--run-dir", str(run), "--no-progress"]  # fmt: skip
    assert kill_after_rows(cmd, run).returncode == -signal.SIGKILL
    saved = ck.load_checkpoint(run / "checkpoint.pt")["update"]
    assert 0 < saved < n_updates
    archive = tmp_path / "a.tar.gz"
    assert pack([], archive, unfinished=[run]) == [run.name]
    with tarfile.open(archive) as tf:
        names = set(tf.getnames())
    assert f"{run.name}/checkpoint.pt" in names and f"{run.name}/done.json" not in names

    fresh = tmp_path / "fresh"
    assert unpack(archive, fresh) == ([run.name], [])
    moved = fresh / run.name
    assert ck.load_checkpoint(moved / "checkpoint.pt")["update"] == saved
    assert ndp_main(["rl", "train", "--resume", str(moved), "--no-progress"]) == 0
    rows = read_metrics(moved / "metrics.csv")
    assert [int(r["update"]) for r in rows] == list(range(1, n_updates + 1))
    assert ck.load_checkpoint(moved / "checkpoint.pt")["update"] == n_updates

    pack([moved], archive)  # finished now: its entry replaced, without the checkpoint
    with tarfile.open(archive) as tf:
        names = set(tf.getnames())
    assert f"{run.name}/done.json" in names and f"{run.name}/checkpoint.pt" not in names
    empty = tmp_path / "runs" / "never-started"
    empty.mkdir()
    with pytest.raises(FileNotFoundError, match=r"has no checkpoint\.pt to resume from"):
        pack([], archive, unfinished=[empty])
    assert ndp_main(["sweep", "--pack-unfinished", "--dry-run"]) != 0
    assert "--pack-unfinished: only with --pack ARCHIVE" in capsys.readouterr().err
