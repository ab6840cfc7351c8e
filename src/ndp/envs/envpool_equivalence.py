"""Equivalence of the EnvPool backend with the metaworld one, task by task.

"Same start": both backends draw the task configuration (objects, goal: metaworld's reset
vector) from the same stream. EnvPool's env of seed ``s`` draws it from ``std::mt19937(s)``;
the metaworld env is given :class:`ndp.envs.envpool_backend.StdUniform` ``(s)`` as its
``np_random``, which yields the same doubles, so both run their own reset (hand reset, object
placement, rejection loops) from the same reset vector. metaworld's ``reset`` runs the task's
``reset_model`` twice (once itself, once through gymnasium's ``MujocoEnv.reset``) and keeps the
second draw; EnvPool runs it once. The stream is therefore rewound to the reset's start before
each ``reset_model`` call, so that both of metaworld's calls draw what EnvPool's one call draws
(under ``--backend metaworld`` the first draw is simply discarded). Nothing else is copied
between them: each simulator's reset state is its own, and the comparison covers the reset
observation too.

Then both run the same fixed action sequence (``steps`` seeded uniform actions in [-1, 1]^4,
``numpy.random.default_rng(action_seed)``) and every step's observation [39], reward and
success are compared. A task matches when

- ``max |obs_envpool - obs_metaworld| <= OBS_ATOL`` over the reset and every step,
- ``max |r_envpool - r_metaworld| <= REWARD_ATOL + REWARD_RTOL * |r_metaworld|`` at every step,
- success is equal at every step.

Run ``python -m ndp.envs.envpool_equivalence --write`` to check the 50 tasks and rewrite
docs/results/envpool_equivalence/ (table, CSV, JSON with command, commit, date, versions) and
:data:`ndp.envs.envpool_tasks.ENVPOOL_DIFFERING`.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import platform
import subprocess
import sys
from pathlib import Path
from typing import Any, TypedDict

import numpy as np

from ndp.envs.envpool_backend import (
    ENVPOOL_SEED_MOD,
    EnvPoolMetaWorldEnv,
    StdUniform,
)
from ndp.envs.metaworld_env import MetaWorldEnv, metaworld_env_names

OBS_ATOL = 1e-4
"""Largest accepted observation difference (m for positions; quaternion entries likewise)."""
REWARD_ATOL = 1e-4
"""Absolute part of the accepted reward difference."""
REWARD_RTOL = 1e-4
"""Relative part of the accepted reward difference (of metaworld's reward)."""
STEPS = 150
"""Env steps compared per task (the tasks' horizon)."""
SEED = 7
"""Reset seed of both backends."""
ACTION_SEED = 20261206
"""Seed of the fixed action sequence."""
RESULTS = Path("docs/results/envpool_equivalence")
"""Where ``--write`` puts the table (relative to the repository root)."""
TASKS_MODULE = Path("src/ndp/envs/envpool_tasks.py")
"""The generated module holding :data:`ndp.envs.envpool_tasks.ENVPOOL_DIFFERING`."""


class _AlignedMetaWorld(MetaWorldEnv):
    """The metaworld path with EnvPool's reset-vector stream as its task generator."""

    stream: StdUniform

    def _task_rng(self) -> Any:
        return self.stream

    def align(self, seed: int) -> None:
        """Draw reset vectors from EnvPool's stream of ``seed``, each of metaworld's two
        ``reset_model`` calls per reset from the reset's start (module docstring)."""
        self.stream = StdUniform(seed)
        inner = self.mw.reset_model

        def reset_model() -> object:
            self.stream.rewind()
            return inner()

        self.mw.reset_model = reset_model

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        self.stream.mark()
        return super().reset(seed=seed, options=options)


def fixed_actions(steps: int, seed: int = ACTION_SEED) -> np.ndarray:
    """The action sequence both backends run: [steps, 4] float32 uniform in [-1, 1]."""
    return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(steps, 4)).astype(np.float32)


def rollouts(
    task: str, steps: int = STEPS, seed: int = SEED, action_seed: int = ACTION_SEED
) -> dict[str, np.ndarray]:
    """Both backends from the same start under the same actions.

    Returns:
        ``obs_mw``, ``obs_ep`` [steps + 1, 39] (row 0: reset), ``r_mw``, ``r_ep`` [steps],
        ``s_mw``, ``s_ep`` [steps] bool, ``pos_mw``, ``pos_ep``, ``vel_mw``, ``vel_ep``
        [steps, 4] (the robot state after each step), ``cmd_mw``, ``cmd_ep`` [steps, 4].
    """
    actions = fixed_actions(steps, action_seed)
    s = int(seed) % ENVPOOL_SEED_MOD
    mw = _AlignedMetaWorld(task, horizon=steps)
    mw.align(s)
    ep = EnvPoolMetaWorldEnv(task, horizon=steps)
    out: dict[str, list[Any]] = {key: [] for key in (
        "obs_mw", "obs_ep", "r_mw", "r_ep", "s_mw", "s_ep", "pos_mw", "pos_ep", "vel_mw",
        "vel_ep", "cmd_mw", "cmd_ep")}  # fmt: skip
    try:
        out["obs_mw"].append(mw.reset()[0])
        out["obs_ep"].append(ep.reset(seed=s)[0])
        for a in actions:
            for tag, env in (("mw", mw), ("ep", ep)):
                obs, r, _, _, info = env.step(a)
                out[f"obs_{tag}"].append(obs)
                out[f"r_{tag}"].append(r)
                out[f"s_{tag}"].append(bool(info["success"]))
                out[f"pos_{tag}"].append(info["robot_pos"])
                out[f"vel_{tag}"].append(info["robot_vel"])
                out[f"cmd_{tag}"].append(np.concatenate(env.command_state())[:4])
    finally:
        mw.close()
        ep.close()
    return {key: np.asarray(v) for key, v in out.items()}


class Verdict(TypedDict):
    """The per-task verdict of :func:`compare` (fields in its docstring)."""

    match: bool
    obs_max_diff: float
    reward_max_diff: float
    reward_excess: float
    success_mismatches: int
    success_steps_metaworld: int
    success_steps_envpool: int
    first_obs_step: int
    hand_vel_max_diff: float
    cmd_max_diff: float


class EquivalenceRow(Verdict):
    """One row of :func:`check_tasks`: the task and its verdict."""

    task: str


class EquivalenceMeta(TypedDict):
    """What :func:`write_results` records beside the rows: the command and its settings."""

    command: str
    commit: str
    date: str
    versions: dict[str, str]
    machine: str
    steps: int
    seed: int
    action_seed: int
    obs_atol: float
    reward_atol: float
    reward_rtol: float


def compare(
    run: dict[str, np.ndarray],
    obs_atol: float = OBS_ATOL,
    reward_atol: float = REWARD_ATOL,
    reward_rtol: float = REWARD_RTOL,
) -> Verdict:
    """The per-task verdict of :func:`rollouts`' arrays (pure).

    Returns:
        ``match`` (bool), ``obs_max_diff``, ``reward_max_diff`` (absolute),
        ``reward_excess`` (max of diff - tolerance; <= 0 passes), ``success_mismatches``
        (steps), ``success_steps_metaworld`` / ``_envpool``, ``first_obs_step`` (first step,
        0 = reset, whose observation is beyond tolerance; -1 if none), ``hand_vel_max_diff``
        and ``cmd_max_diff`` (robot state, reported, not part of the verdict).
    """
    d_obs = np.abs(run["obs_ep"] - run["obs_mw"]).max(axis=1)
    d_r = np.abs(run["r_ep"] - run["r_mw"])
    excess = d_r - (reward_atol + reward_rtol * np.abs(run["r_mw"]))
    s_bad = int((run["s_ep"] != run["s_mw"]).sum())
    bad = np.flatnonzero(d_obs > obs_atol)
    ok = bool(d_obs.max() <= obs_atol and excess.max() <= 0 and s_bad == 0)
    return {
        "match": ok,
        "obs_max_diff": float(d_obs.max()),
        "reward_max_diff": float(d_r.max()),
        "reward_excess": float(excess.max()),
        "success_mismatches": s_bad,
        "success_steps_metaworld": int(run["s_mw"].sum()),
        "success_steps_envpool": int(run["s_ep"].sum()),
        "first_obs_step": int(bad[0]) if bad.size else -1,
        "hand_vel_max_diff": float(np.abs(run["vel_ep"][:, :3] - run["vel_mw"][:, :3]).max()),
        "cmd_max_diff": float(np.abs(run["cmd_ep"] - run["cmd_mw"]).max()),
    }


def check_tasks(
    tasks: list[str], steps: int = STEPS, seed: int = SEED, action_seed: int = ACTION_SEED
) -> list[EquivalenceRow]:
    """:func:`compare` of :func:`rollouts` for each task, ``{"task": ..., **verdict}`` rows."""
    return [{"task": t, **compare(rollouts(t, steps, seed, action_seed))} for t in tasks]


def _versions() -> dict[str, str]:
    from importlib.metadata import version

    names = ("envpool", "metaworld", "mujoco", "gymnasium", "numpy")
    return {n: version(n) for n in names}


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def write_results(rows: list[EquivalenceRow], meta: EquivalenceMeta, root: Path) -> None:
    """Write ``equivalence.csv``, ``equivalence.json`` and ``README.md`` under
    ``root / RESULTS`` and the differing tasks into ``root / TASKS_MODULE``."""
    out = root / RESULTS
    out.mkdir(parents=True, exist_ok=True)
    keys = list(rows[0])
    with open(out / "equivalence.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    (out / "equivalence.json").write_text(json.dumps({**meta, "rows": rows}, indent=1) + "\n")
    differing = sorted(r["task"] for r in rows if not r["match"])
    n_ok = len(rows) - len(differing)
    lines = [
        "# EnvPool backend vs metaworld: per-task equivalence",
        "",
        f"Command: `{meta['command']}`  ",
        f"Commit: {meta['commit']} (the tree the check ran on)  ",
        f"Date: {meta['date']}  ",
        "Versions: " + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()) + "  ",
        f"Machine: {meta['machine']}",
        "",
        f"**{n_ok} of {len(rows)} tasks match.** Same start: both backends draw the reset vector "
        f"from `std::mt19937({meta['seed']})` (metaworld through `StdUniform`); {meta['steps']} "
        f"steps of seeded uniform actions (seed {meta['action_seed']}). Tolerances: observation "
        f"max abs diff <= {meta['obs_atol']:g}, reward |diff| <= {meta['reward_atol']:g} + "
        f"{meta['reward_rtol']:g} |r|, success equal at every step. `hand_vel_max_diff` "
        "(finite-difference vs MuJoCo body velocity, m/s) and `cmd_max_diff` (tracked mocap "
        "target) are reported, not judged.",
        "",
        "Differing (refused by `--backend envpool`): " + (", ".join(differing) or "none"),
        "",
        "| task | match | obs max diff | reward max diff | success mismatches | success steps "
        "(mw / ep) | first obs step off | hand vel max diff | cmd max diff |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['task']} | {'yes' if r['match'] else '**no**'} | {r['obs_max_diff']:.2e} | "
            f"{r['reward_max_diff']:.2e} | {r['success_mismatches']} | "
            f"{r['success_steps_metaworld']} / {r['success_steps_envpool']} | "
            f"{r['first_obs_step']} | {r['hand_vel_max_diff']:.2e} | {r['cmd_max_diff']:.2e} |"
        )
    (out / "README.md").write_text("\n".join(lines) + "\n")
    text = (root / TASKS_MODULE).read_text()
    head, _, rest = text.partition("ENVPOOL_DIFFERING")
    doc = rest[rest.index('"""') :]
    body = "".join(f'        "{t}",\n' for t in differing)  # as ruff formats it
    value = f"frozenset(\n    {{\n{body}    }}\n)" if differing else "frozenset()"
    (root / TASKS_MODULE).write_text(f"{head}ENVPOOL_DIFFERING: frozenset[str] = {value}\n{doc}")


def main(argv: list[str] | None = None) -> None:
    """``python -m ndp.envs.envpool_equivalence [--tasks ...] [--write]``."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--tasks", nargs="*", default=None, help="default: all 50 v3 tasks")
    p.add_argument("--steps", type=int, default=STEPS)
    p.add_argument("--seed", type=int, default=SEED)
    p.add_argument("--action-seed", type=int, default=ACTION_SEED)
    p.add_argument("--write", action="store_true", help="write the results and the task list")
    args = p.parse_args(argv)
    tasks = args.tasks or metaworld_env_names()
    rows = []
    for t in tasks:
        row = check_tasks([t], args.steps, args.seed, args.action_seed)[0]
        rows.append(row)
        print(json.dumps(row), flush=True)
    if args.write:
        meta: EquivalenceMeta = {
            "command": "python -m ndp.envs.envpool_equivalence " + " ".join(sys.argv[1:]),
            "commit": _commit(),
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "versions": _versions(),
            "machine": f"{platform.machine()} {platform.system()} {platform.python_version()}",
            "steps": args.steps,
            "seed": args.seed,
            "action_seed": args.action_seed,
            "obs_atol": OBS_ATOL,
            "reward_atol": REWARD_ATOL,
            "reward_rtol": REWARD_RTOL,
        }
        write_results(rows, meta, Path.cwd())


if __name__ == "__main__":
    main()
