"""``ndp il collect`` and ``ndp il bc``: demonstrations and behaviour cloning on the robot tasks.

Both are typed configs parsed by tyro (:mod:`ndp.runs.cli`); their modules are imported only
once the options are parsed.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass

from ndp.bc.train import BCConfig


@dataclass(frozen=True)
class CollectConfig:
    """``ndp il collect``: record scripted-expert episodes of a task to a demonstrations file."""

    task: str = "push-v3"
    """Task (Meta-World's scripted policies for its tasks; scripts for throw, pick, point-mass)."""
    episodes: int = 25
    """Episodes to record (successful ones unless --keep-failures)."""
    out: str = "demos.npz"
    """Output file (.npz; refused if it exists, unless --overwrite)."""
    seed: int = 0
    """Reset seed of the first attempt (attempt i uses seed + i)."""
    keep_failures: bool = False
    """Also keep episodes in which the expert failed."""
    horizon: int | None = None
    """Episode length; None: the task's default."""
    overwrite: bool = False
    """Replace an existing output file."""


def collect_command(argv: list[str]) -> int:
    from pathlib import Path

    from ndp.runs.cli import parse_config

    cfg = parse_config(CollectConfig, argv, prog="ndp il collect")
    out = Path(cfg.out)
    from ndp.io import check_output_path

    # a part of the path a file, a folder, not writable; an existing file without --overwrite
    check_output_path(out, "out", overwrite=cfg.overwrite)
    from ndp.bc.demos import collect, save_demos

    demos = collect(cfg.task, cfg.episodes, cfg.seed, cfg.keep_failures, cfg.horizon)
    save_demos(demos, out)
    summary = {"out": str(out), "task": demos.task, "episodes": demos.n_episodes,
               "steps": len(demos.obs), "success": float(demos.episode_success.mean())}  # fmt: skip
    print(json.dumps(summary))
    return 0


def bc_command(argv: list[str]) -> int:
    from ndp.runs.cli import parse_config, pop_flag
    from ndp.runs.signals import report_stop, stop_on_sigterm

    overwrite, rest = pop_flag(argv, "--overwrite")
    cfg = parse_config(
        BCConfig,
        rest,
        prog="ndp il bc",
        description="Behaviour cloning of NDP or a plain network on a demonstrations file; the "
        "run directory is an RL run at update 0 (ndp rl eval / render / export work on it; "
        "ndp rl train --resume RUN --steps N fine-tunes it with PPO). A directory holding a "
        "run is refused unless --overwrite.",
    )
    from ndp.bc.train import train_bc

    try:
        with stop_on_sigterm():
            summary = train_bc(cfg, overwrite=overwrite)
    except KeyboardInterrupt as exc:
        return report_stop(exc, f"ndp il bc ... --overwrite --out {cfg.run_dir} (no resume)")
    print(json.dumps(summary, indent=2))
    return 0


CONFIG_COMMANDS = {"il collect": collect_command, "il bc": bc_command}
"""Commands whose options are a typed config (see ndp.cli)."""


def add_subparser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Nothing to add: ``ndp il`` lists ``collect`` and ``bc`` (ndp.il.cli)."""
