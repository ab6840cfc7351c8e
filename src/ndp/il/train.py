"""Training and evaluation of the image-to-trajectory models.

One run directory (the layout and files of :mod:`ndp.runs`, shared with RL) holds everything
of a run::

    <run_dir>/config.json          resolved TrainConfig (written at start)
    <run_dir>/provenance.json      one entry per session: time, command, commit, dirty flag
    <run_dir>/checkpoint.pt        latest good checkpoint (written atomically every epoch)
    <run_dir>/metrics.csv          one row per epoch, stable column names (see METRICS)
    <run_dir>/tb/                  TensorBoard event files (same names)
    <run_dir>/eval.json            evaluation summary (``ndp il eval``)
    <run_dir>/predictions.png      test images with predicted and demonstrated trajectories

Protocol defaults follow the paper: Adam 1e-3, batch 100, 71 epochs, the first 12,000 synthetic
samples shuffled with ``split_seed`` into 10,000 train / 2,000 test.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import json
import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ndp.checks import check_device_available
from ndp.il.config import (
    SAFE_ON_RESUME,
    SPLITS,
    DataConfig,
    ModelConfig,
    TrainConfig,
    data_task_name,
)
from ndp.il.data import (
    DigitData,
    load_npz,
    load_pendigits,
    load_synthetic,
    paper_split,
    writer_split,
)
from ndp.il.metrics import (
    GRID_PICKS,
    dtw_distance,
    grouped,
    per_sample_mse,
    pick_samples,
    save_prediction_grid,
    summarize,
)
from ndp.il.models import CNNDMPModel, TrajectoryModel, build_model
from ndp.il.synthetic import SyntheticConfig
from ndp.io import atomic_save_npz, atomic_write_text, check_output_path
from ndp.runs import MetricsLogger, save_checkpoint
from ndp.runs import load_checkpoint as _load_run_checkpoint
from ndp.runs.driver import RunPlan, run
from ndp.runs.session import LearnerDefaults, Manifest, RunSession, TrainingDivergedError

METRICS = (
    "epoch",
    "train/loss",
    "train/mse_px2",
    "test/mse_px2",
    "test/mse_px2_std",
    "val/mse_px2",
    "val/best_epoch",
    "time/epoch_s",
    "time/samples_per_s",
)
"""Columns of metrics.csv (one row per epoch; the same names in TensorBoard, x axis ``epoch``)."""
METRIC_NAMES = METRICS[1:]
"""The per-epoch metrics without the index column."""

__all__ = [
    "METRICS",
    "METRIC_NAMES",
    "SAFE_ON_RESUME",
    "SPLITS",
    "DataConfig",
    "ModelConfig",
    "NonFiniteLossError",
    "TrainConfig",
    "evaluate",
    "load_checkpoint",
    "load_data",
    "make_split",
    "predict",
    "resolved_split",
    "train",
]

DEFAULT_PENDIGITS = Path(__file__).resolve().parents[4] / "shared" / "data" / "pendigits"


class NonFiniteLossError(TrainingDivergedError, ValueError):
    """Raised when the training loss becomes NaN or Inf; the last good checkpoint is kept (the
    run session's :class:`ndp.runs.session.TrainingDivergedError`, and a ValueError as
    before)."""


# --------------------------------------------------------------------------------------------
# Data
# --------------------------------------------------------------------------------------------


def load_data(cfg: DataConfig, n_points: int = 301, progress: bool = False) -> DigitData:
    """Load the data set named by ``cfg.source``."""
    if cfg.source == "synthetic":
        syn = SyntheticConfig(n_samples=cfg.n_samples, seed=cfg.data_seed)
        data = load_synthetic(syn, cfg.data_dir, progress=progress)
    elif cfg.source == "pendigits":
        path = Path(cfg.pendigits_path) if cfg.pendigits_path else None
        if path is None:
            path = DEFAULT_PENDIGITS / "pendigits-train"
        data = load_pendigits(path, n_points=n_points)
    else:
        data = load_npz(Path(cfg.source), n_points=n_points, resample=cfg.resample)
    if data.n_points != n_points:
        raise ValueError(f"data has {data.n_points} points per trajectory, model needs {n_points}")
    return data


BEST_NAME = "best.pt"
"""The weights with the lowest validation MSE (runs with ``val_fraction`` > 0)."""
DONE_NAME = "done.json"
"""Written when a run has finished (its budget, or an early stop): epoch, reason, best epoch."""


def validation_split(
    train_idx: np.ndarray, fraction: float, seed: int, writers: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(training indices, validation indices): ``fraction`` of ``train_idx`` held out (at least
    one sample, at least one left), drawn with ``seed``; (train_idx, empty) for fraction 0.

    Args:
        train_idx: indices of the training split [n].
        fraction: the part held out.
        seed: seed of the draw.
        writers: writer id of every sample of the data set (indexed by ``train_idx``): when
            given, ``fraction`` of the training split's writers are held out with all their
            samples (at least one writer, at least one left), so validation, like a
            writer-disjoint test split, scores writers the model has not trained on.

    Raises:
        ValueError: too few training samples (or writers) to hold any out.
    """
    if fraction <= 0:
        return train_idx, train_idx[:0]
    if writers is not None:
        w = np.asarray(writers)[train_idx]
        ids = np.unique(w)
        n_ids = max(1, round(fraction * len(ids)))
        if n_ids >= len(ids):
            raise ValueError(
                f"val_fraction: {fraction} of the training split's {len(ids)} writers leaves "
                "none for training"
            )
        held = np.random.default_rng([seed, 0x5A1]).choice(ids, size=n_ids, replace=False)
        is_val = np.isin(w, held)
        return np.sort(train_idx[~is_val]), np.sort(train_idx[is_val])
    n = len(train_idx)
    n_val = max(1, round(fraction * n))
    if n_val >= n:
        raise ValueError(
            f"val_fraction: {fraction} of {n} training samples leaves none for training"
        )
    perm = np.random.default_rng([seed, 0x5A1]).permutation(n)
    return np.sort(train_idx[perm[n_val:]]), np.sort(train_idx[perm[:n_val]])


def resolved_split(data: DigitData, cfg: DataConfig) -> str:
    """``cfg.split`` with 'auto' resolved: 'writer' for Pendigits with writer ids, else
    'paper'."""
    if cfg.split != "auto":
        return cfg.split
    return "writer" if np.all(data.writers >= 0) and cfg.source == "pendigits" else "paper"


def make_split(data: DigitData, cfg: DataConfig) -> tuple[np.ndarray, np.ndarray]:
    """Train / test indices for ``data`` under ``cfg.split`` (see :class:`DataConfig`)."""
    split = resolved_split(data, cfg)
    if split == "all":  # every sample trains; no test part
        return np.arange(len(data)), np.arange(0)
    if split == "writer":
        return writer_split(data.writers, cfg.test_fraction, cfg.split_seed)
    if split != "paper":
        raise ValueError(f"split: expected one of {', '.join(SPLITS)}, got {cfg.split!r}")
    n_train, n_test = cfg.n_train, cfg.n_test
    if cfg.source not in ("synthetic",) and n_train + n_test > len(data):
        n_test = max(1, round(cfg.test_fraction * len(data)))
        n_train = len(data) - n_test
    return paper_split(len(data), n_train, n_test, cfg.split_seed)


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------


def load_checkpoint(path: Path) -> dict[str, Any]:
    """Read an imitation checkpoint (a run directory or the file), one-line errors.

    Raises:
        FileNotFoundError: no checkpoint at ``path``.
        ValueError: unreadable, or not an imitation checkpoint.
    """
    ckpt = _load_run_checkpoint(path, kind="il")
    if "model" not in ckpt or "config" not in ckpt:
        raise ValueError(f"checkpoint: {path} is not an imitation checkpoint of this package")
    return ckpt


# --------------------------------------------------------------------------------------------
# Prediction
# --------------------------------------------------------------------------------------------


@torch.no_grad()
def predict(
    model: TrajectoryModel,
    images: torch.Tensor,
    y0: torch.Tensor,
    batch_size: int = 500,
) -> torch.Tensor:
    """Predicted trajectories [n, T, 2] for images [n, H, W] and start points y0 [n, 2]."""
    model.eval()
    out = [
        model.predict(images[s : s + batch_size], y0[s : s + batch_size])
        for s in range(0, images.shape[0], batch_size)
    ]
    return torch.cat(out, dim=0)


def _set_threads(n: int) -> None:
    if n > 0:
        torch.set_num_threads(n)


# --------------------------------------------------------------------------------------------
# Training
# --------------------------------------------------------------------------------------------


class ImitationLearner(LearnerDefaults):
    """One model trained on one split, an epoch per :meth:`iterate` (an
    :class:`ndp.runs.session.Learner`; :func:`train` runs it inside the run session).

    Each epoch: a shuffled pass over the training split; the validation error (when there is a
    validation split), which keeps ``best.pt`` and counts the epochs without improvement
    (``patience``); the test error when scheduled (``eval_every``) and at the last epoch, where
    it scores the best weights when there is a validation split.

    Args:
        cfg: the run's config (its ``model.frame`` already the data set's).
        session: the run session (divergence messages, paths).
        splits: ``(x, y)`` tensors of the train, validation and test splits, on the device.
    """

    def __init__(
        self,
        cfg: TrainConfig,
        session: RunSession,
        splits: dict[str, tuple[torch.Tensor, torch.Tensor]],
        device: torch.device,
        fresh: bool,
    ) -> None:
        self.cfg, self.session = cfg, session
        (self.x_tr, self.y_tr), (self.x_va, self.y_va), (self.x_te, self.y_te) = (
            splits["train"],
            splits["val"],
            splits["test"],
        )
        self.model = build_model(cfg.model).to(device)
        self.targets = None
        if isinstance(self.model, CNNDMPModel):
            self.targets = self.model.fit_targets(self.y_tr.cpu()).to(device)
            if fresh:
                self.model.set_target_stats(self.targets)
        if cfg.encoder_init and fresh:
            load_encoder(self.model, Path(cfg.encoder_init))
        self.opt = torch.optim.Adam(self.model.parameters(), lr=cfg.lr)
        self.gen = torch.Generator().manual_seed(cfg.seed)
        self.step = 0
        self.history: list[dict[str, float]] = []
        self.early: dict[str, Any] = {"best_val": math.inf, "best_epoch": 0, "bad": 0,
                                      "stopped": False}  # fmt: skip
        self.best_path = session.run.path / BEST_NAME
        self.n_train = int(self.x_tr.shape[0])
        self.steps_per_epoch = math.ceil(self.n_train / cfg.batch_size)
        if cfg.max_train_batches > 0:
            self.steps_per_epoch = min(self.steps_per_epoch, cfg.max_train_batches)
        self.on_batch: Any = None  # progress callback (loss) per batch

    @property
    def stopped(self) -> bool:
        """Early-stopped by patience (:func:`ndp.runs.session.drive` ends the loop)."""
        return bool(self.early["stopped"])

    def state_dict(self) -> dict[str, Any]:
        """Model, optimiser, epoch, history, shuffling generator, early-stopping state."""
        return {
            "model": self.model.state_dict(),
            "optimizer": self.opt.state_dict(),
            "epoch": self.step,
            "history": self.history,
            "generator": self.gen.get_state(),
            "torch_rng": torch.get_rng_state(),  # also in the session's "rng" (older readers)
            "early": dict(self.early),
        }

    def load_state_dict(self, ckpt: dict[str, Any]) -> None:
        self.model.load_state_dict(ckpt["model"])
        self.opt.load_state_dict(ckpt["optimizer"])
        self.step = int(ckpt["epoch"])
        self.history = list(ckpt.get("history", []))
        self.gen.set_state(ckpt["generator"])
        if "rng" not in ckpt:  # checkpoints written before the run session
            torch.set_rng_state(ckpt["torch_rng"])
        self.early.update(ckpt.get("early", {}))

    def iterate(self) -> dict[str, float]:
        """One epoch; returns its metrics row (``epoch`` first).

        Raises:
            NonFiniteLossError: the loss became NaN / Inf (the last good checkpoint stays).
        """
        cfg, model, epoch = self.cfg, self.model, self.step
        model.train()
        t0 = time.perf_counter()
        device = self.x_tr.device
        perm = torch.randperm(self.n_train, generator=self.gen).to(device)
        loss_sum = mse_sum = 0.0
        seen = 0
        for step in range(self.steps_per_epoch):
            idx = perm[step * cfg.batch_size : (step + 1) * cfg.batch_size]
            xb, yb = self.x_tr[idx], self.y_tr[idx]
            loss, pred = model.loss(xb, yb, None if self.targets is None else self.targets[idx])
            if not torch.isfinite(loss):
                what = f"training loss became {loss.item()} at batch {step + 1}"
                raise NonFiniteLossError(str(self.session.diverged(what, epoch)))
            self.opt.zero_grad(set_to_none=True)
            loss.backward()  # type: ignore[no-untyped-call]  # torch: Tensor.backward is unannotated
            self.opt.step()
            b = idx.shape[0]
            loss_sum += loss.item() * b
            mse_sum += float(((pred.detach() - yb) ** 2).mean()) * b
            seen += b
            if self.on_batch is not None:
                self.on_batch(epoch + 1, loss.item())
        dt = time.perf_counter() - t0
        row: dict[str, float] = {
            "train/loss": loss_sum / seen,
            "train/mse_px2": mse_sum / seen,
            "time/epoch_s": dt,
            "time/samples_per_s": seen / dt,
        }
        early = self.early
        if self.x_va.shape[0] > 0:
            val = float(
                per_sample_mse(
                    predict(model, self.x_va, self.y_va[:, 0]).cpu(), self.y_va.cpu()
                ).mean()
            )
            row["val/mse_px2"] = val
            if val < early["best_val"]:
                early.update(best_val=val, best_epoch=epoch + 1, bad=0)
                save_checkpoint(self.best_path, {"model": model.state_dict(), "epoch": epoch + 1,
                                                 "val_mse_px2": val, "config": cfg.as_dict()},
                                kind="il")  # fmt: skip
            else:
                early["bad"] += 1
            row["val/best_epoch"] = early["best_epoch"]
            early["stopped"] = cfg.patience > 0 and early["bad"] >= cfg.patience
        last_epoch = epoch + 1 == cfg.epochs or bool(early["stopped"])
        scheduled = cfg.eval_every > 0 and (epoch + 1) % cfg.eval_every == 0
        if (scheduled or last_epoch) and self.x_te.shape[0] > 0:
            scored = model
            if last_epoch and self.x_va.shape[0] > 0:  # the test split scores the best weights
                scored = copy.deepcopy(model)
                scored.load_state_dict(load_checkpoint(self.best_path)["model"])
            err = per_sample_mse(predict(scored, self.x_te, self.y_te[:, 0]).cpu(), self.y_te.cpu())
            row["test/mse_px2"] = float(err.mean())
            row["test/mse_px2_std"] = float(err.std())
        self.step = epoch + 1
        out: dict[str, float] = {"epoch": self.step, **row}
        self.history.append(out)
        return out

    def close(self) -> None:
        pass


def il_manifest(cfg: TrainConfig, epoch: int, early_stopped: bool = False) -> Manifest:
    """The :class:`ndp.runs.session.Manifest` of an imitation run at ``epoch``."""
    finished = early_stopped or epoch >= cfg.epochs
    return Manifest(
        kind="il",
        task=data_task_name(cfg.as_dict()["data"]),
        label=cfg.model.kind,
        seed=int(cfg.seed),
        budget=int(cfg.epochs),
        unit="epochs",
        done=int(epoch),
        finished=finished,
        reason=("early stop" if early_stopped else "budget") if finished else "",
    )


def train(cfg: TrainConfig, resume: bool = False, overwrite: bool = False) -> dict[str, Any]:
    """Train a model; returns a summary (final metrics, timings, paths).

    Args:
        cfg: run settings. With ``resume`` it must equal the run's saved config outside
            :data:`SAFE_ON_RESUME` (``epochs`` extends the run), as for every trainer
            (``ndp il train --resume`` builds it from the saved one).
        resume: continue from ``<run_dir>/checkpoint.pt``.
        overwrite: remove an earlier run in ``run_dir`` first (its files are named on stderr);
            without it (and without ``resume``) such a directory is refused.

    Raises:
        NonFiniteLossError: the loss became NaN / Inf (the last good checkpoint stays).
        FileNotFoundError, ValueError: bad data paths or files; a refused resume.
    """
    check_device_available(cfg.device)  # before the run folder is made
    _set_threads(cfg.threads)  # the driver seeds, once, before the model is built
    device = torch.device(cfg.device)
    data = load_data(cfg.data, cfg.model.n_points, progress=cfg.progress)
    if cfg.model.frame != data.frame[1]:  # the data set's pixel frame (derived, not chosen)
        cfg = dataclasses.replace(
            cfg, model=dataclasses.replace(cfg.model, frame=float(data.frame[1]))
        )
    # the splits before the run folder is made: a bad split option leaves nothing behind
    tr_idx, te_idx = make_split(data, cfg.data)
    by_writer = cfg.val_split == "writers" or (
        cfg.val_split == "auto" and resolved_split(data, cfg.data) == "writer"
    )
    if by_writer and np.any(data.writers < 0):
        raise ValueError("val_split: 'writers' needs writer ids for every sample (Pendigits)")
    tr_idx, va_idx = validation_split(
        tr_idx, cfg.val_fraction, cfg.data.split_seed, data.writers if by_writer else None
    )
    x_all = torch.from_numpy(data.images)
    y_all = torch.from_numpy(data.trajs)
    splits = {
        name: (x_all[idx].to(device), y_all[idx].to(device))
        for name, idx in (("train", tr_idx), ("val", va_idx), ("test", te_idx))
    }
    return run(ImitationRecipe(cfg, splits, device), resume=resume, overwrite=overwrite)


class ImitationRecipe:
    """The run driver's recipe of an imitation run (:mod:`ndp.runs.driver`): kind ``il``,
    counted in epochs, checkpointed every epoch; ``done.json`` when it finishes (budget or
    patience); :func:`train`'s summary.

    Args:
        cfg: the run's config (its ``model.frame`` already the data set's).
        splits: ``(x, y)`` tensors of the train, validation and test splits, on ``device``.
        device: where the model trains.
    """

    def __init__(
        self,
        cfg: TrainConfig,
        splits: dict[str, tuple[torch.Tensor, torch.Tensor]],
        device: torch.device,
    ) -> None:
        self.cfg, self.splits, self.device = cfg, splits, device
        self.plan = RunPlan.of_config(
            cfg,
            cfg.as_dict(),
            cfg.epochs,
            kind="il",
            unit="epoch",
            hint="Try a lower --lr.",
            safe_on_resume=tuple(SAFE_ON_RESUME),
            threads=None,  # train() set them before the data was loaded
        )
        self.t_run = time.perf_counter()

    def check_checkpoint(self, ckpt: dict[str, Any]) -> None:
        if self.cfg.epochs < int(ckpt["epoch"]):
            raise ValueError(
                f"epochs: the run has trained {int(ckpt['epoch'])} epochs; --epochs "
                f"{self.cfg.epochs} would cut its budget below that (give at least that many, or "
                "start a new run)"
            )

    def build(self, session: RunSession, fresh: bool) -> ImitationLearner:
        return ImitationLearner(self.cfg, session, self.splits, self.device, fresh=fresh)

    def manifest(self, learner: ImitationLearner) -> Manifest:
        return il_manifest(self.cfg, learner.step, learner.stopped)

    @contextlib.contextmanager
    def log(
        self, learner: ImitationLearner, session: RunSession
    ) -> Iterator[Callable[[dict[str, float]], None]]:
        cfg, start = self.cfg, learner.step
        done_path = session.run.path / DONE_NAME
        if done_path.exists() and not learner.stopped:
            done_path.unlink()  # a run extended by --epochs is no longer finished
        logger = MetricsLogger(
            session.run.path,
            METRICS,
            step="epoch",
            tensorboard=cfg.tensorboard,
            resume_index=start if session.resumed else None,
            resume_step=start if session.resumed else None,
        )
        bar = None
        if cfg.progress:
            from tqdm import tqdm

            bar = tqdm(
                total=(cfg.epochs - start) * learner.steps_per_epoch,
                desc=f"il {cfg.model.kind}",
                unit="batch",
                dynamic_ncols=True,
            )

            def on_batch(epoch: int, loss: float) -> None:
                assert bar is not None
                bar.update(1)
                bar.set_postfix(epoch=epoch, loss=f"{loss:.3g}")

            learner.on_batch = on_batch
        self.t_run = time.perf_counter()
        try:
            yield logger.log
        finally:
            if bar is not None:
                bar.close()
            logger.close()

    def checkpoint_due(self, learner: ImitationLearner) -> bool:
        return True  # every epoch

    def summary(
        self, learner: ImitationLearner, last: dict[str, float], session: RunSession
    ) -> dict[str, Any]:
        cfg, early = self.cfg, learner.early
        row = {k: v for k, v in last.items() if k != "epoch"}
        manifest = il_manifest(cfg, learner.step, learner.stopped)
        wall = time.perf_counter() - self.t_run
        if manifest.finished:
            done = {
                "finished": True,
                "epoch": learner.step,
                "reason": manifest.reason,
                "best_epoch": early["best_epoch"] or None,
                "best_val_mse_px2": early["best_val"] if early["best_epoch"] else None,
                "train_wall_s": wall,
            }
            atomic_write_text(session.run.path / DONE_NAME, json.dumps(done, indent=1) + "\n")
        return {
            "run_dir": str(session.run.path),
            "checkpoint": str(session.run.checkpoint),
            "stopped_early": learner.stopped,
            "best_epoch": early["best_epoch"] or None,
            "epochs": cfg.epochs,
            "train_wall_s": wall,
            "final": row,
            "n_train": learner.n_train,
            "n_val": int(self.splits["val"][0].shape[0]),
            "n_test": int(learner.x_te.shape[0]),
        }


def load_encoder(model: TrajectoryModel, path: Path) -> None:
    """Copy the CNN encoder weights of another run's checkpoint into ``model``.

    Raises:
        FileNotFoundError: no checkpoint at ``path``.
        ValueError: the checkpoint has no matching encoder weights.
    """
    state = load_checkpoint(path)["model"]
    enc = {k[len("encoder.") :]: v for k, v in state.items() if k.startswith("encoder.")}
    try:
        model.encoder.load_state_dict(enc)
    except RuntimeError as exc:
        raise ValueError(f"encoder weights in {path} do not fit this model: {exc}") from exc


# --------------------------------------------------------------------------------------------
# Evaluation
# --------------------------------------------------------------------------------------------


def load_model(ckpt: dict[str, Any]) -> tuple[TrajectoryModel, TrainConfig]:
    """Rebuild the model and its TrainConfig from a checkpoint dict."""
    cfg = TrainConfig.from_dict(ckpt["config"])
    model = build_model(cfg.model)
    model.load_state_dict(ckpt["model"])
    model.eval()
    return model, cfg


def data_tag(cfg: DataConfig) -> str:
    """A file-name tag for a data set and split (``pendigits-test-all``, ``synthetic-paper``)."""
    if cfg.source == "pendigits":
        name = "pendigits" + (f"-{Path(cfg.pendigits_path).name}" if cfg.pendigits_path else "")
    elif cfg.source == "synthetic":
        name = f"synthetic-n{cfg.n_samples}-s{cfg.data_seed}"
    else:
        name = Path(cfg.source).stem
    tag = f"{name}-{cfg.split}"
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in tag)


def evaluate(
    run_dir: Path | str,
    data_cfg: DataConfig | None = None,
    out_png: Path | str | None = None,
    n_grid: int = 24,
    dtw: bool = True,
    threads: int = 0,
    include_train: bool = False,
    grid: str = "first",
    save_predictions: bool = False,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Evaluate a run's checkpoint on its test split, or on any data set.

    With the run's own data the results go to ``<run>/eval.json`` and ``predictions.png``; with
    another data set or split (``data_cfg``) to ``eval-<tag>.json`` / ``predictions-<tag>.png``
    (:func:`data_tag`), never over the run's own record. With ``split='all'`` every sample of the
    data is scored.

    Args:
        run_dir: run folder (or a checkpoint file).
        data_cfg: data / split to evaluate on; default: the run's own.
        out_png: where to draw the prediction grid (default: see above).
        n_grid: samples in the picture.
        dtw: also compute the DTW distance (about 10 ms per sample).
        threads: torch CPU threads (0: default).
        include_train: also report the error over the training split.
        grid: which samples the picture shows: 'first', 'random', 'median' or 'worst'.
        save_predictions: also write ``predictions[-<tag>].npz``: predicted and demonstrated
            trajectories, sample indices, labels, writers and per-sample MSE.
        overwrite: replace an existing ``out_png`` (default: refused, FileExistsError naming
            ``out_png``, before anything is loaded); the run's own pictures are replaced.

    Returns:
        Summary dict (also written as JSON): ``test_mse_px2`` and ``test_dtw_px`` as mean / std /
        median / max / percentiles, ``per_class`` and ``per_writer`` tables (n, mean, median,
        max), the epoch, sizes and paths.
    """
    if grid not in GRID_PICKS:
        raise ValueError(f"grid: expected one of {', '.join(GRID_PICKS)}, got {grid!r}")
    if out_png is not None:  # a path the user named: checked before any work
        check_output_path(out_png, "png", overwrite=overwrite)
    _set_threads(threads)
    path = Path(run_dir)
    ckpt = load_checkpoint(path)
    run_path = path if path.is_dir() else path.parent
    model, cfg = load_model(ckpt)
    scored_epoch = _load_best(model, path, int(ckpt["epoch"]))
    own = data_cfg is None or data_cfg == cfg.data
    dcfg = cfg.data if data_cfg is None else data_cfg
    data = load_data(dcfg, cfg.model.n_points)
    tr_idx, te_idx = make_split(data, dcfg)
    scored = tr_idx if len(te_idx) == 0 else te_idx  # 'all': every sample
    suffix = "" if own else f"-{data_tag(dcfg)}"
    out: dict[str, Any] = {
        "model": cfg.model.kind,
        "data": dcfg.source,
        "split": dcfg.split,
        "epoch": int(ckpt["epoch"]),
        "scored_epoch": scored_epoch,
    }
    train_idx = tr_idx if include_train and len(te_idx) > 0 else None
    scores, pred, mse = _score(model, data, scored, dtw, train_idx)
    out.update(scores)
    png = Path(out_png) if out_png else run_path / f"predictions{suffix}.png"
    _draw_grid(png, data, scored, pred, mse, pick_samples(mse, n_grid, grid, seed=0))
    out["png"] = str(png)
    out["grid"] = grid
    if save_predictions:
        npz = run_path / f"predictions{suffix}.npz"
        _save_predictions(npz, data, scored, pred, mse)
        out["predictions"] = str(npz)
    out["json"] = str(run_path / f"eval{suffix}.json")
    atomic_write_text(run_path / f"eval{suffix}.json", json.dumps(out, indent=2) + "\n")
    return out


def _score(
    model: TrajectoryModel,
    data: DigitData,
    scored: np.ndarray,
    dtw: bool,
    train_idx: np.ndarray | None,
) -> tuple[dict[str, object], np.ndarray, np.ndarray]:
    """Predict the ``scored`` samples: (their scores for :func:`evaluate`'s summary, the
    predictions, the per-sample MSE); the training error too where ``train_idx`` is given."""
    x = torch.from_numpy(data.images)
    y = torch.from_numpy(data.trajs)
    t0 = time.perf_counter()
    pred = predict(model, x[scored], y[scored][:, 0]).numpy()
    infer_s = time.perf_counter() - t0
    demo = data.trajs[scored]
    mse = per_sample_mse(pred, demo)
    out: dict[str, object] = {
        "n_test": len(scored),
        "test_mse_px2": summarize(mse),
        "per_class": grouped(mse, data.labels[scored]),
        "per_writer": grouped(mse, data.writers[scored]),
        "inference_s": infer_s,
    }
    if dtw:
        out["test_dtw_px"] = summarize(dtw_distance(pred, demo))
    if train_idx is not None:
        pred_tr = predict(model, x[train_idx], y[train_idx][:, 0]).numpy()
        out["n_train"] = len(train_idx)
        out["train_mse_px2"] = summarize(per_sample_mse(pred_tr, data.trajs[train_idx]))
    return out, pred, mse


def _load_best(model: TrajectoryModel, path: Path, epoch: int) -> int:
    """Load the run's best checkpoint (selected on the validation split) into ``model`` when
    ``path`` is a run folder that has one; the epoch scored (``epoch`` otherwise)."""
    if path.is_dir() and (path / BEST_NAME).is_file():
        best = load_checkpoint(path / BEST_NAME)
        model.load_state_dict(best["model"])
        return int(best["epoch"])
    return epoch


def _draw_grid(
    png: Path,
    data: DigitData,
    scored: np.ndarray,
    pred: np.ndarray,
    mse: np.ndarray,
    pick: np.ndarray,
) -> None:
    """Draw the picked scored samples (demonstration, prediction) titled label, writer, MSE."""
    demo = data.trajs[scored]
    titles = []
    for i in pick:
        w = int(data.writers[scored[i]])
        who = f" w{w}" if w >= 0 else ""
        titles.append(f"{int(data.labels[scored[i]])}{who}: {mse[i]:.2f}")
    save_prediction_grid(png, data.images[scored[pick]], demo[pick], pred[pick], titles=titles)


def _save_predictions(
    npz: Path, data: DigitData, scored: np.ndarray, pred: np.ndarray, mse: np.ndarray
) -> None:
    """Write the predicted and demonstrated trajectories of the scored samples (``.npz``)."""
    atomic_save_npz(
        npz,
        pred=pred.astype(np.float32),
        demo=data.trajs[scored].astype(np.float32),
        index=np.asarray(scored),
        labels=data.labels[scored],
        writers=data.writers[scored],
        mse_px2=mse,
    )
