"""Trained policies as objects: load a run or an export, act from the env's own info, export.

:class:`Policy` wraps a trained actor-critic (NDP, PPO or PPO-multi) with its observation
normaliser and task. ``act(obs, info)`` reads the robot state the head needs (the DMP start)
from the chunked env's ``info`` itself, so it cannot be passed wrong; ``make_env()`` builds the
chunked env the policy was trained for (its k, stale-world rule and horizon).

Without the simulators (a robot, another simulator; only torch, numpy and safetensors
installed), an export still loads and acts: its ``policy.json`` records the task's spec
(``"spec"``: DMP coordinates, action bounds and scale, clocks; ``ndp.schema``), and
``act(obs, robot_state)`` takes the DMP start as a mapping with the keys
:attr:`Policy.state_keys` or a :class:`RobotState`.
``policy.at_exec_k(K2)`` is an evaluation copy that runs each decision as K2 = k * m sub-steps of
a finer env (:mod:`ndp.rl.exec_k`, ``ndp rl eval --exec-k``).

An export (:func:`export_policy`) is a directory with ``policy.safetensors`` (the network's
weights) and ``policy.json`` (format version, resolved config, observation dimension and
normaliser statistics, task, package versions, commit): it loads without unpickling anything
(``safetensors`` + ``json``), unlike a training checkpoint, which also holds optimiser and RNG
state for resuming.

Example::

    import ndp

    policy = ndp.load_policy("runs/push-v3-ndp-s0")        # a run, or an export directory
    env = policy.make_env()
    obs, info = env.reset(seed=0)
    done = False
    while not done:
        obs, reward, term, trunc, info = env.step(policy.act(obs, info))
        done = term or trunc
    print(info["success_any"])

Without a simulator (``obs`` from your own pipeline, the robot's state in physical units)::

    policy = ndp.load_policy("zoo:push-v3-ndp")
    y0, dy0 = hand_xyz_and_gripper, their_velocities    # [D] each (D = policy.spec.dmp_dofs)
    actions = policy.act(obs, ndp.RobotState(y0, dy0))  # [k, A]
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

import ndp.rl.methods  # registers every method's head (e.g. VICES's hold); normalises_obs
from ndp import zoo
from ndp.act_inputs import (  # RobotState: named by the docstrings
    ActInfo,
    ObsRange,
    RobotState,  # noqa: F401
    check_act_inputs,
    obs_range_of,
)
from ndp.checks import check_flag, check_int, install_hint
from ndp.chunk_info import dmp_start_keys
from ndp.hub import download, is_hub_ref
from ndp.io import atomic_write_bytes, atomic_write_text, check_output_path
from ndp.policies import ActorCritic, build_actor_critic
from ndp.provenance import git_commit, installed_versions, portable_path, user_command
from ndp.rl.card import CardEvaluation, check_export_dir, write_card
from ndp.rl.config import EVAL_SEED, TrainConfig, load_config
from ndp.rl.exec_k import at_exec_k
from ndp.rl.normalize import ObsNormalizer, RunningStats
from ndp.rl.onnx_export import write_onnx_export
from ndp.rl.onnx_policy import OnnxPolicy
from ndp.runs import load_checkpoint
from ndp.runs.layout import provenance_sessions, run_commits
from ndp.runs.lock import output_lock
from ndp.runs.session import read_manifest
from ndp.schema import PolicySpec, TaskSchema, check_record, spec_record

if TYPE_CHECKING:
    import gymnasium as gym

    from ndp.envs.chunked import ChunkedEnv

EXPORT_FORMAT = "ndp-policy"
"""``format`` field of ``policy.json``."""
EXPORT_VERSION = 1
"""``version`` field of ``policy.json`` (incremented on incompatible changes; the optional
``"spec"``, ``"training"`` fields were added compatibly)."""
_SIMULATORS = ("gymnasium", "mujoco", "metaworld", "dm_control", "imageio", "imageio_ffmpeg")
"""Packages of the [envs] extra whose absence makes a policy fall back to its recorded spec."""


EXPORT_FORMATS = ("safetensors", "onnx")
"""``Policy.export`` / ``ndp rl export --format``: the loadable export (default) or one ONNX
graph of the deterministic decision (:mod:`ndp.rl.onnx_export`)."""


@dataclass
class Policy:
    """A trained policy: observation and env info -> the decision's k sub-actions."""

    cfg: TrainConfig
    """The run's resolved config (method, task, k, head settings)."""
    spec: TaskSchema
    """The task spec: the task table's row (``ndp.envs.TaskSpec``), or, when the simulators are
    not installed, the one the export recorded (``ndp.schema.PolicySpec``, the same
    fields the head and :meth:`act` read)."""
    model: ActorCritic
    """The actor-critic, in eval mode."""
    obs_norm: ObsNormalizer
    """The observation normaliser (statistics frozen at export / checkpoint time)."""
    substeps: int = 1
    """m: each env step of the trained env runs as m shorter ones (:meth:`at_exec_k`); 1 for
    the policy as trained. ``spec`` is then the finer row (``ndp.envs.spec.finer_spec``)."""
    _generator: torch.Generator | None = field(default=None, repr=False, compare=False)
    """Sampler of the stochastic actions (:meth:`reset` with a seed); None: torch's global."""
    exported: dict[str, Any] | None = field(default=None, repr=False, compare=False)
    """For a policy loaded from an export: that export's ``evaluation`` and ``commit`` (a
    re-export carries them on when it is given no evaluation of its own); None otherwise."""
    training: dict[str, Any] | None = field(default=None, repr=False, compare=False)
    """Where the weights come from, as far as recorded: ``{"commands": [...], "commits":
    [...]}`` (a run's ``provenance.json`` sessions, or an export's ``"training"``); None when
    nothing is recorded. Exports carry it on."""

    obs_range: ObsRange | None = field(default=None, repr=False, compare=False)
    """The trained observation range (:class:`ndp.act_inputs.ObsRange`): :meth:`act` says once
    when an observation leaves it, with the ONNX policy's words; None: set from ``obs_norm`` at
    the first :meth:`act` (a policy without observation normalisation has none)."""

    @property
    def exec_k(self) -> int:
        """Sub-steps (env steps) per decision as executed: ``k * substeps``."""
        return self.cfg.k * self.substeps

    def at_exec_k(self, exec_k: int, hold: bool = False) -> Policy:
        """An evaluation copy running each decision as ``exec_k`` sub-steps of the same total
        duration (``ndp.rl.exec_k.at_exec_k``: allowed values, what each method does, ``hold``);
        the trained policy and its weights are left as they are."""
        return at_exec_k(self, exec_k, hold)

    @property
    def state_keys(self) -> tuple[str, str]:
        """The info keys of the DMP start this policy reads (commanded or measured state):
        ``("cmd_y0", "cmd_dy0")`` or ``("dmp_y0", "dmp_dy0")``, each [D] (D =
        ``spec.dmp_dofs``) or [E, D]."""
        return dmp_start_keys(self.cfg.policy.dmp_state or "measured")

    @property
    def needs_robot_state(self) -> bool:
        """Whether :meth:`act` reads the robot state (the NDP head's DMP start); the other
        heads ignore it, and ``act(obs)`` without one works for them."""
        return bool(self.model.head.needs_robot_state)

    @property
    def simulator_free(self) -> bool:
        """True when the task spec is the one recorded in the export (``PolicySpec``: the
        simulators were not importable at load time); :meth:`make_env` then needs them."""
        return type(self.spec) is PolicySpec  # a task-table row (TaskSpec) extends it

    def reset(self, seed: int | None = None) -> None:
        """Start a new episode. The policy keeps no state between decisions; ``seed`` seeds the
        sampling of ``act(..., deterministic=False)``, so a stochastic episode is reproducible
        (None: the sampler continues as it is; an unseeded policy draws from torch's global
        generator)."""
        if seed is not None:
            check_int("seed", seed, 0)
            self._generator = torch.Generator().manual_seed(int(seed))

    def act(self, obs: np.ndarray, info: ActInfo = None, deterministic: bool = True) -> np.ndarray:
        """The k sub-actions of one decision (``exec_k`` of them for an :meth:`at_exec_k` copy),
        within the task's action bounds.

        Args:
            obs: [O] observation (or [E, O] for E envs), O = ``spec.obs_dim``, as the env
                returns it (the policy normalises it itself).
            info: the robot state the DMP starts from (the ``robot_state``), one of:

                - the chunked env's info of that observation (``reset`` or ``step``; a vector
                  env's info dict for [E, O]): the policy reads its :attr:`state_keys`;
                - any mapping with the two :attr:`state_keys` (``{"dmp_y0": y0, "dmp_dy0":
                  dy0}``), values [D] for an [O] observation or [E, D] for [E, O], D =
                  ``spec.dmp_dofs``, in the units of ``spec.dof_units`` (velocities per second);
                - a :class:`RobotState` ``(y0, dy0)`` with the same shapes;
                - None, for the heads that do not read it (:attr:`needs_robot_state` False).
            deterministic: the distribution's mode (else a sample).

        Returns:
            [K, A] (or [E, K, A]) float32 actions, K = ``exec_k`` (= k as trained). A head with
            fewer sub-actions per decision than K (every head but NDP's at ``at_exec_k``) has
            each of its sub-actions held for K / k env steps of the finer env, whose per-step
            action scale is 1 / m of the trained one: the same displacement per decision.
        """
        deterministic = check_flag("deterministic", deterministic)  # "no" would act as True
        o, y0, dy0, single = check_act_inputs(
            obs,
            info,
            obs_dim=int(self.model.obs_dim),
            dofs=int(self.spec.dmp_dofs),
            state_keys=self.state_keys,
            needs_state=self.needs_robot_state,
            starts_at_rest=self.cfg.policy.dmp_velocity == "zero",
        )
        if self.obs_range is None and self.obs_norm.enabled:
            rms = self.obs_norm.rms
            self.obs_range = obs_range_of(rms.mean, rms.var, self.obs_norm.clip)
        if self.obs_range is not None:
            self.obs_range.check(o)
        with torch.no_grad():
            dist, _ = self.model.distribution(
                torch.from_numpy(self.obs_norm(o)),
                torch.as_tensor(y0, dtype=torch.float32),
                torch.as_tensor(dy0, dtype=torch.float32),
            )
            z = dist.mode() if deterministic else dist.sample(self._generator)
            act = dist.actions(z)
        low = torch.as_tensor(self.spec.action_low, dtype=torch.float32)
        high = torch.as_tensor(self.spec.action_high, dtype=torch.float32)
        out = torch.maximum(torch.minimum(act, high), low).numpy()
        reps = self.exec_k // int(out.shape[-2])
        if reps > 1:  # a sub-action per trained env step, each held for m finer env steps
            out = np.repeat(out, reps, axis=-2)
        return out[0] if single else out

    def make_env(
        self,
        render_mode: str | None = None,
        horizon: int | None = None,
        wrap: Callable[[gym.Env], gym.Env] | None = None,
        render_size: tuple[int | None, int | None] | None = None,
    ) -> ChunkedEnv:
        """The chunked env this policy was trained for (its k, stale-world rule, horizon).

        ``wrap``: applied to the task env before it is chunked (e.g. a frame recorder that sees
        every env step). ``render_size``: ``(width, height)`` of rendered frames (px; None, or a
        None side: the env's own, 480 x 480 for the robots).

        For an :meth:`at_exec_k` copy: the finer env (``substeps`` env steps per trained one,
        ``exec_k`` per decision) with ``horizon * substeps`` env steps (``horizon`` and the
        run's horizon count trained env steps), the same episode duration in seconds.
        """
        try:
            from ndp.envs.chunked import ChunkedEnv
            from ndp.rl.envs import resolve_task
        except ModuleNotFoundError as exc:
            if (exc.name or "ndp").split(".")[0] == "ndp":
                raise
            raise ModuleNotFoundError(
                f"{exc}: policy.make_env() needs the simulators, the [envs] extra "
                f"({install_hint('envs')}); act() does not",
                name=exc.name,
            ) from exc

        h = horizon if horizon is not None else self.cfg.horizon
        m = self.substeps
        kw: dict[str, Any] = {} if m == 1 else {"substeps": m}
        for name, side in zip(("width", "height"), render_size or (None, None), strict=True):
            if side is not None:
                kw[name] = side
        base = resolve_task(self.cfg.task, **self.cfg.env_options()).make(
            horizon=None if h is None else h * m, render_mode=render_mode, **kw
        )
        if wrap is not None:
            base = wrap(base)
        return ChunkedEnv(base, self.exec_k, **self.cfg.chunk_options())

    def export(
        self,
        out_dir: str | Path,
        evaluation: CardEvaluation | None = None,
        format: str = "safetensors",
    ) -> Path:
        """Write ``policy.safetensors`` + ``policy.json`` + the model card ``README.md``
        (:mod:`ndp.rl.card`; ``evaluation``: what was measured, e.g. ``{"success": 0.8,
        "episodes": 50}``, else "not recorded") to ``out_dir`` (see the module), or with
        ``format="onnx"`` the deterministic decision as one graph, ``policy.onnx``
        (:mod:`ndp.rl.onnx_export`)."""
        if format not in EXPORT_FORMATS:
            raise ValueError(f"format: expected one of {', '.join(EXPORT_FORMATS)}, got {format!r}")
        with output_lock(out_dir):  # a second export into the same folder is refused
            if format == "onnx":
                out = write_onnx_export(self, out_dir)
                meta, evaluation = export_meta(self, evaluation)
                write_card(out, meta, evaluation, onnx=True)
                return out
            return _write_export(self, Path(out_dir), evaluation)


def _task_spec(cfg: TrainConfig, recorded: Mapping[str, object] | None, source: str) -> TaskSchema:
    """The task's row of the task table when the simulators import (``ndp.envs``), else the
    spec the export recorded (``PolicySpec``). With both, a recorded field that differs from
    the table's is warned about (the table's is used, as the env is built from it)."""
    try:
        from ndp.rl.envs import resolve_task
    except ImportError as exc:
        if (exc.name or "").split(".")[0] not in _SIMULATORS:
            raise
        if recorded is None:
            raise ModuleNotFoundError(
                f"{source}: this policy records no task spec (an export made before policy.json "
                "had 'spec', or a run directory), so loading it needs the simulators: install "
                "the [envs] extra, or re-export it where they are installed (ndp rl export "
                f"OLD NEW): {exc}",
                name=exc.name,
            ) from exc
        return PolicySpec.from_record(recorded, f"{source}: spec")
    spec = resolve_task(cfg.task).spec
    if recorded is not None:  # (read_export_meta has checked its fields)
        table = spec_record(spec)
        differ = [k for k in table if k != "y0_source" and table[k] != recorded.get(k)]
        if differ:
            warnings.warn(
                f"{source}: the recorded task spec differs from the task table's in "
                f"{', '.join(differ)} (recorded {[recorded.get(k) for k in differ]}, table "
                f"{[table[k] for k in differ]}); acting with the table's",
                stacklevel=3,
            )
    return spec


def _build(
    cfg: TrainConfig,
    obs_dim: int,
    model_state: dict[str, torch.Tensor],
    obs_norm_state: RunningStats,
    source: str = "policy",
    recorded_spec: Mapping[str, object] | None = None,
) -> Policy:
    spec = _task_spec(cfg, recorded_spec, source)
    model = build_actor_critic(obs_dim, spec, cfg.policy)
    _check_weights(model.state_dict(), model_state, source)
    model.load_state_dict(model_state)
    model.eval()
    for key in ("mean", "var"):
        v = np.asarray(obs_norm_state.get(key), dtype=np.float64)
        if v.shape != (obs_dim,) or not np.isfinite(v).all():
            raise ValueError(
                f"{source}: obs_norm.{key}: expected {obs_dim} finite values, got shape "
                f"{list(v.shape)}"
            )
    # as the learner fed its policy: SAC / TD3 train on raw observations (their config's
    # norm_obs is not read), so their loaded policy passes them through unchanged too
    normalise = cfg.norm_obs and ndp.rl.methods.normalises_obs(cfg.algo)
    obs_norm = ObsNormalizer(obs_dim, cfg.clip_obs, normalise)
    obs_norm.load_state_dict(obs_norm_state)
    return Policy(cfg, spec, model, obs_norm)


def _check_weights(want: dict[str, torch.Tensor], have: Mapping[str, object], source: str) -> None:
    """The saved weights match the network the config builds: names and shapes (one line
    naming the file and the first tensor that differs)."""
    missing = [k for k in want if k not in have]
    extra = [k for k in have if k not in want]
    if missing or extra:
        raise ValueError(
            f"{source}: the weights do not belong to this config's network (missing "
            f"{missing[:3]}, unexpected {extra[:3]})"
        )
    for k, t in want.items():
        got = tuple(getattr(have[k], "shape", ()))
        if got != tuple(t.shape):
            raise ValueError(
                f"{source}: weight {k!r} has shape {list(got)}, the config's network needs "
                f"{list(t.shape)}"
            )


def load_policy(path: str | Path) -> Policy:
    """Load a trained policy from a run directory or an export directory.

    Args:
        path: a directory with ``config.json`` + ``checkpoint.pt`` (``ndp rl train``) or with
            ``policy.json`` + ``policy.safetensors`` (:func:`export_policy`), or
            ``"zoo:<name>"``, a policy shipped with the package (``ndp.zoo.list()``), or
            ``"hf://ORG/NAME[@REVISION]"``, an export on the Hugging Face Hub (:mod:`ndp.hub`).

    An export loads without the simulators (only torch, numpy and safetensors) when its
    ``policy.json`` records the task's spec (exports of this version on, and the zoo's); a run
    directory and older exports need the [envs] extra.

    Raises:
        FileNotFoundError: neither kind of directory.
        ValueError: an export of another format or version; an unknown zoo name.
        TypeError: ``path`` neither a string nor a path object (``os.PathLike``).
    """
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(
            f"path: expected a folder path or 'zoo:NAME', got {type(path).__name__} {path!r}"
        )
    if isinstance(path, str) and path.startswith("zoo:"):
        path = zoo.path(path)

    if is_hub_ref(path):
        path = download(str(path))
    path = Path(path)
    if (path / "policy.json").is_file():
        meta = read_export_meta(path / "policy.json")
        weights = path / "policy.safetensors"
        if not weights.is_file():
            raise FileNotFoundError(f"policy: {path} has policy.json but no policy.safetensors")
        from safetensors import SafetensorError
        from safetensors.torch import load_file

        try:
            state = load_file(str(weights))
        except (SafetensorError, OSError, ValueError) as exc:
            raise ValueError(
                f"{weights}: not a readable safetensors file ({str(exc)[:120]})"
            ) from None
        try:
            cfg = TrainConfig.from_dict(meta["config"])
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{path / 'policy.json'}: config: {exc}") from None
        pol = _build(cfg, meta["obs_dim"], state, meta["obs_norm"], str(weights), meta.get("spec"))
        training = meta.get("training")
        pol.training = training if isinstance(training, dict) else None
        evaluation = meta.get("evaluation")
        if not isinstance(evaluation, dict):  # exports before the field: their card's numbers
            evaluation = card_evaluation(path / "README.md")
        pol.exported = {"evaluation": evaluation, "commit": meta.get("commit")}
        return pol
    if (path / "config.json").is_file():
        cfg = load_config(path / "config.json")
        ckpt = load_checkpoint(path, kind="rl")
        for key in ("obs_dim", "model", "obs_norm"):
            if key not in ckpt:
                raise ValueError(f"{path / 'checkpoint.pt'}: no {key!r} (not an RL checkpoint)")
        ck = str(path / "checkpoint.pt")
        pol = _build(cfg, int(ckpt["obs_dim"]), ckpt["model"], ckpt["obs_norm"], ck)
        pol.training = run_training(path)
        return pol
    if (path.suffix == ".onnx" and path.is_file()) or (path / "policy.onnx").is_file():
        raise OnnxExportFound(path)
    if not path.exists():
        raise FileNotFoundError(_not_found(path))
    raise FileNotFoundError(
        f"path: {path} holds neither a training run (config.json + checkpoint.pt), an exported "
        "policy (policy.json + policy.safetensors) nor an ONNX export (policy.onnx)"
    )


class OnnxExportFound(ValueError):
    """:func:`load_policy` met an ONNX export: what needs the torch policy (evaluation,
    rendering, export) says so in one line; ``ndp.load_policy`` (:func:`load_any_policy`) loads
    it as an :class:`ndp.rl.onnx_export.OnnxPolicy`."""

    def __init__(self, path: Path) -> None:
        super().__init__(
            f"path: {path} is an ONNX export (policy.onnx): ndp.load_policy gives its "
            "OnnxPolicy (act() only); evaluating, rendering and exporting need the run or its "
            "safetensors export"
        )
        self.path = path


def load_any_policy(path: str | Path) -> Policy | OnnxPolicy:
    """``ndp.load_policy``: :func:`load_policy` (a run, a safetensors export, ``zoo:NAME``), or
    for an ONNX export (a ``policy.onnx`` file or a folder holding one) its
    :class:`ndp.rl.onnx_export.OnnxPolicy`, which acts with the same calling convention
    (``act(obs, robot_state)``; deterministic only)."""
    try:
        return load_policy(path)
    except OnnxExportFound as found:
        return OnnxPolicy(found.path)


def _not_found(path: Path) -> str:
    """The message for a policy path that does not exist: the zoo's name where it is one
    (``load_policy("zoo/push-v3-ndp")`` outside a checkout), else the closest zoo names."""
    import difflib

    names = zoo.list()
    if path.name in names:
        return (
            f"path: no such directory {path}; {path.name!r} is a policy of the zoo, shipped with "
            f"the package: ndp.load_policy('zoo:{path.name}')"
        )
    close = difflib.get_close_matches(path.name, names, n=3, cutoff=0.6)
    hint = (
        f"; close zoo names: {', '.join('zoo:' + c for c in close)}"
        if close
        else f"; the zoo's policies load as 'zoo:NAME' (ndp.zoo.list(): {len(names)} names)"
    )
    return f"path: no such directory {path}{hint}"


def run_training(run_dir: Path) -> dict[str, Any] | None:
    """A run's training record for its exports: the command line of each session (start,
    resumes) and the commits they ran at, from its ``provenance.json``; None without one."""
    import shlex

    sessions = provenance_sessions(run_dir)
    if not sessions:
        return None
    commands = [
        shlex.join(user_command([str(a) for a in e["argv"]]))
        for e in sessions
        if isinstance(e, dict) and isinstance(e.get("argv"), list)
    ]
    manifest = read_manifest(run_dir)
    trained = int(manifest.done) if manifest is not None else None
    return {"commands": commands, "commits": run_commits(run_dir), "env_steps_trained": trained}


EXPORT_SCHEMA: dict[str, tuple[type, ...]] = {
    "format": (str,),
    "version": (int,),
    "task": (str,),
    "algo": (str,),
    "obs_dim": (int,),
    "config": (dict,),
    "obs_norm": (dict,),
}
"""Required fields of ``policy.json`` and their JSON types (``versions`` and ``commit`` are
provenance, optional when loading; ``spec``, the task's spec for loading without the simulators
(``ndp.schema``), and ``training``, the run's command lines and commits, are optional:
exports older than them load too)."""


def read_export_meta(path: Path) -> dict[str, Any]:
    """``policy.json`` read and checked against :data:`EXPORT_SCHEMA` (format, version, field
    types, ``obs_norm`` statistics of ``obs_dim`` numbers).

    Raises:
        ValueError: one line naming the file and the field.
    """
    try:
        meta = json.loads(Path(path).read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: expected a JSON object")
    if meta.get("format") != EXPORT_FORMAT or meta.get("version") != EXPORT_VERSION:
        raise ValueError(
            f"{path}: format {meta.get('format')!r} version {meta.get('version')!r}; expected "
            f"{EXPORT_FORMAT!r} version {EXPORT_VERSION}"
        )
    for key, types in EXPORT_SCHEMA.items():
        if key not in meta:
            raise ValueError(f"{path}: missing field {key!r}")
        v = meta[key]
        if isinstance(v, bool) or not isinstance(v, types):
            names = " or ".join(t.__name__ for t in types)
            raise ValueError(f"{path}: field {key!r}: expected {names}, got {type(v).__name__}")
    check_int(f"{path}: field 'obs_dim'", meta["obs_dim"], 1)
    for key in ("mean", "var", "count"):
        if key not in meta["obs_norm"]:
            raise ValueError(f"{path}: field 'obs_norm.{key}' is missing")
    for key in ("mean", "var"):  # the normaliser's statistics live here, not in the weights
        v = meta["obs_norm"][key]
        n = len(v) if isinstance(v, list) else None
        if n != meta["obs_dim"] or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in v
        ):
            got = f"{n} values" if n is not None else type(v).__name__
            raise ValueError(
                f"{path}: field 'obs_norm.{key}': expected {meta['obs_dim']} numbers (obs_dim), "
                f"got {got}"
            )
    if meta["config"].get("task") != meta["task"] or meta["config"].get("algo") != meta["algo"]:
        raise ValueError(f"{path}: fields 'task' / 'algo' disagree with the config's")
    if "spec" in meta:
        check_record(meta["spec"], f"{path}: field 'spec'")
    return meta


def export_policy(
    path: str | Path,
    out_dir: str | Path,
    evaluation: CardEvaluation | None = None,
    format: str = "safetensors",
) -> Path:
    """Export the policy of a run (or re-export an export) to ``out_dir``; returns it
    (``format``: see :meth:`Policy.export`).

    The export's model card (``README.md``) reports ``evaluation`` (``{"success", "episodes",
    ...}``: :func:`ndp.rl.card.card_fields`); without one, a run's cached deterministic
    evaluation (``eval-det-e<N>.json``, written by ``ndp report``; the largest N), else "not
    recorded".
    """
    if format not in EXPORT_FORMATS:  # before loading anything
        raise ValueError(f"format: expected one of {', '.join(EXPORT_FORMATS)}, got {format!r}")
    if evaluation is None and not str(path).startswith("zoo:"):
        evaluation = cached_evaluation(Path(path))
    return load_policy(path).export(out_dir, evaluation, format)


def cached_evaluation(run_dir: Path) -> CardEvaluation | None:
    """A run's cached deterministic evaluation (``eval-det-e<N>.json``, episode seeds 10,000
    on; the largest N) in the card's terms, or None."""
    import re

    best: tuple[int, int, str, dict[str, Any]] | None = None
    for f in Path(run_dir).glob("eval-det-e*.json"):
        # eval-det-e<N>.json (the report's cache, seeds from EVAL_SEED) or
        # eval-det-e<N>-s<seed>.json (ndp rl eval --save); an --exec-k file is not the trained k
        m = re.fullmatch(r"eval-det-e(\d+)(?:-s(\d+))?\.json", f.name)
        if m is None:
            continue
        try:
            data = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        seed = int(m[2]) if m[2] is not None else EVAL_SEED
        if (
            isinstance(data, dict)
            and "success_any" in data
            and (best is None or int(m[1]) > best[0])
        ):
            best = (int(m[1]), seed, f.name, data)
    if best is None:
        return None
    n, seed, name, data = best
    how = (
        f"ndp rl eval RUN --episodes {n} --seed {seed} --save ({name})"
        if _saved_by_eval(name)
        else f"ndp report (its cached evaluation of the run, {name})"
    )
    return {
        "success": float(data["success_any"]),
        "episodes": n,
        "deterministic": True,
        "first_seed": seed,
        "success_final": data.get("success_final"),
        "episode_return": data.get("episode_return"),
        "command": how,
    }


def _saved_by_eval(name: str) -> bool:
    """Whether an evaluation file was written by ``ndp rl eval --save`` (it names its seed)."""
    return "-s" in name.removeprefix("eval-det-")


def _write_export(policy: Policy, out_dir: Path, evaluation: CardEvaluation | None = None) -> Path:
    from safetensors.torch import save

    if policy.substeps != 1:
        raise ValueError(
            "policy: an exec-k evaluation copy cannot be exported; export the trained policy"
        )
    check_output_path(out_dir, "out_dir", folder=True, create=False)  # the one path check
    check_export_dir(out_dir, ("policy.safetensors", "policy.json"))
    out_dir.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().contiguous().clone() for k, v in policy.model.state_dict().items()}
    atomic_write_bytes(out_dir / "policy.safetensors", save(state))
    meta, evaluation = export_meta(policy, evaluation)
    atomic_write_text(out_dir / "policy.json", json.dumps(meta, indent=1) + "\n")
    write_card(out_dir, meta, evaluation)
    return out_dir


def export_meta(
    policy: Policy, evaluation: CardEvaluation | None
) -> tuple[dict[str, Any], CardEvaluation | None]:
    """``(policy.json's fields, the evaluation the card reports)`` of an export of ``policy``:
    a re-export of an export given no ``evaluation`` keeps the source's results and commit (its
    weights are the same); the evaluation is recorded in ``policy.json`` too."""
    src = policy.exported or {}
    if evaluation is None and isinstance(src.get("evaluation"), dict):
        evaluation = src["evaluation"]
    norm = policy.obs_norm.state_dict()
    meta: dict[str, Any] = {
        "format": EXPORT_FORMAT,
        "version": EXPORT_VERSION,
        "task": policy.cfg.task,
        "algo": policy.cfg.algo,
        "obs_dim": policy.model.obs_dim,
        # where it trained, without this machine's absolute path (ndp.provenance.portable_path)
        "config": {**policy.cfg.to_dict(), "run_dir": portable_path(policy.cfg.run_dir or ".")},
        "obs_norm": {
            "mean": np.asarray(norm["mean"]).tolist(),
            "var": np.asarray(norm["var"]).tolist(),
            "count": float(norm["count"]),
        },
        "versions": installed_versions(),
        "commit": str(src.get("commit") or git_commit()),
        "spec": spec_record(policy.spec),
    }
    if policy.training is not None:
        meta["training"] = policy.training
    if evaluation is not None:
        meta["evaluation"] = evaluation
    return meta, evaluation


def card_evaluation(card: Path) -> CardEvaluation | None:
    """The evaluation an export's card reports (its front matter's ``success_rate``,
    ``episodes``, ``evaluation_command``), for exports written before ``policy.json`` held
    it; None without one."""
    import re

    try:
        head = card.read_text().split("---")[1]
    except (OSError, IndexError):
        return None
    found = {}
    for key in ("success_rate", "episodes", "evaluation_command"):
        m = re.search(rf"^{key}: (.+)$", head, re.MULTILINE)
        if m:
            found[key] = m.group(1).strip().strip('"')
    try:
        out: CardEvaluation = {
            "success": float(found["success_rate"]),
            "episodes": int(found["episodes"]),
        }
    except (KeyError, ValueError):
        return None
    if found.get("evaluation_command") not in (None, "not recorded"):
        out["command"] = found["evaluation_command"]
    return out
