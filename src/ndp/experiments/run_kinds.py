"""What sweeps and reports need to know about each kind of run, in one table.

A run kind is a trainer seen from the experiment layer: how its budget is counted, which
metrics column measures progress, which command line trains it, whether it resumes, and
whether it counts only once evaluated. Sweeps, studies and reports read :data:`RUN_KINDS`
instead of branching on the strings "rl" / "il" / "sb3"; a new trainer is one row (and the
kind its :class:`ndp.runs.session.Manifest` names).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RunKind:
    """One kind of run, as the experiment layer sees it."""

    name: str
    """``"rl"`` (``ndp rl train``: PPO, NDP, PPO-multi, VICES, Dyn-E), ``"il"`` (``ndp il
    train``: digit writing) or ``"sb3"`` (the Stable-Baselines3 reference)."""
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
        ),
    )
}
"""Run kind name -> :class:`RunKind`."""

REPORT_KIND = {"rl": "rl", "il": "il", "sb3": "rl", "bc": "rl"}
"""Which table a kind's runs go to: success tables ("rl") or imitation error tables ("il").
A behaviour-cloning run is an RL run at update 0 once cloned."""


def config_class(kind: RunKind) -> type:
    """The typed config class of ``kind.prog`` (imported here)."""
    import importlib

    if not kind.config_class:
        raise ValueError(f"kind: {kind.name!r} runs take no trainer options")
    module, name = kind.config_class.split(":")
    cls: type = getattr(importlib.import_module(module), name)
    return cls


def run_kind(name: str) -> RunKind:
    """The :class:`RunKind` named ``name`` (a ValueError naming the known ones otherwise)."""
    try:
        return RUN_KINDS[name]
    except KeyError:
        raise ValueError(f"kind: expected one of {', '.join(RUN_KINDS)}, got {name!r}") from None
