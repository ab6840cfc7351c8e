"""Neural Dynamic Policies (Bahl, Mukadam, Gupta, Pathak, NeurIPS 2020).

A policy network predicts the goal ``g`` and forcing-term weights ``w`` of a Dynamic Movement
Primitive (DMP); a differentiable integrator (:mod:`ndp.dmp`) turns them into a trajectory, and
the robot follows it for ``k`` sub-steps per decision.

Packages, in the order the data flows:

- :mod:`ndp.dmp`          DMP maths: basis functions, integrators, layer, fit, sensitivities
- :mod:`ndp.nets`         MLP and CNN encoders
- :mod:`ndp.policies`     action heads (step, multi, ndp), k-head critic
- :mod:`ndp.envs`         task table, Meta-World and Jaco tasks, chunked stale-world wrapper
- :mod:`ndp.rl`           rollout buffer, GAE, PPO trainer
- :mod:`ndp.il`           digit-writing data, models, trainer, metrics
- :mod:`ndp.experiments`  presets, sweeps, result tables and plots
- :mod:`ndp.cli`          the ``ndp`` command

Public API (imported lazily, so ``import ndp`` stays cheap; ``__all__``, ``dir(ndp)``):

- ``ndp.DMPLayer``, ``ndp.DMPConfig``: the differentiable DMP layer for your own network;
- ``ndp.make_env(task, k=5)``: a task's chunked env (k sub-steps per decision, stale-world rule);
- ``ndp.load_policy(path)``: a trained policy (a run directory, an export, or ``"zoo:<name>"``,
  one shipped with the package: ``ndp.zoo.list()``) with ``act(obs, robot_state)``, ``reset()``
  and ``make_env()``; ``robot_state`` is the env's info or an ``ndp.RobotState(y0, dy0)``, so
  an export acts without any simulator. ``ndp.export_policy(run, out)`` writes a safetensors +
  JSON export with a model card that loads without unpickling;
- ``ndp.version()``: the installed version (``ndp --version``).

``pip install neural-dynamic-policies`` (torch, numpy, safetensors) gives :mod:`ndp.dmp`,
:mod:`ndp.nets`, :mod:`ndp.policies` and trained policies (``load_policy``, ``ndp.zoo``); the
simulators, trainers and tools are extras: ``[envs]`` (``make_env``), ``[rl]`` (``ndp rl``),
``[il]`` (``ndp il``), ``[ray]``, and ``[dev]`` for all of them plus the test tools.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ndp.checks import install_hint

if TYPE_CHECKING:
    from ndp.envs import ChunkedEnv

__version__ = "0.1.0"
"""The source tree's version (``pyproject.toml``'s; a test keeps them equal). The installed
distribution's version: :func:`version`."""

# name -> (module, attribute (None: the module itself), the extra that module needs; None: the
# core install)
_LAZY = {
    "DMPLayer": ("ndp.dmp", "DMPLayer", None),
    "DMPConfig": ("ndp.dmp", "DMPConfig", None),
    "Policy": ("ndp.rl.policy", "Policy", None),
    "load_policy": ("ndp.rl.loading", "load_any", None),
    "export_policy": ("ndp.rl.policy", "export_policy", None),
    "RobotState": ("ndp.act_inputs", "RobotState", None),
    "zoo": ("ndp.zoo", None, None),
}

__all__ = [
    "DMPConfig",
    "DMPLayer",
    "Policy",
    "RobotState",
    "export_policy",
    "load_policy",
    "make_env",
    "version",
    "zoo",
]


def version() -> str:
    """The installed version of ``neural-dynamic-policies`` (``importlib.metadata``), else the
    version of this source tree (``pyproject.toml`` next to ``src/``, else ``__version__``)."""
    from importlib import metadata

    try:
        return metadata.version("neural-dynamic-policies")
    except metadata.PackageNotFoundError:
        pass
    from pathlib import Path

    pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
    try:
        import re

        text = pyproject.read_text()
        project = text.split("[project]", 1)[1].split("\n[", 1)[0]
        found = re.search(r'^version\s*=\s*"([^"]+)"', project, re.MULTILINE)
        if found:
            return found.group(1)
    except (OSError, IndexError):
        pass
    return __version__


def make_env(
    task: str,
    k: int = 5,
    stale_world: bool = True,
    horizon: int | None = None,
    seed: int | None = None,
    render_mode: str | None = None,
    reward_version: str = "v2",
    fixed_goal: int | str | None = None,
    observation: str = "full",
    reward: str = "dense",
    smooth_lambda: float | None = None,
) -> ChunkedEnv:
    """The chunked env of a task: k sub-steps per decision (``k = 1``: plain per-step).

    Args:
        task: a name or alias of ``ndp.envs.TASKS`` (``"push-v3"``, ``"throw"``, ...).
        k: sub-steps per decision (5 for NDP and PPO-multi in the paper, 1 for PPO).
        stale_world: the stale-world reward rule at sub-steps 1..k-1.
        horizon: episode length in env steps (None: the task's default).
        seed: seed of the first reset (later resets continue its generator).
        render_mode: None or ``"rgb_array"``.
        reward_version: Meta-World's reward function, ``"v2"`` (default) or ``"v1"`` (the 2021
            release's shaped rewards; success is the v2 evaluation under both).
        fixed_goal: None (a fresh seeded goal every reset), the seed of the one task
            configuration every reset uses (a run with ``goals="per-seed"`` uses
            ``ndp.envs.fixed_goal_seed(run_seed)``), or ``"release"``: the 2021 release's one
            hard-coded configuration (``ndp.envs.release``).
        observation: ``"full"`` or ``"release9"`` (Meta-World: the release's 9-D observation,
            hand, object and goal xyz).
        reward: ``"dense"`` (the task's own), ``"sparse"`` (1 at the first successful env
            step, which ends the episode) or ``"smooth"`` (minus ``smooth_lambda`` times the
            squared change of the executed action per env step): ``ndp.envs.rewards``; the
            last two need ``stale_world=False`` at k > 1.
        smooth_lambda: the smooth reward's price (None: ``ndp.envs.rewards.
            DEFAULT_SMOOTH_LAMBDA``).

    Returns:
        An :class:`ndp.envs.ChunkedEnv` (actions [k, A]; info with the robot and commanded
        state a policy's ``act(obs, info)`` reads).
    """
    try:
        from ndp.envs import ChunkedEnv
        from ndp.envs import make_env as make_step_env
    except ModuleNotFoundError as exc:
        hint = _missing_extra(exc, "make_env", "envs")
        if hint is None:
            raise
        raise hint from exc

    base = make_step_env(
        task,
        horizon=horizon,
        seed=seed,
        render_mode=render_mode,
        reward_version=reward_version,
        fixed_goal=fixed_goal,
        observation=observation,
        reward=reward,
        smooth_lambda=smooth_lambda,
    )
    return ChunkedEnv(base, k, stale_world=stale_world)


def _missing_extra(
    exc: ModuleNotFoundError, what: str, extra: str | None
) -> ModuleNotFoundError | None:
    """``exc`` with the extra that installs the missing module named (None: not an extra's)."""
    if extra is None or (exc.name or "ndp").split(".")[0] == "ndp":
        return None
    return ModuleNotFoundError(
        f"{exc}: ndp.{what} needs the [{extra}] extra ({install_hint(extra)})",
        name=exc.name,
    )


def __dir__() -> list[str]:
    """The public API (``__all__``, imported lazily) and the package's submodules imported so
    far; not the typing helpers this file itself imports (``Any``, ``annotations``)."""
    import types

    loaded = {
        n for n, v in globals().items() if isinstance(v, types.ModuleType) and not n.startswith("_")
    }
    return sorted(set(__all__) | loaded)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        module, attr, extra = _LAZY[name]
        try:
            mod = importlib.import_module(module)
            return mod if attr is None else getattr(mod, attr)
        except ModuleNotFoundError as exc:
            hint = _missing_extra(exc, name, extra)
            if hint is None:
                raise
            raise hint from exc
    raise AttributeError(f"module 'ndp' has no attribute {name!r}")
