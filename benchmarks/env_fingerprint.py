"""Fingerprint of the environments a study trains and evaluates in, to check that two commits'
runs saw the same tasks (e.g. the off-policy study's SAC runs and ndp-regimes' on-policy runs,
trained from different pinned worktrees).

For each task: the per-step env at a training seed (0) and at the first evaluation seed
(10,000), reset and 50 seeded random actions; and the chunked vector env (k = 5, 2 envs, seeds
0 and 1), 30 seeded random chunks. The SHA-256 of the observations (rounded to 1e-10), rewards
and success flags is printed as JSON, one per task and kind. Equal digests: the same
observations, rewards and successes step for step.

Run it from each worktree (it uses only ``ndp.rl.envs.resolve_task`` and ``make_vector_env``,
which every pinned study commit has)::

    cd ../wt/rg && PYTHONPATH=src MUJOCO_GL=egl python $REPO/benchmarks/env_fingerprint.py
"""

from __future__ import annotations

import argparse
import hashlib
import json

import numpy as np


def _update(h: hashlib._Hash, *xs: object) -> None:
    for x in xs:
        h.update(np.asarray(x, dtype=np.float64).round(10).tobytes())


def fingerprint(task: str, steps: int = 50, chunks: int = 30) -> dict[str, str]:
    """{'per-step': digest, 'chunked-k5': digest} of ``task`` (see the module doc)."""
    from ndp.rl import envs as rl_envs

    t = rl_envs.resolve_task(task)
    h = hashlib.sha256()
    for seed in (0, 10_000):
        env = t.make(seed=seed)
        obs, _ = env.reset(seed=seed)
        _update(h, obs)
        rng = np.random.default_rng(seed)
        for _ in range(steps):
            obs, r, _, _, info = env.step(rng.uniform(-1, 1, size=env.action_space.shape))
            _update(h, obs, r, float(info.get("success", 0.0)))
        env.close()
    out = {"per-step": h.hexdigest()}
    h = hashlib.sha256()
    venv = rl_envs.make_vector_env(t, 5, 2)
    obs, _ = venv.reset(seed=[0, 1])
    _update(h, obs)
    rng = np.random.default_rng(0)
    for _ in range(chunks):
        obs, r, _, _, _ = venv.step(rng.uniform(-1, 1, size=venv.action_space.shape))
        _update(h, obs, r)
    venv.close()
    out["chunked-k5"] = h.hexdigest()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="+", default=["push-v3", "throw"])
    args = ap.parse_args()
    print(json.dumps({t: fingerprint(t) for t in args.tasks}, indent=1))


if __name__ == "__main__":
    main()
