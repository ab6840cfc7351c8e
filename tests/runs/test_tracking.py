"""``--track wandb``: every metrics row in a real, offline W&B run (read back from its file)."""

from __future__ import annotations

import csv
import json
import struct
import sys
from pathlib import Path

import pytest

from ndp.cli import main
from ndp.runs.tracking import ID_FILE, WandbTracker, check_track

RL = ["--task", "point-mass", "--algo", "ndp", "--steps-per-update", "256", "--minibatches", "2",
      "--vector", "sync", "--num-envs", "2", "--no-progress", "--no-tensorboard",
      "--eval-every", "0"]  # fmt: skip


def _records(path: Path) -> list[bytes]:
    """The records of a W&B transaction log (LevelDB's log format: 32 KiB blocks of
    checksum, length, type, data after a 7-byte header)."""
    data, block, pos = path.read_bytes(), 32768, 7
    assert data[:4] == b":W&B"
    out, part = [], b""
    while pos + 7 <= len(data):
        if block - pos % block < 7:  # a block's tail too short for a header is padding
            pos += block - pos % block
            continue
        _, length, kind = struct.unpack("<IHB", data[pos : pos + 7])
        if length == 0 and kind == 0:
            break
        chunk, pos = data[pos + 7 : pos + 7 + length], pos + 7 + length
        if kind == 1:  # full
            out.append(chunk)
        elif kind == 2:  # first
            part = chunk
        elif kind == 3:  # middle
            part += chunk
        elif kind == 4:  # last
            out.append(part + chunk)
    return out


def _key(item: object) -> str:
    """A record item's name (W&B stores it in ``key`` or, split, in ``nested_key``)."""
    return getattr(item, "key", "") or "/".join(getattr(item, "nested_key", ()))


def _history_and_config(run_dir: Path) -> tuple[list[dict[str, float]], dict[str, object]]:
    from wandb.proto import wandb_internal_pb2 as pb

    rows: list[dict[str, float]] = []
    config: dict[str, object] = {}
    for log in sorted((run_dir / "wandb").glob("offline-run-*/run-*.wandb")):
        for raw in _records(log):
            rec = pb.Record()
            rec.ParseFromString(raw)
            kind = rec.WhichOneof("record_type")
            if kind == "history":
                rows.append({_key(i): json.loads(i.value_json) for i in rec.history.item})
            elif kind == "run":  # the run record carries the config given to wandb.init
                config.update({_key(i): json.loads(i.value_json) for i in rec.run.config.update})
    return rows, config


def _log_summary(run_dir: Path) -> str:
    """The offline logs' sizes and record kinds, for a failure message."""
    from collections import Counter

    from wandb.proto import wandb_internal_pb2 as pb

    parts = []
    for log in sorted((run_dir / "wandb").glob("offline-run-*/run-*.wandb")):
        kinds: Counter[str] = Counter()
        for raw in _records(log):
            rec = pb.Record()
            rec.ParseFromString(raw)
            kinds[str(rec.WhichOneof("record_type"))] += 1
        parts.append(f"{log.name}: {log.stat().st_size} bytes, records {dict(kinds)}")
    return "; ".join(parts) or "no offline log"


@pytest.fixture
def offline_wandb(tmp_path, monkeypatch):
    pytest.importorskip("wandb")
    monkeypatch.delenv("WANDB_MODE", raising=False)  # unset: the run is offline
    for var in ("WANDB_CONFIG_DIR", "WANDB_CACHE_DIR", "WANDB_DATA_DIR"):
        monkeypatch.setenv(var, str(tmp_path / "wandb-home" / var.lower()))
    monkeypatch.setenv("WANDB_SILENT", "true")


def test_a_tracked_run_logs_every_row_offline_and_a_resume_continues_its_id(
    tmp_path, offline_wandb
):
    run = tmp_path / "r"
    assert main(["rl", "train", *RL, "--steps", "512", "--run-dir", str(run),
                 "--track", "wandb"]) == 0  # fmt: skip
    with (run / "metrics.csv").open() as fh:
        csv_rows = list(csv.DictReader(fh))
    rows, config = _history_and_config(run)
    assert [int(r["_step"]) for r in rows] == [int(r["global_step"]) for r in csv_rows], (
        _log_summary(run)  # a rare flake under load (no history rows): say what the file held
    )
    for logged, written in zip(rows, csv_rows, strict=True):
        assert logged["charts/episode_return"] == pytest.approx(
            float(written["charts/episode_return"]), rel=1e-12
        )
        assert "global_step" not in logged and "update" not in logged  # the x axis, the index
    assert config["algo"] == "ndp" and config["track"] == "wandb"
    run_id = (run / "wandb" / ID_FILE).read_text().strip()
    # a resume (a longer budget) continues the same W&B run: a second offline log, same id
    assert main(["rl", "train", "--resume", str(run), "--steps", "1024"]) == 0
    logs = sorted((run / "wandb").glob("offline-run-*"))
    assert len(logs) == 2 and all(p.name.endswith(run_id) for p in logs)
    steps = [int(r["_step"]) for r in _history_and_config(run)[0]]
    assert steps == sorted(steps) and steps[-1] >= 1024


def test_track_values_and_a_missing_wandb_are_one_line(tmp_path, monkeypatch, capsys):
    with pytest.raises(ValueError, match=r"^track: expected one of none, wandb, got 'mlflow'$"):
        check_track("mlflow")
    assert main(["rl", "train", *RL, "--steps", "256", "--run-dir", str(tmp_path / "r"),
                 "--track", "mlflow"]) == 2  # fmt: skip
    assert "track: expected one of none, wandb" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()
    monkeypatch.setitem(sys.modules, "wandb", None)  # as if not installed
    with pytest.raises(ValueError, match=r"^track: --track wandb needs wandb: pip install"):
        WandbTracker(tmp_path / "r2", "r2", {})
    monkeypatch.delitem(sys.modules, "wandb")
    pytest.importorskip("wandb")
    monkeypatch.setenv("WANDB_MODE", "sometimes")
    with pytest.raises(ValueError, match=r"^track: WANDB_MODE must be one of offline, online"):
        WandbTracker(tmp_path / "r3", "r3", {})
