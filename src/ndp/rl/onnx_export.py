"""A trained policy's deterministic decision as one ONNX graph (``ndp rl export --format onnx``).

The graph is :class:`DecisionModule`: observation normaliser (clip included) -> actor MLP ->
action head (NDP: goal and weights -> DMP rollout from (y0, dy0) -> inverse controller -> k
sub-actions; PPO: one action; PPO-multi: k actions; VICES: the impedance action; Dyn-E: the
decoded k actions) -> the distribution's mode -> clip to the task's action bounds. It computes
exactly what ``Policy.act(obs, info, deterministic=True)`` computes:

- inputs ``obs`` [E, O], ``y0`` [E, D], ``dy0`` [E, D], all float32 (what deployment runtimes
  feed; format version 1 took float64; the normaliser runs in float64 inside like the eager
  policy's, the rest in float32). y0
  and dy0 are the DMP start, read from the chunked env's info keys named in the metadata
  (``state_keys``: ``cmd_y0`` / ``cmd_dy0`` for the commanded state, ``dmp_y0`` / ``dmp_dy0``
  for the measured one). Heads without a DMP ignore their values (every graph takes the three
  inputs, so one calling code serves every method; their batch size must be E);
- output ``actions`` [E, k, A] float32 within the action bounds; E is a dynamic axis.

The file's ``metadata_props`` hold the task, method, k, the dimensions, the state keys and DMP
frame, the bounds, the resolved config, package versions and the commit (:func:`onnx_metadata`).

Exporter: ``torch.onnx.export(..., dynamo=False)``, the TorchScript-based exporter. torch 2.13's
default (``dynamo=True``) records the module with ``torch.export`` (which this module passes:
``tests/rl/test_onnx.py``) and then needs the ``onnxscript`` package, which is not among this
project's dependencies; the TorchScript exporter needs nothing beyond torch, and ``onnx``
(checker, metadata) and ``onnxruntime`` (the export is run once on probe inputs and compared
with the eager policy before it is written: a graph that does not reproduce the policy is
refused, naming the method).
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import nn

from ndp.chunk_info import frame_of_keys
from ndp.io import atomic_write_bytes, check_output_path
from ndp.provenance import git_commit, installed_versions
from ndp.rl.onnx_policy import (  # noqa: F401  # re-exported: the export's public names
    ONNX_FILE,
    ONNX_FORMAT,
    ONNX_VERSION,
    ONNX_VERSIONS,
    OnnxPolicy,
    _require,
    onnx_metadata,
)
from ndp.schema import spec_record

if TYPE_CHECKING:
    from ndp.rl.policy import Policy

OPSET = 17
"""ONNX opset of the graph (supported by onnxruntime >= 1.14)."""
INPUTS = ("obs", "y0", "dy0")
OUTPUTS = ("actions",)
VERIFY_ATOL = 1e-5
"""Largest absolute difference from the eager policy accepted on the probe inputs."""


class DecisionModule(nn.Module):
    """``(obs, y0, dy0) -> actions``: the deterministic decision of a :class:`Policy`.

    Args:
        policy: a trained policy (not an ``at_exec_k`` copy); its actor-critic is shared, not
            copied.

    Shapes: obs [E, O], y0 and dy0 [E, D] float32 (what deployment runtimes feed; the
    normaliser still computes in float64 inside) -> actions [E, k, A] float32.
    """

    # buffers registered in __init__
    obs_mean: torch.Tensor
    obs_std: torch.Tensor
    low: torch.Tensor
    high: torch.Tensor

    def __init__(self, policy: Policy) -> None:
        super().__init__()
        self.model = policy.model
        norm = policy.obs_norm
        self.normalise = bool(norm.enabled)
        self.clip = float(norm.clip)
        mean = torch.as_tensor(np.asarray(norm.rms.mean, dtype=np.float64))
        std = torch.as_tensor(np.sqrt(np.asarray(norm.rms.var, dtype=np.float64) + 1e-8))
        self.register_buffer("obs_mean", mean, persistent=False)
        self.register_buffer("obs_std", std, persistent=False)
        low = torch.as_tensor(np.asarray(policy.spec.action_low, dtype=np.float32))
        high = torch.as_tensor(np.asarray(policy.spec.action_high, dtype=np.float32))
        self.register_buffer("low", low, persistent=False)
        self.register_buffer("high", high, persistent=False)
        self.k = int(policy.model.head.k)
        self.action_dim = int(policy.model.head.action_dim)

    def forward(self, obs: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor) -> torch.Tensor:
        x = obs.to(torch.float64)
        if self.normalise:  # ObsNormalizer: float64, then float32
            x = torch.clamp((x - self.obs_mean) / self.obs_std, -self.clip, self.clip)
        state = y0.to(torch.float32), dy0.to(torch.float32)
        dist, _ = self.model.distribution(x.to(torch.float32), *state)
        act = dist.actions(dist.mode())
        act = torch.maximum(torch.minimum(act, self.high), self.low)
        # the batch sizes of y0 and dy0 enter the graph, so every method's graph keeps the
        # three inputs (an exporter drops inputs whose values are not used) and checks them
        act = act.reshape(y0.shape[0], self.k, self.action_dim)
        return act.reshape(dy0.shape[0], self.k, self.action_dim)


def probe_inputs(policy: Policy, batch: int, seed: int = 0) -> tuple[torch.Tensor, ...]:
    """Float32 inputs (the graph's input type) spread around the normaliser's statistics
    (observations within 3 std, some beyond the clip) and robot states in [-1, 1], for tracing
    and verification."""
    gen = np.random.default_rng(seed)
    norm = policy.obs_norm
    std = np.sqrt(np.asarray(norm.rms.var, dtype=np.float64) + 1e-8)
    obs = norm.rms.mean + std * gen.normal(0.0, 3.0, (batch, policy.model.obs_dim))
    d = int(policy.spec.dmp_dofs)
    y0 = gen.uniform(-1.0, 1.0, (batch, d))
    dy0 = gen.uniform(-1.0, 1.0, (batch, d))
    return tuple(torch.as_tensor(a, dtype=torch.float32) for a in (obs, y0, dy0))


def _method(policy: Policy) -> str:
    return f"method {policy.cfg.algo!r} (head {type(policy.model.head).__name__})"


def onnx_model_bytes(policy: Policy) -> bytes:
    """The decision of ``policy`` as a serialised ONNX model with its metadata, checked by
    ``onnx.checker`` and verified against the eager policy in onnxruntime.

    Raises:
        ValueError: an ``at_exec_k`` copy; a head the exporter cannot record, or whose graph
            does not reproduce the policy (one line naming the method).
    """
    import io

    onnx = _require("onnx")
    _require("onnxruntime")  # before the export's work: the verification needs it
    if policy.substeps != 1:
        raise ValueError(
            "policy: an exec-k evaluation copy cannot be exported; export the trained policy"
        )
    module = DecisionModule(policy).eval()
    args = probe_inputs(policy, 2)
    buf = io.BytesIO()
    try:
        with torch.no_grad(), warnings.catch_warnings():
            # the TorchScript exporter is deprecated in favour of dynamo=True (the module doc
            # says why it is used); tracer warnings concern the shape checks, constant here
            warnings.simplefilter("ignore")
            torch.onnx.export(
                module,
                args,
                # typed str | PathLike, but the TorchScript exporter (dynamo=False) takes a file
                buf,  # type: ignore[arg-type]
                dynamo=False,
                input_names=list(INPUTS),
                output_names=list(OUTPUTS),
                dynamic_axes={name: {0: "E"} for name in INPUTS + OUTPUTS},
                opset_version=OPSET,
            )
    except Exception as exc:  # any exporter failure: one line naming the method and head
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:160]
        raise ValueError(f"{_method(policy)}: cannot be exported to ONNX ({first})") from None
    model = onnx.load_from_string(buf.getvalue())
    names = [i.name for i in model.graph.input]
    if names != list(INPUTS):  # an input whose values were recorded as constants is dropped
        raise ValueError(
            f"{_method(policy)}: the ONNX graph does not reproduce the policy (its inputs are "
            f"{names}, not {list(INPUTS)}: the head computes outside torch); use the default "
            "format"
        )
    for key, value in onnx_metadata_of(policy).items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(model, full_check=True)
    data = model.SerializeToString()
    _verify(policy, module, data)
    return bytes(data)


def _verify(policy: Policy, module: DecisionModule, data: bytes) -> None:
    """Run the graph on probe inputs of another batch size than the traced one; refuse it when
    it differs from the eager module by more than :data:`VERIFY_ATOL`."""
    ort = _require("onnxruntime")
    session = ort.InferenceSession(data, providers=["CPUExecutionProvider"])
    for batch, seed in ((5, 1), (1, 2)):
        inputs = probe_inputs(policy, batch, seed)
        with torch.no_grad():
            want = module(*inputs).numpy()
        feed = {name: t.numpy() for name, t in zip(INPUTS, inputs, strict=True)}
        try:
            got = session.run(None, feed)[0]
        except Exception as exc:  # onnxruntime's own error types
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:160]
            raise ValueError(
                f"{_method(policy)}: the ONNX graph does not run in onnxruntime ({first})"
            ) from None
        err = float(np.abs(got - want).max()) if got.shape == want.shape else float("inf")
        if not err <= VERIFY_ATOL:
            raise ValueError(
                f"{_method(policy)}: the ONNX graph does not reproduce the policy (batch "
                f"{batch}: shape {list(got.shape)} vs {list(want.shape)}, max difference "
                f"{err:.3g}); use the default format"
            )


def onnx_metadata_of(policy: Policy) -> dict[str, str]:
    """The ``metadata_props`` of a policy's ONNX file (every value a string; JSON where it is
    not one)."""
    spec, head = policy.spec, policy.model.head
    ky, kdy = policy.state_keys
    meta: dict[str, Any] = {
        "format": ONNX_FORMAT,
        "version": ONNX_VERSION,
        "task": policy.cfg.task,
        "algo": policy.cfg.algo,
        "head": policy.cfg.policy.head,
        "k": int(head.k),
        "obs_dim": int(policy.model.obs_dim),
        "action_dim": int(head.action_dim),
        "dmp_dofs": int(spec.dmp_dofs),
        "inputs": list(INPUTS),
        "outputs": list(OUTPUTS),
        "input_dtype": "float32",
        "output_dtype": "float32",
        "state_keys": [ky, kdy],
        "dmp_state": frame_of_keys(ky),
        "uses_robot_state": bool(head.needs_robot_state),
        "action_low": np.asarray(spec.action_low, dtype=np.float64).tolist(),
        "action_high": np.asarray(spec.action_high, dtype=np.float64).tolist(),
        "obs_norm": {
            "enabled": bool(policy.obs_norm.enabled),
            "mean": np.asarray(policy.obs_norm.rms.mean, dtype=np.float64).tolist(),
            "var": np.asarray(policy.obs_norm.rms.var, dtype=np.float64).tolist(),
            "clip": float(policy.obs_norm.clip),
        },
        "config": policy.cfg.to_dict(),
        "spec": spec_record(spec),
        "versions": installed_versions(),
        "commit": git_commit(),
    }
    return {k: v if isinstance(v, str) else json.dumps(v) for k, v in meta.items()}


def write_onnx_export(policy: Policy, out_dir: str | Path) -> Path:
    """Write ``out_dir/policy.onnx`` (a new directory, or one holding none of the files an
    export writes, :func:`ndp.rl.card.check_export_dir`); returns ``out_dir``."""
    out = Path(out_dir)
    check_output_path(out, "out_dir", folder=True, create=False)  # before the export's work
    from ndp.rl.card import check_export_dir

    check_export_dir(out, (ONNX_FILE,))
    data = onnx_model_bytes(policy)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(out / ONNX_FILE, data)
    return out
