"""Stable-Baselines3 references on this package's tasks, logged like ``ndp rl train``.

- ``sb3-ppo``: the reference trainer of ``benchmarks/ppo_vs_sb3.py`` (study ``ppo-vs-sb3``):
  SB3's PPO with the supplement's hyperparameters (the defaults of ``ndp.rl.config.PPOConfig``
  and of the run's ``gamma``, ``steps_per_update`` and ``clip_obs``; SB3's own value loss, i.e.
  no value clip, advantages normalised per mini-batch) on the same per-step env this package's
  PPO trains on (``ndp.envs.make_env``; Meta-World random goals at every reset),
  ``DummyVecEnv`` + ``VecNormalize`` (observations and returns, clip 10).
- ``sb3-ndp`` and ``sb3-multi`` (study ``sb3-ndp``): SB3's PPO on the chunked env
  ``ndp.make_env(task, k=SB3_K)`` (one SB3 step is one decision of k env steps, its reward the
  sum of the k sub-step rewards), the same settings for both: SB3's default networks ([64, 64]
  tanh) and PPO settings except ``n_steps`` 128 decisions per env and ``gamma`` 0.99 ** k (0.99
  per env step); ``VecNormalize`` of returns and observations (the ``obs`` entry only for NDP:
  the DMP's start stays in physical units). They differ in the policy only: ``sb3-ndp`` is
  ``ndp.sb3.NDPPolicy`` on ``ndp.sb3.with_robot_state(env)`` (the actor gives DMP goal and
  weights, the DMP and the inverse controller the k sub-actions), ``sb3-multi`` SB3's
  ``MlpPolicy`` giving the k * A sub-actions directly (SB3's PPO-multi). Env steps are counted
  as decisions x k (sub-step slots, as ``ndp rl train`` counts them).
- ``sb3-sac`` and ``sb3-td3`` (studies ``sac-vs-sb3``, ``td3-vs-sb3``): SB3's SAC / TD3 with
  the settings of this package's ``--algo sac`` / ``--algo td3`` defaults on the per-step env,
  no normalisation (:data:`OFF_POLICY_REFERENCES`, one row per reference).

All three run one torch thread. Success is counted per env and per episode: a per-env flag is
set when the step's success (``info["success"]``; ``info["success_decision"]``, success at any
sub-step, on the chunked env) is true at any step of the episode and read when that env's
episode ends (a callback that pools every env's infos into one list miscounts when several envs
end at the same step). One row per rollout goes to ``<run_dir>/metrics.csv`` with the keys
``update``, ``global_step`` (env steps), ``charts/episodes``, ``charts/success_any``,
``charts/episode_return`` (this package's metric names, docs/metrics.md). With
``--eval-episodes E`` > 0 the deterministic policy then runs E episodes (reset seeds 10,000 on)
with the normaliser frozen, written to ``eval-det-e<E>.json`` (``success_any``, ``return``):
the file ``ndp report --eval-episodes E`` reads as the run's deterministic success.
``done.json`` is written atomically at the end. The run directory is made by the run session
like every trainer's (:mod:`ndp.runs.session`: refused over another run, ``config.json``
(:class:`SB3RunConfig`), provenance, ``run.json``). A killed run is restarted from scratch (SB3
runs are short; nothing partial is reported as finished).

Usage::

    python -m ndp.sb3.runs --task push-v3 --steps 150000 --seed 0 --run-dir DIR
    python -m ndp.sb3.runs --method sb3-ndp --task point-mass --steps 100000 \\
        --eval-episodes 20 --run-dir DIR
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from ndp.checks import check_int
from ndp.io import atomic_write_text
from ndp.rl.config import EVAL_SEED, PPOConfig, RunConfig
from ndp.rl.sac.config import SACConfig
from ndp.rl.td3.config import TD3Config
from ndp.runs import MetricsLogger
from ndp.runs.driver import Row, RunPlan, run
from ndp.runs.session import LearnerDefaults, Manifest, RunSession

if TYPE_CHECKING:
    import gymnasium as gym
    from stable_baselines3 import PPO, SAC, TD3
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecEnv

SB3_METHODS = ("sb3-ppo", "sb3-ndp", "sb3-multi", "sb3-sac", "sb3-td3")
"""The methods this module trains (the ``sb3`` run kind's arms)."""
SB3_K = 5
"""Env steps per decision of ``sb3-ndp`` and ``sb3-multi`` unless ``--k`` says otherwise."""
FIELDS = (
    "update",
    "global_step",
    "charts/episodes",
    "charts/success_any",
    "charts/episode_return",
    "time/wall_s",
)


class EpisodeCounter:
    """Per-env success-any and return of finished episodes (pure bookkeeping, testable).

    Args:
        num_envs: envs of the vector env.
    """

    def __init__(self, num_envs: int) -> None:
        self.success = np.zeros(num_envs, dtype=bool)
        self.ret = np.zeros(num_envs)
        self.finished: list[tuple[float, float]] = []

    def step(
        self, rewards: np.ndarray, dones: np.ndarray, infos: Sequence[Mapping[str, object]]
    ) -> None:
        """One vector step: rewards [E] (raw, unnormalised), dones [E], infos (one per env; a
        chunked env's ``success_decision``, else ``success``)."""
        for i, info in enumerate(infos):
            self.success[i] |= bool(info.get("success_decision", info.get("success", False)))
            self.ret[i] += float(rewards[i])
            if dones[i]:
                self.finished.append((float(self.success[i]), float(self.ret[i])))
                self.success[i] = False
                self.ret[i] = 0.0

    def pop(self) -> tuple[int, float, float]:
        """(episodes, mean success-any, mean return) since the last pop (NaN when none)."""
        eps, self.finished = self.finished, []
        if not eps:
            return 0, math.nan, math.nan
        arr = np.array(eps)
        return len(eps), float(arr[:, 0].mean()), float(arr[:, 1].mean())


def silent_logger() -> Logger:
    """An SB3 logger that writes nothing. SB3's default (``verbose=0`` and no
    ``tensorboard_log``) makes a new folder ``$TMPDIR/SB3-<date-time>`` on every ``learn()``
    call and never removes it; an SB3 run here calls ``learn`` once per metrics row, so it
    would leave one folder per row behind."""
    from stable_baselines3.common.logger import Logger

    return Logger(folder=None, output_formats=[])


def make_sb3_ppo(venv: VecEnv, seed: int, num_envs: int) -> PPO:
    """SB3 PPO with the supplement's settings (``PPOConfig`` defaults) on a normalised venv."""
    import torch
    from stable_baselines3 import PPO

    p = PPOConfig()
    n_steps = RunConfig.steps_per_update // num_envs
    return PPO(
        "MlpPolicy",
        venv,
        learning_rate=p.lr,
        n_steps=n_steps,
        batch_size=n_steps * num_envs // p.minibatches,
        n_epochs=p.epochs,
        gamma=RunConfig.gamma,
        gae_lambda=p.gae_lambda,
        clip_range=p.clip,
        ent_coef=p.ent_coef,
        vf_coef=p.vf_coef,
        max_grad_norm=p.max_grad_norm,
        seed=seed,
        device="cpu",
        verbose=0,
        policy_kwargs={
            "net_arch": {"pi": [100, 100], "vf": [100, 100]},
            "activation_fn": torch.nn.Tanh,
            "optimizer_kwargs": {"eps": p.adam_eps},
        },
    )


@dataclass(frozen=True)
class SB3RunConfig:
    """The reference run's settings (its ``config.json``)."""

    task: str
    """The per-step task (``push-v3``)."""
    steps: int
    """Env steps (SB3's ``total_timesteps``)."""
    seed: int = 0
    """Seed of SB3, its envs and torch."""
    num_envs: int = 4
    """Envs of the ``DummyVecEnv``."""
    horizon: int | None = None
    """Episode length in env steps (None: the task's)."""
    run_dir: str = ""
    """Where the run is (never compared on a restart)."""
    method: str = "sb3-ppo"
    """``sb3-ppo`` (per-step env), ``sb3-ndp`` or ``sb3-multi`` (chunked env, ``k`` steps per
    decision); configs written before the field ran sb3-ppo."""
    k: int = 1
    """Env steps per decision (1 for sb3-ppo, :data:`SB3_K` for the chunked methods)."""
    eval_episodes: int = 0
    """Deterministic evaluation episodes after training (0: none)."""

    def __post_init__(self) -> None:
        if self.method not in SB3_METHODS:
            raise ValueError(
                f"method: expected one of {', '.join(SB3_METHODS)}, got {self.method!r}"
            )
        for name, low in (("steps", 1), ("seed", 0), ("num_envs", 1), ("k", 1),
                          ("eval_episodes", 0)):  # fmt: skip
            check_int(name, getattr(self, name), low)
        if self.method in PER_STEP_METHODS and self.k != 1:
            raise ValueError(f"k: {self.method} runs one env step per decision, got k={self.k}")

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SB3RunConfig:
        return cls(**d)


SB3_SAC_ROLLOUT = 2048
"""Env steps per :meth:`SB3Learner.iterate` of ``sb3-sac`` and ``sb3-td3`` (one metrics row;
SB3's SAC / TD3 itself
steps the envs once and takes its gradient steps between)."""


class _OffPolicyKwargs(TypedDict):
    """The keywords SB3's SAC and TD3 get alike here."""

    learning_rate: float
    buffer_size: int
    learning_starts: int
    batch_size: int
    tau: float
    gamma: float
    train_freq: int
    gradient_steps: int
    seed: int
    device: str
    verbose: int


def _off_policy_kwargs(c: SACConfig | TD3Config, seed: int, num_envs: int) -> _OffPolicyKwargs:
    """SB3's SAC / TD3 keywords from our config ``c``: its lr, buffer, batch, tau and random
    steps (SB3 counts env steps, num_envs per vector step), gamma 0.99, one gradient step per
    env step (``num_envs`` after each vector step), on the CPU, quiet."""
    return _OffPolicyKwargs(learning_rate=c.lr, buffer_size=c.buffer_size,
                            learning_starts=c.random_steps, batch_size=c.batch_size, tau=c.tau,
                            gamma=0.99, train_freq=1, gradient_steps=num_envs, seed=seed,
                            device="cpu", verbose=0)  # fmt: skip


def make_sb3_sac(venv: VecEnv, seed: int, num_envs: int) -> SAC:
    """SB3's SAC with the settings of ``ndp.rl.sac.config.SACConfig``'s defaults: buffer 1M,
    batch 256, lr 3e-4, tau 0.005, gamma 0.99, automatic temperature (initial 1), 256-256 ReLU,
    5,000 random env steps first, and one gradient step per env step (``gradient_steps`` =
    ``num_envs`` after each vector step, as ``ndp rl train --algo sac`` with as many envs)."""
    from stable_baselines3 import SAC

    c = SACConfig()
    return SAC(
        "MlpPolicy",
        venv,
        ent_coef=f"auto_{c.init_alpha}",
        **_off_policy_kwargs(c, seed, num_envs),
        policy_kwargs={"net_arch": [256, 256]},
    )


def make_sb3_td3(venv: VecEnv, seed: int, num_envs: int) -> TD3:
    """SB3's TD3 with the settings of ``ndp.rl.td3.config.TD3Config``'s defaults (SB3's own
    defaults, but two): lr 1e-3, buffer 1M, batch 256, tau 0.005, gamma 0.99, policy delay 2,
    target policy noise 0.2 clipped at 0.5, 400-300 ReLU (SB3's default ``net_arch`` for TD3),
    and, as ours, Gaussian exploration noise N(0, 0.1^2) on the [-1, 1]-scaled action (SB3's
    default: none) and 5,000 random env steps first (SB3's default ``learning_starts``: 100);
    one gradient step per env step (``gradient_steps`` = ``num_envs`` after each vector
    step)."""
    from stable_baselines3 import TD3
    from stable_baselines3.common.noise import NormalActionNoise

    c = TD3Config()
    shape = venv.action_space.shape
    assert shape is not None  # a Box action space
    n_act = int(np.prod(shape))
    noise = NormalActionNoise(np.zeros(n_act), np.full(n_act, c.expl_noise))
    return TD3(
        "MlpPolicy",
        venv,
        action_noise=noise,
        policy_delay=c.policy_delay,
        target_policy_noise=c.target_noise,
        target_noise_clip=c.target_noise_clip,
        **_off_policy_kwargs(c, seed, num_envs),
        policy_kwargs={"net_arch": [400, 300]},
    )


OFF_POLICY_REFERENCES: dict[str, Callable[[VecEnv, int, int], BaseAlgorithm]] = {
    "sb3-sac": make_sb3_sac,
    "sb3-td3": make_sb3_td3,
}
"""SB3's off-policy references, one row each: method -> ``make(venv, seed, num_envs)``. They
run on the per-step env without normalisation, one metrics row per :data:`SB3_SAC_ROLLOUT`
env steps, with one gradient step per env step (studies ``sac-vs-sb3``, ``td3-vs-sb3``)."""


def make_sb3_chunked(venv: VecEnv, method: str, seed: int, k: int) -> PPO:
    """SB3 PPO for ``sb3-ndp`` / ``sb3-multi``: SB3's defaults but ``n_steps`` 128 and
    ``gamma`` 0.99 ** k (the same for both; they differ in the policy only)."""
    from stable_baselines3 import PPO

    import ndp.sb3

    policy = ndp.sb3.NDPPolicy if method == "sb3-ndp" else "MlpPolicy"
    return PPO(policy, venv, n_steps=128, gamma=0.99**k, seed=seed, device="cpu", verbose=0)


@dataclass(frozen=True)
class SB3Method:
    """How the run kind builds one SB3 method: its env, the wrapper of its vector env, its model
    and the decisions of one rollout (one ``metrics.csv`` row). :data:`SB3_METHOD_ROWS` holds
    one per method of :data:`SB3_METHODS`; the run reads the row, never the method's name."""

    per_step: bool
    """The per-step env (k = 1); otherwise the chunked env, k env steps per decision."""
    robot_state: bool
    """The chunked env with the DMP's start in the observation (``ndp.sb3.with_robot_state``,
    what ``NDPPolicy`` reads)."""
    wrap: Callable[[VecEnv, SB3RunConfig], VecEnv]
    """The vector env the model trains on (normalisation, or none)."""
    make: Callable[[VecEnv, SB3RunConfig], BaseAlgorithm]
    """The model on the wrapped vector env."""
    rollout: Callable[[SB3RunConfig], int]
    """Decisions (over all envs) per rollout."""


def _ppo_venv(venv: VecEnv, cfg: SB3RunConfig) -> VecEnv:
    """``sb3-ppo``'s normalisation: the supplement's settings (the run's ``gamma`` and
    ``clip_obs``, ``PPOConfig``'s ``clip_reward``)."""
    from stable_baselines3.common.vec_env import VecNormalize

    p = PPOConfig()
    return VecNormalize(
        venv, gamma=RunConfig.gamma, clip_obs=RunConfig.clip_obs, clip_reward=p.clip_reward
    )


def _chunked_venv(venv: VecEnv, cfg: SB3RunConfig) -> VecEnv:
    """The chunked methods' normalisation at the decision's discount 0.99 ** k (``sb3-ndp``:
    the observation key only, the robot state stays raw)."""
    from stable_baselines3.common.vec_env import VecNormalize

    keys = ["obs"] if SB3_METHOD_ROWS[cfg.method].robot_state else None
    return VecNormalize(venv, gamma=0.99**cfg.k, norm_obs_keys=keys)


def _off_policy_row(make: Callable[[VecEnv, int, int], BaseAlgorithm]) -> SB3Method:
    """An off-policy reference: the per-step env, no normalisation (off-policy's usual
    setting), one row per :data:`SB3_SAC_ROLLOUT` env steps."""
    return SB3Method(
        per_step=True,
        robot_state=False,
        wrap=lambda venv, cfg: venv,
        make=lambda venv, cfg: make(venv, cfg.seed, cfg.num_envs),
        rollout=lambda cfg: SB3_SAC_ROLLOUT,
    )


def _chunked_row(robot_state: bool) -> SB3Method:
    """``sb3-ndp`` (``robot_state``: NDPPolicy) or ``sb3-multi`` (MlpPolicy) on the chunked env,
    128 decisions per env per rollout."""
    return SB3Method(
        per_step=False,
        robot_state=robot_state,
        wrap=_chunked_venv,
        make=lambda venv, cfg: make_sb3_chunked(venv, cfg.method, cfg.seed, cfg.k),
        rollout=lambda cfg: 128 * cfg.num_envs,
    )


SB3_METHOD_ROWS: dict[str, SB3Method] = {
    "sb3-ppo": SB3Method(
        per_step=True,
        robot_state=False,
        wrap=_ppo_venv,
        make=lambda venv, cfg: make_sb3_ppo(venv, cfg.seed, cfg.num_envs),
        rollout=lambda cfg: RunConfig.steps_per_update // cfg.num_envs * cfg.num_envs,
    ),
    "sb3-ndp": _chunked_row(robot_state=True),
    "sb3-multi": _chunked_row(robot_state=False),
    **{name: _off_policy_row(make) for name, make in OFF_POLICY_REFERENCES.items()},
}
"""One :class:`SB3Method` per method of :data:`SB3_METHODS` (a test checks they agree)."""

PER_STEP_METHODS = tuple(name for name, row in SB3_METHOD_ROWS.items() if row.per_step)
"""The methods on the per-step env (k = 1); the others run the chunked env."""


def _env_maker(cfg: SB3RunConfig) -> Callable[[], gym.Env]:
    """A function building one env of the run (per-step env, or chunked one for k > 1)."""
    row = SB3_METHOD_ROWS[cfg.method]
    if row.per_step:
        from ndp.rl.envs import resolve_task

        h = resolve_task(cfg.task)
        return lambda: h.make(horizon=cfg.horizon)
    import ndp.sb3  # binds ndp too (ndp.make_env)

    def make() -> gym.Env:
        env: gym.Env = ndp.make_env(cfg.task, k=cfg.k, horizon=cfg.horizon)
        if row.robot_state:
            env = ndp.sb3.with_robot_state(env, cfg.task)
        return env

    return make


def evaluate_sb3(
    model: BaseAlgorithm, venv: VecEnv, make: Callable[[], gym.Env], episodes: int
) -> dict[str, float]:
    """The deterministic policy over ``episodes`` fresh episodes (reset seeds from
    :data:`ndp.rl.config.EVAL_SEED`), observations normalised by ``venv``'s frozen statistics
    (as they are where ``venv`` does not normalise: ``sb3-sac``, ``sb3-td3``): success at any
    step (the mean of the per-episode flags) and the mean raw return."""
    from stable_baselines3.common.vec_env import VecNormalize

    norm = venv.normalize_obs if isinstance(venv, VecNormalize) else (lambda o: o)
    if isinstance(venv, VecNormalize):  # frozen statistics (the others have none)
        venv.training = False
    env = make()
    succ, rets = [], []
    try:
        for ep in range(episodes):
            obs, info = env.reset(seed=EVAL_SEED + ep)
            done, ret, hit = False, 0.0, False
            while not done:
                act, _ = model.predict(norm(obs), deterministic=True)
                obs, r, term, trunc, info = env.step(act)
                hit |= bool(info.get("success_decision", info.get("success", False)))
                ret += float(r)
                done = bool(term or trunc)
            succ.append(float(hit))
            rets.append(ret)
    finally:
        env.close()
    return {
        "episodes": episodes,
        "deterministic": True,
        "first_seed": EVAL_SEED,
        "success_any": float(np.mean(succ)),
        "return": float(np.mean(rets)),
    }


def train_sb3(
    task: str,
    steps: int,
    seed: int,
    run_dir: Path,
    num_envs: int = 4,
    horizon: int | None = None,
    method: str = "sb3-ppo",
    k: int | None = None,
    eval_episodes: int = 0,
) -> Path:
    """Train one of :data:`SB3_METHODS` through the run driver; returns the run directory (see
    the module docstring).

    Args:
        task: the task name (``push-v3``, ``point-mass``).
        steps: env steps (SB3 counts decisions: it runs ``ceil(steps / k)`` of them, rounded up
            to whole rollouts).
        seed: seed of SB3, its envs and torch.
        run_dir: the run directory (refused when it holds another run).
        num_envs: envs of the ``DummyVecEnv``.
        horizon: episode length in env steps (None: the task's).
        method: ``sb3-ppo``, ``sb3-ndp`` or ``sb3-multi``.
        k: env steps per decision (None: 1 for sb3-ppo, :data:`SB3_K` otherwise).
        eval_episodes: deterministic evaluation episodes after training (0: none).
    """
    per_step = method in PER_STEP_METHODS
    cfg = SB3RunConfig(task, int(steps), int(seed), int(num_envs), horizon, str(run_dir), method,
                       (1 if per_step else SB3_K) if k is None else int(k),
                       int(eval_episodes))  # fmt: skip
    recipe = SB3Recipe(cfg)
    return run(recipe)


def rollout_decisions(cfg: SB3RunConfig) -> int:
    """Decisions (SB3 steps, over all envs) per rollout of the method's PPO."""
    return SB3_METHOD_ROWS[cfg.method].rollout(cfg)


def rollouts(cfg: SB3RunConfig) -> int:
    """Rollouts of a run: SB3's ``learn(ceil(steps / k))`` runs whole rollouts until it has
    that many decisions."""
    decisions = -(-cfg.steps // cfg.k)
    return -(-decisions // rollout_decisions(cfg))


class SB3Learner(LearnerDefaults):
    """SB3's PPO as a :class:`ndp.runs.session.Learner`: one :meth:`iterate` is one SB3
    rollout and its update (``learn`` continued with ``reset_num_timesteps=False``; SB3's
    schedules are constant here, so the sequence equals one ``learn`` call). After the last
    rollout it runs the deterministic evaluation (``eval_episodes``) and writes ``done.json``.
    """

    def __init__(self, cfg: SB3RunConfig, session: RunSession) -> None:
        from stable_baselines3.common.callbacks import BaseCallback
        from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

        self.cfg, self.session = cfg, session
        row = SB3_METHOD_ROWS[cfg.method]
        self.make = make = _env_maker(cfg)
        raw_venv = DummyVecEnv([make for _ in range(cfg.num_envs)])
        raw_venv.seed(cfg.seed)
        self.venv: Any = row.wrap(raw_venv, cfg)
        self.model = row.make(self.venv, cfg)
        self.model.set_logger(silent_logger())  # the run writes its own metrics.csv
        self.step = 0
        self.rollout = rollout_decisions(cfg)
        self.budget = rollouts(cfg)
        counter = EpisodeCounter(cfg.num_envs)
        self.t0 = time.perf_counter()

        self.counter = counter

        class _Episodes(BaseCallback):
            def _on_step(self) -> bool:
                env = self.training_env
                # unnormalised rewards (SAC's venv is not normalised)
                raw = env.get_original_reward() if isinstance(env, VecNormalize) else None
                raw = self.locals["rewards"] if raw is None else raw
                counter.step(raw, self.locals["dones"], self.locals["infos"])
                return True

        self.callback = _Episodes()

    def iterate(self) -> dict[str, float]:
        self.model.learn(total_timesteps=self.rollout, callback=self.callback,
                         reset_num_timesteps=self.step == 0)  # fmt: skip
        self.step += 1
        n, succ, ret = self.counter.pop()
        row = {
            "update": self.step,
            "global_step": self.global_step,
            "charts/episodes": n,
            "charts/success_any": succ,
            "charts/episode_return": ret,
            "time/wall_s": time.perf_counter() - self.t0,
        }
        if self.step >= self.budget:
            self._finish()
        return row

    def _finish(self) -> None:
        cfg, run_dir = self.cfg, self.session.run.path
        wall = time.perf_counter() - self.t0
        if cfg.eval_episodes:
            ev = evaluate_sb3(self.model, self.venv, self.make, cfg.eval_episodes)
            name = f"eval-det-e{cfg.eval_episodes}.json"
            atomic_write_text(run_dir / name, json.dumps(ev) + "\n")
        done = {"task": cfg.task, "method": cfg.method, "steps": cfg.steps, "seed": cfg.seed,
                "num_envs": cfg.num_envs, "k": cfg.k, "global_step": self.global_step,
                "wall_s": wall}  # fmt: skip
        atomic_write_text(run_dir / "done.json", json.dumps(done) + "\n")

    @property
    def global_step(self) -> int:
        """Env steps run (decisions x k)."""
        return int(self.model.num_timesteps) * self.cfg.k

    def state_dict(self) -> dict[str, Any]:
        raise NotImplementedError("SB3 reference runs are not checkpointed (restarted instead)")

    def load_state_dict(self, state: dict[str, Any]) -> None:
        raise NotImplementedError("SB3 reference runs do not resume")

    def close(self) -> None:
        self.venv.close()


class SB3Recipe:
    """The run driver's recipe of an SB3 reference run: kind ``sb3``, counted in rollouts,
    never checkpointed (a killed run restarts; SB3 runs are short)."""

    def __init__(self, cfg: SB3RunConfig) -> None:
        self.cfg = cfg
        _env_maker(cfg)  # an unknown task fails here, before the run folder is made
        self.plan = RunPlan(
            run_dir=Path(cfg.run_dir),
            kind="sb3",
            unit="update",
            seed=cfg.seed,
            budget=rollouts(cfg),
            config=cfg,
            config_dict=dataclasses.asdict(cfg),
            config_from_dict=SB3RunConfig.from_dict,
            threads=1,
            resumable=False,
        )

    def check_checkpoint(self, ckpt: dict[str, Any]) -> None:
        pass  # never resumed

    def build(self, session: RunSession, fresh: bool) -> SB3Learner:
        return SB3Learner(self.cfg, session)

    def manifest(self, learner: SB3Learner) -> Manifest:
        cfg = self.cfg
        done = learner.global_step
        end = done >= cfg.steps
        return Manifest(kind="sb3", task=cfg.task, label=cfg.method, seed=int(cfg.seed),
                        budget=int(cfg.steps), unit="env_steps", done=int(done), finished=end,
                        reason="budget" if end else "")  # fmt: skip

    @contextlib.contextmanager
    def log(self, learner: SB3Learner, session: RunSession) -> Iterator[Callable[[Row], None]]:
        with MetricsLogger(session.run.path, FIELDS, step="global_step",
                           tensorboard=False) as metrics:  # fmt: skip
            yield metrics.log

    def checkpoint_due(self, learner: SB3Learner) -> bool:
        return False

    def summary(self, learner: SB3Learner, last: dict[str, float], session: RunSession) -> Path:
        return session.run.path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--task", required=True)
    ap.add_argument("--steps", type=int, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--num-envs", type=int, default=4)
    ap.add_argument("--run-dir", type=Path, required=True)
    ap.add_argument("--method", choices=SB3_METHODS, default="sb3-ppo")
    ap.add_argument("--k", type=int, default=None, help=f"env steps per decision (default: 1 "
                    f"for sb3-ppo, {SB3_K} for sb3-ndp and sb3-multi)")  # fmt: skip
    ap.add_argument("--eval-episodes", type=int, default=0,
                    help="deterministic evaluation episodes after training")  # fmt: skip
    a = ap.parse_args(argv)
    try:
        train_sb3(a.task, a.steps, a.seed, a.run_dir, a.num_envs, method=a.method, k=a.k,
                  eval_episodes=a.eval_episodes)  # fmt: skip
    except ValueError as exc:
        ap.error(str(exc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
