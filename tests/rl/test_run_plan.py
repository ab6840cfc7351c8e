"""The run directory is named once (ndp.rl.config.default_run_dir, ndp.runs.layout.run_name):
an alias task or VICES's task variant, interrupted after a checkpoint, resumes with the command
the interrupt prints; a run that could resume is never offered to --overwrite."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ndp.runs.layout import parse_run_name, run_name

ENV = {**os.environ, "MUJOCO_GL": "egl", "OMP_NUM_THREADS": "1"}


def test_run_name_and_its_inverse():
    assert run_name("push-v3", "ppo-multi", 3) == "push-v3-ppo-multi-s3"
    tasks = ["push-v3", "push-v3-osc", "faucet-open-v3"]
    for task, label, seed in (("push-v3", "ppo-multi", 3), ("push-v3-osc", "vices", 0),
                              ("faucet-open-v3", "ndp-v1-fixed", 12)):  # fmt: skip
        assert parse_run_name(run_name(task, label, seed), tasks) == (task, label, seed)
    assert parse_run_name("throw-ndp-s0") == ("throw", "ndp", 0)
    assert parse_run_name("notarun") is None


def _interrupt_after_checkpoint(cmd: list[str], cwd: Path, ckpt: Path) -> str:
    proc = subprocess.Popen(cmd, cwd=cwd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.time() + 240
    while not ckpt.is_file():
        if proc.poll() is not None:
            pytest.fail(f"training exited early: {proc.stderr.read().decode()[-1500:]}")
        if time.time() > deadline:
            proc.kill()
            pytest.fail("no checkpoint in time")
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    return err.decode()


@pytest.mark.parametrize(
    ("task", "algo", "folder", "extra"),
    [
        ("reach", "ppo", "runs/reach-v3-ppo-s0", ["--steps-per-update", "1024"]),
        ("push", "vices", "runs/push-v3-osc-vices-s0", ["--steps-per-update", "512"]),
    ],
)
def test_alias_and_task_variant_interrupt_then_resume_with_the_printed_command(
    tmp_path, task, algo, folder, extra
):
    ndp = [sys.executable, "-m", "ndp.cli"]
    cmd = [*ndp, "rl", "train", "--task", task, "--algo", algo, "--steps", "6000",
           "--num-envs", "2", "--vector", "sync", "--no-progress", "--no-tensorboard",
           "--checkpoint-every", "1", "--eval-every", "0", *extra]  # fmt: skip
    run = tmp_path / folder
    err = _interrupt_after_checkpoint(cmd, tmp_path, run / "checkpoint.pt")
    assert f"Continue with: ndp rl train --resume {folder}" in err, err
    assert "nothing to resume" not in err
    # the same command again: refused, pointing to --resume, never to --overwrite
    again = subprocess.run(cmd, cwd=tmp_path, env=ENV, capture_output=True, text=True)
    assert again.returncode != 0
    assert f"resume it (--resume {folder})" in again.stderr and "--overwrite" not in again.stderr
    # the printed command finishes the run
    done = subprocess.run([*ndp, "rl", "train", "--resume", folder, "--no-progress"],
                          cwd=tmp_path, env=ENV, capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr[-1500:]
    assert (run / "run.json").is_file() and '"finished": true' in (run / "run.json").read_text()
