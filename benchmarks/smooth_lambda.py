"""How the smooth reward's default price (``ndp.envs.rewards.DEFAULT_SMOOTH_LAMBDA``) was chosen.

The smooth reward is the task's reward minus ``lambda * ||a_t - a_{t-1}||^2`` per env step. This
script measures, on push-v3 (v2 reward, episodes from the evaluation seeds 10,000 on), the mean
per-step reward and the mean squared action change between consecutive env steps (the executed,
clipped actions; the first step of an episode has none) of

- the zoo's push-v3 PPO, PPO-multi and NDP policies, stochastic (a sample per decision, as they
  act in training) and deterministic (their mode, as evaluated);
- a fresh policy's stand-in: clipped N(0, 1) actions (every method starts with std 1 around a
  mean near 0).

It prints one JSON document: per row the two means and the penalty's share of the reward at the
default lambda, and the lambda at which the penalty is ``--share`` (15 %) of the mean per-step
reward at the stochastic trained policies' mean action change (the default rounds it).

Usage: python benchmarks/smooth_lambda.py [--episodes 10] [--share 0.15]
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import gymnasium as gym
import numpy as np

import ndp
from ndp.envs import make_env
from ndp.envs.rewards import DEFAULT_SMOOTH_LAMBDA
from ndp.rl.config import EVAL_SEED

POLICIES = ("push-v3-ppo", "push-v3-ppo-multi", "push-v3-ndp")
"""The zoo's push-v3 policies measured."""


class _Record(gym.Wrapper):
    """Per env step: the reward and the squared change of the executed action (NaN at the
    first step of an episode)."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.rows: list[tuple[float, float]] = []
        self._prev: np.ndarray | None = None

    def reset(self, **kw: Any) -> Any:
        self._prev = None
        return self.env.reset(**kw)

    def step(self, action: Any) -> Any:
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        out = self.env.step(a)
        change = np.nan if self._prev is None else float(np.sum((a - self._prev) ** 2))
        self._prev = a
        self.rows.append((float(out[1]), change))
        return out


def _summary(rows: list[tuple[float, float]]) -> dict[str, float]:
    arr = np.asarray(rows, dtype=np.float64)
    change = arr[:, 1][~np.isnan(arr[:, 1])]
    reward, da2 = float(arr[:, 0].mean()), float(change.mean())
    return {
        "reward_per_step": reward,
        "action_change_sq": da2,
        "share_at_default": DEFAULT_SMOOTH_LAMBDA * da2 / reward,
        "steps": len(arr),
    }


def measure_policy(name: str, deterministic: bool, episodes: int) -> dict[str, float]:
    pol = ndp.load_policy(f"zoo:{name}")
    rec: list[_Record] = []
    env = pol.make_env(wrap=lambda e: rec.append(_Record(e)) or rec[-1])
    pol.reset(seed=0)
    for ep in range(episodes):
        obs, info = env.reset(seed=EVAL_SEED + ep)
        done = False
        while not done:
            obs, _, term, trunc, info = env.step(pol.act(obs, info, deterministic=deterministic))
            done = term or trunc
    env.close()
    return _summary(rec[0].rows)


def measure_random(episodes: int) -> dict[str, float]:
    env = _Record(make_env("push-v3"))
    rng = np.random.default_rng(0)
    for ep in range(episodes):
        env.reset(seed=EVAL_SEED + ep)
        done = False
        while not done:
            _, _, term, trunc, _ = env.step(np.clip(rng.normal(size=4), -1.0, 1.0))
            done = term or trunc
    env.close()
    return _summary(env.rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--share", type=float, default=0.15)
    args = parser.parse_args()
    rows: dict[str, dict[str, float]] = {"fresh (clipped N(0, 1))": measure_random(args.episodes)}
    for name in POLICIES:
        for det in (False, True):
            label = f"{name} {'deterministic' if det else 'stochastic'}"
            rows[label] = measure_policy(name, det, args.episodes)
    trained = [rows[f"{n} stochastic"] for n in POLICIES]
    reward = float(np.mean([r["reward_per_step"] for r in trained]))
    change = float(np.mean([r["action_change_sq"] for r in trained]))
    out = {
        "task": "push-v3",
        "episodes": args.episodes,
        "default_lambda": DEFAULT_SMOOTH_LAMBDA,
        "rows": rows,
        "trained_stochastic_mean": {"reward_per_step": reward, "action_change_sq": change},
        "lambda_for_share": {"share": args.share, "lambda": args.share * reward / change},
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
