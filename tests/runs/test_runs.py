"""The shared run infrastructure: run directories, metrics logger, checkpoints, typed CLIs."""

from __future__ import annotations

import dataclasses
import json

import pytest
import torch

from ndp.runs import (
    MetricsLogger,
    RunDir,
    load_checkpoint,
    metrics_path,
    read_metrics,
    save_checkpoint,
)
from ndp.runs.cli import changed_fields, parse_config, pop_option

COLS = ("update", "global_step", "loss")


def _log(run, rows, **kw):
    with MetricsLogger(run, COLS, step="global_step", **kw) as log:
        for u, loss in rows:
            log.log({"update": u, "global_step": 100 * u, "loss": loss})


def _tb_scalars(run, tag="loss"):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    acc = EventAccumulator(str(run / "tb"))
    acc.Reload()
    return {e.step: e.value for e in acc.Scalars(tag)}


def test_resume_keeps_rows_and_events_up_to_the_checkpoint(tmp_path):
    run = tmp_path / "r"
    _log(run, [(u, float(u)) for u in range(1, 6)])
    # killed after update 5, last checkpoint at update 3 (global_step 300): updates 4, 5 rerun
    _log(run, [(4, 40.0), (5, 50.0)], resume_index=3, resume_step=300)
    rows = read_metrics(run)
    assert [r["update"] for r in rows] == [1, 2, 3, 4, 5]
    assert [r["loss"] for r in rows] == [1.0, 2.0, 3.0, 40.0, 50.0]
    # the checkpoint's own update keeps its TensorBoard point; the later ones are replaced
    assert _tb_scalars(run) == {100: 1.0, 200: 2.0, 300: 3.0, 400: 40.0, 500: 50.0}


def test_logger_refuses_unknown_names_and_keeps_nan_empty(tmp_path):
    with MetricsLogger(tmp_path, COLS, step="global_step", tensorboard=False) as log:
        with pytest.raises(ValueError, match="unknown names"):
            log.log({"update": 1, "global_step": 1, "lossy": 1.0})
        log.log({"update": 1, "global_step": 1, "loss": float("nan")})
    assert (tmp_path / "metrics.csv").read_text().splitlines()[1] == "1,1,"
    with pytest.raises(ValueError, match="step"):
        MetricsLogger(tmp_path, COLS, step="epoch")


def test_legacy_progress_csv_is_read_and_renamed_on_resume(tmp_path):
    run = RunDir(tmp_path / "old")
    run.path.mkdir()
    (run.path / "progress.csv").write_text("update,global_step,loss\n1,100,0.5\n")
    assert metrics_path(run.path).name == "progress.csv"
    assert read_metrics(run.path)[0]["loss"] == 0.5
    with pytest.raises(ValueError, match=r"already holds a run's progress\.csv"):
        run.create()
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        run.open_for_resume()
    save_checkpoint(run.checkpoint, {"update": 1}, kind="rl")
    run.open_for_resume()
    assert not (run.path / "progress.csv").exists() and read_metrics(run.path)[0]["loss"] == 0.5


def test_checkpoint_kind_is_checked_and_inferred_for_old_files(tmp_path):
    save_checkpoint(tmp_path / "a.pt", {"x": torch.ones(2)}, kind="il")
    assert load_checkpoint(tmp_path / "a.pt", kind="il")["kind"] == "il"
    with pytest.raises(ValueError, match="is an imitation checkpoint; expected an RL one"):
        load_checkpoint(tmp_path / "a.pt", kind="rl")
    # written before ``kind`` existed: recognised from its config
    torch.save({"config": {"algo": "ndp"}, "update": 3}, tmp_path / "old.pt")
    assert load_checkpoint(tmp_path / "old.pt", kind="rl")["update"] == 3
    d = tmp_path / "run"
    d.mkdir()
    save_checkpoint(d / "checkpoint.pt", {"y": 1}, kind="rl")
    assert load_checkpoint(d)["y"] == 1  # a run directory works too
    with pytest.raises(FileNotFoundError, match="no such file"):
        load_checkpoint(tmp_path / "missing")


def test_sessions_are_recorded_with_provenance(tmp_path):
    run = RunDir(tmp_path / "r")
    run.create()
    run.write_config({"b": 1, "a": 2})
    assert run.read_config() == {"a": 2, "b": 1}
    run.record_session("start", ["ndp", "rl", "train"])
    run.record_session("resume", ["ndp", "rl", "train", "--resume", "r"])
    sessions = json.loads((run.path / "provenance.json").read_text())
    assert [s["event"] for s in sessions] == ["start", "resume"]
    assert sessions[1]["argv"][-2:] == ["--resume", "r"]
    assert {"time", "commit", "dirty", "host", "versions"} <= set(sessions[0])
    (run.path / "config.json").write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        run.read_config()


@dataclasses.dataclass(frozen=True)
class _Inner:
    width: int = 3
    """Width."""


@dataclasses.dataclass(frozen=True)
class _Outer:
    name: str = "a"
    """Name."""
    flag: bool = False
    """A flag."""
    inner: _Inner = dataclasses.field(default_factory=_Inner)
    """Nested."""


def test_typed_cli_is_flat_and_reports_changed_fields():
    base = _Outer()
    got = parse_config(_Outer, ["--width", "5", "--flag"], prog="t")
    assert got == _Outer(flag=True, inner=_Inner(width=5))
    assert changed_fields(base, got) == ["flag", "inner.width"]
    again = parse_config(_Outer, ["--name", "b"], prog="t", default=got)
    assert again.inner.width == 5 and again.name == "b"  # defaults come from the given config


def test_pop_option():
    assert pop_option(["--a", "1", "--resume", "x", "--b"], "--resume") == (
        "x",
        ["--a", "1", "--b"],
    )
    assert pop_option(["--resume=x"], "--resume") == ("x", [])
    assert pop_option(["--a"], "--resume") == (None, ["--a"])
    with pytest.raises(ValueError, match="expected a run directory"):
        pop_option(["--resume"], "--resume")
    with pytest.raises(ValueError, match="more than once"):
        pop_option(["--resume", "a", "--resume", "b"], "--resume")


def test_sessions_record_the_environment_fingerprint(tmp_path):
    """Every session records the versions of Python, torch, numpy, MuJoCo and Meta-World (from
    the package metadata: Meta-World has no __version__, which older runs recorded as
    'unknown') and the CPU model; run_fingerprints gives each distinct one once, with 'not
    recorded' for what an older session lacks."""
    from importlib import metadata

    from ndp.provenance import FINGERPRINT_KEYS, fingerprint_text
    from ndp.runs import RunDir, run_fingerprints

    run = RunDir(tmp_path / "r")
    run.create()
    entry = run.record_session("start")
    assert {"python", "torch", "numpy", "mujoco", "metaworld"} <= set(entry["versions"])
    assert entry["versions"]["torch"] == metadata.version("torch")
    try:
        assert entry["versions"]["metaworld"] == metadata.version("metaworld")
    except metadata.PackageNotFoundError:
        assert entry["versions"]["metaworld"] == "not installed"
    assert isinstance(entry["cpu"], str) and entry["cpu"]
    run.record_session("resume")
    fps = run_fingerprints(run.path)
    assert len(fps) == 1 and set(fps[0]) == set(FINGERPRINT_KEYS)
    (run.path / "provenance.json").write_text(json.dumps([
        {"event": "start", "versions": {"python": "3.11.7", "metaworld": "unknown"}},
        {"event": "resume", "versions": {"python": "3.11.7", "metaworld": "unknown"}},
    ]))  # fmt: skip
    (old,) = run_fingerprints(run.path)
    assert old["metaworld"] == "unknown" and old["cpu"] == old["torch"] == "not recorded"
    assert fingerprint_text(old).startswith("python 3.11.7, torch not recorded, ")
    (run.path / "provenance.json").write_text("not json")
    assert run_fingerprints(run.path) == []


def test_run_commits_reads_the_provenance_record(tmp_path):
    """run_commits: the commits of a run's recorded sessions; nothing for a run without a
    readable provenance.json."""
    from ndp.runs import RunDir, run_commits

    run = RunDir(tmp_path / "r")
    run.create()
    assert run_commits(run.path) == []
    run.record_session("start")
    run.record_session("resume")
    commits = run_commits(run.path)
    assert len(commits) <= 1 and all(len(c) == 7 for c in commits)
    (run.path / "provenance.json").write_text(
        '[{"event": "start", "commit": "0123456789abcdef"}, {"event": "resume", '
        '"commit": "fedcba9876543210"}, {"event": "resume"}]'
    )
    assert run_commits(run.path) == ["0123456", "fedcba9"]
    (run.path / "provenance.json").write_text("not json")
    assert run_commits(run.path) == []


def test_a_stop_during_a_checkpoint_write_waits_for_the_write(tmp_path, monkeypatch):
    """SIGTERM delivered while the checkpoint is being written: the write completes (the file
    loads) and Terminated is raised afterwards, not the zip writer's error from inside
    torch.save (which turned a clean stop into exit 1 once)."""
    import os
    import signal

    from ndp.runs import checkpoint as ckpt_mod
    from ndp.runs.signals import Terminated, deferred_stops, stop_on_sigterm

    real = ckpt_mod.atomic_torch_save

    def signalled(obj, path):
        os.kill(os.getpid(), signal.SIGTERM)  # handled at the next bytecode: mid-write
        real(obj, path)

    monkeypatch.setattr(ckpt_mod, "atomic_torch_save", signalled)
    path = tmp_path / "checkpoint.pt"
    with stop_on_sigterm(), pytest.raises(Terminated):
        ckpt_mod.save_checkpoint(path, {"update": 3, "w": torch.ones(1000)}, kind="rl")
    assert ckpt_mod.load_checkpoint(path, kind="rl")["update"] == 3
    # outside a deferred block a stop is raised at once; an error inside one wins
    with stop_on_sigterm():
        with pytest.raises(Terminated):
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(1000):
                pass
        with pytest.raises(Terminated):  # the pending stop is raised by the next block
            with pytest.raises(OSError, match="disk"):
                with deferred_stops():
                    os.kill(os.getpid(), signal.SIGTERM)
                    raise OSError("disk full")
            with deferred_stops():
                pass
