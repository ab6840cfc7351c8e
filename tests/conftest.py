"""Setup of the whole suite: one BLAS / torch thread per pytest-xdist worker.

``make test`` runs the suite on 2 workers (``-n 2 --dist loadfile``) on a 2-core machine; a
worker that also ran torch (or numpy's BLAS) on 2 threads would make 4 busy threads on 2 cores.
The variables are set before any test module imports torch (torch reads ``OMP_NUM_THREADS`` at
import), and the training subprocesses that tests start inherit them. A test that sets torch's
threads itself (a trainer's ``threads`` setting) is followed by a reset to 1, so the next test
on that worker starts from one thread as it would in a fresh process. A serial run (no
``PYTEST_XDIST_WORKER``) is left as it was.

``--dist loadfile`` keeps each test file on one worker: a module-scope fixture (a training, a
report, the API reference build) runs once, as in a serial run. (``--dist loadgroup`` with
``xdist_group`` marks would group finer, but pytest-xdist 3.8.0 loses the marks under pytest 9.2:
pytest-xdist issue 1386.)

At the end, the controller prints each worker's share: tests run, seconds spent in tests and the
CPU seconds of the worker and of the subprocesses it waited for (the balance of the two).
"""

from __future__ import annotations

import os
import resource
import sys
import time
from collections.abc import Iterator
from typing import Any

import pytest

XDIST_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")

if XDIST_WORKER:
    for _var in THREAD_VARS:
        os.environ[_var] = "1"


@pytest.fixture(autouse=True)
def _one_thread_per_worker() -> Iterator[None]:
    yield
    torch = sys.modules.get("torch")  # never imported here: some tests check what is imported
    if XDIST_WORKER and torch is not None and torch.get_num_threads() != 1:
        torch.set_num_threads(1)


_SHARE: dict[str, float] = {"tests": 0, "test_s": 0.0, "start": time.perf_counter()}
_SHARES: dict[str, dict[str, Any]] = {}  # on the controller: each worker's share


def _cpu_seconds() -> tuple[float, float]:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    _SHARE["test_s"] += report.duration
    if report.when == "call" or (report.when == "setup" and report.outcome != "passed"):
        _SHARE["tests"] += 1


def pytest_sessionfinish(session: pytest.Session) -> None:
    out = getattr(session.config, "workeroutput", None)  # set on xdist workers only
    if out is None:
        return
    own, children = _cpu_seconds()
    out["ndp_share"] = {
        "tests": int(_SHARE["tests"]),
        "test_s": round(_SHARE["test_s"]),
        "wall_s": round(time.perf_counter() - _SHARE["start"]),
        "cpu_s": round(own),
        "children_cpu_s": round(children),
    }


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node: Any, error: Any) -> None:
    share = getattr(node, "workeroutput", {}).get("ndp_share")
    if share is not None:
        _SHARES[node.gateway.id] = share


def pytest_terminal_summary(terminalreporter: Any) -> None:
    if not _SHARES:
        return
    terminalreporter.write_sep("-", "xdist workers (the balance of the two)")
    for worker, s in sorted(_SHARES.items()):
        terminalreporter.write_line(
            f"{worker}: {s['tests']} tests, {s['test_s']} s in tests, wall {s['wall_s']} s, "
            f"CPU {s['cpu_s']} s + {s['children_cpu_s']} s in subprocesses"
        )
