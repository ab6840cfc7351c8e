"""Does our TD3's actor saturate early, and is the initialisation the cause? (td3-vs-sb3)

In the ``td3-vs-sb3`` check at 100k env steps (docs/offpolicy.md, "TD3"), two of our three
TD3 runs on push-v3 ended with every action at +-1 (the actor's tanh saturated, so its gradient
vanished) and a training return of about 1.3, below the random steps' 7-9, from the first
update after the random steps on; none of SB3's three did. The one network difference left
between the two runners is the initialisation: ours is every learner's orthogonal one
(``ndp.nets.mlp.MLP``), SB3's TD3 keeps PyTorch's ``nn.Linear`` default. This script trains
short TD3 runs with each (``--td3-init orthogonal`` / ``torch``, everything else the check's
settings) on the same seeds, and scores each final actor on fresh episodes:

* ``saturated``: the fraction of the deterministic action's entries with |a| > 0.99;
* ``return`` and ``success_any``: of the deterministic policy on the same episodes;
* ``train_return_last``: the training episodes' return in the last metrics row.

Runs go to ``--runs-dir`` (resumable: a finished run is scored again, not retrained), two
at a time, one torch thread each. Prints one JSON object: per init the runs and their means.

With ``--score RUN [RUN ...]`` it trains nothing and scores those runs' final actors the same
way (any TD3 run, e.g. the check's own; a folder without a ``config.json`` is refused); it
prints ``{RUN as given: score}``.

Examples (docs/offpolicy.md, "TD3")::

    MUJOCO_GL=egl python benchmarks/td3_saturation.py --runs-dir runs/td3_saturation \\
        --steps 20000 --seeds 0 1 2
    MUJOCO_GL=egl python benchmarks/td3_saturation.py --score \\
        runs/td3_vs_sb3_init/push-v3-td3-s0 runs/td3_vs_sb3_300k/push-v3-td3-s0
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

INITS = ("orthogonal", "torch")


def train(run: Path, init: str, seed: int, steps: int, task: str) -> None:
    """``ndp rl train --algo td3`` (the check's settings but ``--td3-init``), unless finished."""
    state = run / "run.json"
    if state.is_file() and json.loads(state.read_text()).get("finished"):
        return
    cmd = [sys.executable, "-m", "ndp.cli", "rl", "train", "--task", task, "--algo", "td3",
           "--seed", str(seed), "--steps", str(steps), "--num-envs", "4", "--vector", "sync",
           "--td3-init", init, "--no-progress", "--no-tensorboard",
           "--eval-every", "0"]  # fmt: skip
    cmd += ["--resume", str(run)] if run.is_dir() else ["--run-dir", str(run)]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)


def score(run: Path, task: str, episodes: int) -> dict[str, float]:
    """Saturation, return and success of the run's deterministic policy on fresh episodes
    (seeds from 30,000), and the last training return."""
    import ndp
    from ndp.runs import read_metrics

    policy = ndp.load_policy(run)
    env = ndp.make_env(task, k=1)
    sat, rets, succ = [], [], []
    for e in range(episodes):
        obs, info = env.reset(seed=30_000 + e)
        total, hit, done = 0.0, 0.0, False
        while not done:
            a = np.asarray(policy.act(obs, info, deterministic=True))
            sat.append(float((np.abs(a) > 0.99).mean()))
            obs, r, term, trunc, info = env.step(a)
            total += float(r)
            hit = max(hit, float(info.get("success", 0.0)))
            done = bool(term or trunc)
        rets.append(total)
        succ.append(hit)
    env.close()
    last = read_metrics(run)[-1]
    return {"saturated": float(np.mean(sat)), "return": float(np.mean(rets)),
            "success_any": float(np.mean(succ)),
            "train_return_last": float(last["charts/episode_return"])}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs-dir", help="folder of the runs (made if missing)")
    ap.add_argument("--score", nargs="+", metavar="RUN", type=Path,
                    help="train nothing: score these finished TD3 runs")  # fmt: skip
    ap.add_argument("--task", default="push-v3")
    ap.add_argument("--steps", type=int, default=20_000, help="env steps per run")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--episodes", type=int, default=5, help="fresh episodes scored per run")
    ap.add_argument("--jobs", type=int, default=2, help="trainings at once")
    args = ap.parse_args(argv)
    if args.steps < 1 or args.episodes < 1 or args.jobs < 1:
        ap.error("--steps, --episodes and --jobs: expected integers >= 1")
    if args.score:
        missing = [str(run) for run in args.score if not (run / "config.json").is_file()]
        if missing:
            ap.error(f"--score: expected run folders (with config.json), got {', '.join(missing)}")
        scores = {str(run): score(run, args.task, args.episodes) for run in args.score}
        print(json.dumps(scores, indent=1))
        return 0
    if args.runs_dir is None:
        ap.error("--runs-dir: required unless --score names runs")
    root = Path(args.runs_dir)
    root.mkdir(parents=True, exist_ok=True)
    cells = [(init, s) for s in args.seeds for init in INITS]
    runs = {c: root / f"{args.task}-td3-{c[0]}-s{c[1]}" for c in cells}
    with ThreadPoolExecutor(args.jobs) as pool:
        list(pool.map(lambda c: train(runs[c], c[0], c[1], args.steps, args.task), cells))
    out: dict[str, object] = {"task": args.task, "steps": args.steps, "seeds": args.seeds,
                              "episodes": args.episodes}  # fmt: skip
    for init in INITS:
        per = {str(s): score(runs[(init, s)], args.task, args.episodes) for s in args.seeds}
        keys = next(iter(per.values())).keys()
        mean = {k: float(np.mean([r[k] for r in per.values()])) for k in keys}
        out[init] = {"runs": per, "mean": mean}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
