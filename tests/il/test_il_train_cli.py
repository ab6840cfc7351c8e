"""Trainer and ``ndp il`` commands: files, logs, resume, bad input, NaN handling."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from ndp.cli import main
from ndp.il.models import ModelConfig
from ndp.il.train import (
    METRIC_NAMES,
    DataConfig,
    NonFiniteLossError,
    TrainConfig,
    evaluate,
    load_checkpoint,
    train,
)


def _tiny(tmp_path: Path, run: str = "run", **kw) -> TrainConfig:
    data = DataConfig(
        data_dir=str(tmp_path / "data"), n_samples=60, n_train=40, n_test=20, split_seed=1
    )
    base = dict(
        run_dir=str(tmp_path / run),
        data=data,
        model=ModelConfig(kind="ndp"),
        epochs=2,
        batch_size=20,
        threads=1,
        progress=False,
    )
    base.update(kw)
    return TrainConfig(**base)


def _tiny_args(tmp_path: Path, out: str) -> list[str]:
    return [
        "il", "train", "--data-dir", str(tmp_path / "data"), "--n-samples", "60",
        "--n-train", "40", "--n-test", "20", "--batch-size", "20", "--epochs", "1",
        "--threads", "1", "--out", str(tmp_path / out), "--no-progress",
    ]  # fmt: skip


@pytest.mark.parametrize("model", ["ndp", "cnn", "cnn-dmp"])
def test_cli_train_writes_run_files(tmp_path: Path, model: str, capsys) -> None:
    rc = main([*_tiny_args(tmp_path, model), "--model", model])
    assert rc == 0
    run = tmp_path / model
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["model"]["kind"] == model and cfg["lr"] == 1e-3 and cfg["batch_size"] == 20
    with (run / "metrics.csv").open() as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == ("epoch", *METRIC_NAMES)
    assert len(rows) == 2 and float(rows[1][3]) > 0  # test/mse_px2
    assert list((run / "tb").glob("events.out.tfevents.*"))
    assert load_checkpoint(run)["epoch"] == 1
    ev = json.loads((run / "eval.json").read_text())
    assert ev["n_test"] == 20 and ev["test_mse_px2"]["mean"] > 0 and ev["test_dtw_px"]["mean"] > 0
    assert (run / "predictions.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(run.glob("*.tmp"))
    out = json.loads(capsys.readouterr().out)
    assert out["eval"]["test_mse_px2"]["mean"] == pytest.approx(ev["test_mse_px2"]["mean"])


def test_resume_equals_uninterrupted(tmp_path: Path) -> None:
    straight = train(_tiny(tmp_path, "a", epochs=2))
    train(_tiny(tmp_path, "b", epochs=1))
    resumed = train(_tiny(tmp_path, "b", epochs=2), resume=True)
    a = load_checkpoint(Path(straight["checkpoint"]))
    b = load_checkpoint(Path(resumed["checkpoint"]))
    assert b["epoch"] == 2
    for k, v in a["model"].items():
        assert torch.equal(v, b["model"][k]), k
    with (tmp_path / "b" / "metrics.csv").open() as f:
        assert [r["epoch"] for r in csv.DictReader(f)] == ["1", "2"]


def test_nan_loss_stops_and_keeps_last_good_checkpoint(tmp_path: Path, monkeypatch) -> None:
    cfg = _tiny(tmp_path, epochs=1)
    train(cfg)
    good = load_checkpoint(tmp_path / "run")
    from ndp.il import models

    def nan_loss(self, images, demos, targets=None):
        pred = self.predict(images, demos[:, 0])
        return (pred * float("nan")).mean(), pred

    monkeypatch.setattr(models.NDPModel, "loss", nan_loss)
    with pytest.raises(
        NonFiniteLossError, match=r"loss became nan.*last good checkpoint is kept.*epoch 1"
    ):
        train(_tiny(tmp_path, epochs=3), resume=True)
    kept = load_checkpoint(tmp_path / "run")
    assert kept["epoch"] == 1
    for k, v in good["model"].items():
        assert torch.equal(v, kept["model"][k])


def test_cli_nan_loss_is_a_one_line_error(tmp_path: Path, monkeypatch, capsys) -> None:
    from ndp.il import models

    def nan_loss(self, images, demos, targets=None):
        pred = self.predict(images, demos[:, 0])
        return (pred * float("nan")).mean(), pred

    monkeypatch.setattr(models.NDPModel, "loss", nan_loss)
    rc = main(_tiny_args(tmp_path, "nan"))
    assert rc == 2
    err = capsys.readouterr().err
    assert "loss became nan" in err and err.count("\n") == 1


def test_eval_command_and_bad_runs(tmp_path: Path, capsys) -> None:
    train(_tiny(tmp_path, epochs=1))
    rc = main(["il", "eval", str(tmp_path / "run"), "--no-dtw", "--train-error",
               "--png", str(tmp_path / "grid.png"), "--n-grid", "6"])  # fmt: skip
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_test"] == 20 and out["n_train"] == 40 and "test_dtw_px" not in out
    assert (tmp_path / "grid.png").exists()
    before = (tmp_path / "grid.png").read_bytes()  # a path the user named: kept ...
    again = ["il", "eval", str(tmp_path / "run"), "--no-dtw", "--png", str(tmp_path / "grid.png"),
             "--n-grid", "3"]  # fmt: skip
    assert main(again) == 2
    assert "png: " in capsys.readouterr().err and (tmp_path / "grid.png").read_bytes() == before
    assert main([*again, "--overwrite"]) == 0  # ... unless --overwrite
    capsys.readouterr()
    assert (tmp_path / "grid.png").read_bytes() != before
    assert main(["il", "eval", str(tmp_path / "missing")]) == 2
    assert "checkpoint: no such file" in capsys.readouterr().err
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "checkpoint.pt").write_bytes(b"garbage")
    assert main(["il", "eval", str(bad)]) == 2
    assert "checkpoint: cannot read" in capsys.readouterr().err


def test_cli_bad_data_paths(tmp_path: Path, capsys) -> None:
    args = _tiny_args(tmp_path, "x")
    assert main([*args, "--data", str(tmp_path / "nope.npz")]) == 2
    assert "no such file" in capsys.readouterr().err
    corrupt = tmp_path / "corrupt.npz"
    corrupt.write_bytes(b"not an npz")
    assert main([*args, "--data", str(corrupt)]) == 2
    assert "cannot read" in capsys.readouterr().err
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, x=np.zeros((3, 40, 40)))
    assert main([*args, "--data", str(wrong)]) == 2
    assert "must contain arrays 'images'" in capsys.readouterr().err
    assert main([*args, "--data", "pendigits", "--pendigits-path", str(tmp_path / "no")]) == 2
    assert "Pendigits file not found" in capsys.readouterr().err


def test_cli_user_npz_other_length(tmp_path: Path, capsys) -> None:
    rng = np.random.default_rng(0)
    n = 30
    images = rng.random((n, 40, 40)).astype(np.float32)
    t = np.linspace(0, 1, 101)[None, :, None]
    trajs = 20 + 10 * np.concatenate([np.cos(6 * t), np.sin(6 * t)], axis=2) * rng.random((n, 1, 1))
    p = tmp_path / "mine.npz"
    np.savez(p, images=images, trajectories=trajs)
    args = [*_tiny_args(tmp_path, "npz"), "--data", str(p), "--no-dtw"]
    assert main(args) == 2
    assert "101 points, expected 301" in capsys.readouterr().err
    assert main([*args, "--resample"]) == 0
    cfg = json.loads((tmp_path / "npz" / "config.json").read_text())
    assert cfg["data"]["resample"] is True
    ev = json.loads((tmp_path / "npz" / "eval.json").read_text())
    assert ev["n_test"] == 6  # 20 % of 30 samples held out


def test_pendigits_writer_split_run(tmp_path: Path, pendigits_path: Path) -> None:
    # the first 400 real digits (several writers) keep the run short
    text = pendigits_path.read_text()
    cut = [i for i in range(len(text)) if text.startswith(".SEGMENT", i)][400]
    subset = tmp_path / "pendigits-subset"
    subset.write_text(text[:cut])
    cfg = TrainConfig(
        run_dir=str(tmp_path / "pen"),
        data=DataConfig(source="pendigits", pendigits_path=str(subset)),
        epochs=1,
        batch_size=50,
        threads=1,
        progress=False,
        max_train_batches=2,
    )
    summary = train(cfg)
    assert summary["n_test"] > 0 and summary["n_train"] + summary["n_test"] == 400
    ev = evaluate(tmp_path / "pen", dtw=False, n_grid=4)
    assert ev["n_test"] == summary["n_test"]


def test_validation_holds_out_writers_over_a_writer_disjoint_test_split(tmp_path: Path) -> None:
    """Over a writer-disjoint test split (as on Pendigits) validation holds out whole training
    writers, so selection and early stopping score unseen writers like the test does;
    'samples' keeps the earlier draw, and configs saved before the option read as what they
    ran with."""
    from ndp.il.train import load_data, make_split, validation_split

    d = load_data(DataConfig(data_dir=str(tmp_path / "data"), n_samples=80))
    writers = np.repeat(np.arange(10), [2, 4, 6, 8, 10, 10, 10, 10, 10, 10])  # unequal writers
    p = tmp_path / "ten_writers.npz"
    np.savez(p, images=d.images, trajectories=d.trajs, writers=writers)
    dcfg = DataConfig(source=str(p), split="writer")
    base = dict(data=dcfg, epochs=1, batch_size=16, threads=1, progress=False,
                max_train_batches=1, val_fraction=0.25, eval_every=0)  # fmt: skip
    by_writer = train(TrainConfig(run_dir=str(tmp_path / "w"), **base))
    by_sample = train(TrainConfig(run_dir=str(tmp_path / "s"), val_split="samples", **base))
    tr, te = make_split(load_data(dcfg), dcfg)
    assert len(np.unique(writers[tr])) == 8 and not set(writers[tr]) & set(writers[te])
    t2, va = validation_split(tr, 0.25, 0, writers)
    assert not set(writers[t2]) & set(writers[va]) and len(np.unique(writers[va])) == 2
    n_sample_val = round(0.25 * len(tr))
    assert len(va) != n_sample_val  # so the run's count tells which split it drew
    assert by_writer["n_val"] == len(va) and by_writer["n_train"] == len(t2)
    assert by_sample["n_val"] == n_sample_val
    # configs from before the option: a writer split drew samples, others are 'auto' as before
    old = TrainConfig(run_dir=str(tmp_path / "o"), **base).as_dict()
    del old["val_split"]
    assert TrainConfig.from_dict(old).val_split == "samples"
    old["data"] = dataclasses.asdict(DataConfig())
    assert TrainConfig.from_dict(old).val_split == "auto"
    with pytest.raises(ValueError, match="val_split"):
        TrainConfig(run_dir=str(tmp_path / "x"), val_split="writer")
    with pytest.raises(ValueError, match="writers"):
        validation_split(tr, 0.99, 0, writers)


def test_train_config_json_roundtrip(tmp_path: Path) -> None:
    cfg = _tiny(tmp_path, model=ModelConfig(kind="ndp", head_hidden=(16,)))
    again = TrainConfig.from_dict(json.loads(json.dumps(cfg.as_dict())))
    assert again.as_dict() == cfg.as_dict()
    with pytest.raises(ValueError, match="batch_size"):
        _tiny(tmp_path, batch_size=0)


def test_encoder_init_from_another_run(tmp_path: Path) -> None:
    first = train(_tiny(tmp_path, "pre", epochs=1))
    enc = {
        k: v
        for k, v in load_checkpoint(Path(first["checkpoint"]))["model"].items()
        if k.startswith("encoder.")
    }
    cfg = _tiny(
        tmp_path,
        "cnn",
        epochs=1,
        model=ModelConfig(kind="cnn"),
        lr=1e-12,
        encoder_init=str(tmp_path / "pre"),
    )
    second = train(cfg)
    got = load_checkpoint(Path(second["checkpoint"]))["model"]
    for k, v in enc.items():  # lr 1e-12: the copied weights are still (almost) there
        assert torch.allclose(got[k], v, atol=1e-6), k
    cfg = dataclasses.replace(
        cfg, encoder_init=str(tmp_path / "missing"), run_dir=str(tmp_path / "other")
    )
    with pytest.raises(FileNotFoundError):
        train(cfg)


def test_new_run_refuses_a_directory_holding_a_run(tmp_path: Path, capsys) -> None:
    train(_tiny(tmp_path, epochs=1))
    before = (tmp_path / "run" / "checkpoint.pt").read_bytes()
    with pytest.raises(ValueError, match=r"run_dir: .* already holds a checkpoint"):
        train(_tiny(tmp_path, epochs=1))
    assert main([*_tiny_args(tmp_path, "run")]) == 2
    assert "already holds a checkpoint" in capsys.readouterr().err
    assert (tmp_path / "run" / "checkpoint.pt").read_bytes() == before  # nothing lost


def test_cli_resume_extends_epochs_and_refuses_other_changes(tmp_path: Path, capsys) -> None:
    assert main([*_tiny_args(tmp_path, "run"), "--no-eval"]) == 0
    capsys.readouterr()
    run = str(tmp_path / "run")
    assert main(["il", "train", "--resume", run, "--lr", "0.1"]) == 2
    assert "['lr']" in capsys.readouterr().err
    assert main(["il", "train", "--resume", run, "--epochs", "2", "--no-eval"]) == 0
    capsys.readouterr()
    assert load_checkpoint(tmp_path / "run")["epoch"] == 2
    with (tmp_path / "run" / "metrics.csv").open() as f:
        assert [r["epoch"] for r in csv.DictReader(f)] == ["1", "2"]
    sessions = json.loads((tmp_path / "run" / "provenance.json").read_text())
    assert [s["event"] for s in sessions] == ["start", "resume"]
    assert all(s["commit"] and "argv" in s and "dirty" in s for s in sessions)


def test_every_il_field_is_an_option_of_ndp_il_train(capsys) -> None:
    """Every field of the IL config tree (data and model included) is reachable, except the
    data-derived pixel frame; the old spellings --data, --model and --out still work."""
    assert main(["il", "train", "--help"]) == 0
    text = capsys.readouterr().out
    renamed = {"source": "data", "kind": "model"}
    names = [
        renamed.get(f.name, f.name)
        for c in (TrainConfig, DataConfig, ModelConfig)
        for f in dataclasses.fields(c)
        if f.name not in ("data", "model", "frame")
    ]
    missing = [n for n in names if f"--{n.replace('_', '-')}" not in text]
    assert not missing
    assert "--out" in text and "--frame" not in text


def _npz_of(tmp_path: Path, n: int = 30) -> Path:
    """A user file: n samples of the synthetic set with labels and three writers."""
    from ndp.il.train import load_data

    d = load_data(DataConfig(data_dir=str(tmp_path / "data"), n_samples=60))
    p = tmp_path / "user_digits.npz"
    np.savez(p, images=d.images[:n], trajectories=d.trajs[:n], labels=d.labels[:n],
             writers=np.arange(n) % 3)  # fmt: skip
    return p


def test_eval_on_any_file_scores_every_sample_and_keeps_the_runs_record(tmp_path, capsys):
    train(_tiny(tmp_path, epochs=1))
    own = evaluate(tmp_path / "run", dtw=False)
    record = (tmp_path / "run" / "eval.json").read_text()
    f = _npz_of(tmp_path)
    capsys.readouterr()
    rc = main(["il", "eval", str(tmp_path / "run"), "--data", str(f), "--split", "all",
               "--no-dtw", "--grid", "worst", "--n-grid", "4", "--save-predictions"])  # fmt: skip
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_test"] == 30 and out["split"] == "all"
    assert out["json"].endswith("eval-user_digits-all.json") and Path(out["json"]).is_file()
    assert (tmp_path / "run" / "eval.json").read_text() == record  # untouched
    assert own["n_test"] == 20
    m = out["test_mse_px2"]
    assert m["p10"] <= m["p25"] <= m["median"] <= m["p75"] <= m["p90"] <= m["p99"] <= m["max"]
    assert sum(v["n"] for v in out["per_writer"].values()) == 30 and set(out["per_writer"]) == {
        "0",
        "1",
        "2",
    }
    assert sum(v["n"] for v in out["per_class"].values()) == 30
    z = np.load(out["predictions"])
    assert z["pred"].shape == (30, 301, 2) and z["mse_px2"].shape == (30,)
    assert np.isclose(z["mse_px2"].mean(), m["mean"])
    assert Path(out["png"]).name == "predictions-user_digits-all.png"


def test_grid_picks_and_whole_file_training(tmp_path):
    from ndp.il.metrics import pick_samples

    e = np.array([5.0, 1.0, 9.0, 3.0, 7.0])
    assert list(pick_samples(e, 2, "worst")) == [2, 4]
    assert list(pick_samples(e, 1, "median")) == [0]
    assert list(pick_samples(e, 3, "first")) == [0, 1, 2]
    assert len(set(pick_samples(e, 3, "random"))) == 3
    with pytest.raises(ValueError, match="grid"):
        pick_samples(e, 2, "best")
    f = _npz_of(tmp_path)
    data = DataConfig(source=str(f), split="all")
    summary = train(_tiny(tmp_path, "whole", data=data, epochs=1))
    assert summary["n_train"] == 30 and summary["n_test"] == 0
    row = read_rows(tmp_path / "whole")[0]
    assert row["train/mse_px2"] > 0 and np.isnan(row["test/mse_px2"])


def read_rows(run: Path):
    from ndp.runs import read_metrics

    return read_metrics(run)


def test_early_stopping_on_a_validation_split_keeps_the_best_weights(tmp_path, capsys):
    """--val-fraction holds out part of the training split; every epoch logs val/mse_px2; the
    lowest one's weights are best.pt, which the last row's test MSE and ndp il eval score;
    --patience stops the run (done.json says why), and a sweep / report count it finished."""
    import json

    from ndp.experiments.study import is_finished
    from ndp.il.train import validation_split
    from ndp.runs import load_checkpoint, read_metrics

    tr, va = validation_split(np.arange(100), 0.1, 0)
    assert len(va) == 10 and len(tr) == 90 and not set(tr) & set(va)
    assert np.array_equal(validation_split(np.arange(100), 0.1, 0)[1], va)  # seeded
    run = tmp_path / "es"
    # a learning rate this high makes validation stop improving within a few epochs
    argv = ["il", "train", "--data", "synthetic", "--n-train", "64", "--n-test", "16",
            "--model", "cnn", "--batch-size", "16", "--epochs", "40", "--lr", "0.05",
            "--val-fraction", "0.25", "--patience", "2", "--eval-every", "0",
            "--out", str(run), "--no-progress", "--no-tensorboard"]  # fmt: skip
    assert main(argv) == 0
    capsys.readouterr()
    rows = read_metrics(run)
    done = json.loads((run / "done.json").read_text())
    best = load_checkpoint(run / "best.pt")
    vals = [r["val/mse_px2"] for r in rows]
    assert done["reason"] == "early stop" and done["epoch"] == len(rows) < 40
    assert best["epoch"] == done["best_epoch"] == 1 + int(np.argmin(vals))
    assert len(rows) - best["epoch"] == 2  # patience
    assert all(np.isnan(r.get("test/mse_px2", np.nan)) for r in rows[:-1])  # test touched once
    ev = json.loads((run / "eval.json").read_text())
    assert ev["scored_epoch"] == best["epoch"]
    assert abs(ev["test_mse_px2"]["mean"] - rows[-1]["test/mse_px2"]) < 1e-3
    assert is_finished(run, kind="il")
    from ndp.runs.session import read_manifest

    m = read_manifest(run)  # the run session's manifest says the same
    assert (m.kind, m.task, m.label, m.unit, m.budget) == (
        "il",
        "synthetic-64",
        "cnn",
        "epochs",
        40,
    )
    assert m.finished and m.reason == "early stop" and m.done == len(rows)
    assert main(["il", "train", *argv[2:-6], "--patience", "2", "--out", str(tmp_path / "x"),
                 "--val-fraction", "0"]) == 2  # fmt: skip
    assert "patience: early stopping needs a validation split" in capsys.readouterr().err


def test_dmp_floor_is_zero_on_dmp_trajectories_and_falls_with_n(tmp_path, capsys):
    """ndp il floor: trajectories that are themselves rollouts of the models' DMP (N = 30) are
    fitted to ~0 px^2; on synthetic digits the floor falls as N grows."""
    from ndp.dmp import DMPLayer
    from ndp.il.config import DataConfig, ModelConfig
    from ndp.il.floor import dmp_floor

    cfg = ModelConfig().dmp_config()
    g = torch.Generator().manual_seed(0)
    n = 12
    y0 = torch.rand(n, 2, generator=g, dtype=torch.float64) * 28
    goal = torch.rand(n, 2, generator=g, dtype=torch.float64) * 28
    w = torch.randn(n, 2, cfg.n_basis, generator=g, dtype=torch.float64) * 50
    trajs = DMPLayer(cfg)(goal, w, y0).pos.numpy()
    npz = tmp_path / "dmp.npz"
    np.savez(npz, images=np.zeros((n, 28, 28), np.float32), trajectories=trajs)
    (row,) = dmp_floor(DataConfig(source=str(npz), split="all"), (30,))
    assert row["n_test"] == n and row["mse_px2"]["max"] < 1e-8
    out = tmp_path / "floor.json"
    argv = ["il", "floor", "--data", "synthetic", "--n-train", "100", "--n-test", "50",
            "--n-basis", "5", "30", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    rows = json.loads(out.read_text())["floor"]
    assert rows[0]["mse_px2"]["mean"] > 10 * rows[1]["mse_px2"]["mean"]
    assert main(argv) == 2  # an existing file is refused, not overwritten
    assert "exists" in capsys.readouterr().err
