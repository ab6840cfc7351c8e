"""Signals from the first instant (issue "nothing silent, part 4"): SIGINT / SIGTERM during the
start-up imports of a command end it with one line and 130 / 143, also where SIGINT was
ignored at start-up (a shell's background job), never a traceback or a lost signal."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest


def _ignore_sigint() -> None:  # as a non-interactive shell starts a background job
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@pytest.mark.parametrize(
    "command,sig,code",
    [
        (["il", "train", "--data", "synthetic", "--n-train", "50", "--epochs", "1"],
         signal.SIGINT, 130),
        (["rl", "train", "--task", "point-mass", "--steps", "100"], signal.SIGINT, 130),
        (["rl", "train", "--task", "point-mass", "--steps", "100"], signal.SIGTERM, 143),
    ],
)  # fmt: skip
def test_a_signal_during_start_up_ends_the_command_with_one_line(tmp_path, command, sig, code):
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    out = tmp_path / "run"
    args = [*command, "--run-dir" if command[0] == "rl" else "--out", str(out)]
    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys; from ndp.cli import main; sys.exit(main())", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path,
        preexec_fn=_ignore_sigint,
    )  # fmt: skip
    time.sleep(0.5)  # inside the imports (torch alone takes longer on this machine)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    assert "Traceback" not in err, err
    assert err.strip().count("\n") == 0, err  # one line
