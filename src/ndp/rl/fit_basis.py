"""``ndp rl fit-basis``: the 'pca' chunk basis of PPO-multi, fitted to trained PPO-multi policies.

Each run's policy (``ndp.load_policy``) acts in its own chunked env for ``decisions`` decisions
(deterministic by default: the executed chunk is the mean, clipped to the action bounds; episodes
reset with seeds ``seed, seed + 1, ...``); at every decision the head's k sub-action means
[k, A] (unclipped) are recorded. The chunks of all runs, [M, k, A], give per action dimension
the top ``1 + N`` right singular vectors (``ndp.policies.chunk_basis.pca_basis``, uncentred),
saved with their provenance (runs, their commits, task, k, N, decisions, date, commit) in one
``.npz`` file that ``ndp rl train --algo ppo-multi --chunk-basis pca --chunk-basis-file FILE``
reads (and refuses where its task, k, DoF count or N disagree with the run's).
"""

from __future__ import annotations

import datetime
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from ndp.checks import check_int
from ndp.io import atomic_write_bytes, check_output_path
from ndp.policies import chunk_basis
from ndp.provenance import git_commit, installed_versions, portable_path
from ndp.rl.config import EVAL_SEED
from ndp.rl.policy import Policy, load_policy
from ndp.runs.layout import run_commits

FIT_ALGOS = ("ppo-multi",)
"""Methods whose runs ``fit-basis`` reads: PPO-multi (its chunk is the k free means)."""


def decision_means(policy: Policy, obs: np.ndarray) -> np.ndarray:
    """The head's k sub-action means [k, A] (not clipped) of one observation [O] of a head
    that reads no robot state (PPO-multi's)."""
    o = np.asarray(obs, dtype=np.float64).reshape(1, -1)
    with torch.no_grad():
        dist, _ = policy.model.distribution(torch.from_numpy(policy.obs_norm(o)))
        mean: np.ndarray = dist.mode()[0].numpy().astype(np.float64)
    return mean


def collect_chunks(
    policy: Policy, decisions: int, seed: int = EVAL_SEED, deterministic: bool = True
) -> np.ndarray:
    """Sub-action means [decisions, k, A] along the policy's own rollouts in its env.

    Episodes reset with seeds ``seed, seed + 1, ...``; the policy acts with its mode
    (``deterministic``) or samples (seeded with ``seed``).
    """
    env = policy.make_env()
    policy.reset(seed)
    out: list[np.ndarray] = []
    episode = 0
    try:
        obs, info = env.reset(seed=seed)
        while len(out) < decisions:
            out.append(decision_means(policy, obs))
            obs, _, term, trunc, info = env.step(policy.act(obs, info, deterministic))
            if term or trunc:
                episode += 1
                obs, info = env.reset(seed=seed + episode)
    finally:
        env.close()
    return np.stack(out)


def fit_basis(
    run_dirs: Sequence[str | Path],
    out: str | Path,
    decisions: int = 2000,
    n_basis: int | None = None,
    seed: int = EVAL_SEED,
    deterministic: bool = True,
    overwrite: bool = False,
) -> dict[str, object]:
    """Fit the 'pca' chunk basis to the rollouts of trained PPO-multi runs and write it.

    Args:
        run_dirs: run (or export) directories of PPO-multi policies of one task and one k.
        out: the ``.npz`` file to write.
        decisions: decisions recorded per run.
        n_basis: N (1 + N columns per DoF); None: the task's NDP preset (the NDP head's).
        seed: the first episode's reset seed.
        deterministic: act with the mean (else sample).
        overwrite: replace an existing ``out``.

    Returns:
        A summary: ``out``, ``task``, ``k``, ``action_dim``, ``columns``, ``decisions`` (in
        all) and ``explained`` (per DoF: the fraction of the chunks' sum of squares the basis
        holds).

    Raises:
        ValueError: no run, ``decisions`` < 1, a run of another method, task, k or DoF count
            than the first, or 1 + N > k.
        FileExistsError: ``out`` exists and not ``overwrite``.
    """
    if not run_dirs:
        raise ValueError("run_dirs: expected at least one PPO-multi run directory")
    check_int("decisions", decisions, 1)
    check_int("seed", seed, 0)
    out_path = check_output_path(out, "out", overwrite=overwrite)
    policies = [load_policy(r) for r in run_dirs]
    first = policies[0]
    task, k, a = _check_runs(run_dirs, policies)
    if n_basis is None:
        from ndp.envs.presets import preset_of

        n_basis = int(preset_of(first.spec).n_basis)
    check_int("n_basis", n_basis, 1)
    columns = 1 + n_basis
    chunk_basis.check_columns("pca", columns, k)
    chunks = np.concatenate([collect_chunks(p, decisions, seed, deterministic) for p in policies])
    basis, sing, explained = chunk_basis.pca_basis(chunks, columns)
    mode = "deterministic" if deterministic else "stochastic"
    provenance = _provenance(run_dirs, policies, n_basis, decisions, len(chunks), mode, seed)
    data = chunk_basis.basis_file_bytes(
        basis,
        provenance,
        singular_values=sing,
        explained=explained,
        mean=chunks.mean(axis=0).T,  # [A, k], for reference (the basis is not centred)
    )
    atomic_write_bytes(out_path, data)
    return {
        "out": str(out_path),
        "task": task,
        "k": k,
        "action_dim": a,
        "columns": columns,
        "decisions": int(chunks.shape[0]),
        "explained": [round(float(e), 6) for e in explained],
    }


def _check_runs(run_dirs: Sequence[str | Path], policies: Sequence[Policy]) -> tuple[str, int, int]:
    """``(task, k, DoF count)`` of the first run, every run checked to be a PPO-multi run of
    the same (ValueError naming the run)."""
    first = policies[0]
    task, k, a = first.cfg.task, first.cfg.k, int(first.spec.action_dim)
    for run, pol in zip(run_dirs, policies, strict=True):
        if pol.cfg.algo not in FIT_ALGOS:
            raise ValueError(
                f"run_dirs: {run} is a {pol.cfg.algo} run; expected {', '.join(FIT_ALGOS)}"
            )
        got = (pol.cfg.task, pol.cfg.k, int(pol.spec.action_dim))
        if got != (task, k, a):
            raise ValueError(
                f"run_dirs: {run} has (task, k, DoF count) {got}, the first run {(task, k, a)}"
            )
    return task, k, a


def _provenance(
    run_dirs: Sequence[str | Path],
    policies: Sequence[Policy],
    n_basis: int,
    decisions_per_run: int,
    decisions: int,
    mode: str,
    seed: int,
) -> dict[str, object]:
    """The basis file's provenance (JSON): its format, what it was fitted to and how (the
    runs: :func:`_runs_provenance`), the date, commit and installed versions."""
    first = policies[0]
    return {
        "format": chunk_basis.BASIS_FILE_FORMAT,
        "version": chunk_basis.BASIS_FILE_VERSION,
        "basis": "pca",
        "centred": False,
        "task": first.cfg.task,
        "algo": first.cfg.algo,
        "k": first.cfg.k,
        "action_dim": int(first.spec.action_dim),
        "n_basis": n_basis,
        "columns": 1 + n_basis,
        "decisions_per_run": decisions_per_run,
        "decisions": decisions,
        "mode": mode,
        "seed": seed,
        "runs": _runs_provenance(run_dirs, policies),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "commit": git_commit(),
        "versions": installed_versions(),
    }


def _runs_provenance(
    run_dirs: Sequence[str | Path], policies: Sequence[Policy]
) -> list[dict[str, object]]:
    """The basis file's record of each run it was fitted to: its path, seed, budget, chunk
    basis and commits."""
    return [
        {
            "path": portable_path(r),
            "seed": p.cfg.seed,
            "steps": p.cfg.steps,
            "chunk_basis": p.cfg.policy.chunk_basis,
            "commits": run_commits(r) or list((p.training or {}).get("commits") or []),
        }
        for r, p in zip(run_dirs, policies, strict=True)
    ]
