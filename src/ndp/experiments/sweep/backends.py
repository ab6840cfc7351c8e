"""Where a sweep's runs execute: a local process pool, or Ray tasks.

Part of :mod:`ndp.experiments.sweep` (its docstring describes the whole).
"""

from __future__ import annotations

import dataclasses
import os
import signal
from collections.abc import Hashable, Sequence
from concurrent import futures
from typing import TYPE_CHECKING, Any, Protocol, cast

from ndp.checks import install_hint
from ndp.experiments.sweep.jobs import STOP_GRACE_S, Job, Outcome
from ndp.experiments.sweep.runner import _STOP, _stop_all, execute

if TYPE_CHECKING:
    from ray import ObjectRef

Settled = list[tuple[Hashable, "Outcome | BaseException"]]
"""What a backend's wait / interrupt returns: (handle, the run's outcome or the error that
ended its task) for each finished run."""


class Backend(Protocol):
    """Where runs execute; a handle (what ``submit`` returns) is opaque outside its backend."""

    name: str
    slots: int

    def describe(self) -> str: ...

    def submit(self, job: Job) -> Hashable: ...

    def wait(self, handles: Sequence[Hashable], timeout: float) -> Settled: ...

    def interrupt(self, handles: Sequence[Hashable]) -> Settled: ...

    def close(self) -> None: ...


# ----------------------------------------------------------------------------- backends


class LocalBackend:
    """At most ``workers`` trainer processes at once (threads of this process wait on them)."""

    name = "local"

    def __init__(self, workers: int | None = None) -> None:
        self.slots = max(1, workers or default_workers())
        self.pool = futures.ThreadPoolExecutor(max_workers=self.slots, thread_name_prefix="sweep")
        _STOP.clear()

    def describe(self) -> str:
        return f"local, {self.slots} at once"

    def submit(self, job: Job) -> Hashable:
        return self.pool.submit(execute, job)

    def wait(self, handles: Sequence[Hashable], timeout: float) -> Settled:
        done, _ = futures.wait(_futures(handles), timeout=timeout,
                               return_when=futures.FIRST_COMPLETED)  # fmt: skip
        out: Settled = []
        for h in done:
            try:
                out.append((h, h.result()))
            except Exception as exc:
                out.append((h, exc))
        return out

    def interrupt(self, handles: Sequence[Hashable]) -> Settled:
        _stop_all(signal.SIGINT)
        try:
            futures.wait(_futures(handles), timeout=STOP_GRACE_S + 10)
        except KeyboardInterrupt:  # a second Ctrl-C: kill (the checkpoints stay)
            _stop_all(signal.SIGKILL)
            futures.wait(_futures(handles))
        return self.wait(handles, 0) if handles else []

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)
        _STOP.clear()


def _futures(handles: Sequence[Hashable]) -> list[futures.Future[Outcome]]:
    """The local backend's handles as what they are (the futures its ``submit`` returns)."""
    return cast("list[futures.Future[Outcome]]", list(handles))


class RayBackend:
    """Every run a Ray task with one CPU; at most ``workers`` in flight (default: the cluster's
    CPUs). Starts (and at the end shuts down) a local Ray instance unless ``address`` is given
    or Ray is already initialised in this process."""

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None) -> None:
        try:
            import ray
        except ModuleNotFoundError:
            raise ValueError("--backend ray: needs Ray (" + install_hint("ray") + ")") from None
        self.ray = ray
        self.started = False
        if not ray.is_initialized():
            kw: dict[str, Any] = {"include_dashboard": False, "logging_level": "WARNING"}
            if address:
                ray.init(address=address, **kw)
            else:
                ray.init(num_cpus=max(1, workers or default_workers()), **kw)
            self.started = True
        self.remote = ray.remote(num_cpus=1, max_retries=0)(execute)
        cpus = int(ray.cluster_resources().get("CPU", 1))  # type: ignore[no-untyped-call]  # Ray: unannotated
        self.slots = max(1, workers or cpus)
        self.where = address or ("a local Ray instance" if self.started else "the running Ray")

    def describe(self) -> str:
        return f"ray ({self.where}), {self.slots} at once"

    def submit(self, job: Job) -> Hashable:
        # the task may run on another node, in another directory: an absolute run directory
        return self.remote.remote(dataclasses.replace(job, run_dir=job.run_dir.absolute()))

    def _get(self, h: Hashable) -> Outcome | BaseException:
        try:
            return self.ray.get(_refs([h])[0])
        except Exception as exc:  # TaskCancelledError, WorkerCrashedError, RayTaskError, ...
            return exc

    def wait(self, handles: Sequence[Hashable], timeout: float) -> Settled:
        if not handles:
            return []
        ready, rest = self.ray.wait(_refs(handles), num_returns=1, timeout=timeout)
        if ready and rest:
            more, _ = self.ray.wait(rest, num_returns=len(rest), timeout=0)
            ready += more
        return [(h, self._get(h)) for h in ready]

    def interrupt(self, handles: Sequence[Hashable]) -> Settled:
        for h in handles:
            self.ray.cancel(
                _refs([h])[0]
            )  # KeyboardInterrupt in the task: its trainer gets one SIGINT
        try:
            self.ray.wait(_refs(handles), num_returns=len(handles), timeout=STOP_GRACE_S + 10)
        except KeyboardInterrupt:
            for h in handles:
                self.ray.cancel(_refs([h])[0], force=True)
        return [(h, self._get(h)) for h in handles]

    def close(self) -> None:
        if self.started:
            self.ray.shutdown()


def _refs(handles: Sequence[Hashable]) -> list[ObjectRef[Outcome]]:
    """The Ray backend's handles as what they are (the object refs its ``submit`` returns)."""
    return cast("list[ObjectRef[Outcome]]", list(handles))


def default_workers() -> int:
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def make_backend(backend: str, workers: int | None = None, address: str | None = None) -> Backend:
    """'local' or 'ray' (``address``: an existing cluster)."""
    if backend == "local":
        if address:
            raise ValueError("--address: only with --backend ray")
        return LocalBackend(workers)
    if backend == "ray":
        return RayBackend(address, workers)
    raise ValueError(f"backend: expected 'local' or 'ray', got {backend!r}")
