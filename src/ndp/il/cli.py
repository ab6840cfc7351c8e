"""``ndp il train`` and ``ndp il eval``: thin command-line wiring over :mod:`ndp.il.train`."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ndp.il.models import MODEL_KINDS, ModelConfig
from ndp.il.train import DataConfig, TrainConfig, evaluate, train


def _add_data_args(p: argparse.ArgumentParser, defaults: bool) -> None:
    """Data options; without ``defaults`` every option defaults to None (= keep the run's)."""
    d = DataConfig()
    p.add_argument(
        "--data",
        default=d.source if defaults else None,
        help="'synthetic', 'pendigits', or a path to an .npz with images [n,H,W] and "
        "trajectories [n,T,2] (default: %(default)s)",
    )
    p.add_argument(
        "--data-dir",
        default=d.data_dir if defaults else None,
        help="cache folder of the synthetic set (default: %(default)s)",
    )
    p.add_argument(
        "--n-samples",
        type=int,
        default=d.n_samples if defaults else None,
        help="synthetic set size (default: %(default)s)",
    )
    p.add_argument(
        "--data-seed",
        type=int,
        default=d.data_seed if defaults else None,
        help="synthetic generator seed (default: %(default)s)",
    )
    p.add_argument(
        "--pendigits-path",
        default=d.pendigits_path if defaults else None,
        help="Pendigits UNIPEN file (default: ../shared/data/pendigits/pendigits-train)",
    )
    p.add_argument(
        "--split",
        choices=("auto", "paper", "writer"),
        default=d.split if defaults else None,
        help="paper: shuffle the first n-train + n-test samples; writer: "
        "writer-disjoint; auto: writer for Pendigits (default: %(default)s)",
    )
    p.add_argument(
        "--n-train",
        type=int,
        default=d.n_train if defaults else None,
        help="training samples of the paper split (default: %(default)s)",
    )
    p.add_argument(
        "--n-test",
        type=int,
        default=d.n_test if defaults else None,
        help="test samples of the paper split (default: %(default)s)",
    )
    p.add_argument(
        "--test-fraction",
        type=float,
        default=d.test_fraction if defaults else None,
        help="held-out fraction of writers / samples (default: %(default)s)",
    )
    p.add_argument(
        "--split-seed",
        type=int,
        default=d.split_seed if defaults else None,
        help="seed of the train/test shuffle (default: %(default)s)",
    )
    p.add_argument(
        "--resample",
        action="store_true",
        default=None,
        help="resample .npz trajectories of another length to 301 points",
    )


def _data_config(args: argparse.Namespace, base: DataConfig | None = None) -> DataConfig:
    base = base or DataConfig()
    fields = {
        "source": args.data,
        "data_dir": args.data_dir,
        "n_samples": args.n_samples,
        "data_seed": args.data_seed,
        "pendigits_path": args.pendigits_path,
        "split": args.split,
        "n_train": args.n_train,
        "n_test": args.n_test,
        "test_fraction": args.test_fraction,
        "split_seed": args.split_seed,
        "resample": args.resample,
    }
    values = {k: v for k, v in fields.items() if v is not None}
    d = DataConfig(**{**base.__dict__, **values})
    if d.source not in ("synthetic", "pendigits"):
        path = Path(d.source)
        if not path.exists():
            raise FileNotFoundError(f"data file not found: {path}")
    return d


def _cmd_train(args: argparse.Namespace) -> int:
    mdef = ModelConfig()
    model = ModelConfig(
        kind=args.model,
        n_basis=args.n_basis,
        a_z=args.a_z,
        head_hidden=tuple(args.head_hidden),
        forcing_param=args.forcing_param,
        amp_scale=args.amp_scale if args.amp_scale is not None else mdef.amp_scale,
    )
    cfg = TrainConfig(
        run_dir=args.out,
        data=_data_config(args),
        model=model,
        epochs=args.epochs,
        batch_size=args.batch_size,
        lr=args.lr,
        seed=args.seed,
        threads=args.threads,
        progress=not args.no_progress,
        eval_every=args.eval_every,
        max_train_batches=args.max_train_batches,
        encoder_init=args.encoder_init,
    )
    summary = train(cfg, resume=args.resume)
    if not args.no_eval:
        summary["eval"] = evaluate(cfg.run_dir, dtw=not args.no_dtw, threads=args.threads)
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
    data_cfg = None
    if any(
        getattr(args, k) is not None
        for k in (
            "data",
            "data_dir",
            "n_samples",
            "data_seed",
            "pendigits_path",
            "split",
            "n_train",
            "n_test",
            "test_fraction",
            "split_seed",
            "resample",
        )
    ):
        from ndp.il.train import load_checkpoint

        base = DataConfig(**load_checkpoint(Path(args.run))["config"]["data"])
        data_cfg = _data_config(args, base)
    out = evaluate(
        args.run,
        data_cfg=data_cfg,
        out_png=args.png,
        n_grid=args.n_grid,
        dtw=not args.no_dtw,
        threads=args.threads,
        include_train=args.train_error,
    )
    print(json.dumps(out, indent=2))
    return 0


def add_subparser(sub: argparse._SubParsersAction) -> None:
    """Register ``il`` with its sub-commands ``train`` and ``eval``."""
    il = sub.add_parser("il", help="imitation learning: image -> pen trajectory (digits)")
    il_sub = il.add_subparsers(dest="il_command", metavar="{train,eval}")
    il_sub.required = True

    t = il_sub.add_parser(
        "train",
        help="train NDP, CNN or CNN-DMP",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    _add_data_args(t, defaults=True)
    t.add_argument("--model", choices=MODEL_KINDS, default="ndp", help="model to train")
    t.add_argument("--epochs", type=int, default=71, help="passes over the training split")
    t.add_argument("--batch-size", type=int, default=100, help="samples per Adam step")
    t.add_argument("--lr", type=float, default=1e-3, help="Adam learning rate")
    t.add_argument("--seed", type=int, default=0, help="initialisation / batch-order seed")
    t.add_argument("--out", default="runs/il", help="run directory")
    t.add_argument("--resume", action="store_true", help="continue from <out>/checkpoint.pt")
    t.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: default)")
    t.add_argument("--n-basis", type=int, default=30, help="DMP basis functions N")
    t.add_argument("--a-z", type=float, default=25.0, help="DMP alpha_z")
    t.add_argument(
        "--head-hidden", type=int, nargs="*", default=[], help="hidden widths of the MLP head"
    )
    t.add_argument(
        "--forcing-param",
        choices=("amplitude", "weights"),
        default="amplitude",
        help="DMP head output: forcing amplitude w (g - y0) or raw weights",
    )
    t.add_argument(
        "--amp-scale",
        type=float,
        default=None,
        help="scale of the forcing-amplitude outputs (default 1000)",
    )
    t.add_argument(
        "--eval-every", type=int, default=1, help="test MSE every this many epochs (0: at the end)"
    )
    t.add_argument(
        "--max-train-batches",
        type=int,
        default=0,
        help="cap batches per epoch (0: all; smoke tests)",
    )
    t.add_argument(
        "--encoder-init",
        default="",
        help="pretraining: initialise the CNN encoder from this run's checkpoint",
    )
    t.add_argument("--no-progress", action="store_true", help="no progress bar")
    t.add_argument("--no-eval", action="store_true", help="skip the final evaluation")
    t.add_argument("--no-dtw", action="store_true", help="skip DTW in the final evaluation")
    t.set_defaults(func=_cmd_train)

    e = il_sub.add_parser(
        "eval",
        help="evaluate a run: MSE px^2 (mean +- std), DTW, PNG grid",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    e.add_argument("run", help="run directory (or checkpoint file)")
    _add_data_args(e, defaults=False)
    e.add_argument("--png", default=None, help="output picture (default <run>/predictions.png)")
    e.add_argument("--n-grid", type=int, default=24, help="test samples in the picture")
    e.add_argument("--no-dtw", action="store_true", help="skip the DTW distance")
    e.add_argument("--train-error", action="store_true", help="also the training-split error")
    e.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: default)")
    e.set_defaults(func=_cmd_eval)
