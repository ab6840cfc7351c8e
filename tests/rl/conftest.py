"""Shared helpers of the RL tests (as fixtures, so that test modules need no imports)."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ndp.runs import read_metrics


@pytest.fixture
def kill_after_rows() -> Callable[..., subprocess.Popen]:
    """``kill(cmd, run, rows=5, timeout=120)``: start ``cmd`` (a training process writing
    ``run/metrics.csv``), SIGKILL it once the run has ``rows`` metrics rows, wait for it and
    return the finished process (fails the test if it exits early or makes no progress)."""

    def kill(cmd: list[str], run: Path, rows: int = 5, timeout: float = 120) -> subprocess.Popen:
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        deadline = time.time() + timeout
        try:
            while time.time() < deadline:
                if proc.poll() is not None:
                    assert proc.stderr is not None
                    err = proc.stderr.read().decode()[-2000:]
                    pytest.fail(f"training exited early: {err}")
                if (Path(run) / "metrics.csv").is_file() and len(read_metrics(run)) >= rows:
                    break
                time.sleep(0.05)
            else:
                pytest.fail("training produced no progress in time")
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        return proc

    return kill


@pytest.fixture
def record_actions() -> Callable[[Any], list[np.ndarray]]:
    """``seen = record(envs)``: from now on every action batch ``envs.step`` gets is appended
    (copied) to ``seen``."""

    def record(envs: Any) -> list[np.ndarray]:
        seen: list[np.ndarray] = []
        step = envs.step

        def spy(actions: Any) -> Any:
            seen.append(np.asarray(actions).copy())
            return step(actions)

        envs.step = spy
        return seen

    return record
