"""Cost (ms) of one SAC gradient step and of its parts, variants interleaved in one process.

Two parts:

* **The parts** (as before): the twin critics' gradient step with the learner's fused Adam
  against the default per-tensor loop, and the soft target update (one ``foreach`` lerp
  against a per-parameter loop), on the learner's critics (256-256 ReLU) at push-v3's sizes
  (observation 39, action 4), batch 256.
* **The whole step** (``--full``, issue 63 "speed, part 3"): ``SACLearner.gradient_step`` of a
  real learner (``ndp.rl.run.open_run``, ``--algo sac`` on push-v3, batch 256, 256-256 ReLU)
  on replay batches of random rows, with the plain critics (:class:`TwinQ`, two MLP passes)
  against the batched ones (:class:`BatchedTwinQ`, one ``baddbmm`` per layer for both), with
  1 against 2 torch threads, and (``--compile``) with the critics under ``torch.compile``
  (the compile time and the largest difference from the eager step are printed). Each
  variant keeps its own copy of the learner's networks and optimisers, starting equal.
  It also prints the **arithmetic floor**: the step's matrix-product FLOPs (counted by
  ``torch.utils.flop_counter``) at the rate this core reaches on a 256x256x256 product.

The variants alternate call by call (``--rounds`` x ``--steps`` timed calls each); per
variant the median and the minimum ms per call are kept, and ratios are variant / plain of
each (the medians are the robust ones under load). Under load (other processes on the
cores) only the ratios mean something.

Example (docs/results/sac_throughput/sac_step.md)::

    python benchmarks/sac_step.py --full --compile --steps 50 --rounds 7
"""

from __future__ import annotations

import argparse
import copy
import json
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ndp.experiments.provenance import git_commit
from ndp.rl.offpolicy.critics import BatchedTwinQ, TwinQ
from ndp.rl.optim import soft_update


def _time(
    variants: dict[str, Callable[[], None]],
    steps: int,
    rounds: int,
    few: dict[str, int] | None = None,
) -> dict[str, list[float]]:
    """The ms of every call of each variant: after 3 warm-up calls each, ``rounds`` x
    ``steps`` calls, the variants alternating call by call (so that a change of the machine's
    load falls on all of them alike); ``few``: variants called only on the first n steps of
    each round (name -> n)."""
    out: dict[str, list[float]] = {name: [] for name in variants}
    for fn in variants.values():
        for _ in range(3):
            fn()
    for _ in range(rounds):
        for step in range(steps):
            for name, fn in variants.items():
                if step >= (few or {}).get(name, steps):
                    continue
                t0 = time.perf_counter()
                fn()
                out[name].append((time.perf_counter() - t0) * 1e3)
    return out


def _summary(times: dict[str, list[float]], base: str) -> dict[str, dict[str, float]]:
    """Per variant the median and minimum ms, and their ratios to ``base``'s."""
    med = {k: statistics.median(v) for k, v in times.items()}
    low = {k: min(v) for k, v in times.items()}
    return {
        "ms_median": {k: round(v, 4) for k, v in med.items()},
        "ms_min": {k: round(v, 4) for k, v in low.items()},
        "ratio_median": {k: round(v / med[base], 3) for k, v in med.items()},
        "ratio_min": {k: round(v / low[base], 3) for k, v in low.items()},
    }


def parts(steps: int, rounds: int, batch: int) -> dict[str, Any]:
    """The critics' Adam (fused vs default) and the soft update (foreach vs loop)."""
    torch.manual_seed(0)
    obs_dim, act_dim = 39, 4
    critic = TwinQ(obs_dim, act_dim, (256, 256), "relu")
    target = copy.deepcopy(critic).requires_grad_(False)
    obs, act = torch.randn(batch, obs_dim), torch.randn(batch, act_dim)
    y = torch.randn(batch)

    def critic_step(opt: torch.optim.Optimizer) -> None:
        q1, q2 = critic(obs, act)
        loss = 0.5 * (((q1 - y) ** 2).mean() + ((q2 - y) ** 2).mean())
        opt.zero_grad(set_to_none=True)
        loss.backward()  # type: ignore[no-untyped-call]
        opt.step()

    def soft_loop() -> None:
        with torch.no_grad():
            for t, s in zip(target.parameters(), critic.parameters(), strict=True):
                t.lerp_(s, 0.005)

    default = torch.optim.Adam(critic.parameters(), lr=3e-4)
    fused = torch.optim.Adam(critic.parameters(), lr=3e-4, fused=True)
    variants: dict[str, Callable[[], None]] = {
        "critic_step_adam_default": lambda: critic_step(default),
        "critic_step_adam_fused": lambda: critic_step(fused),
        "soft_update_loop": soft_loop,
        "soft_update_foreach": lambda: soft_update(target, critic, 0.005),
    }
    times = _time(variants, steps, rounds)
    med = {k: statistics.median(v) for k, v in times.items()}
    return {
        "ms_median": {k: round(v, 4) for k, v in med.items()},
        "fused_vs_default": round(
            med["critic_step_adam_fused"] / med["critic_step_adam_default"], 3
        ),
        "foreach_vs_loop": round(med["soft_update_foreach"] / med["soft_update_loop"], 3),
    }


GEMM_N = 256
"""The square product whose rate sets the floor (n x n x n, float32, one thread)."""


def _gemm() -> Callable[[], None]:
    """Ten GEMM_N-cubed products (timed beside the steps: GFLOP/s = 20 n^3 / time)."""
    a, b = torch.randn(GEMM_N, GEMM_N), torch.randn(GEMM_N, GEMM_N)
    out = torch.empty(GEMM_N, GEMM_N)

    def run() -> None:
        for _ in range(10):
            torch.mm(a, b, out=out)

    return run


class _State:
    """One variant's copy of the learner's trainable state (swapped in before its steps)."""

    NAMES = ("model", "critic", "critic_target", "log_alpha", "actor_opt", "critic_opt",
             "alpha_opt", "_critic_params")  # fmt: skip

    def __init__(self, learner: Any, critic: str) -> None:
        s = learner.settings
        self.model = copy.deepcopy(learner.model)
        base = copy.deepcopy(learner.critic)
        self.critic = BatchedTwinQ.from_twin(base) if critic == "batched" else base
        if critic == "compiled":
            self.critic = torch.compile(base)
        self.critic_target = copy.deepcopy(self.critic if critic != "compiled" else base)
        self.critic_target.requires_grad_(False)
        if critic == "compiled":
            self.critic_target = torch.compile(self.critic_target)
        self.log_alpha = learner.log_alpha.detach().clone().requires_grad_(True)
        self.actor_opt = torch.optim.Adam(self.model.actor.parameters(), lr=s.lr, fused=True)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=s.lr, fused=True)
        self.alpha_opt = torch.optim.Adam([self.log_alpha], lr=s.lr)
        self._critic_params = list(self.critic.parameters())

    def enter(self, learner: Any) -> None:
        for name in self.NAMES:
            setattr(learner, name, getattr(self, name))


def _open_learner(tmp: Path, batch: int) -> Any:
    from ndp.rl.config import TrainConfig
    from ndp.rl.run import open_run
    from ndp.rl.sac.config import SACConfig

    sac = SACConfig(random_steps=0, batch_size=batch, buffer_size=10_000)
    cfg = TrainConfig(task="push-v3", algo="sac", steps=2_000, seed=0, run_dir=str(tmp / "sac"),
                      progress=False, tensorboard=False, vector="sync", num_envs=1,
                      steps_per_update=1_000, sac=sac, eval_every=0)  # fmt: skip
    return open_run(cfg)


def _fill(learner: Any, rows: int, rng: np.random.Generator) -> None:
    """``rows`` random decisions in the learner's replay (discount in [0, 0.99])."""
    cols = {}
    for name, slc in learner.replay._slices.items():
        cols[name] = rng.standard_normal((rows, slc.stop - slc.start)).astype(np.float32)
    cols["discount"] = rng.uniform(0.0, 0.99, size=(rows, 1)).astype(np.float32)
    cols["u"] = np.clip(cols["u"], -3.0, 3.0)
    learner.replay.add(**cols)


def _step_flops(learner: Any, b: dict[str, torch.Tensor]) -> int:
    """Matrix-product FLOPs of one ``gradient_step`` (mm, addmm, bmm, baddbmm; forward and
    backward)."""
    from torch.utils.flop_counter import FlopCounterMode

    with FlopCounterMode(display=False) as fc:
        learner.gradient_step(b)
    return int(fc.get_total_flops())


def _max_diff(learner: Any, a: _State, b: _State, batch: dict[str, torch.Tensor]) -> float:
    """Largest difference of the losses and of every parameter after one step of variant
    ``a`` against ``b`` from the same state and the same seed."""
    diffs = []
    losses = []
    for st in (a, b):
        fresh = copy.deepcopy(st)  # from the same state: copy both variants' states
        fresh.enter(learner)
        torch.manual_seed(1)
        losses.append(learner.gradient_step(batch))
    for k in losses[0]:
        diffs.append(abs(losses[0][k] - losses[1][k]))
    return max(diffs)


def full(
    steps: int, rounds: int, batch: int, compile_critic: bool, thread_steps: int
) -> dict[str, Any]:
    """``SACLearner.gradient_step``: plain vs batched critics, 1 vs 2 threads, compiled."""
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        opened = _open_learner(Path(tmp), batch)
        try:
            learner = opened.learner
            rng = np.random.default_rng(0)
            _fill(learner, 10 * batch, rng)
            batches = [learner.replay.sample(batch, rng) for _ in range(8)]
            torch.manual_seed(0)
            flops = _step_flops(learner, batches[0])
            kinds = ("plain", "batched", "compiled") if compile_critic else ("plain", "batched")
            states = {kind: _State(learner, kind) for kind in kinds}  # the same weights
            out: dict[str, Any] = {"step_matmul_gflop": round(flops / 1e9, 4)}
            # equality: the same step (same seed, same batch) on both critics
            out["batched_vs_plain_max_loss_diff"] = _max_diff(
                learner, states["plain"], states["batched"], batches[0]
            )
            if compile_critic:
                copy.deepcopy(states["plain"]).enter(learner)
                torch.manual_seed(1)
                ref = learner.gradient_step(batches[0])
                states["compiled"].enter(learner)
                torch.manual_seed(1)
                t0 = time.perf_counter()
                got = learner.gradient_step(batches[0])  # compiles here
                for _ in range(2):  # any recompilation
                    learner.gradient_step(batches[0])
                out["compile_s"] = round(time.perf_counter() - t0, 1)
                out["compiled_vs_plain_max_loss_diff"] = max(abs(ref[k] - got[k]) for k in ref)
            i = [0]

            def step(name: str, threads: int = 1) -> Callable[[], None]:
                def run() -> None:
                    states[name].enter(learner)
                    torch.set_num_threads(threads)
                    learner.gradient_step(batches[i[0] % len(batches)])
                    torch.set_num_threads(1)
                    i[0] += 1

                return run

            variants = {"plain": step("plain"), "batched": step("batched"),
                        "plain_2_threads": step("plain", 2), "gemm_x10": _gemm()}  # fmt: skip
            if compile_critic:
                variants["compiled"] = step("compiled")
            times = _time(variants, steps, rounds, {"plain_2_threads": thread_steps})
        finally:
            opened.close()
    gemm_ms = times.pop("gemm_x10")
    # GFLOP/s of the product at its median and at its best call
    rate = {q: 10 * 2 * GEMM_N**3 / (f(gemm_ms) * 1e-3) / 1e9
            for q, f in (("median", statistics.median), ("min", min))}  # fmt: skip
    summary = _summary(times, "plain")
    out.update(summary)
    out["gemm_256_gflops"] = {q: round(r, 1) for q, r in rate.items()}
    floor = {q: flops / (r * 1e9) * 1e3 for q, r in rate.items()}
    out["floor_ms"] = {q: round(f, 3) for q, f in floor.items()}
    out["vs_floor"] = {
        f"{k}_{q}": round(summary[f"ms_{q}"][k] / floor[q], 3)
        for q in ("median", "min")
        for k in ("plain", "batched")
    }
    return out


def main(argv: list[str] | None = None) -> dict[str, object]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300, help="timed steps per variant and round")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds (minimum kept)")
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--full", action="store_true", help="time SACLearner.gradient_step too")
    ap.add_argument("--compile", action="store_true", help="with --full: torch.compile too")
    ap.add_argument(
        "--thread-steps",
        type=int,
        default=5,
        help="timed steps per round of the 2-thread variant (slow on busy cores)",
    )
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    out: dict[str, object] = {"commit": git_commit(), "batch": args.batch,
                              "steps": args.steps, "rounds": args.rounds,
                              "torch": torch.__version__}  # fmt: skip
    out.update(parts(args.steps, args.rounds, args.batch))
    if args.full:
        out["full_step"] = full(
            args.steps, args.rounds, args.batch, args.compile, args.thread_steps
        )
    print(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
