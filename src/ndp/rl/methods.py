"""Method registry: a method names its action head, how its policy settings are resolved
against a task, and the extra metrics it logs, in one place.

Adding an on-policy method = its head (``ndp.policies.heads.register_head``) and one
:func:`register_method` line; ``ndp rl train --algo NAME`` then trains it with the shared
trainer, envs, evaluation and rendering (``tests/rl/test_rl_methods.py`` does exactly that).

An off-policy (or any other) learner plugs in through :attr:`Method.learner`: it gets the
resolved config and builds its envs with :func:`ndp.rl.envs.make_vector_env`, writes its run
with :mod:`ndp.runs` and leaves a checkpoint with the keys of :data:`POLICY_CHECKPOINT_KEYS`;
``ndp rl eval / render / export`` and ``ndp.load_policy`` then work on its runs unchanged
(``tests/rl/test_rl_methods.py`` registers a toy random-search learner and evaluates it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

_NDP_FIELDS = ("n_basis", "a_z", "dmp_steps", "goal_scale", "weight_scale")


def no_dmp(policy: Any, spec: Any) -> dict[str, Any]:
    """Resolution of heads without a DMP: the NDP-only fields are cleared."""
    return {**dict.fromkeys(_NDP_FIELDS), "param_noise": False}


def resolve_ndp(policy: Any, spec: Any) -> dict[str, Any]:
    """NDP: ``n_basis``, ``a_z``, ``goal_scale`` from the task's preset where None;
    ``dmp_steps`` = preset steps per sub-step * k; ``weight_scale`` = a_z^2 / 4 where None."""
    from ndp.envs.presets import preset_of

    pre = preset_of(spec)
    a_z = float(policy.a_z if policy.a_z is not None else pre.a_z)
    return {
        "n_basis": policy.n_basis if policy.n_basis is not None else pre.n_basis,
        "a_z": a_z,
        "dmp_steps": policy.dmp_steps
        if policy.dmp_steps is not None
        else pre.steps_per_substep * policy.k,
        "goal_scale": float(policy.goal_scale if policy.goal_scale is not None else pre.goal_scale),
        "weight_scale": float(
            policy.weight_scale if policy.weight_scale is not None else a_z * a_z / 4.0
        ),
    }


@dataclass(frozen=True)
class Method:
    """One training method of the shared on-policy trainer."""

    name: str
    """``--algo`` value."""
    head: str
    """Action head (a name registered with ``ndp.policies.heads.register_head``)."""
    description: str
    """One line for ``--help`` and docs."""
    resolve: Callable[[Any, Any], dict[str, Any]] = no_dmp
    """``(policy config with k set, task spec) -> PolicyConfig changes`` (task presets)."""
    metrics: tuple[str, ...] = field(default=())
    """Extra metric keys this method fills (docs/metrics.md)."""
    task_variant: Callable[[Any], Any] | None = None
    """``task spec -> the task-table row this method runs on`` (VICES: the torque-actuated
    variant of the requested task, ``ndp.envs.torque_variant``); None: the requested row."""
    learner: Callable[[Any, bool], Any] | None = None
    """``learner(resolved TrainConfig, resume) -> object with train(max_updates=None) -> last
    metrics and close()``, for a method with its own learning loop (off-policy, evolution, ...);
    None: the shared PPO trainer (:class:`ndp.rl.trainer.Trainer`)."""


POLICY_CHECKPOINT_KEYS = ("model", "obs_norm", "obs_dim", "config", "update", "global_step")
"""What a learner's ``checkpoint.pt`` (``ndp.runs.save_checkpoint(..., kind='rl')``) must hold
for evaluation, rendering, export and resume bookkeeping: ``model`` is the state dict of
``ndp.policies.build_actor_critic(obs_dim, spec, config.policy)``, ``obs_norm`` that of
``ndp.rl.normalize.ObsNormalizer``, ``config`` the resolved ``TrainConfig.to_dict()``."""


METHODS: dict[str, Method] = {}
"""Method name -> :class:`Method`."""


def register_method(method: Method) -> Method:
    """Add a method (its head must be registered); returns it."""
    from ndp.policies.heads import HEAD_BUILDERS

    if method.name in METHODS:
        raise ValueError(f"name: method {method.name!r} is already registered")
    if method.head not in HEAD_BUILDERS:
        raise ValueError(
            f"head: {method.head!r} is not a registered head ({', '.join(HEAD_BUILDERS)})"
        )
    METHODS[method.name] = method
    return method


register_method(Method("ppo", "step", "PPO: one raw action per env step (k = 1)"))
register_method(Method("ppo-multi", "multi", "PPO-multi: k raw actions per decision"))
register_method(
    Method(
        "ndp",
        "ndp",
        "NDP: DMP parameters per decision, integrated into k actions",
        resolve=resolve_ndp,
        metrics=("dmp/goal_norm", "dmp/weight_norm"),
    )
)


DYNE_METRICS = (
    "dyne/embed_loss",
    "dyne/embed_kl",
    "dyne/decoder_loss",
    "dyne/q",
    "dyne/replay",
    "dyne/gradient_steps",
)
"""Extra ``metrics.csv`` columns of Dyn-E runs (docs/metrics.md)."""


def resolve_dyne(policy: Any, spec: Any) -> dict[str, Any]:
    """Dyn-E: no DMP; the TD3 actor is 400-300 ReLU (the original's) unless ``hidden`` /
    ``activation`` were changed from the PPO defaults ((100, 100), tanh)."""
    out = no_dmp(policy, spec)
    if tuple(policy.hidden) == (100, 100):
        out["hidden"] = (400, 300)
    if policy.activation == "tanh":
        out["activation"] = "relu"
    return out


def _dyne_learner(cfg: Any, resume: bool) -> Any:
    from ndp.rl.dyne import DyneLearner  # torch and the simulators only once it trains

    return DyneLearner(cfg, resume)


register_method(
    Method(
        "dyne",
        "dyne",
        "Dyn-E: TD3 in a learned, dynamics-aware embedding of k-action sequences",
        resolve=resolve_dyne,
        metrics=DYNE_METRICS,
        learner=_dyne_learner,
    )
)


from ndp.rl import vices as _vices  # noqa: E402  (registers vices, vices-pos, vices-low-freq)

del _vices
