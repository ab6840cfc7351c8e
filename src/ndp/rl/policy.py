"""Trained policies as objects: load a run or an export, act from the env's own info, export.

:class:`Policy` wraps a trained actor-critic (NDP, PPO or PPO-multi) with its observation
normaliser and task. ``act(obs, info)`` reads the robot state the head needs (the DMP start)
from the chunked env's ``info`` itself, so it cannot be passed wrong; ``make_env()`` builds the
chunked env the policy was trained for (its k, stale-world rule and horizon).
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
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ndp.policies import ActorCritic, build_actor_critic
from ndp.rl.config import TrainConfig
from ndp.rl.normalize import ObsNormalizer

EXPORT_FORMAT = "ndp-policy"
"""``format`` field of ``policy.json``."""
EXPORT_VERSION = 1
"""``version`` field of ``policy.json`` (incremented on incompatible changes)."""


@dataclass
class Policy:
    """A trained policy: observation and env info -> the decision's k sub-actions."""

    cfg: TrainConfig
    """The run's resolved config (method, task, k, head settings)."""
    spec: Any
    """The task spec (``ndp.envs.TaskSpec``)."""
    model: ActorCritic
    """The actor-critic, in eval mode."""
    obs_norm: ObsNormalizer
    """The observation normaliser (statistics frozen at export / checkpoint time)."""
    substeps: int = 1
    """m: each env step of the trained env runs as m shorter ones (:meth:`at_exec_k`); 1 for
    the policy as trained. ``spec`` is then the finer row (``ndp.envs.spec.finer_spec``)."""

    @property
    def exec_k(self) -> int:
        """Sub-steps (env steps) per decision as executed: ``k * substeps``."""
        return self.cfg.k * self.substeps

    def at_exec_k(self, exec_k: int, hold: bool = False) -> Policy:
        """An evaluation copy running each decision as ``exec_k`` sub-steps of the same total
        duration (``ndp.rl.exec_k.at_exec_k``: allowed values, what each method does, ``hold``);
        the trained policy and its weights are left as they are."""
        from ndp.rl.exec_k import at_exec_k

        return at_exec_k(self, exec_k, hold)

    @property
    def state_keys(self) -> tuple[str, str]:
        """The info keys of the DMP start this policy reads (commanded or measured state)."""
        if self.cfg.policy.dmp_state == "commanded":
            return "cmd_y0", "cmd_dy0"
        return "dmp_y0", "dmp_dy0"

    def reset(self) -> None:
        """Start a new episode (the policy keeps no state between decisions; kept so that
        callers need not know)."""

    def act(self, obs: np.ndarray, info: dict[str, Any], deterministic: bool = True) -> np.ndarray:
        """The k sub-actions of one decision (``exec_k`` of them for an :meth:`at_exec_k` copy),
        within the task's action bounds.

        Args:
            obs: [O] observation (or [E, O] for E envs).
            info: the chunked env's info of that observation (``reset`` or ``step``; a vector
                env's info dict for [E, O]).
            deterministic: the distribution's mode (else a sample).

        Returns:
            [K, A] (or [E, K, A]) float32 actions, K = ``exec_k`` (= k as trained). A head with
            fewer sub-actions per decision than K (every head but NDP's at ``at_exec_k``) has
            each of its sub-actions held for K / k env steps of the finer env, whose per-step
            action scale is 1 / m of the trained one: the same displacement per decision.
        """
        ky, kdy = self.state_keys
        if ky not in info or kdy not in info:
            raise ValueError(
                f"info: expected the chunked env's {ky!r} and {kdy!r} (use policy.make_env() "
                "or ndp.make_env(task, k=...)), got keys "
                f"{sorted(info)[:8]}"
            )
        single = np.ndim(obs) == 1
        o = np.asarray(obs, dtype=np.float64).reshape(1 if single else len(obs), -1)
        if o.shape[1] != self.model.obs_dim:
            raise ValueError(f"obs: expected {self.model.obs_dim} values, got {o.shape[1]}")
        y0 = np.asarray(info[ky], dtype=np.float64).reshape(len(o), -1)
        dy0 = np.asarray(info[kdy], dtype=np.float64).reshape(len(o), -1)
        with torch.no_grad():
            dist, _ = self.model.distribution(
                torch.from_numpy(self.obs_norm(o)),
                torch.as_tensor(y0, dtype=torch.float32),
                torch.as_tensor(dy0, dtype=torch.float32),
            )
            z = dist.mode() if deterministic else dist.sample()
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
        wrap: Callable[[Any], Any] | None = None,
    ) -> Any:
        """The chunked env this policy was trained for (its k, stale-world rule, horizon).

        ``wrap``: applied to the task env before it is chunked (e.g. a frame recorder that sees
        every env step).

        For an :meth:`at_exec_k` copy: the finer env (``substeps`` env steps per trained one,
        ``exec_k`` per decision) with ``horizon * substeps`` env steps (``horizon`` and the
        run's horizon count trained env steps), the same episode duration in seconds.
        """
        from ndp.envs.chunked import ChunkedEnv
        from ndp.rl.envs import resolve_task

        h = horizon if horizon is not None else self.cfg.horizon
        m = self.substeps
        kw: dict[str, Any] = {} if m == 1 else {"substeps": m}
        base = resolve_task(self.cfg.task, **self.cfg.env_options()).make(
            horizon=None if h is None else h * m, render_mode=render_mode, **kw
        )
        if wrap is not None:
            base = wrap(base)
        return ChunkedEnv(base, self.exec_k, stale_world=self.cfg.stale_world)

    def export(self, out_dir: str | Path) -> Path:
        """Write ``policy.safetensors`` + ``policy.json`` to ``out_dir`` (see the module)."""
        return _write_export(self, Path(out_dir))


def _build(
    cfg: TrainConfig,
    obs_dim: int,
    model_state: dict[str, torch.Tensor],
    obs_norm_state: dict[str, Any],
) -> Policy:
    from ndp.rl.envs import resolve_task

    spec = resolve_task(cfg.task).spec
    model = build_actor_critic(obs_dim, spec, cfg.policy)
    model.load_state_dict(model_state)
    model.eval()
    obs_norm = ObsNormalizer(obs_dim, cfg.ppo.clip_obs, cfg.ppo.norm_obs)
    obs_norm.load_state_dict(obs_norm_state)
    return Policy(cfg, spec, model, obs_norm)


def load_policy(path: str | Path) -> Policy:
    """Load a trained policy from a run directory or an export directory.

    Args:
        path: a directory with ``config.json`` + ``checkpoint.pt`` (``ndp rl train``) or with
            ``policy.json`` + ``policy.safetensors`` (:func:`export_policy`).

    Raises:
        FileNotFoundError: neither kind of directory.
        ValueError: an export of another format or version.
    """
    path = Path(path)
    if (path / "policy.json").is_file():
        from safetensors.torch import load_file

        meta = json.loads((path / "policy.json").read_text())
        if meta.get("format") != EXPORT_FORMAT or meta.get("version") != EXPORT_VERSION:
            raise ValueError(
                f"path: {path} holds format {meta.get('format')!r} version "
                f"{meta.get('version')!r}; expected {EXPORT_FORMAT!r} version {EXPORT_VERSION}"
            )
        state = load_file(str(path / "policy.safetensors"))
        return _build(
            TrainConfig.from_dict(meta["config"]), int(meta["obs_dim"]), state, meta["obs_norm"]
        )
    if (path / "config.json").is_file():
        from ndp.rl.config import load_config
        from ndp.runs import load_checkpoint

        cfg = load_config(path / "config.json")
        ckpt = load_checkpoint(path, kind="rl")
        return _build(cfg, int(ckpt["obs_dim"]), ckpt["model"], ckpt["obs_norm"])
    raise FileNotFoundError(
        f"path: {path} holds neither a training run (config.json + checkpoint.pt) nor an "
        "exported policy (policy.json + policy.safetensors)"
    )


def export_policy(path: str | Path, out_dir: str | Path) -> Path:
    """Export the policy of a run (or re-export an export) to ``out_dir``; returns it."""
    return load_policy(path).export(out_dir)


def _versions() -> dict[str, str]:
    from importlib import metadata

    out = {}
    for name in (
        "neural-dynamic-policies",
        "torch",
        "numpy",
        "gymnasium",
        "mujoco",
        "metaworld",
        "dm_control",
    ):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _write_export(policy: Policy, out_dir: Path) -> Path:
    from safetensors.torch import save

    from ndp.io import atomic_write_bytes, atomic_write_text
    from ndp.provenance import git_commit

    if policy.substeps != 1:
        raise ValueError(
            "policy: an exec-k evaluation copy cannot be exported; export the trained policy"
        )
    if (out_dir / "policy.json").exists():
        raise FileExistsError(f"out_dir: {out_dir} already holds an export; choose another")
    out_dir.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().contiguous().clone() for k, v in policy.model.state_dict().items()}
    atomic_write_bytes(out_dir / "policy.safetensors", save(state))
    norm = policy.obs_norm.state_dict()
    meta = {
        "format": EXPORT_FORMAT,
        "version": EXPORT_VERSION,
        "task": policy.cfg.task,
        "algo": policy.cfg.algo,
        "obs_dim": policy.model.obs_dim,
        "config": policy.cfg.to_dict(),
        "obs_norm": {
            "mean": norm["mean"].tolist(),
            "var": norm["var"].tolist(),
            "count": float(norm["count"]),
        },
        "versions": _versions(),
        "commit": git_commit(),
    }
    atomic_write_text(out_dir / "policy.json", json.dumps(meta, indent=1) + "\n")
    return out_dir
