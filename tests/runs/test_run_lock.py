"""One writer per run directory (ndp.runs.lock), with real processes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ndp.runs import lock
from policy_fixtures import fixture_policy

ENV = {**os.environ, "MUJOCO_GL": "egl", "OMP_NUM_THREADS": "1"}


def test_lock_is_reentrant_in_a_process_and_leaves_no_bare_directory(tmp_path):
    run = tmp_path / "r"
    lock.acquire(run)
    lock.acquire(run)  # the same process: counted
    assert (run / lock.RUN_LOCK_NAME).is_file()
    lock.release(run)
    assert (run / lock.RUN_LOCK_NAME).is_file()  # still held once
    lock.release(run)
    assert not run.exists()  # made by the lock and still empty: removed
    # a directory that held files before is kept
    (tmp_path / "k").mkdir()
    (tmp_path / "k" / "notes.txt").write_text("mine")
    with lock.held(tmp_path / "k"):
        pass
    assert (tmp_path / "k" / "notes.txt").is_file()


def _holder(run) -> subprocess.Popen:
    code = (
        "import sys, time; from ndp.runs import lock; lock.acquire(sys.argv[1]); "
        "print('held', flush=True); time.sleep(600)"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(run)], stdout=subprocess.PIPE)
    assert proc.stdout is not None and proc.stdout.readline().strip() == b"held"
    return proc


def test_a_second_process_is_refused_and_a_killed_holder_is_taken_over(tmp_path):
    run = tmp_path / "r"
    proc = _holder(run)
    try:
        with pytest.raises(lock.RunBusyError, match=r"is being trained now \(pid \d+"):
            lock.acquire(run)
        assert lock.holder(run) is not None and str(proc.pid) in lock.holder(run)
    finally:
        proc.kill()
        proc.wait()
    lock.acquire(run)  # the kernel released the killed holder's lock: taken over
    assert lock.holder(run) is None
    lock.release(run)


def test_two_trainers_one_run_directory(tmp_path):
    """A second `ndp rl train` on a run being trained, its --overwrite and its --resume are each
    refused in one line naming the holder; the first run is untouched and resumes after it is
    stopped."""
    ndp = [sys.executable, "-m", "ndp.cli", "rl", "train"]
    base = ["--task", "point-mass", "--algo", "ndp", "--num-envs", "2", "--vector", "sync",
            "--no-progress", "--no-tensorboard", "--checkpoint-every", "1", "--eval-every", "0",
            "--steps-per-update", "200", "--run-dir", str(tmp_path / "r")]  # fmt: skip
    first = subprocess.Popen([*ndp, *base, "--steps", "400000"], env=ENV,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)  # fmt: skip
    try:
        deadline = time.time() + 120
        while not (tmp_path / "r" / "checkpoint.pt").is_file():
            assert first.poll() is None and time.time() < deadline
            time.sleep(0.1)
        for extra in (["--steps", "400000"], ["--steps", "400000", "--overwrite"]):
            res = subprocess.run([*ndp, *base, *extra], env=ENV, capture_output=True, text=True)
            assert res.returncode == 2
            assert f"is being trained now (pid {first.pid}" in res.stderr, res.stderr
            assert "Traceback" not in res.stderr
        res = subprocess.run([*ndp, "--resume", str(tmp_path / "r")], env=ENV,
                             capture_output=True, text=True)  # fmt: skip
        assert res.returncode == 2 and f"(pid {first.pid}" in res.stderr
        assert first.poll() is None  # the first trainer runs on
    finally:
        first.send_signal(signal.SIGINT)
        first.wait(timeout=60)
    assert (tmp_path / "r" / "checkpoint.pt").is_file()
    from ndp.runs import read_metrics

    more = str(int(read_metrics(tmp_path / "r")[-1]["global_step"]) + 600)
    res = subprocess.run([*ndp, "--resume", str(tmp_path / "r"), "--steps", more], env=ENV,
                         capture_output=True, text=True)  # fmt: skip
    assert res.returncode == 0, res.stderr[-800:]


def test_an_interrupt_before_anything_is_written_leaves_no_run_directory(tmp_path, monkeypatch):
    """Ctrl-C while the learner is being built (after its session locked and made the run
    folder, before config.json): no empty folder stays for --resume to stumble on, and the
    lock is free again."""
    from ndp.rl import run as T
    from ndp.rl.config import TrainConfig

    def interrupt_the_build(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(T, "Trainer", interrupt_the_build)
    run = tmp_path / "fresh"
    cfg = TrainConfig(task="point-mass", steps=200, run_dir=str(run), progress=False,
                      tensorboard=False, vector="sync")  # fmt: skip
    with pytest.raises(KeyboardInterrupt):
        T.train(cfg)
    assert not run.exists()
    # this test's locks only: another test of the same process (a worker under xdist runs files in
    # another order) may hold one of its own
    mine = [p for p in lock._HELD if Path(p).resolve().is_relative_to(tmp_path.resolve())]
    assert lock.holder(tmp_path) is None and not mine, mine


@pytest.mark.parametrize("where", ["run", "sweep"])
def test_a_lock_that_is_a_symlink_is_refused_and_its_target_untouched(tmp_path, where):
    """A planted .run.lock / .sweep.lock symlink: refused in one line naming the file; the
    target keeps its bytes (it was truncated and overwritten before)."""
    from ndp.experiments.sweep.jobs import LOCK_NAME
    from ndp.experiments.sweep.runner import _RunLock

    run = tmp_path / "r"
    run.mkdir()
    target = tmp_path / "precious.txt"
    target.write_text("keep me\n")
    name = lock.RUN_LOCK_NAME if where == "run" else LOCK_NAME
    (run / name).symlink_to(target)
    with pytest.raises(OSError, match=rf"{name} is a symbolic link, not a lock file"):
        lock.acquire(run) if where == "run" else _RunLock.take(run)
    assert target.read_text() == "keep me\n"


def test_a_lock_that_is_a_directory_is_refused_in_one_line(tmp_path):
    run = tmp_path / "r"
    (run / lock.RUN_LOCK_NAME).mkdir(parents=True)
    with pytest.raises(OSError, match=r"\.run\.lock is a directory, not a lock file \(remove it"):
        lock.acquire(run)
    with pytest.raises(OSError, match="is a directory, not a lock file"):
        lock.open_lock(run / lock.RUN_LOCK_NAME)


def test_a_sweep_leaves_a_run_that_a_hand_started_trainer_holds(tmp_path):
    """The sweep honours the run's own lock: a run held by a trainer started outside any sweep
    is reported busy, not trained a second time, and no failed.json is written into it."""
    from ndp.experiments.sweep.runner import is_busy

    run = tmp_path / "r"
    proc = _holder(run)
    try:
        assert is_busy(run) is not None
        assert "pid" in is_busy(run)
        assert not (run / "failed.json").exists()
    finally:
        proc.kill()
        proc.wait()
    assert is_busy(run) is None  # the holder died: the lock is free again


def test_two_exports_into_one_folder_one_is_refused(tmp_path):
    """A second writer of the same export folder is refused while the first writes (it used to
    succeed too, interleaving files); the lock beside the folder is gone afterwards."""
    out = tmp_path / "export"
    code = (
        "import sys, time; from ndp.runs import lock\n"
        "with lock.output_lock(sys.argv[1]):\n"
        "    print('held', flush=True); time.sleep(600)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == b"held"
        import ndp

        with pytest.raises(lock.RunBusyError, match=r"out_dir: .* is being written now by pid"):
            ndp.load_policy(fixture_policy("push-v3-ndp")).export(out)
        assert not out.exists()
    finally:
        proc.kill()
        proc.wait()
    with lock.output_lock(out):
        pass
    assert not (tmp_path / ".export.lock").exists()
