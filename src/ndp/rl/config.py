"""Typed configuration of an RL run, its resolution against a task, and its argparse CLI.

A run is one :class:`TrainConfig`: the run's own fields (:class:`RunConfig`: task, method,
budget, envs, and what every learner reads: the discount ``gamma``, the update's size
``steps_per_update``, the observation normaliser), a :class:`PPOConfig` (the shared on-policy
trainer's settings, read by the on-policy methods only; defined with its learner in
:mod:`ndp.rl.onpolicy.config` and re-exported here), a :class:`ndp.policies.PolicyConfig`
and one settings section per registered learner (``ndp.rl.methods.register_learner``; this
module names none of them). ``TrainConfig`` is
built here from :class:`RunConfig` (the run's own fields) and the registered sections, once,
when this module is imported. Every field has a docstring, which becomes its ``--help`` text:
``ndp rl train`` is this dataclass tree parsed by tyro (:mod:`ndp.runs.cli`), one flat
``--field-name`` option per field. :func:`resolve_config` fills what depends on the task (the
action head of the method, the NDP preset, k = 1 for PPO) and validates everything before any
environment is built; the resolved config is what runs and what is saved as
``config.json`` in the run directory.

Defaults are the supplement's PPO hyperparameters (ndp-method.md section 3): hidden [100, 100]
tanh, Adam 3e-4 (eps 1e-5), gamma 0.99, GAE lambda 0.95, entropy 0, value coefficient 0.5, max
grad norm 0.5, 10 epochs, 32 mini-batches, clip 0.1, 2048 env steps per update, observation and
return normalisation, k = 5, 35 DMP integration steps per decision. The value loss is not
clipped by default (``clip_value_loss``: the release's PPO code base clips it; that is not in the
supplement and it costs most of the gap to SB3's PPO, see docs/rl.md).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, TypedDict, cast

from ndp.checks import (
    check_choice,
    check_int,
    check_positive,
    check_unit_interval,
    plain_numbers,
)
from ndp.policies.config import PolicyConfig
from ndp.rl.methods import METHOD_RUN_FIELDS, METHODS, SETTINGS, Method, settings_sections
from ndp.rl.onpolicy.config import PPOConfig as PPOConfig  # re-exported: its old home
from ndp.runs.cli import cli
from ndp.runs.tracking import check_track

EVAL_SEED = 10_000
"""Reset seed of the first evaluation episode (episodes ``EVAL_SEED .. EVAL_SEED + N - 1``) for
``ndp rl eval``, ``ndp rl render``, the report's cached evaluation, the smoothness study and the
SB3 runs. Training resets draw 32-bit seeds from ``SeedSequence([seed, epoch])``
(:func:`ndp.rl.envs.env_seeds`), so evaluation episodes are fresh ones."""
FRESH_EVAL_SEED = 20_000
"""Reset seed of the first episode of a re-scoring of final policies (``ndp rl eval --episodes
100 --seed 20000 --save``): disjoint from the periodic evaluation's fixed seeds (from
:data:`EVAL_SEED`, at most a few hundred) and from training's 32-bit seeds drawn from
``SeedSequence`` (a collision with 100 small seeds is improbable, not impossible)."""

GOALS = ("random", "per-seed", "release", "as-release")
"""Values of ``TrainConfig.goals``."""
EXECUTIONS = ("all", "first-held")
"""Values of ``TrainConfig.execution`` (``ndp.envs.chunked.EXECUTIONS``)."""
FIRST_HELD_RATIOS = ("own", "release")
"""Values of ``TrainConfig.first_held_ratio``."""
REWARDS = ("dense", "sparse", "smooth")
"""Values of ``TrainConfig.reward`` (``ndp.envs.rewards.REWARDS``)."""
BACKENDS = ("metaworld", "envpool")
"""Values of ``TrainConfig.backend`` (``ndp.envs.envpool_backend.BACKENDS``; here too, so that
a config checks without the simulators installed)."""


class EnvOptions(TypedDict, total=False):
    """The task options of a run's envs (:meth:`RunConfig.env_options`: the keywords of
    ``ndp.envs.make_env`` and :func:`ndp.rl.envs.resolve_task`)."""

    reward_version: str
    backend: str
    observation: str
    reward: str
    smooth_lambda: float
    fixed_goal: int | str


class ChunkOptions(TypedDict):
    """The :class:`ndp.envs.ChunkedEnv` keywords of a run (:meth:`RunConfig.chunk_options`)."""

    stale_world: bool
    execution: str


SAFE_ON_RESUME = (
    "progress",
    "tensorboard",
    "track",
    "steps",
    "vector",
    "env_workers",
    "device",
    "eval_every",
    "eval_episodes",
)
"""TrainConfig fields a resume may change: they change neither the numbers nor the history
(``steps`` extends or shortens the budget; ``device`` moves the update, which changes float
rounding only; the periodic evaluation draws nothing from the training stream)."""


@dataclass(frozen=True)
class RunConfig:
    """One training run: task, method, budget, envs, logging; plus PPO and policy settings
    (:class:`TrainConfig` adds the registered learners' sections)."""

    task: str = "reach-v3"
    """Task name (see ndp.envs.TASKS) or 'point-mass' (the toy task)."""
    algo: str = "ndp"
    """Method: a name registered in ``ndp.rl.methods`` (this command's description and
    ``ndp rl methods`` list them, a line each)."""
    steps: int = 500_000
    """Total env steps (sub-steps) to train for."""
    seed: int = 0
    """Seed of torch, numpy and the environments."""
    num_envs: int = 4
    """Parallel environments."""
    vector: str = "auto"
    """Vector env: 'auto' (env workers when 2+ cores are free, else sync), 'sync' (one process;
    debugging and determinism), 'workers' (env_workers subprocesses, several envs each, shared
    memory) or 'async' (gymnasium's AsyncVectorEnv, one subprocess per env). Same numbers.
    'overlap' (opt-in, an even num_envs): two env groups (halves), all in worker processes
    (env_workers split between them); the on-policy trainer (PPO, PPO-multi, NDP, VICES)
    computes one group's decision while the other group steps. With norm_obs=False its rollout
    is the 'sync' one bit for bit; with the normaliser it differs only through it (a first-half
    env's decision is normalised before the second half's latest observations are merged;
    docs/rl.md). Other learners step both groups at once (no overlap). Not with
    noise='ar1'."""
    env_workers: int | None = None
    """Worker processes of the 'workers' / 'auto' vector env (of 'overlap': split between its two
    groups, at least one each); None: one per core (<= num_envs)."""
    stale_world: bool = True
    """Stale-world reward rule during the k sub-steps (NDP and PPO-multi; no effect for k = 1)."""
    horizon: int | None = None
    """Episode length in env steps; None: the task's default."""
    reward_version: str = "v2"
    """Meta-World's reward function: 'v2' (metaworld's default) or 'v1' (the shaped rewards the
    2021 release trained on; success is the v2 evaluation under both). Meta-World tasks only."""
    goals: str = "random"
    """'random' (a fresh seeded task configuration every episode), 'per-seed' (one object + goal
    configuration for the whole run, drawn from the run's seed; 'fixed' is its old name, still
    read), 'release' (the 2021 release's ONE hard-coded configuration, the same for every run
    and seed: push, soccer, faucet-open, Throw, Pick; ndp.envs.release) or 'as-release' (what the
    release gave this method on this task: random for PPO on push and soccer, 'release'
    otherwise; resolved to one of the two before the run starts). Evaluation of the run uses
    the same."""
    execution: str = "all"
    """How a decision's k sub-actions run: 'all' (each in turn) or 'first-held' (only the first,
    held for the k env steps: the 2021 release's defect, reproduced as a labelled condition for
    chunked methods; no effect at k = 1). The update's ratio per sub-step under 'first-held' is
    ``first_held_ratio``'s."""
    first_held_ratio: str = "own"
    """The PPO ratio of sub-step j under ``execution='first-held'``: 'own' (sub-step j's own,
    un-executed sample a_j: pi_j,new(a_j) / pi_j,old(a_j)) or 'release' (the 2021 release's:
    the executed a_0 scored under sub-step j's new distribution against sub-step 0's old one,
    pi_j,new(a_0) / pi_0,old(a_0); ``ndp.rl.onpolicy.losses.release_first_held``). 'release'
    needs ``execution='first-held'`` and a per-sub-action distribution (not parameter noise)."""
    observation: str = "full"
    """'full' (the task's observation) or 'release9' (Meta-World only: the 2021 release's 9
    values, hand, object and goal xyz)."""
    reward: str = "dense"
    """The reward every env step of the run (training and evaluation) gets: 'dense' (the
    task's own), 'sparse' (1 at the first env step the task reports success, which ends the
    episode, else 0) or 'smooth' (the task's reward minus smooth_lambda times the squared
    change of the executed action since the previous env step); ndp.envs.rewards. Success is
    the task's own under all three. 'sparse' and 'smooth' need --no-stale-world at k > 1."""
    smooth_lambda: float | None = None
    """Price of the 'smooth' reward per unit squared action change (>= 0); None: 0.25
    (ndp.envs.rewards.DEFAULT_SMOOTH_LAMBDA: 15 % of push-v3's per-step reward at trained
    policies' training-time action changes, docs/envs.md). Only with --reward smooth."""
    backend: str = "metaworld"
    """Simulator of the Meta-World tasks: 'metaworld' (metaworld's Python envs) or 'envpool'
    (EnvPool 1.2.5's C++ port, the [envpool] extra; ndp.envs.envpool_backend). 'envpool' serves
    the live reward only (k = 1, or --no-stale-world), the v2 reward, random goals and the tasks
    its equivalence check accepted (docs/envs.md, "Simulator backend"); anything else is
    refused before the run starts."""
    run_dir: str | None = None
    """Run directory; None: runs/<task>-<algo>-s<seed>."""
    checkpoint_every: int = 10
    """Updates between checkpoints (one is always written at the end)."""
    eval_every: int = 15_000
    """Env steps between deterministic evaluations of the policy during training (and one after
    the last update): eval_episodes episodes of its mode on the fixed evaluation seeds, logged as
    eval/* in metrics.csv (ndp.rl.periodic_eval; about 20 in a 300k-step run); 0: off."""
    eval_episodes: int = 10
    """Episodes per periodic deterministic evaluation (0: off)."""
    tensorboard: bool = True
    """Write TensorBoard event files besides the CSV."""
    track: str = "none"
    """Also log every metrics row to an experiment tracker: 'none' or 'wandb' (Weights & Biases,
    the [track] extra; offline in RUN/wandb unless WANDB_MODE says otherwise; ndp.runs.tracking)."""
    progress: bool = True
    """Show a progress bar."""
    torch_threads: int = 1
    """torch intra-op threads of the trainer (1 where env workers run beside it)."""
    device: str = "cpu"
    """torch device of the PPO update ('cpu', 'cuda', 'cuda:1', ...); the rollout always acts
    on the CPU beside the simulators (with a copy of the policy refreshed after each update)."""
    # The run's own learning fields: the problem every learner solves and the shape of its
    # iterations, read by every method (config.json held them under "ppo" before; from_dict
    # reads them there: MOVED_FROM_PPO).
    gamma: float = 0.99
    """Discount per env step (sub-step): part of the problem (the return every learner
    maximises), so one field of the run, read by every method (PPO's GAE and return
    normalisation, the off-policy learners' chunk return and bootstrap)."""
    steps_per_update: int = 2048
    """Env steps (sub-steps) collected per update, over all envs (rounded up to k * num_envs):
    the run's iteration, every method's (PPO's rollout; an off-policy learner's collection
    between two metrics rows). The budget counts updates of this size (run.json, checkpoints,
    --checkpoint-every)."""
    norm_obs: bool = True
    """Normalise observations with running mean / std: the observation normaliser of the run's
    policy (its statistics are saved with the policy, and eval, export and ndp.load_policy read
    it). The on-policy methods and Dyn-E read it; the SAC family and TD3 learn on the raw
    observations (their normaliser stays disabled) and refuse --no-norm-obs
    (ndp.rl.methods.METHOD_RUN_FIELDS)."""
    clip_obs: float = 10.0
    """Clip normalised observations to +- this (the run's observation normaliser, as
    norm_obs)."""
    ppo: PPOConfig = field(default_factory=PPOConfig)
    """PPO hyperparameters."""
    policy: PolicyConfig = field(default_factory=PolicyConfig)
    """Actor-critic and action-head settings (head follows algo)."""

    def __post_init__(self) -> None:
        plain_numbers(self)

        if self.algo not in METHODS:
            raise ValueError(f"algo: expected one of {', '.join(METHODS)}, got {self.algo!r}")
        if not isinstance(self.task, str) or not self.task:
            raise ValueError(f"task: expected a task name, got {self.task!r}")
        check_int("steps", self.steps, 1)
        check_int("steps_per_update", self.steps_per_update, 1)
        check_unit_interval("gamma", self.gamma)
        check_positive("clip_obs", self.clip_obs)
        check_int("seed", self.seed, 0)
        check_int("num_envs", self.num_envs, 1)
        check_int("checkpoint_every", self.checkpoint_every, 1)
        check_int("eval_every", self.eval_every, 0)
        check_int("eval_episodes", self.eval_episodes, 0)
        check_int("torch_threads", self.torch_threads, 1)
        check_track(self.track)
        if self.horizon is not None:
            check_int("horizon", self.horizon, 1)
        check_choice("reward_version", self.reward_version, ("v1", "v2"))
        if self.goals == "fixed":  # the old name of 'per-seed' (configs and arms written before)
            object.__setattr__(self, "goals", "per-seed")
        if self.goals not in GOALS:
            raise ValueError(
                f"goals: expected one of {', '.join(GOALS)} ('fixed' = 'per-seed'), "
                f"got {self.goals!r}"
            )
        for name, choices in (
            ("execution", EXECUTIONS),
            ("reward", REWARDS),
            ("backend", BACKENDS),
            ("first_held_ratio", FIRST_HELD_RATIOS),
        ):
            check_choice(name, getattr(self, name), choices)
        if self.smooth_lambda is not None:
            if self.reward != "smooth":
                raise ValueError(
                    f"smooth_lambda: only --reward smooth has a price, got smooth_lambda="
                    f"{self.smooth_lambda!r} with reward={self.reward!r}"
                )
            v = self.smooth_lambda
            if isinstance(v, bool) or not isinstance(v, (int, float)) or v < 0:
                raise ValueError(f"smooth_lambda: expected a finite number >= 0, got {v!r}")
        if self.first_held_ratio == "release" and self.execution != "first-held":
            raise ValueError(
                "first_held_ratio: 'release' scores the executed first sub-action and needs "
                f"execution='first-held', got execution={self.execution!r}"
            )
        _check_device(self.device)
        if self.vector not in ("auto", "sync", "workers", "async", "overlap"):
            raise ValueError(
                "vector: expected 'auto', 'sync', 'workers', 'async' or 'overlap', "
                f"got {self.vector!r}"
            )
        if self.vector == "overlap" and (self.num_envs < 2 or self.num_envs % 2):
            raise ValueError(
                "vector: 'overlap' steps two equal env groups and needs an even num_envs >= 2, "
                f"got num_envs={self.num_envs}"
            )
        if self.vector == "overlap" and self.policy.noise == "ar1":
            raise ValueError(
                "vector: 'overlap' is not built for noise='ar1' (an ended episode's fresh carry is "
                "drawn between two decisions of all envs, an order two groups cannot keep): use "
                "vector='auto'"
            )
        if self.env_workers is not None:
            check_int("env_workers", self.env_workers, 1)
            if self.env_workers > self.num_envs:
                raise ValueError(
                    f"env_workers: expected at most num_envs={self.num_envs}, "
                    f"got {self.env_workers}"
                )

    # ----------------------------------------------------------------- derived values
    @property
    def k(self) -> int:
        """Sub-steps per decision (1 for PPO; an unresolved config's k is the method's)."""
        if self.policy.k is None:
            # every instance is a TrainConfig (RunConfig is only ever built as its base)
            return resolve_config(cast("TrainConfig", self)).k
        return self.policy.k

    @property
    def decisions_per_env(self) -> int:
        """Decisions each env makes per update: ceil(steps_per_update / (k * num_envs))."""
        return math.ceil(self.steps_per_update / (self.k * self.num_envs))

    @property
    def env_steps_per_update(self) -> int:
        """Env steps (sub-step slots) per update after rounding: decisions * k * num_envs."""
        return self.decisions_per_env * self.k * self.num_envs

    @property
    def num_updates(self) -> int:
        """Updates in the run: ceil(steps / env_steps_per_update)."""
        return math.ceil(self.steps / self.env_steps_per_update)

    def env_options(self) -> EnvOptions:
        """The task options every env of this run gets (``ndp.envs.make_env`` keywords):
        ``reward_version``, ``backend`` where not 'metaworld', ``observation`` where not 'full',
        ``reward`` where not 'dense' (with
        ``smooth_lambda`` where set), and the ``fixed_goal``: for ``goals="per-seed"`` the seed
        derived from ``seed`` (``ndp.envs.fixed_goal_seed``), for ``goals="release"`` the
        string ``"release"``."""
        out: EnvOptions = {"reward_version": self.reward_version}
        if self.backend != "metaworld":
            out["backend"] = self.backend
        if self.observation != "full":
            out["observation"] = self.observation
        if self.reward != "dense":
            out["reward"] = self.reward
        if self.smooth_lambda is not None:
            out["smooth_lambda"] = self.smooth_lambda
        if self.goals == "per-seed":
            from ndp.envs.factory import fixed_goal_seed

            out["fixed_goal"] = fixed_goal_seed(self.seed)
        elif self.goals == "release":
            out["fixed_goal"] = "release"
        return out

    def chunk_options(self) -> ChunkOptions:
        """The :class:`ndp.envs.ChunkedEnv` keywords of this run (``stale_world``,
        ``execution``): every env the run's policy acts in gets them (training, evaluation,
        rendering)."""
        return {"stale_world": self.stale_world, "execution": self.execution}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (nested for ``ppo``, ``policy`` and each learner's section)."""
        return dataclasses.asdict(self)

    @staticmethod
    def from_dict(d: dict[str, Any]) -> TrainConfig:
        """Inverse of :meth:`to_dict` (unknown keys raise ValueError); also reads every
        earlier layout (:func:`current_layout`: the run fields once under ``"ppo"``)."""
        d = current_layout(d)
        pol = dict(d.pop("policy", {}))
        # configs written before the per-task frame preset always hold these two keys; older
        # ones (without them) ran the fixed default of their time, the commanded frame at rest
        pol.setdefault("dmp_state", "commanded")
        pol.setdefault("dmp_velocity", "zero")
        d.setdefault("eval_every", 0)  # configs written before the periodic evaluation: none ran
        policy = PolicyConfig.from_dict(pol)  # flat (before NDPHeadConfig) or nested
        try:
            ppo = PPOConfig(**d.pop("ppo", {}))
            # a section missing (a config written before its learner): its defaults
            sections = {s.name: s.cls(**d.pop(s.name, {})) for s in SETTINGS.values()}
            return TrainConfig(ppo=ppo, policy=policy, **sections, **d)
        except TypeError as exc:
            raise ValueError(f"config: {exc}") from None


MOVED_FROM_PPO = ("gamma", "steps_per_update", "norm_obs", "clip_obs")
"""The run's fields that ``config.json`` (and a ``--config`` file, an export's
``policy.json``) held under ``"ppo"`` before they became the run's own: every learner reads
them, PPO's section holds only PPO's settings."""


def current_layout(d: dict[str, Any]) -> dict[str, Any]:
    """A config dict (a run's ``config.json``, an export's, a ``--config`` file's fields) in
    this version's layout: the fields of :data:`MOVED_FROM_PPO` found under ``"ppo"`` moved to
    the top level (a new dict; the sections copied, not changed in place).

    Raises:
        ValueError: a field given both at the top level and under ``"ppo"`` with two values.
    """
    d = dict(d)
    ppo = d.get("ppo")
    if not isinstance(ppo, dict) or not any(name in ppo for name in MOVED_FROM_PPO):
        return d
    ppo = dict(ppo)
    for name in MOVED_FROM_PPO:
        if name not in ppo:
            continue
        value = ppo.pop(name)
        if name in d and d[name] != value:
            raise ValueError(
                f"config: {name} is given twice, {d[name]!r} and ppo.{name}={value!r} (it is "
                f"the run's own field now: give it once, at the top level)"
            )
        d[name] = value
    d["ppo"] = ppo
    return d


def _train_config() -> type[RunConfig]:
    """:class:`RunConfig` plus one field per registered settings section (``name:
    cls = cls()``, its help the section's line), frozen; built once."""
    fields = [
        (s.name, Annotated[s.cls, cli(help=s.doc)], field(default_factory=s.cls))
        for s in settings_sections()
    ]
    # built in this module's namespace: pickled as ndp.rl.config.TrainConfig, and the
    # generated __init__ resolves RunConfig's string annotations here
    here = {"__module__": __name__, "__qualname__": "TrainConfig"}
    cls = dataclasses.make_dataclass(
        "TrainConfig", fields, bases=(RunConfig,), frozen=True, namespace=here
    )
    for s in SETTINGS.values():  # the class attribute: the section's defaults (as a plain
        setattr(cls, s.name, s.cls())  # dataclass field with a default has; docs tools read it)
    cls.__doc__ = (
        "One training run: task, method, budget, envs, logging; plus PPO and policy settings, "
        f"and the learners' sections ({', '.join(SETTINGS)})."
    )
    return cls


def help_config_class(algo: str) -> type[RunConfig]:
    """The config class ``ndp rl train --algo ALGO --help`` shows: :class:`RunConfig` plus the
    learner sections ``ALGO`` reads (``Method.reads``), the others left out.

    Raises:
        ValueError: an unknown ``algo`` (naming the registered ones).
    """
    method = METHODS.get(algo)
    if method is None:
        raise ValueError(f"algo: expected one of {', '.join(METHODS)}, got {algo!r}")
    sections = {r.split(".", 1)[0] for r in method.reads}
    fields = [
        (s.name, Annotated[s.cls, cli(help=s.doc)], field(default_factory=s.cls))
        for s in settings_sections()
        if s.name in sections
    ]
    here = {"__module__": __name__, "__qualname__": "TrainConfig"}
    return dataclasses.make_dataclass(
        "TrainConfig", fields, bases=(RunConfig,), frozen=True, namespace=here
    )


if TYPE_CHECKING:
    from ndp.envs.spec import TaskSpec

    class TrainConfig(RunConfig):
        """:class:`RunConfig` plus the registered learners' sections (for the type checker:
        the sections are read typed with ``ndp.rl.methods.section(cfg, SACConfig)`` and
        replaced with ``ndp.rl.methods.with_section``; the constructor takes every field)."""

        def __init__(self, **fields: object) -> None: ...

else:
    TrainConfig = _train_config()


def resolve_config(cfg: TrainConfig, spec: TaskSpec | None = None) -> TrainConfig:
    """Fill the task-dependent fields and validate; nothing here builds an environment.

    - ``task``: the method's task-table row (``Method.task_variant``: VICES runs the
      torque-actuated variant of the requested task), by its canonical name.
    - ``policy.head`` follows ``algo``; ``policy.k``, ``hidden`` and ``activation`` left at
      None get the method's (k: 1 for the one-action methods, 5 otherwise, the controller's
      period for VICES); a k the method cannot run is refused (ValueError naming k).
    - ``policy.dmp_state`` / ``dmp_velocity`` (the DMP's frame) from the task's preset where
      None (every method: the trainer records the robot state in that frame);
    - NDP: ``n_basis``, ``a_z``, ``goal_scale`` from the task's preset where None;
      ``dmp_steps`` = preset steps per sub-step * k; ``weight_scale`` = a_z^2 / 4 where None.
    - ``policy.chunk_basis`` / ``chunk_basis_file``: PPO-multi's (``ndp.rl.methods.
      resolve_multi`` checks them and resolves ``n_basis``); cleared for every other head.
    - ``run_dir`` defaults to ``runs/<task>-<algo>-s<seed>``.
    - ``goals="as-release"`` becomes what the release gave the method on the task
      (``ndp.envs.release.release_goals``).
    - ``smooth_lambda`` of a smooth reward: ``ndp.envs.rewards.DEFAULT_SMOOTH_LAMBDA`` where
      None; a sparse or smooth reward with the stale-world rule at k > 1 is refused
      (ValueError naming ``--reward`` and ``--no-stale-world``).
    - ``backend='envpool'``: refused (ValueError naming ``backend``) for what it does not serve
      (``ndp.envs.envpool_backend.check_backend``), and ImportError with the install hint where
      EnvPool is missing.

    Args:
        cfg: the requested config.
        spec: the task spec (resolved from ``cfg.task`` when None; unknown task: ValueError).

    Returns:
        The resolved config (a new object).
    """
    if spec is None:
        from ndp.rl.envs import resolve_task

        spec = resolve_task(cfg.task).spec
    from ndp.checks import check_device_available
    from ndp.envs.factory import check_observation, task_options

    task_options(spec, cfg.reward_version)  # v1 rewards on a task without them: refused here
    check_observation(spec, cfg.observation)
    check_device_available(cfg.device)  # before any env is built or run folder made
    method = METHODS[cfg.algo]
    if method.task_variant is not None:
        spec = method.task_variant(spec)
    policy = _resolve_policy(cfg, method, spec)
    run_dir = cfg.run_dir or default_run_dir(spec.name, cfg.algo, cfg.seed)
    goals = _resolve_goals(cfg, spec)
    assert policy.k is not None  # set by _resolve_policy
    _check_env_options(cfg, spec, policy.k, goals)
    from ndp.envs.rewards import check_smooth_lambda

    price = check_smooth_lambda(cfg.smooth_lambda, cfg.reward) if cfg.reward == "smooth" else None
    return dataclasses.replace(
        cfg, task=spec.name, policy=policy, run_dir=run_dir, goals=goals, smooth_lambda=price
    )


def _resolve_policy(cfg: TrainConfig, method: Method, spec: TaskSpec) -> PolicyConfig:
    """:func:`resolve_config`'s policy: the method's head and k (a k the method cannot run
    refused, naming k), the DMP frame from the task's preset where None, PPO-multi's chunk
    basis cleared for the other heads, then the method's own resolution and the defaults."""
    from ndp.envs.presets import preset_of
    from ndp.policies.config import BASIS_HEADS, DEFAULT_K
    from ndp.policies.heads import SINGLE_STEP_HEADS

    pol = cfg.policy
    k_asked = pol.k
    one_action = method.head in SINGLE_STEP_HEADS
    k = 1 if one_action else (k_asked or DEFAULT_K)
    # the DMP frame is read by the trainer for every method (the robot state it records)
    preset = preset_of(spec)
    frame = {
        name: getattr(pol, name) if getattr(pol, name) is not None else getattr(preset, name)
        for name in ("dmp_state", "dmp_velocity")
    }
    if method.head not in BASIS_HEADS:  # PPO-multi's chunk basis: cleared for other heads
        frame.update(chunk_basis="none", chunk_basis_file=None)  # (a note names it: cli)
    with_k = dataclasses.replace(pol, head=method.head, k=k, **frame)
    policy = with_k.updated(**method.resolve(with_k, spec)).with_defaults()
    if k_asked is not None and policy.k != k_asked:  # one check for every method's own k
        how = (
            "runs one action per decision (k = 1)"
            if one_action
            else f"decides every {policy.k} env step(s) on {spec.name}"
        )
        raise ValueError(f"k: --algo {cfg.algo} {how}, got k={k_asked}")
    return policy


def _resolve_goals(cfg: TrainConfig, spec: TaskSpec) -> str:
    """:func:`resolve_config`'s ``goals``: ``"as-release"`` becomes what the release gave the
    method on the task; ``"release"`` is refused, before any run folder, where there is none."""
    from ndp.envs.factory import task_options

    goals = cfg.goals
    if goals == "as-release":
        from ndp.envs.release import release_goals

        try:
            goals = release_goals(spec.name, cfg.algo)
        except ValueError as exc:
            raise ValueError(f"goals: 'as-release' needs a task the release ran ({exc})") from None
    if goals == "release":  # refused here, before any run folder, where there is none
        task_options(spec, cfg.reward_version, "release")
    return goals


def _check_env_options(cfg: TrainConfig, spec: TaskSpec, k: int, goals: str) -> None:
    """:func:`resolve_config`'s environment checks: the stale-world rule with the reward at
    this k, and the backend (what EnvPool does not serve refused; its install hint where it is
    missing), before any run folder."""
    from ndp.envs.envpool_backend import check_backend
    from ndp.envs.rewards import check_stale_world

    check_stale_world(cfg.reward, cfg.stale_world, k)
    fixed = None if goals == "random" else goals
    check_backend(cfg.backend, spec, k=k, stale_world=cfg.stale_world,
                  reward_version=cfg.reward_version, fixed_goal=fixed)  # fmt: skip
    if cfg.backend == "envpool":
        from ndp.envs.envpool_backend import import_envpool

        import_envpool()  # the install hint before any run folder


def default_run_dir(task: str, algo: str, seed: int) -> str:
    """``runs/<task>-<algo>-s<seed>`` (:func:`ndp.runs.layout.run_name`), the run directory of
    a config without one; ``task`` is the canonical name of the row the method runs
    (:func:`resolve_config` is the one caller: an alias or VICES's task variant is resolved
    first, so every message and ``--resume`` names the directory the run is in)."""
    from ndp.runs.layout import run_name

    return str(Path("runs") / run_name(task, algo, seed))


def unused_head_options(cfg: TrainConfig) -> list[str]:
    """The NDP head's fields set away from their defaults for a method whose head has no DMP
    (``--algo ppo --n-basis 3``): ``["n_basis=3", ...]``, empty when none or when the method runs
    the NDP head. Such options are accepted and not used (a sweep's ``-o`` overrides span every
    arm); ``ndp rl train`` names them in a note so that they are not dropped silently."""
    from ndp.policies.config import BASIS_HEADS, DMP_HEADS, NDPHeadConfig

    method = METHODS.get(cfg.algo)
    if method is None or method.head in DMP_HEADS:
        return []
    default = NDPHeadConfig()
    used = _basis_reads(cfg) if method.head in BASIS_HEADS else ()
    return [
        f"{f.name}={getattr(cfg.policy.ndp, f.name)!r}"
        for f in dataclasses.fields(NDPHeadConfig)
        if getattr(cfg.policy.ndp, f.name) != getattr(default, f.name) and f.name not in used
    ]


def _basis_reads(cfg: TrainConfig) -> tuple[str, ...]:
    """The NDP head's fields PPO-multi's chunk basis reads: ``n_basis`` (its columns), and for
    the 'dmp' basis every field of the NDP head it is the span of (not ``param_noise``,
    ``mean_clip``: its exploration and mean are PPO-multi's)."""
    from ndp.policies.config import NDP_FIELDS

    basis = cfg.policy.chunk_basis
    if basis == "none":
        return ()
    if basis == "dmp":
        return tuple(f for f in NDP_FIELDS if f not in ("param_noise", "mean_clip"))
    return ("n_basis",)


def unused_basis_options(cfg: TrainConfig) -> list[str]:
    """PPO-multi's chunk-basis options given to a method whose head does not read them
    (``--algo ndp --chunk-basis dct``): ``["chunk_basis='dct'", ...]``; empty when none.
    Accepted and cleared by :func:`resolve_config`; ``ndp rl train`` names them in a note."""
    from ndp.policies.config import BASIS_HEADS

    method = METHODS.get(cfg.algo)
    if method is None or method.head in BASIS_HEADS:
        return []
    pol = cfg.policy
    return [
        f"{name}={getattr(pol, name)!r}"
        for name, default in (("chunk_basis", "none"), ("chunk_basis_file", None))
        if getattr(pol, name) != default
    ]


LEARNER_SECTIONS = ("ppo", *SETTINGS)
"""The sections of :class:`TrainConfig` that belong to one learner (``Method.reads``): the
shared on-policy trainer's ``ppo`` and every registered learner's."""


def unused_method_options(cfg: TrainConfig) -> list[str]:
    """The learner settings set away from their defaults that ``cfg.algo`` does not read
    (``--algo ppo --sac-lr 1e-3``, ``--algo sac --clip 0.1``, ``--algo sac --no-norm-obs``):
    ``["sac.lr=0.001", ...]``, a run field of :data:`ndp.rl.methods.METHOD_RUN_FIELDS` by its
    name (``"norm_obs=False"``); empty when none. ``ndp rl train`` refuses them."""
    method = METHODS.get(cfg.algo)
    if method is None:
        return []
    out = [
        f"{name}={getattr(cfg, name)!r}"
        for name in METHOD_RUN_FIELDS
        if name not in method.reads and getattr(cfg, name) != getattr(RunConfig, name)
    ]
    for section in LEARNER_SECTIONS:
        if section in method.reads:
            continue
        value, default = getattr(cfg, section), type(getattr(cfg, section))()
        for f in dataclasses.fields(value):
            v = getattr(value, f.name)
            if v != getattr(default, f.name) and f"{section}.{f.name}" not in method.reads:
                out.append(f"{section}.{f.name}={v!r}")
    return out


def load_config(path: Path) -> TrainConfig:
    """Read a run's ``config.json`` (written by the trainer through :class:`ndp.runs.RunDir`)."""
    path = Path(path)
    from ndp.runs.layout import kind_of_run, wrong_kind

    kind = kind_of_run(path.parent)
    if kind not in (None, "rl"):  # an imitation or SB3 run: say so, and what reads it
        raise ValueError(wrong_kind(path.parent, kind, "rl"))
    if not path.is_file():
        raise FileNotFoundError(f"config: no such file {path}")
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"config: {path} is not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"config: {path} does not hold a JSON object")
    try:
        return TrainConfig.from_dict(data)
    except ValueError as exc:
        raise ValueError(
            f"config: {path} is not a config of this version ({str(exc).removeprefix('config: ')})"
        ) from None


def _check_device(device: object) -> None:
    import torch

    try:
        torch.device(device)  # type: ignore[call-overload]
    except (RuntimeError, TypeError):
        raise ValueError(
            f"device: expected a torch device such as 'cpu' or 'cuda', got {device!r}"
        ) from None
