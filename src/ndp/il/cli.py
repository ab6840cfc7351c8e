"""``ndp il train`` and ``ndp il eval``: typed configs parsed by tyro (:mod:`ndp.runs.cli`).

``ndp il train`` takes one option per field of :class:`ndp.il.train.TrainConfig` (its data and
model settings included) plus ``--eval/--no-eval`` and ``--dtw/--no-dtw`` for the evaluation
after training; ``--resume RUN_DIR`` continues a run (``--epochs`` extends it).
``ndp il eval RUN`` evaluates a run's checkpoint, on its own test split or, with data options, on
another data set (options not given keep the run's values).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

from ndp.il.config import DataConfig, TrainConfig
from ndp.runs.cli import POSITIONAL

TRAIN_DESCRIPTION = (
    "Train NDP, CNN or CNN-DMP on digit images -> pen trajectories (paper protocol by default). "
    "--resume RUN_DIR continues a killed run from its checkpoint with its saved config; only "
    "--epochs (extends it), --progress, --threads, --tensorboard and --eval-every may change. "
    "A directory that holds a run is refused unless --overwrite (which names what it removes)."
)


@dataclass(frozen=True)
class TrainCommand:
    """``ndp il train``: a training run, then (by default) its evaluation."""

    config: TrainConfig = field(default_factory=TrainConfig)
    """The run."""
    eval: bool = True
    """Evaluate the final checkpoint (test MSE, DTW, predictions.png, eval.json)."""
    dtw: bool = True
    """Include the DTW distance in that evaluation (about 10 ms per test sample)."""


@dataclass(frozen=True)
class EvalCommand:
    """``ndp il eval RUN``: MSE in px^2 (mean, std, percentiles, per class and per writer), DTW
    and a picture of a run's checkpoint; on its test split, or on any data with the data options
    (``--split all`` scores every sample; results then go to RUN/eval-<tag>.json)."""

    run: Annotated[str, POSITIONAL]
    """Run directory (or its checkpoint file)."""
    data: DataConfig = field(default_factory=DataConfig)
    """Data set and split to evaluate on (default: the run's own)."""
    png: str | None = None
    """Output picture (None: RUN/predictions.png; with other data RUN/predictions-<tag>.png,
    replaced on every evaluation). A path given here is refused if it exists, unless
    --overwrite."""
    overwrite: bool = False
    """Replace an existing --png."""
    n_grid: int = 24
    """Samples drawn in the picture."""
    grid: str = "first"
    """Which samples the picture shows: 'first', 'random', 'median' (around the median error)
    or 'worst'; each panel is titled with the digit, the writer and the MSE."""
    save_predictions: bool = False
    """Also save the predictions, demonstrations, indices, labels, writers and per-sample MSE
    as RUN/predictions[-<tag>].npz."""
    dtw: bool = True
    """Compute the DTW distance."""
    train_error: bool = False
    """Also report the training split's error."""
    threads: int = 0
    """torch CPU threads (0: torch's default)."""


def _check_data_path(d: DataConfig) -> None:
    if d.source not in ("synthetic", "pendigits") and not Path(d.source).exists():
        raise FileNotFoundError(f"data: no such file {d.source}")


def train_command(argv: list[str]) -> int:
    """``ndp il train [--resume RUN_DIR] [options]``."""
    from ndp.il.config import SAFE_ON_RESUME
    from ndp.runs import load_checkpoint
    from ndp.runs.cli import changed_fields, parse_config, pop_flag, pop_option
    from ndp.runs.signals import report_stop, stop_on_sigterm

    resume_dir, rest = pop_option(argv, "--resume")
    overwrite, rest = pop_flag(rest, "--overwrite")
    if overwrite and resume_dir is not None:
        raise ValueError("--overwrite: cannot be combined with --resume (replace or continue)")
    prog = "ndp il train"
    if resume_dir is not None:
        saved = TrainConfig.from_dict(load_checkpoint(Path(resume_dir), kind="il")["config"])
        saved = dataclasses.replace(saved, run_dir=str(resume_dir))
        cmd = parse_config(
            TrainCommand,
            rest,
            prog=prog,
            description=TRAIN_DESCRIPTION,
            default=TrainCommand(config=saved),
        )
        safe = (*SAFE_ON_RESUME, "model.frame")
        refused = [f for f in changed_fields(saved, cmd.config) if f not in safe]
        if refused:
            raise ValueError(
                f"resume: these options would change the run and are refused: {refused} (only "
                f"{list(SAFE_ON_RESUME)} may change; start a new run for the others)"
            )
    else:
        cmd = parse_config(TrainCommand, rest, prog=prog, description=TRAIN_DESCRIPTION)
    cfg = cmd.config
    _check_data_path(cfg.data)
    from ndp.il.train import evaluate, train  # torch and the data loaders, once parsed

    try:
        with stop_on_sigterm():
            summary = train(cfg, resume=resume_dir is not None, overwrite=overwrite)
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (ndp.runs.signals.Terminated)
        return report_stop(exc, f"ndp il train --resume {cfg.run_dir}", cfg.run_dir)
    if cmd.eval:
        summary["eval"] = evaluate(cfg.run_dir, dtw=cmd.dtw, threads=cfg.threads)
    print(json.dumps(summary, indent=2))
    return 0


def eval_command(argv: list[str]) -> int:
    """``ndp il eval RUN [options]``: data options not given keep the run's values."""
    from ndp.runs import load_checkpoint
    from ndp.runs.cli import parse_config

    prog = "ndp il eval"
    first = parse_config(EvalCommand, argv, prog=prog)  # finds RUN (and handles --help)
    saved = DataConfig(**load_checkpoint(Path(first.run), kind="il")["config"]["data"])
    cmd = parse_config(EvalCommand, argv, prog=prog, default=EvalCommand(run=first.run, data=saved))
    _check_data_path(cmd.data)
    from ndp.il.train import evaluate

    out = evaluate(
        cmd.run,
        data_cfg=cmd.data if cmd.data != saved else None,
        out_png=cmd.png,
        overwrite=cmd.overwrite,
        n_grid=cmd.n_grid,
        dtw=cmd.dtw,
        threads=cmd.threads,
        include_train=cmd.train_error,
        grid=cmd.grid,
        save_predictions=cmd.save_predictions,
    )
    print(json.dumps(out, indent=2))
    return 0


@dataclass(frozen=True)
class FloorCommand:
    """``ndp il floor``: the DMP's floor, the test MSE (px^2) of least-squares DMP fits to every
    test trajectory of a data set and split, per number of basis functions (ndp.il.floor)."""

    data: DataConfig = field(default_factory=DataConfig)
    """Data set and split (the test part is scored)."""
    n_basis: tuple[int, ...] = (30,)
    """Numbers of basis functions N to fit with (the models' N is 30)."""
    ridge: float = 0.0
    """Ridge of the least-squares fit (0: plain least squares)."""
    out: str | None = None
    """JSON file to write (atomically; refused if it exists); None: print only."""


def floor_command(argv: list[str]) -> int:
    """``ndp il floor [options]``."""
    from ndp.runs.cli import parse_config

    cmd = parse_config(FloorCommand, argv, prog="ndp il floor")
    _check_data_path(cmd.data)
    if cmd.out is not None and Path(cmd.out).exists():
        raise FileExistsError(f"out: {cmd.out} exists; choose another file")
    from ndp.il.floor import dmp_floor
    from ndp.io import atomic_write_text

    rows = dmp_floor(cmd.data, cmd.n_basis, ridge=cmd.ridge)
    text = json.dumps({"data": dataclasses.asdict(cmd.data), "floor": rows}, indent=2)
    if cmd.out is not None:
        atomic_write_text(Path(cmd.out), text + "\n")
    print(text)
    return 0


CONFIG_COMMANDS = {"il train": train_command, "il eval": eval_command, "il floor": floor_command}
"""Commands whose options are a typed config (see ndp.cli)."""


def add_subparser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``il`` (listing only: its commands are parsed by :data:`CONFIG_COMMANDS`)."""
    il = sub.add_parser("il", help="imitation learning: image -> pen trajectory (digits)")
    il_sub = il.add_subparsers(dest="il_command", metavar="{train,eval,floor,collect,bc}")
    il_sub.required = True
    il_sub.add_parser("train", help="train NDP, CNN or CNN-DMP (ndp il train --help)")
    il_sub.add_parser("eval", help="evaluate a run: MSE px^2, DTW, PNG grid (ndp il eval --help)")
    il_sub.add_parser("floor", help="the DMP's floor: test MSE of least-squares DMP fits, per N")
    il_sub.add_parser("collect", help="record scripted-expert demonstrations of a robot task")
    il_sub.add_parser("bc", help="behaviour cloning (NDP or a plain network) on demonstrations")
