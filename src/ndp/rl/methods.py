"""Method registry: a method names its action head, how its policy settings are resolved
against a task, and the extra metrics it logs, in one place.

Adding an on-policy method = its head (``ndp.policies.heads.register_head``) and one
:func:`register_method` line; ``ndp rl train --algo NAME`` then trains it with the shared
trainer, envs, evaluation and rendering (``tests/rl/test_rl_methods.py`` does exactly that).

An off-policy (or any other) learner plugs in through :attr:`Method.learner`: an
:class:`ndp.rl.run.RLLearner` built from the resolved config and the run session, which builds
its envs with :func:`ndp.rl.envs.make_vector_env`; the run driver (:mod:`ndp.runs.driver`)
opens, seeds, restores, drives and checkpoints it, and its ``state_dict`` holds the keys of
:data:`POLICY_CHECKPOINT_KEYS`;
``ndp rl eval / render / export`` and ``ndp.load_policy`` then work on its runs unchanged
(``tests/rl/test_rl_methods.py`` registers a toy random-search learner and evaluates it).

A learner with its own settings is one package that calls :func:`register_learner` once: its
settings section (:class:`Settings`: the ``TrainConfig`` field, the frozen dataclass, the
``--prefix-`` of its options) and its methods. :mod:`ndp.rl.config` builds ``TrainConfig``
from the registered sections (nothing there names a learner); ``config.json``, ``--help``,
resume and the note on options a method does not read (``Method.reads``) follow.

The on-policy methods (``ppo``, ``ppo-multi``, ``ppo-repeat``, ``ndp``, ``vices``,
``vices-pos``, ``vices-low-freq``) are registered below; the learner packages of
:data:`BUILTIN_LEARNERS` (Dyn-E, the SAC family, TD3) register themselves and are imported here
by name. Registering imports no torch (a built-in head is taken on its name) and the registry
imports no learner module: learners are named by entry point, so the learners and the config
may import the registry without an import circle (``tests/test_import_graph.py``).
"""

from __future__ import annotations

import dataclasses
import importlib
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar

from ndp.policies import chunk_basis
from ndp.policies.config import FILE_BASES, PRESET_FIELDS, PolicyConfig
from ndp.runs.cli import HIDDEN

if TYPE_CHECKING:
    from ndp.envs.spec import TaskSpec
    from ndp.rl.config import TrainConfig
    from ndp.rl.run import RLLearner
    from ndp.runs.session import RunSession
    from ndp.schema import TaskSchema

METHOD_RUN_FIELDS = ("norm_obs",)
"""The run's fields (``ndp.rl.config.RunConfig``) that not every method reads: a method reads
one where its :attr:`Method.reads` names it (the on-policy methods and Dyn-E normalise their
observations; the SAC family and TD3 learn on raw ones), and ``ndp rl train`` refuses one set
for a method that does not, as it refuses a learner section's option. Every other run field
(the discount, the update's size, the observation clip, ...) is every method's."""

PolicyChanges = dict[str, object]
"""A method's ``PolicyConfig`` changes, by field name (the NDP head's fields flat, as
``PolicyConfig.updated`` takes them)."""


def no_dmp(policy: PolicyConfig, spec: TaskSchema) -> PolicyChanges:
    """Resolution of heads without a DMP: the NDP head's preset fields are cleared (and its
    exploration and parameter map set back to their defaults)."""
    return {**dict.fromkeys(PRESET_FIELDS), "param_noise": False, "param_map": "tanh"}


def resolve_ndp(policy: PolicyConfig, spec: TaskSchema) -> PolicyChanges:
    """NDP: ``n_basis``, ``a_z``, ``goal_scale`` from the task's preset where None;
    ``dmp_steps`` = preset steps per sub-step * k; ``weight_scale`` = a_z^2 / 4 where None."""
    from ndp.envs.presets import preset_of

    pre, head = preset_of(spec), policy.ndp
    assert policy.k is not None  # resolvers get the config with k set (resolve_config)
    a_z = float(head.a_z if head.a_z is not None else pre.a_z)
    return {
        "n_basis": head.n_basis if head.n_basis is not None else pre.n_basis,
        "a_z": a_z,
        "dmp_steps": head.dmp_steps
        if head.dmp_steps is not None
        else pre.steps_per_substep * policy.k,
        "goal_scale": float(head.goal_scale if head.goal_scale is not None else pre.goal_scale),
        "weight_scale": float(
            head.weight_scale if head.weight_scale is not None else a_z * a_z / 4.0
        ),
    }


def resolve_multi(policy: PolicyConfig, spec: TaskSchema) -> PolicyChanges:
    """PPO-multi: no DMP, unless its chunk is restricted to a basis (``policy.chunk_basis``).

    A basis has 1 + N columns per DoF, N = ``n_basis`` (the task's NDP preset where None); the
    'dmp' basis resolves every NDP field as the 'ndp' method does (:func:`resolve_ndp`: the
    DMP, bounds and clocks whose span it is). Checked here, before any env is built: 1 + N
    <= k; 'dmp' without ``only_g``, ``learn_az`` or forcing 'goal' (not affine in (g, w));
    'pca': its file exists and was fitted for this task, k, DoF count and N.

    Raises:
        ValueError: one line naming the option and what was expected.
    """
    basis = policy.chunk_basis
    if basis == "none":
        return no_dmp(policy, spec)
    from ndp.envs.presets import preset_of

    head = policy.ndp
    assert policy.k is not None  # resolvers get the config with k set (resolve_config)
    n_basis = int(head.n_basis if head.n_basis is not None else preset_of(spec).n_basis)
    chunk_basis.check_columns(basis, 1 + n_basis, int(policy.k))
    if basis == "dmp":
        bad = [f"{name}={value!r}" for name, value, ok in (
            ("only_g", head.only_g, False), ("learn_az", head.learn_az, False),
            ("forcing", head.forcing, "amplitude")) if value != ok]  # fmt: skip
        if bad:
            raise ValueError(
                f"chunk_basis: the 'dmp' basis is the NDP head's affine span in (g, w) "
                f"(forcing 'amplitude', no only_g, no learn_az), got {', '.join(bad)}"
            )
        # the mean and the exploration are PPO-multi's: no clip of the mean, no parameter noise
        return {**resolve_ndp(policy, spec), "param_noise": False, "mean_clip": False}
    if basis in FILE_BASES:
        path = policy.chunk_basis_file
        assert path is not None  # PolicyConfig requires the file of a file basis
        data = chunk_basis.read_basis_file(path)
        chunk_basis.check_basis_file(
            data,
            path,
            task=spec.name,
            k=int(policy.k),
            action_dim=int(spec.action_dim),
            columns=1 + n_basis,
        )
    return {**no_dmp(policy, spec), "n_basis": n_basis}


@dataclass(frozen=True)
class Method:
    """One training method of the shared on-policy trainer."""

    name: str
    """``--algo`` value."""
    head: str
    """Action head (a name registered with ``ndp.policies.heads.register_head``)."""
    description: str
    """One line for ``--help`` and docs."""
    resolve: Callable[[PolicyConfig, TaskSpec], PolicyChanges] = no_dmp
    """``(policy config with k set, task spec) -> PolicyConfig changes`` (task presets; the NDP
    head's fields flat, as ``PolicyConfig.updated`` takes them)."""
    metrics: tuple[str, ...] = field(default=())
    """Extra metric keys this method fills (docs/metrics.md)."""
    task_variant: Callable[[TaskSpec], TaskSpec] | None = None
    """``task spec -> the task-table row this method runs on`` (VICES: the torque-actuated
    variant of the requested task, ``ndp.envs.torque_variant``); None: the requested row."""
    learner: Callable[[TrainConfig, RunSession], RLLearner] | str | None = None
    """``learner(resolved TrainConfig, RunSession) -> ndp.rl.run.RLLearner``, for a method with
    its own learning loop (off-policy, evolution, ...), or its entry point
    ``"package.module:name"`` (imported at the first :meth:`build_learner`, as gymnasium's
    registry imports an env's ``entry_point``: the registry imports no learner, so a learner
    module may import the registry and the config); None: the shared PPO trainer
    (:class:`ndp.rl.onpolicy.trainer.Trainer`)."""
    hint: str = "Try a smaller learning rate or check the task's reward / actions."
    """What to try after the run diverges (ends the divergence error's message)."""
    reads: tuple[str, ...] = ("ppo", "norm_obs")
    """The learner settings of :class:`ndp.rl.config.TrainConfig` this method reads: a
    section (``"ppo"``, ``"sac"``, ``"dyne"``), one field of it (``"ppo.lr"``), or a run field
    of :data:`METHOD_RUN_FIELDS` (``"norm_obs"``). An option of a section or such a field it
    does not read, set on the command line, is refused
    (:func:`ndp.rl.config.unused_method_options`) instead of being dropped without a word. The
    run's other fields (``gamma``, ``steps_per_update``, ...) every method reads."""

    def __post_init__(self) -> None:
        if isinstance(self.learner, str):
            mod, sep, attr = self.learner.partition(":")
            if not (sep and mod and attr and all(p.isidentifier() for p in mod.split("."))):
                raise ValueError(
                    f"learner: expected a callable or an entry point 'package.module:name', "
                    f"got {self.learner!r}"
                )

    def build_learner(self, cfg: TrainConfig, session: RunSession) -> RLLearner | None:
        """The learner of a resolved config in its run ``session`` (``learner`` called, its
        entry point imported first); None when the method trains with the shared PPO
        trainer."""
        if self.learner is None:
            return None
        build = self.learner
        if isinstance(build, str):
            mod, _, attr = build.partition(":")
            try:
                build = getattr(importlib.import_module(mod), attr)
            except (ImportError, AttributeError) as e:
                raise ValueError(
                    f"learner: method {self.name!r} names {self.learner!r}, which does not "
                    f"import ({e})"
                ) from e
        return build(cfg, session)


POLICY_CHECKPOINT_KEYS = ("model", "obs_norm", "obs_dim", "config", "update", "global_step")
"""What a learner's ``checkpoint.pt`` (``ndp.runs.save_checkpoint(..., kind='rl')``) must hold
for evaluation, rendering, export and resume bookkeeping: ``model`` is the state dict of
``ndp.policies.build_actor_critic(obs_dim, spec, config.policy)``, ``obs_norm`` that of
``ndp.rl.normalize.ObsNormalizer``, ``config`` the resolved ``TrainConfig.to_dict()``."""


METHODS: dict[str, Method] = {}
"""Method name -> :class:`Method`."""


BUILTIN_HEADS = ("step", "multi", "hold", "ndp", "dyne", "squashed", "ndp-squashed")
"""The heads ``ndp.policies`` registers (when ``ndp.policies.heads`` is imported): a method on
one of them registers without importing torch (``tests/rl/test_rl_methods.py`` checks the
list against ``HEAD_BUILDERS``)."""


def normalises_obs(algo: str) -> bool:
    """Whether method ``algo``'s learner feeds its policy normalised observations (it reads
    ``norm_obs``: the PPO trainer, Dyn-E); the SAC family and TD3 train on the raw observations,
    so a policy loaded from their runs must not normalise (nor clip) them either. An unknown
    method: True (the run's ``norm_obs`` decides)."""
    m = METHODS.get(algo)
    return m is None or "norm_obs" in m.reads


def register_method(method: Method) -> Method:
    """Add a method (its head must be registered); returns it. A built-in head
    (:data:`BUILTIN_HEADS`) is taken on its name, so registering imports no torch; any other
    head is looked up in ``ndp.policies.heads.HEAD_BUILDERS``."""
    if method.name in METHODS:
        raise ValueError(f"name: method {method.name!r} is already registered")
    if method.head not in BUILTIN_HEADS:
        from ndp.policies.heads import HEAD_BUILDERS  # torch: only for a head of one's own

        if method.head not in HEAD_BUILDERS:
            raise ValueError(
                f"head: {method.head!r} is not a registered head ({', '.join(HEAD_BUILDERS)})"
            )
    METHODS[method.name] = method
    return method


T = TypeVar("T")


@dataclass(frozen=True)
class Settings:
    """One learner's settings: a section of :class:`ndp.rl.config.TrainConfig` (its field
    ``name``, nested under that key in ``config.json``), a frozen dataclass whose every field
    has a default and a docstring (its ``--help`` text)."""

    name: str
    """The section's name: the ``TrainConfig`` field, the ``config.json`` key, the prefix of
    the dotted names in ``Method.reads`` and in notes (``"sac"``: ``sac.lr``)."""
    cls: type
    """The settings dataclass (frozen; ``cls()`` gives the defaults; ``cls(**dict)`` reads a
    saved section; its ``__post_init__`` refuses a bad value with a one-line ValueError naming
    the field)."""
    flag_prefix: str
    """The prefix of the section's command-line options (``"sac"``: ``--sac-lr``; the fields
    spell it with ``ndp.runs.cli.cli(name="sac-lr")``, checked at registration); ``""``: plain
    ``--field-name`` options (Dyn-E's, older than the convention)."""
    doc: str
    """One line: what the section holds and which methods read it (the section's help)."""

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or self.name in RESERVED_SECTIONS:
            raise ValueError(f"name: expected an identifier not in {RESERVED_SECTIONS}, "
                             f"got {self.name!r}")  # fmt: skip
        if not (dataclasses.is_dataclass(self.cls) and isinstance(self.cls, type)):
            raise ValueError(f"cls: expected a dataclass, got {self.cls!r}")
        if not self.cls.__dataclass_params__.frozen:  # type: ignore[attr-defined]
            raise ValueError(f"cls: expected a frozen dataclass, got {self.cls.__name__}")
        for f in dataclasses.fields(self.cls) if TYPED_CLI else ():  # (no tyro: no options)
            flag = _flag_of(self.cls, f.name)
            if self.flag_prefix and not flag.startswith(self.flag_prefix + "-"):
                raise ValueError(
                    f"flag_prefix: {self.cls.__name__}.{f.name}'s option --{flag} does not "
                    f"start with --{self.flag_prefix}- (annotate it with "
                    f'ndp.runs.cli.cli(name="{self.flag_prefix}-..."))'
                )


RESERVED_SECTIONS = ("ppo", "policy")
"""``TrainConfig`` sections that belong to no registered learner: the shared on-policy
trainer's PPO settings and the policy (every method's)."""

SETTINGS: dict[str, Settings] = {}
"""Section name -> :class:`Settings`, in registration order (the order of ``TrainConfig``'s
sections after ``ppo`` and ``policy``, and of ``--help``)."""

_SETTINGS_FROZEN: list[bool] = [False]


TYPED_CLI = HIDDEN is not None
"""Whether tyro (the command lines' parser, an extra) is installed; without it the options'
annotations are empty and :class:`Settings` checks no prefix."""


def _flag_of(cls: type, name: str) -> str:
    """The command-line option (without ``--``) of field ``name`` of ``cls``: its
    ``cli(name=...)`` annotation, else the field name with dashes."""
    hint = typing.get_type_hints(cls, include_extras=True).get(name)
    for meta in getattr(hint, "__metadata__", ()):
        given = getattr(meta, "name", None)
        if isinstance(given, str):
            return given
    return name.replace("_", "-")


def register_learner(settings: Settings | None, *methods: Method) -> None:
    """A learner's one registration call: its settings section (None: it has none) and its
    methods (each reads its section: list it in ``Method.reads``). A learner registers when its
    package is imported; the built-in ones are listed in :data:`BUILTIN_LEARNERS`. Settings
    must be registered before :mod:`ndp.rl.config` builds ``TrainConfig`` (a learner package
    that ``ndp.rl.methods`` imports, or one imported before ``ndp.rl.config``).

    Raises:
        ValueError: a taken section or method name, a bad settings class or entry point, or
            settings registered after ``TrainConfig`` was built.
    """
    if settings is not None:
        if settings.name in SETTINGS:
            raise ValueError(f"name: settings {settings.name!r} are already registered")
        if _SETTINGS_FROZEN[0]:
            raise ValueError(
                f"settings: {settings.name!r} registered after ndp.rl.config built TrainConfig "
                "(import the learner's package before ndp.rl.config, or list it in "
                "ndp.rl.methods.BUILTIN_LEARNERS)"
            )
    for m in methods:
        if m.name in METHODS:
            raise ValueError(f"name: method {m.name!r} is already registered")
    if settings is not None:
        SETTINGS[settings.name] = settings
    for m in methods:
        register_method(m)


def settings_sections() -> tuple[Settings, ...]:
    """The registered settings, in order; from now on no section may be added (called once,
    when :mod:`ndp.rl.config` builds ``TrainConfig``)."""
    _SETTINGS_FROZEN[0] = True
    return tuple(SETTINGS.values())


def section(cfg: TrainConfig, cls: type[T]) -> T:
    """The settings of type ``cls`` of a ``TrainConfig`` (typed: ``section(cfg, SACConfig)``),
    from the section registered with that class.

    Raises:
        ValueError: no section was registered with ``cls``.
    """
    for s in SETTINGS.values():
        if s.cls is cls:
            value = getattr(cfg, s.name)
            assert isinstance(value, cls)
            return value
    raise ValueError(f"cls: no settings section is registered with {cls.__name__}")


def with_section(cfg: T, value: object) -> T:
    """``cfg`` with its settings section of ``type(value)`` replaced by ``value`` (a new
    config).

    Raises:
        ValueError: no section was registered with that class.
    """
    for s in SETTINGS.values():
        if s.cls is type(value):
            changes: dict[str, Any] = {s.name: value}
            out: T = dataclasses.replace(cfg, **changes)  # type: ignore[type-var]
            return out
    raise ValueError(f"value: no settings section is registered with {type(value).__name__}")


register_method(Method("ppo", "step", "PPO: one raw action per env step (k = 1)"))
register_method(
    Method(
        "ppo-multi",
        "multi",
        "PPO-multi: k raw actions per decision (--chunk-basis: restricted to a fixed basis of "
        "1 + n_basis columns per DoF)",
        resolve=resolve_multi,
    )
)
register_method(
    Method(
        "ppo-repeat",
        "hold",
        "PPO with action repeat: one raw action per decision, held for the k env steps (one "
        "log-prob per decision; the baseline of the release's first-held execution)",
    )
)
register_method(
    Method(
        "ndp",
        "ndp",
        "NDP: DMP parameters per decision, integrated into k actions",
        resolve=resolve_ndp,
        metrics=("dmp/goal_norm", "dmp/weight_norm"),
    )
)


def networks(policy: PolicyConfig, hidden: tuple[int, ...], activation: str) -> PolicyChanges:
    """A method's own networks: ``hidden`` / ``activation`` where the config leaves them at
    None (the method's); a value the user gave is kept."""
    out: PolicyChanges = {}
    if policy.hidden is None:
        out["hidden"] = hidden
    if policy.activation is None:
        out["activation"] = activation
    return out


def with_networks(
    hidden: tuple[int, ...], activation: str, *, k: int | None = None, dmp: bool = False
) -> Callable[[PolicyConfig, TaskSpec], PolicyChanges]:
    """The resolution (:attr:`Method.resolve`) of a method with networks of its own (the
    off-policy learners): the NDP head's task presets (``dmp``: :func:`resolve_ndp`) or no DMP
    (:func:`no_dmp`), the networks ``hidden`` / ``activation`` where the config leaves them at
    None (:func:`networks`), and ``k`` where given (1: one action per decision)."""

    def resolve(policy: PolicyConfig, spec: TaskSpec) -> PolicyChanges:
        head = resolve_ndp(policy, spec) if dmp else no_dmp(policy, spec)
        return {**head, **networks(policy, hidden, activation), **({} if k is None else {"k": k})}

    what = "the NDP head's presets" if dmp else "no DMP"
    hid = "-".join(map(str, hidden))
    resolve.__doc__ = f"{what}, {hid} {activation} networks" + ("" if k is None else f", k = {k}")
    return resolve


BUILTIN_LEARNERS = ("ndp.rl.dyne", "ndp.rl.sac", "ndp.rl.td3")
"""The packages of the built-in learners with their own settings and methods, imported here
(each registers itself with one :func:`register_learner` call, as a learner of one's own
would): by name, as gymnasium imports an env's entry point, so that the registry has no import
edge to a learner (``tests/test_import_graph.py``); none of them imports torch until it
trains. Their order is the order of the ``TrainConfig`` sections."""

for _package in BUILTIN_LEARNERS:
    importlib.import_module(_package)


# --------------------------------------------------------------------------------------------
# VICES (Martin-Martin et al., IROS 2019) and its two ablations: PPO on the torque-actuated
# variant of the task (ndp.envs.TORQUE_TASKS), actions = target displacement + stiffness (and
# optionally damping) of the impedance controller of ndp.envs.impedance, which computes torques
# at every simulator step (docs/vices.md). The requested task may be a position-controlled row
# (its torque variant is used) or a torque row (the method's space and period still apply).

LOW_FREQ_K = 5
"""Env steps per decision of ``vices-low-freq`` (NDP's k)."""


def _torque_variant(space: str | None = None, period: int = 1) -> Callable[[TaskSpec], TaskSpec]:
    def variant(spec: TaskSpec) -> TaskSpec:
        from ndp.envs import torque_variant

        return torque_variant(spec, space=space, period=period)

    return variant


def _resolve_low_freq(policy: PolicyConfig, spec: TaskSchema) -> PolicyChanges:
    """``k`` = the torque row's decision period (5)."""
    from ndp.envs.impedance import ImpedanceController

    ctrl = spec.controller
    if not isinstance(ctrl, ImpedanceController):
        raise AttributeError(f"task {spec.name!r} has no impedance controller (no period)")
    return {**no_dmp(policy, spec), "k": int(ctrl.period)}


register_method(
    Method(
        "vices",
        "step",
        "VICES: PPO on the torque-actuated task, actions = target displacement + stiffness "
        "of an impedance controller at the simulator rate (OSC on Meta-World, joint space on "
        "Throw / Pick)",
        task_variant=_torque_variant(None, 1),
        metrics=("ctrl/gains_clipped", "ctrl/torque_saturated", "ctrl/nonfinite"),
    )
)
register_method(
    Method(
        "vices-pos",
        "step",
        "VICES in end-effector space on every task (OSC; the Throw / Pick ablation)",
        task_variant=_torque_variant("osc", 1),
        metrics=("ctrl/gains_clipped", "ctrl/torque_saturated", "ctrl/nonfinite"),
    )
)
register_method(
    Method(
        "vices-low-freq",
        "hold",
        f"VICES deciding once per k = {LOW_FREQ_K} env steps (as NDP), target and gains held",
        resolve=_resolve_low_freq,
        task_variant=_torque_variant(None, LOW_FREQ_K),
        metrics=("ctrl/gains_clipped", "ctrl/torque_saturated", "ctrl/nonfinite"),
    )
)
