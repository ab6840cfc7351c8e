"""Training throughput (env steps/s) of PPO, PPO-multi, NDP and Dyn-E vs raw env stepping and SB3.

In one run, per task, measured in interleaved rounds (``--repeats``, median reported), with the
supplement's PPO settings everywhere (2048 env steps per update over ``--num-envs`` envs, 32
mini-batches, 10 epochs, [100, 100] tanh, observation and return normalisation):

- ``raw-1``: the per-step env stepped with uniform random actions in a plain loop in ONE
  process (resets included): what one core can simulate;
- ``raw-N``: the same in N processes at once (N = cores, one per core, started together behind
  a barrier), summed: the practical limit of this machine;
- ``ndp`` / ``ppo`` / ``ppo-multi``: a run through the run driver (``ndp.rl.run.open_run``),
  for ``--steps`` env steps with the default vector env (``auto``: env slices in the main
  process and N - 1 workers) and,
  as ``<method>-sync``, in one process; setup (process start) excluded; the run's rollout and
  update times are reported apart (seconds per update);
- ``ppo-overlap`` / ``ppo-multi-overlap`` / ``ndp-overlap`` / ``vices-overlap`` (not in the
  default set: ``--methods``): the same runs with ``vector='overlap'``: two env groups, all
  envs in workers, one group's decision computed while the other group steps;
- ``vices`` / ``vices-sync``: ``ndp rl train --algo vices`` likewise (PPO on the torque-actuated
  variant of the task, the impedance controller at every simulator step), against
  ``raw-1-vices``: the torque-actuated env stepped in one process as ``raw-1``;
- ``dyne`` / ``dyne-sync``: Dyn-E's TD3 phase (``ndp.rl.dyne.DyneLearner``) at the original work's
  update-to-data ratio (one TD3 gradient step per env step, batch 100), acting, decoding and
  updating included; its exploration phase and the embedding's training (one iteration, a few
  hundred steps, done first) are excluded from the rate; rollout / update seconds per iteration;
- ``sb3-dummy`` / ``sb3-subproc``: stable-baselines3 PPO with ``DummyVecEnv`` and with
  ``SubprocVecEnv`` (+ ``VecNormalize``), same hyperparameters, same per-step env; the better
  of the two is ``sb3-best``;
- ``sac`` / ``sac-chunk`` / ``ndp-sac`` (not in the default set: ``--methods``): the SAC family
  (``ndp.rl.sac``) at one gradient step of batch 256 per env step, after its random steps (one
  update of random steps and buffer filling first, not timed), against ``sb3-sac``:
  stable-baselines3's SAC with the same settings on ``DummyVecEnv`` (its ``learning_starts``
  passed first, not timed); ratio ``vs_sb3-sac``.

Our runs train with the periodic deterministic evaluation off (``eval_every=0``; SB3 runs none):
at the defaults it adds ``eval_episodes * horizon`` = 1,500 single-env steps per 15,000 env steps
of training (10% more simulated steps, in the main process), which the ``ndp rl train`` wall time
includes and these rates do not.

The ceiling of an on-policy method on this machine (``ceiling``, steps/s): its update is serial
(PPO trains on the rollout it just collected, and the next rollout needs the new policy), so at
best the rollout runs at ``raw-N`` and the update adds its own time:
``2048 / (2048 / raw-N + update_s)``. ``vs_ceiling`` is the measured rate over it: the part of
the rollout's time that is not simulation (the policy call, the vector env's messages and the
bookkeeping) is what keeps a method below 1.

Ratios are against ``raw-N`` (the issue's targets: NDP and PPO-multi >= 0.6, PPO >= 0.45),
``raw-1`` and ``sb3-best`` (>= 2x). ``ndp_1M_push_minutes`` vs ``raw1_1M_minutes``: the wall
time of a 1M-step NDP run at the measured rate, against one core merely stepping 1M times.

Examples (the table of docs/rl-results.md; the SAC rows)::

    python benchmarks/rl_throughput.py --tasks reach-v3 push-v3 --steps 10240 --repeats 3 \
        --out docs/results/rl_throughput/rl_throughput
    python benchmarks/rl_throughput.py --tasks push-v3 --steps 4096 --repeats 1 \
        --methods sac-sync ndp-sac-sync sac-chunk-sync sb3-sac \
        --out docs/results/sac_throughput/sac_throughput
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import multiprocessing as mp
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ndp.experiments.provenance import git_commit

OURS = ("ppo", "ppo-multi", "ndp", "dyne")
STEPS_PER_UPDATE = 2048
"""Env steps per PPO update (the supplement's setting, ``TrainConfig``'s default)."""
SAC_FAMILY = ("sac", "sac-chunk", "ndp-sac")
"""The SAC rows (``--methods``; not in the default set: a gradient step per env step)."""
VICES = ("vices", "vices-sync", "raw-1-vices")
"""The VICES rows (``--methods``; in the default set)."""


def torque_task(task: str) -> str:
    """The torque-actuated row VICES trains on for ``task``."""
    from ndp.envs import get_task_spec, torque_variant

    return torque_variant(get_task_spec(task)).name


def _raw_loop(task: str, steps: int, num_envs: int, seed: int, backend: str = "metaworld") -> float:
    """Steps/s of a plain random-action loop over ``num_envs`` envs in this process."""
    import torch

    from ndp.rl.envs import resolve_task

    torch.set_num_threads(1)
    h = resolve_task(task, backend=backend)
    envs = [h.make() for _ in range(num_envs)]
    for i, e in enumerate(envs):
        e.reset(seed=seed + i)
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(h.spec.action_low), np.asarray(h.spec.action_high)
    acts = rng.uniform(lo, hi, size=(steps, len(lo))).astype(np.float32)
    t0 = time.perf_counter()
    for i in range(steps):
        e = envs[i % num_envs]
        _, _, term, trunc, _ = e.step(acts[i])
        if term or trunc:
            e.reset()
    w = time.perf_counter() - t0
    for e in envs:
        e.close()
    return steps / w


def _raw_worker(
    task: str, steps: int, num_envs: int, seed: int, barrier, out, backend: str = "metaworld"
) -> None:
    barrier.wait()
    out.put(_raw_loop(task, steps, num_envs, seed, backend))


def bench_raw_parallel(
    task: str, steps: int, num_envs: int, seed: int, procs: int, backend: str = "metaworld"
) -> float:
    """Summed steps/s of ``procs`` processes stepping at the same time."""
    ctx = mp.get_context("spawn")
    barrier, out = ctx.Barrier(procs), ctx.Queue()
    ps = [
        ctx.Process(
            target=_raw_worker,
            args=(task, steps, num_envs, seed + 100 * i, barrier, out, backend),
        )
        for i in range(procs)
    ]
    for p in ps:
        p.start()
    rates = [out.get() for _ in ps]
    for p in ps:
        p.join()
    return float(sum(rates))


def bench_ours(
    task: str,
    algo: str,
    steps: int,
    num_envs: int,
    seed: int,
    vector: str,
    backend: str = "metaworld",
    live: bool = False,
) -> dict[str, float]:
    """Wall steps/s of a training run, and its mean rollout / update seconds per update.

    ``backend``: the simulator (``TrainConfig.backend``); ``live``: the live reward at every
    sub-step (``stale_world=False``; EnvPool serves only that). Dyn-E: one exploration iteration
    and a short embedding fit first (not timed), then ``steps`` env steps of TD3 (timed)."""
    import dataclasses

    from ndp.rl.config import TrainConfig
    from ndp.rl.dyne.config import DyneConfig
    from ndp.rl.run import open_run
    from ndp.rl.sac.config import SACConfig
    from ndp.runs import read_metrics

    with tempfile.TemporaryDirectory() as tmp:
        cfg = TrainConfig(
            task=task,
            algo=algo,
            steps=steps,
            seed=seed,
            num_envs=num_envs,
            run_dir=str(Path(tmp) / "r"),
            progress=False,
            tensorboard=False,
            vector=vector,
            eval_every=0,  # the periodic deterministic evaluation is timed on its own: EVAL
            backend=backend,
            **({"stale_world": False} if live else {}),
        )
        if algo == "dyne":
            cfg = dataclasses.replace(
                cfg,
                steps=steps + cfg.env_steps_per_update,
                dyne=DyneConfig(explore_steps=1, embed_updates=200, decoder_updates=200),
            )
        sac = algo in SAC_FAMILY
        if sac:  # one update of random steps (the replay fills), then timed learning
            sac_cfg = SACConfig(random_steps=cfg.env_steps_per_update)
            cfg = dataclasses.replace(
                cfg, steps=steps + cfg.env_steps_per_update, eval_every=0, sac=sac_cfg
            )
        opened = open_run(cfg)
        tr = opened.learner
        try:
            skip = 1 if sac else getattr(tr, "n_explore", 0)
            if skip:
                opened.train(skip)
            g0 = tr.global_step
            w0 = time.perf_counter()
            opened.train()
            w = time.perf_counter() - w0
            rows = read_metrics(Path(tmp) / "r" / "metrics.csv")[skip:]
            return {
                "wall": (tr.global_step - g0) / w,
                "rollout_s": float(np.mean([r["time/rollout_s"] for r in rows])),
                "update_s": float(np.mean([r["time/update_s"] for r in rows])),
            }
        finally:
            opened.close()


def bench_sb3(task: str, steps: int, num_envs: int, seed: int, subproc: bool) -> float:
    import torch
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    from ndp.rl.envs import resolve_task
    from ndp.sb3.runs import make_sb3_ppo

    torch.set_num_threads(1)
    h = resolve_task(task)
    fns = [h.make for _ in range(num_envs)]
    base = SubprocVecEnv(fns, start_method="spawn") if subproc else DummyVecEnv(fns)
    venv = VecNormalize(base, gamma=0.99)
    model = make_sb3_ppo(venv, seed, num_envs)
    w0 = time.perf_counter()
    model.learn(total_timesteps=steps)
    w = time.perf_counter() - w0
    done = model.num_timesteps
    venv.close()
    return done / w


def bench_sb3_sac(task: str, steps: int, num_envs: int, seed: int) -> float:
    """Env steps/s of SB3's SAC (``ndp.sb3.runs.make_sb3_sac``) after its
    ``learning_starts`` (passed first, not timed)."""
    import torch
    from stable_baselines3.common.vec_env import DummyVecEnv

    from ndp.rl.envs import resolve_task
    from ndp.sb3.runs import make_sb3_sac

    torch.set_num_threads(1)
    h = resolve_task(task)
    venv = DummyVecEnv([h.make for _ in range(num_envs)])
    model = make_sb3_sac(venv, seed, num_envs)
    model.learn(total_timesteps=model.learning_starts + 256)
    w0 = time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    rate = steps / (time.perf_counter() - w0)
    venv.close()
    return rate


def split_method(method: str) -> tuple[str, bool, bool, bool]:
    """(base method, sync, envpool, live) of a row name ``<base>[-live][-envpool][-sync]``:
    ``-sync`` one process, ``-envpool`` the EnvPool backend (live reward implied), ``-live`` the
    live reward on the metaworld backend (the comparison row of an EnvPool one)."""
    sync = method.endswith("-sync")
    method = method.removesuffix("-sync")
    envpool = method.endswith("-envpool")
    method = method.removesuffix("-envpool")
    live = envpool or method.endswith("-live")
    return method.removesuffix("-live"), sync, envpool, live


def measure(
    method: str, task: str, steps: int, num_envs: int, seed: int, cores: int
) -> dict[str, float]:
    import torch

    torch.set_num_threads(1)
    base, sync, envpool, live = split_method(method)
    if (envpool or live) and base in ("raw-1", "raw-N", *OURS):
        backend = "envpool" if envpool else "metaworld"
        if base == "raw-1":
            return {"wall": _raw_loop(task, steps, num_envs, seed, backend)}
        if base == "raw-N":
            return {"wall": bench_raw_parallel(task, steps, num_envs, seed, cores, backend)}
        vector = "sync" if sync else "auto"
        return bench_ours(task, base, steps, num_envs, seed, vector, backend, live)
    if method == "raw-1":
        return {"wall": _raw_loop(task, steps, num_envs, seed)}
    if method == "raw-1-vices":
        return {"wall": _raw_loop(torque_task(task), steps, num_envs, seed)}
    if method == "raw-N":
        return {"wall": bench_raw_parallel(task, steps, num_envs, seed, cores)}
    if method == "sb3-sac":
        return {"wall": bench_sb3_sac(task, steps, num_envs, seed)}
    if method.startswith("sb3-"):
        return {"wall": bench_sb3(task, steps, num_envs, seed, method == "sb3-subproc")}
    if method.endswith("-sync"):
        return bench_ours(task, method.removesuffix("-sync"), steps, num_envs, seed, "sync")
    if method.endswith("-overlap"):
        return bench_ours(task, method.removesuffix("-overlap"), steps, num_envs, seed, "overlap")
    return bench_ours(task, method, steps, num_envs, seed, "auto")


def main(argv: list[str] | None = None) -> int:
    from ndp.envs.vector import default_workers

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", nargs="+", default=["reach-v3", "push-v3"])
    p.add_argument("--steps", type=int, default=10240, help="env steps per measurement")
    p.add_argument("--num-envs", type=int, default=4)
    p.add_argument("--repeats", type=int, default=3, help="interleaved rounds (median)")
    p.add_argument(
        "--methods",
        nargs="+",
        default=None,
        help="subset of: raw-1 raw-N ppo ppo-multi ndp dyne <m>-sync <m>-overlap (ppo, "
        "ppo-multi, ndp, vices) vices vices-sync "
        "raw-1-vices sb3-dummy sb3-subproc sac sac-chunk ndp-sac sb3-sac; EnvPool rows "
        "<m>-envpool[-sync] and raw-1-envpool raw-N-envpool (live reward), with their metaworld "
        "comparison <m>-live[-sync]",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None, help="write <out>.json and <out>.md")
    args = p.parse_args(argv)
    cores = default_workers(64)
    methods = args.methods or [
        "raw-1",
        "raw-N",
        *OURS,
        *(f"{m}-sync" for m in OURS),
        *VICES,
        "sb3-dummy",
        "sb3-subproc",
    ]
    samples: dict[str, dict[str, list[dict[str, float]]]] = {
        t: {m: [] for m in methods} for t in args.tasks
    }
    for r in range(args.repeats):
        for task in args.tasks:
            for m in methods:
                res = measure(m, task, args.steps, args.num_envs, args.seed, cores)
                samples[task][m].append(res)
                extra = "".join(f"  {k} {v:.3f}" for k, v in res.items() if k != "wall")
                print(f"round {r} {task:10s} {m:14s} {res['wall']:8.0f} steps/s{extra}", flush=True)
    results: dict[str, dict[str, dict[str, float]]] = {}
    for task in args.tasks:
        res = {
            m: {k: statistics.median(s[k] for s in v) for k in v[0]}
            for m, v in samples[task].items()
            if v
        }
        sb3 = [m for m in ("sb3-dummy", "sb3-subproc") if m in res]
        if sb3:
            res["sb3-best"] = dict(max((res[m] for m in sb3), key=lambda v: v["wall"]))
        for m, v in res.items():
            for base in ("raw-N", "raw-1", "sb3-best"):
                if base in res and m != base and not m.startswith("raw"):
                    v[f"vs_{base}"] = v["wall"] / res[base]["wall"]
        for m in (*SAC_FAMILY, *(f"{a}-sync" for a in SAC_FAMILY)):
            if m in res and "sb3-sac" in res:
                res[m]["vs_sb3-sac"] = res[m]["wall"] / res["sb3-sac"]["wall"]
        for m in ("vices", "vices-sync"):
            if m in res and "raw-1-vices" in res:
                res[m]["vs_raw-1-vices"] = res[m]["wall"] / res["raw-1-vices"]["wall"]
        if "raw-N" in res:
            for m, v in res.items():
                on_policy = m.removesuffix("-sync").removesuffix("-overlap")
                if "update_s" in v and on_policy in ("ppo", "ppo-multi", "ndp"):
                    v["ceiling"] = STEPS_PER_UPDATE / (
                        STEPS_PER_UPDATE / res["raw-N"]["wall"] + v["update_s"]
                    )
                    v["vs_ceiling"] = v["wall"] / v["ceiling"]
                    v["ceiling_vs_raw-N"] = v["ceiling"] / res["raw-N"]["wall"]
        if "ndp" in res and "raw-1" in res:
            res["ndp"]["minutes_1M"] = 1e6 / res["ndp"]["wall"] / 60
            res["raw-1"]["minutes_1M"] = 1e6 / res["raw-1"]["wall"] / 60
        for m, v in res.items():  # the EnvPool rows: 1M-step wall time, and against their raw
            base, _, envpool, live = split_method(m)
            if live and base in OURS:
                v["minutes_1M"] = 1e6 / v["wall"] / 60
                if envpool and "raw-N-envpool" in res:
                    v["vs_raw-N-envpool"] = v["wall"] / res["raw-N-envpool"]["wall"]
        results[task] = res
    cmd = "python benchmarks/rl_throughput.py " + " ".join(
        argv if argv is not None else sys.argv[1:]
    )
    out = {
        "tasks": args.tasks,
        "steps": args.steps,
        "num_envs": args.num_envs,
        "repeats": args.repeats,
        "cores": cores,
        "commit": git_commit(),
        "date": dt.date.today().isoformat(),
        "command": cmd,
        "results": results,
        "samples": samples,
    }
    print(json.dumps(results, indent=1))
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.with_suffix(".json").write_text(json.dumps(out, indent=1) + "\n")
        lines = [
            f"# RL training throughput ({', '.join(args.tasks)})",
            "",
            f"Command: `{cmd}`  ",
            f"Commit: {out['commit']}, date: {out['date']}; "
            f"{cores} cores, {args.num_envs} envs, {args.steps} env steps per measurement, "
            f"median of {args.repeats} interleaved round(s).",
            "",
        ]
        for task, res in results.items():
            lines += [
                f"## {task}",
                "",
                "| method | env steps/s | vs raw-N | vs raw-1 | "
                "vs SB3 best | rollout s / update | update s / update | ceiling (vs raw-N) | "
                "vs ceiling |",
                "|---|---|---|---|---|---|---|---|---|",
            ]
            for m, v in res.items():

                def f(key: str, fmt: str = "{:.2f}", v: dict = v) -> str:
                    return fmt.format(v[key]) if key in v else "-"

                lines.append(
                    f"| {m} | {v['wall']:.0f} | {f('vs_raw-N')} | {f('vs_raw-1')} | "
                    f"{f('vs_sb3-best')} | {f('rollout_s')} | {f('update_s')} | "
                    f"{f('ceiling', '{:.0f}')} ({f('ceiling_vs_raw-N')}) | {f('vs_ceiling')} |"
                )
            if "minutes_1M" in res.get("ndp", {}):
                lines += [
                    "",
                    f"1M env steps: NDP training {res['ndp']['minutes_1M']:.1f} min, "
                    f"one core only stepping the env {res['raw-1']['minutes_1M']:.1f} min.",
                ]
            timed = [(m, v) for m, v in res.items() if split_method(m)[3] and "minutes_1M" in v]
            if timed:
                lines += [
                    "",
                    "Live reward (EnvPool rows and their metaworld comparison): 1M env steps "
                    + ", ".join(f"{m} {v['minutes_1M']:.1f} min" for m, v in timed)
                    + "; against EnvPool's own raw-N: "
                    + ", ".join(
                        f"{m} {v['vs_raw-N-envpool']:.2f}"
                        for m, v in timed
                        if "vs_raw-N-envpool" in v
                    )
                    + ".",
                ]
            lines.append("")
        args.out.with_suffix(".md").write_text("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
