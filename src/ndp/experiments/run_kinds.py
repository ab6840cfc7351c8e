"""What sweeps and reports need to know about each kind of run, in one table.

A run kind is a trainer seen from the experiment layer: how its budget is counted, which
metrics column measures progress, which command line trains it, whether it resumes, and
whether it counts only once evaluated. Sweeps, studies and reports read :data:`RUN_KINDS`
instead of branching on the strings "rl" / "il" / "sb3"; a new trainer is one row (and the
kind its :class:`ndp.runs.session.Manifest` names).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ndp.experiments.rows import CLONING_ROW, IMITATION_ROW, SUCCESS_ROW, ReportRow

if TYPE_CHECKING:
    from ndp.bc.train import BCConfig
    from ndp.experiments.study import Arm
    from ndp.il.cli import TrainCommand
    from ndp.rl.config import TrainConfig

EXTERNAL_METHODS = ("sb3-ppo", "sb3-ndp", "sb3-multi", "sb3-sac", "sb3-td3")
"""Methods an arm can name besides the trainer's registered ones (``ndp.rl.methods``): the
Stable-Baselines3 runs of :mod:`ndp.sb3.runs` (``SB3_METHODS`` there; kept here as
a literal so that ``ndp --help`` imports nothing of it)."""
SB3_EVAL_EPISODES = 20
"""Deterministic evaluation episodes a sweep's ``sb3-ndp`` / ``sb3-multi`` run ends with
(``eval-det-e20.json``: ``ndp report --eval-episodes 20`` shows it)."""
IL_METHODS = {"il-ndp": "ndp", "il-cnn": "cnn", "il-cnn-dmp": "cnn-dmp"}
"""Imitation arms (``ndp il train --model VALUE``); their "task" is a data set
(:func:`il_data_args`) and their budget is in epochs."""
IL_DATASETS = ("pendigits", "synthetic", "synthetic-N")
"""Data sets an imitation arm trains on: Pendigits with the writer-disjoint split, the synthetic
set with the paper's split (10,000 training digits), or its first N training digits."""


def il_data_args(task: str) -> list[str]:
    """The ``ndp il train`` data options of an imitation "task" (a data set, :data:`IL_DATASETS`).

    Raises:
        ValueError: not a known data set (the message names the known ones).
    """
    if task == "pendigits":
        return ["--data", "pendigits", "--split", "writer"]
    if task == "synthetic":
        return ["--data", "synthetic", "--split", "paper"]
    m = re.fullmatch(r"synthetic-([1-9][0-9]*)", task)
    if m:
        return ["--data", "synthetic", "--split", "paper", "--n-train", m.group(1)]
    raise ValueError(
        f"task: unknown imitation data set {task!r}; expected 'pendigits', 'synthetic' (all "
        "training digits) or 'synthetic-N' (the first N training digits)"
    )


# ------------------------------------------------------------------ per-kind behaviour
# Each row of RUN_KINDS names these functions; nothing else in the experiment layer branches
# on a kind's name.


def _rl_algos() -> tuple[str, ...]:
    from ndp.rl.methods import METHODS

    return tuple(METHODS)


def _start_or_resume(command: str, run: Path, start: list[str]) -> list[str]:
    """``ndp COMMAND --resume RUN`` where the run has a checkpoint, else ``ndp COMMAND START``."""
    prog = [sys.executable, "-m", "ndp.cli", *command.split()]
    if (run / "checkpoint.pt").is_file():
        return [*prog, "--resume", str(run), "--no-progress"]
    return [*prog, *start]


def _rl_command(
    task: str, arm: Arm, seed: int, steps: int, run: Path, num_envs: int, vector: str
) -> list[str]:
    start = ["--task", task, "--algo", arm.algo, "--seed", str(seed), "--steps", str(steps),
             "--num-envs", str(num_envs), "--run-dir", str(run), "--no-progress",
             "--no-tensorboard", "--vector", vector, *arm.args]  # fmt: skip
    return _start_or_resume("rl train", run, start)


def _rl_argv(task: str, arm: Arm) -> list[str]:
    return ["--task", task, "--algo", arm.algo, *arm.args]


def _rl_check(cfg: TrainConfig, task: str) -> None:
    from ndp.rl.config import resolve_config

    resolve_config(cfg)


def _rl_checkpoint_finished(run: Path) -> bool:
    from ndp.rl.config import TrainConfig
    from ndp.runs import load_checkpoint

    state = load_checkpoint(run / "checkpoint.pt", kind="rl")
    return int(state["update"]) >= TrainConfig.from_dict(state["config"]).num_updates


def _il_algos() -> tuple[str, ...]:
    return tuple(IL_METHODS)


def _il_command(
    task: str, arm: Arm, seed: int, steps: int, run: Path, num_envs: int, vector: str
) -> list[str]:
    start = [*il_data_args(task), "--model", IL_METHODS[arm.algo], "--seed", str(seed),
             "--epochs", str(steps), "--run-dir", str(run), "--no-progress", "--no-tensorboard",
             "--threads", "1", *arm.args]  # fmt: skip
    return _start_or_resume("il train", run, start)


def _il_argv(task: str, arm: Arm) -> list[str]:
    return [*il_data_args(task), "--model", IL_METHODS[arm.algo], *arm.args]


def _il_check(cfg: TrainCommand, task: str) -> None:
    if cfg.config.data.source != "pendigits":
        return
    from ndp.il.train import DEFAULT_PENDIGITS

    given = cfg.config.data.pendigits_path
    path = Path(given) if given else DEFAULT_PENDIGITS / "pendigits-train"
    if not path.is_file():
        raise ValueError(
            f"data: the Pendigits file {path} does not exist (give its path with "
            "-o pendigits_path=FILE)"
        )


def _il_checkpoint_finished(run: Path) -> bool:
    from ndp.runs import load_checkpoint

    state = load_checkpoint(run / "checkpoint.pt", kind="il")
    return int(state["epoch"]) >= int(state["config"]["epochs"])


def _sb3_algos() -> tuple[str, ...]:
    return EXTERNAL_METHODS


def _sb3_command(
    task: str, arm: Arm, seed: int, steps: int, run: Path, num_envs: int, vector: str
) -> list[str]:
    cmd = [sys.executable, "-m", "ndp.sb3.runs", "--task", task,
           "--steps", str(steps), "--seed", str(seed), "--num-envs", str(num_envs),
           "--run-dir", str(run)]  # fmt: skip
    if arm.algo != "sb3-ppo":  # the others (sb3-ppo's command is as it always was)
        cmd += ["--method", arm.algo, "--eval-episodes", str(SB3_EVAL_EPISODES)]
    return cmd


BC_METHODS = {"bc-ndp": "ndp", "bc-nn": "nn", "bc-nn-step": "nn-step"}
"""Behaviour-cloning arms (``ndp il bc --model VALUE``, run by :mod:`ndp.experiments.sweep.bc_job`);
their budget is in epochs and their demonstrations are recorded once per task and folder."""


BC_DEMOS_EPISODES = 400
"""Successful expert episodes recorded per task for a folder of cloning runs (the largest
demonstration count of the ``il-robot`` study; :mod:`ndp.experiments.sweep.bc_job`)."""


def _bc_algos() -> tuple[str, ...]:
    return tuple(BC_METHODS)


def _bc_command(
    task: str, arm: Arm, seed: int, steps: int, run: Path, num_envs: int, vector: str
) -> list[str]:
    return [sys.executable, "-m", "ndp.experiments.sweep.bc_job", "--task", task, "--",
            "--model", BC_METHODS[arm.algo], "--seed", str(seed), "--epochs", str(steps),
            "--run-dir", str(run), "--no-progress", "--no-tensorboard", "--threads", "1",
            *arm.args]  # fmt: skip


def _bc_argv(task: str, arm: Arm) -> list[str]:
    return ["--model", BC_METHODS[arm.algo], *arm.args]


def _bc_check(cfg: BCConfig, task: str) -> None:
    from ndp.bc.experts import expert_builder

    expert_builder(task)  # a task without a scripted expert has no demonstrations to clone
    if cfg.episodes and cfg.episodes > BC_DEMOS_EPISODES:
        raise ValueError(
            f"episodes: {cfg.episodes} demonstrations asked; a study records "
            f"{BC_DEMOS_EPISODES} per task"
        )


def _no_command(
    task: str, arm: Arm, seed: int, steps: int, run: Path, num_envs: int, vector: str
) -> list[str]:
    raise ValueError(f"arm {arm.label!r}: its run kind names no command")


def _no_algos() -> tuple[str, ...]:
    return ()


def _no_argv(task: str, arm: Arm) -> list[str]:
    return []


def _no_check(cfg: object, task: str) -> None:
    return None


def _never_from_checkpoint(run: Path) -> bool:
    return False


@dataclass(frozen=True)
class RunKind:
    """One kind of run, as the experiment layer sees it."""

    name: str
    """``"rl"`` (``ndp rl train``: PPO, NDP, PPO-multi, VICES, Dyn-E), ``"il"`` (``ndp il
    train``: digit writing), ``"sb3"`` (the Stable-Baselines3 reference) or ``"bc"``
    (behaviour cloning on the robot tasks, :mod:`ndp.experiments.sweep.bc_job`)."""
    unit: str
    """The budget's unit in messages and tables: ``"env steps"`` or ``"epochs"``."""
    progress_column: str
    """The metrics.csv column that counts the budget (``global_step``, ``epoch``)."""
    budget_key: str
    """The config.json key holding the budget (``steps``, ``epochs``)."""
    default_budget: int
    """A grid's budget when ``--steps`` is not given."""
    prog: str
    """The command that trains it (``ndp rl train``); empty where arms take no options."""
    takes_options: bool = True
    """Arms of this kind may add trainer options (the SB3 reference takes none)."""
    resumable: bool = True
    """A killed run continues from its checkpoint (else it restarts from scratch)."""
    needs_eval: bool = False
    """A run counts as finished only once evaluated too (imitation: eval.json)."""
    task_is_dataset: bool = False
    """Its "task" is a data set (imitation), not a robot task of ``ndp.envs``."""
    evaluable: bool = False
    """``ndp rl eval`` / ``ndp.load_policy`` act with its runs (success tables, smoothness)."""
    config_class: str = ""
    """``module:Class`` of the typed config its ``prog`` parses (empty: none)."""
    reserved: tuple[str, ...] = ()
    """Options the sweep sets itself for every run (task / data set, method, seed, budget,
    directory); an arm may not give them."""
    algos: Callable[[], Sequence[str]] = field(default=_no_algos)
    """The arm methods (``Arm.algo``) this kind trains (an arm's kind is the row that lists its
    method)."""
    command: Callable[[str, Arm, int, int, Path, int, str], list[str]] = field(default=_no_command)
    """``(task, arm, seed, budget, run dir, num_envs, vector) -> argv`` that starts the run, or
    resumes it from its checkpoint."""
    argv: Callable[[str, Arm], list[str]] = field(default=_no_argv)
    """``(task, arm) -> the arm's options`` as ``prog`` parses them (the sweep's checks)."""
    check: Callable[[Any, str], None] = field(default=_no_check)
    """``(parsed config, task)``: further checks before anything runs (a ValueError naming the
    field)."""
    metrics_file: str = ""
    """The metrics file whose ``progress_column`` counts the budget (empty: the run's
    ``metrics.csv``, :func:`ndp.runs.metrics_path`)."""
    checkpoint_finished: Callable[[Path], bool] = field(default=_never_from_checkpoint)
    """For runs written before ``run.json``: whether the checkpoint completed the budget."""
    report: ReportRow = SUCCESS_ROW
    """What one of its runs contributes to ``ndp report``: its table, numbers and CSV columns
    (:mod:`ndp.experiments.rows`)."""


RUN_KINDS: dict[str, RunKind] = {
    k.name: k
    for k in (
        RunKind(
            "rl",
            "env steps",
            "global_step",
            "steps",
            300_000,
            "ndp rl train",
            evaluable=True,
            config_class="ndp.rl.config:TrainConfig",
            algos=_rl_algos,
            command=_rl_command,
            argv=_rl_argv,
            check=_rl_check,
            checkpoint_finished=_rl_checkpoint_finished,
            reserved=(
                "--task",
                "--algo",
                "--seed",
                "--steps",
                "--run-dir",
                "--resume",
                "--overwrite",
            ),
        ),
        RunKind(
            "il",
            "epochs",
            "epoch",
            "epochs",
            71,
            "ndp il train",
            needs_eval=True,
            task_is_dataset=True,
            config_class="ndp.il.cli:TrainCommand",
            algos=_il_algos,
            command=_il_command,
            argv=_il_argv,
            check=_il_check,
            checkpoint_finished=_il_checkpoint_finished,
            report=IMITATION_ROW,
            reserved=(
                "--data",
                "--split",
                "--n-train",
                "--model",
                "--seed",
                "--epochs",
                "--run-dir",
                "--out",
                "--resume",
                "--overwrite",
            ),
        ),
        RunKind(
            "sb3",
            "env steps",
            "global_step",
            "steps",
            300_000,
            "",
            takes_options=False,
            resumable=False,
            algos=_sb3_algos,
            command=_sb3_command,
        ),
        RunKind(
            "bc",
            "epochs",
            "epoch",
            "epochs",
            100,
            "ndp il bc",
            resumable=False,
            needs_eval=True,
            evaluable=True,
            config_class="ndp.bc.train:BCConfig",
            algos=_bc_algos,
            command=_bc_command,
            argv=_bc_argv,
            check=_bc_check,
            metrics_file="bc_metrics.csv",
            report=CLONING_ROW,
            reserved=(
                "--demos",
                "--data",
                "--model",
                "--seed",
                "--epochs",
                "--run-dir",
                "--out",
                "--overwrite",
            ),
        ),
    )
}
"""Run kind name -> :class:`RunKind`."""


def config_class(kind: RunKind) -> type:
    """The typed config class of ``kind.prog`` (imported here)."""
    import importlib

    if not kind.config_class:
        raise ValueError(f"kind: {kind.name!r} runs take no trainer options")
    module, name = kind.config_class.split(":")
    cls: type = getattr(importlib.import_module(module), name)
    return cls


def kind_of_algo(algo: str) -> RunKind:
    """The run kind that trains arms of method ``algo`` (a ValueError naming the known methods
    otherwise)."""
    known: list[str] = []
    for kind in RUN_KINDS.values():
        algos = list(kind.algos())
        if algo in algos:
            return kind
        known += algos
    raise ValueError(f"algo: expected one of {', '.join(known)}, got {algo!r}")


def run_kind(name: str) -> RunKind:
    """The :class:`RunKind` named ``name`` (a ValueError naming the known ones otherwise)."""
    try:
        return RUN_KINDS[name]
    except KeyError:
        raise ValueError(f"kind: expected one of {', '.join(RUN_KINDS)}, got {name!r}") from None
