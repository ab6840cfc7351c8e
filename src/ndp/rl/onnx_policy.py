"""An exported ONNX policy, run in onnxruntime without torch (``ndp.load_policy`` of a folder
holding ``policy.onnx``).

This module imports neither torch nor a simulator: numpy, and onnx / onnxruntime when a policy
is loaded. The export itself (the graph from a torch policy) is :mod:`ndp.rl.onnx_export`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from ndp.act_inputs import ActInfo, ObsRange, check_act_inputs, obs_range_of
from ndp.checks import check_flag, install_hint

ONNX_FORMAT = "ndp-policy-onnx"
"""``format`` entry of the ONNX file's metadata."""
ONNX_VERSION = 2
"""``version`` entry of the metadata (incremented on incompatible changes: 2 takes float32
inputs, 1 took float64; both load)."""
ONNX_VERSIONS = (1, 2)
"""Versions :func:`onnx_metadata` reads."""
ONNX_FILE = "policy.onnx"
"""File name of the graph inside the export directory."""


def _require(name: str) -> ModuleType:
    """Import ``onnx`` / ``onnxruntime``, or say which extra installs them."""
    import importlib

    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        raise ModuleNotFoundError(
            f"{exc}: the ONNX export needs the [onnx] extra ({install_hint('onnx')})",
            name=exc.name,
        ) from None


def _onnx_file(path: str | Path) -> Path:
    """The graph file of an export: ``path`` itself, or ``path/policy.onnx`` for a folder.

    Raises:
        FileNotFoundError: no such file.
    """
    p = Path(path)
    if p.is_dir():
        p = p / ONNX_FILE
    if not p.is_file():
        raise FileNotFoundError(f"policy: no {ONNX_FILE} at {p}")
    return p


def onnx_metadata(path: str | Path) -> dict[str, Any]:
    """The metadata of an exported ``policy.onnx`` (or of the directory holding it), JSON values
    decoded.

    Raises:
        ValueError: not an export of this format and version.
    """
    onnx = _require("onnx")
    path = _onnx_file(path)
    try:
        model = onnx.load(str(path), load_external_data=False)
    except Exception as exc:  # protobuf's DecodeError and others for a damaged file
        raise ValueError(
            f"{path}: not a readable ONNX file ({type(exc).__name__}: {str(exc)[:120]})"
        ) from None
    meta: dict[str, Any] = {}
    for entry in model.metadata_props:
        try:
            meta[entry.key] = json.loads(entry.value)
        except json.JSONDecodeError:
            meta[entry.key] = entry.value
    if meta.get("format") != ONNX_FORMAT or meta.get("version") not in ONNX_VERSIONS:
        raise ValueError(
            f"{path}: format {meta.get('format')!r} version {meta.get('version')!r}; expected "
            f"{ONNX_FORMAT!r} version {' or '.join(map(str, ONNX_VERSIONS))}"
        )
    return meta


class OnnxPolicy:
    """An exported ``policy.onnx`` run in onnxruntime, with ``Policy.act``'s calling convention.

    Example::

        pol = OnnxPolicy("exports/push-v3-ndp-onnx")
        obs, info = env.reset(seed=0)                  # the chunked env (ndp.make_env)
        actions = pol.act(obs, info)                   # [k, A] float32
    """

    def __init__(self, path: str | Path) -> None:
        ort = _require("onnxruntime")
        path = _onnx_file(path)
        self.path = path
        self.meta = onnx_metadata(path)
        keys = self.meta.get("state_keys")
        if not (isinstance(keys, list) and len(keys) == 2):
            raise ValueError(f"{path}: metadata 'state_keys' is missing or not two names")
        self.state_keys: tuple[str, str] = (str(keys[0]), str(keys[1]))
        try:
            self.session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own error kinds for a bad graph
            raise ValueError(
                f"{path}: onnxruntime cannot load the graph ({type(exc).__name__}: "
                f"{str(exc).splitlines()[0][:160]})"
            ) from None
        # the graph's input types (float32 from version 2; float64 in version 1 files)
        self._dtypes = {
            i.name: np.float64 if i.type == "tensor(double)" else np.float32
            for i in self.session.get_inputs()
        }
        config = self.meta.get("config") or {}
        velocity = (config.get("policy") or {}).get("dmp_velocity", "zero")
        self._checks = {
            "obs_dim": int(self.meta["obs_dim"]),
            "dofs": int(self.meta["dmp_dofs"]),
            "state_keys": self.state_keys,
            "needs_state": bool(self.meta.get("uses_robot_state", True)),
            "starts_at_rest": velocity == "zero",
            "what": "this ONNX policy",
        }
        self.obs_range: ObsRange | None = _obs_range(self.meta, path)
        """The trained observation range (exports that record ``obs_norm``; None for older
        ones, or without observation normalisation): :meth:`act` says once when an
        observation leaves it, with the torch policy's words."""
        found = self.meta.get("spec")
        rec: dict[str, Any] = found if isinstance(found, dict) else {}
        self.spec = OnnxSpec(
            task=str(self.meta.get("task", "")),
            obs_dim=int(self.meta["obs_dim"]),
            action_dim=int(self.meta["action_dim"]),
            dmp_dofs=int(self.meta["dmp_dofs"]),
            k=int(self.meta["k"]),
            action_low=tuple(float(x) for x in self.meta.get("action_low", [])),
            action_high=tuple(float(x) for x in self.meta.get("action_high", [])),
            dof_names=tuple(str(x) for x in rec.get("dof_names", ())),
            dof_units=tuple(str(x) for x in rec.get("dof_units", ())),
            control_dt=float(rec["control_dt"]) if "control_dt" in rec else None,
        )
        """The task facts the export records (:class:`OnnxSpec`)."""

    def act(self, obs: np.ndarray, info: ActInfo = None, deterministic: bool = True) -> np.ndarray:
        """The deterministic decision: [k, A] for obs [O], [E, k, A] for obs [E, O].

        Takes what ``Policy.act`` takes (the chunked env's info, a mapping with
        :attr:`state_keys`, an ``ndp.RobotState``, or None for a policy without a DMP) and
        refuses what it refuses, with the same one-line messages (:mod:`ndp.act_inputs`).
        ``deterministic=False`` is refused: the graph holds the mode only (sample with the
        torch policy, ``ndp.load_policy`` of the run or its safetensors export)."""
        if not check_flag("deterministic", deterministic):
            raise ValueError(
                "deterministic: an ONNX export holds the deterministic decision only; sample "
                "with the torch policy (ndp.load_policy of the run or its safetensors export)"
            )
        o, y0, dy0, single = check_act_inputs(obs, info, **self._checks)
        if self.obs_range is not None:
            self.obs_range.check(o)
        feed = {
            name: value.astype(self._dtypes[name])
            for name, value in (("obs", o), ("y0", y0), ("dy0", dy0))
        }
        try:
            out: np.ndarray = self.session.run(None, feed)[0]
        except Exception as exc:  # onnxruntime's own error kinds
            raise ValueError(
                f"{self.path}: onnxruntime failed on the inputs ({type(exc).__name__}: "
                f"{str(exc).splitlines()[0][:160]})"
            ) from None
        return out[0] if single else out


def _obs_range(meta: dict[str, Any], path: Path) -> ObsRange | None:
    """The metadata's ``obs_norm`` as an :class:`ObsRange` (None where absent or disabled).

    Raises:
        ValueError: naming the file and the field, where it is malformed.
    """
    norm = meta.get("obs_norm")
    if norm is None:
        return None
    n = int(meta["obs_dim"])
    try:
        if not norm["enabled"]:
            return None
        rng = obs_range_of(norm["mean"], norm["var"], float(norm["clip"]))
    except (KeyError, TypeError, ValueError):
        rng = None
    if rng is None or rng.mean.shape != (n,) or rng.std.shape != (n,) or rng.clip <= 0:
        raise ValueError(
            f"{path}: metadata 'obs_norm': expected enabled, mean [{n}], var [{n}] and clip > 0"
        )
    if not (np.isfinite(rng.mean).all() and np.isfinite(rng.std).all()):
        raise ValueError(f"{path}: metadata 'obs_norm': expected finite mean and var")
    return rng


@dataclass(frozen=True)
class OnnxSpec:
    """What an ONNX export records of its task (``OnnxPolicy.spec``; the torch policy's spec is
    a :class:`ndp.schema.TaskSchema`, which needs torch)."""

    task: str
    obs_dim: int
    """Observation size O."""
    action_dim: int
    """Action size A (per sub-step)."""
    dmp_dofs: int
    """Robot-state size D (``y0``, ``dy0``)."""
    k: int
    """Sub-steps per decision."""
    action_low: tuple[float, ...]
    action_high: tuple[float, ...]
    dof_names: tuple[str, ...] = ()
    """Names of the D robot-state entries (exports from this version on; empty before)."""
    dof_units: tuple[str, ...] = ()
    control_dt: float | None = None
    """Seconds per env step (exports from this version on; None before)."""


def is_onnx_export(path: str | Path) -> bool:
    """A ``policy.onnx`` file, or a folder holding one and no torch policy (``policy.json`` /
    ``config.json``)."""
    p = Path(path)
    if p.suffix == ".onnx":
        return p.is_file()
    return (p / ONNX_FILE).is_file() and not (
        (p / "policy.json").is_file() or (p / "config.json").is_file()
    )
