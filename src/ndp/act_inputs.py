"""What a policy's ``act(obs, robot_state)`` accepts, checked in one place for every runtime.

The torch policy (:class:`ndp.rl.policy.Policy`) and the ONNX one
(:class:`ndp.rl.onnx_export.OnnxPolicy`) take the same inputs and refuse the same bad ones with
the same one-line messages: the observation's shape and finiteness, and the robot state the DMP
starts from, given as the chunked env's info, any mapping with the policy's two state keys, a
:class:`RobotState`, or None for a policy that does not read it. NumPy only (no torch), so a
deployment with onnxruntime alone uses it too.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeAlias

import numpy as np
from numpy.typing import ArrayLike

FLOAT32_MAX = float(np.finfo(np.float32).max)
"""The largest magnitude an observation may have: every runtime computes in float32 at some
point (the ONNX graph's inputs, the torch network), where a larger value becomes inf."""


@dataclass(frozen=True)
class RobotState:
    """The robot state a policy's DMP starts from (the ``robot_state`` of ``Policy.act``).

    Units are the task's DMP coordinates (``policy.spec.dof_names`` / ``dof_units``; where the
    env reads them: ``policy.spec.y0_source``); which state (commanded or measured) is
    ``policy.cfg.policy.dmp_state``, i.e. the info keys ``Policy.state_keys``.
    """

    y0: Any
    """Position [D] (or [E, D] for E observations), e.g. Meta-World: hand x, y, z (m) and the
    last gripper command; Jaco: 6 joint angles and the finger angle (rad)."""
    dy0: Any = None
    """Velocity [D] / [E, D] per second; None: at rest (zeros), allowed only for a policy whose
    DMP starts at rest (``dmp_velocity == "zero"``)."""


ActInfo: TypeAlias = Mapping[str, object] | RobotState | None
"""The robot state ``act`` takes beside the observation (``Policy.act``, ``OnnxPolicy.act``):
the chunked env's info, a mapping with the policy's ``state_keys``, a :class:`RobotState`, or
None for a policy without a DMP."""


@dataclass
class ObsRange:
    """The inputs a policy was trained on: the observation normaliser's frozen statistics.

    An observation entry further than ``clip`` standard deviations from the training mean is
    cut to that bound by the normaliser (torch and ONNX alike): :meth:`check` says so once per
    policy (a ``RuntimeWarning`` naming ``obs``, the index, the value and the range), with the
    same words in every runtime, instead of acting on it silently.
    """

    mean: np.ndarray
    """Training mean [O]."""
    std: np.ndarray
    """Training standard deviation [O] (sqrt(var + 1e-8), as the normaliser divides)."""
    clip: float
    """The normaliser's bound in standard deviations."""
    warned: bool = field(default=False, compare=False)
    """Set after the first warning (once per policy)."""

    def check(self, obs: np.ndarray, stacklevel: int = 3) -> None:
        """Warn (once) where ``obs`` [E, O] leaves ``mean +- clip * std``."""
        if self.warned:
            return
        z = np.abs(obs - self.mean) / self.std
        if not (z > self.clip).any():
            return
        self.warned = True
        idx = [int(i) for i in np.unravel_index(int(np.argmax(z)), z.shape)]
        j = idx[-1]
        lo, hi = self.mean[j] - self.clip * self.std[j], self.mean[j] + self.clip * self.std[j]
        where = idx if obs.shape[0] > 1 else idx[-1:]
        warnings.warn(
            f"obs: entry {where} is {float(obs[tuple(idx)]):.3g}, outside the trained range "
            f"[{lo:.3g}, {hi:.3g}] (mean +- {self.clip:g} std of the training observations): "
            "clipped to it; the policy has not seen such inputs (said once per policy)",
            RuntimeWarning,
            stacklevel=stacklevel,
        )


def obs_range_of(mean: ArrayLike, var: ArrayLike, clip: float) -> ObsRange:
    """An :class:`ObsRange` from the normaliser's mean [O] and variance [O]."""
    m = np.asarray(mean, dtype=np.float64)
    return ObsRange(m, np.sqrt(np.asarray(var, dtype=np.float64) + 1e-8), float(clip))


def check_act_inputs(
    obs: object,
    info: object,
    *,
    obs_dim: int,
    dofs: int,
    state_keys: tuple[str, str],
    needs_state: bool,
    starts_at_rest: bool,
    what: str = "this policy",
    state_name: str = "info",
) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """``(obs [E, O] float64, y0 [E, D], dy0 [E, D], single)`` of a policy's inputs, checked.

    Args:
        obs: [O] or [E, O] observations as the env returns them (any real dtype).
        info: the chunked env's info, a mapping with ``state_keys``, a :class:`RobotState`
            (or any object with ``y0`` / ``dy0``), or None where the policy does not read it.
        obs_dim: O.
        dofs: D, the DMP's degrees of freedom.
        state_keys: the two info keys of the DMP start (``("cmd_y0", "cmd_dy0")`` ...).
        needs_state: the policy reads the robot state (NDP); else zeros stand in for it.
        starts_at_rest: the DMP starts at rest, so a RobotState without dy0 is allowed.
        what: how messages name the policy.
        state_name: how messages name the argument holding the robot state (``info``; SB3's
            ``observation`` dict).

    Raises:
        ValueError: one line naming the argument, the expected and the received shape or value.
    """
    ky, kdy = state_keys
    try:
        o = np.asarray(obs, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(
            f"obs: expected an array of numbers [{obs_dim}] or [E, {obs_dim}], got "
            f"{type(obs).__name__}"
        ) from None
    single = o.ndim == 1
    if o.ndim not in (1, 2) or o.shape[-1] != obs_dim:
        raise ValueError(f"obs: expected [{obs_dim}] or [E, {obs_dim}], got shape {list(o.shape)}")
    o = o.reshape(1 if single else len(o), -1)
    if not np.isfinite(o).all():
        bad = np.argwhere(~np.isfinite(o))[0].tolist()
        raise ValueError(f"obs: expected finite values, got {o[tuple(bad)]} at {bad}")
    if (np.abs(o) > FLOAT32_MAX).any():
        bad = np.argwhere(np.abs(o) > FLOAT32_MAX)[0].tolist()
        raise ValueError(
            f"obs: expected values within float32's range (|x| <= {FLOAT32_MAX:.3g}), got "
            f"{o[tuple(bad)]:.3g} at {bad}"
        )
    shape = (dofs,) if single else (len(o), dofs)
    mapping = _state_mapping(info, shape, state_keys, needs_state, starts_at_rest, what)
    if ky not in mapping or kdy not in mapping:
        raise ValueError(
            f"info: expected the chunked env's {ky!r} and {kdy!r} (use policy.make_env() "
            "or ndp.make_env(task, k=...)), or a robot state (ndp.RobotState(y0, dy0) or "
            f"a mapping with those keys), got keys {sorted(map(str, mapping))[:8]}"
        )
    states = []
    for key in (ky, kdy):
        try:
            v = np.asarray(mapping[key], dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(
                f"{state_name}: {key!r} expected numbers, got {mapping[key]!r}"
            ) from None
        if v.shape != shape:
            want = f"[{dofs}]" if single else f"[{len(o)}, {dofs}] for {len(o)} observations"
            raise ValueError(f"{state_name}: {key!r} expected shape {want}, got {list(v.shape)}")
        if not np.isfinite(v).all():
            raise ValueError(f"{state_name}: {key!r} expected finite values, got {v.tolist()}")
        states.append(v.reshape(len(o), dofs))
    return o, states[0], states[1], single


def _state_mapping(
    info: object,
    shape: tuple[int, ...],
    state_keys: tuple[str, str],
    needs_state: bool,
    starts_at_rest: bool,
    what: str,
) -> Mapping[object, object]:
    """The robot state as a mapping with ``state_keys`` (a RobotState, None)."""
    ky, kdy = state_keys
    if isinstance(info, RobotState) or (
        not isinstance(info, Mapping) and hasattr(info, "y0") and hasattr(info, "dy0")
    ):
        dy0 = info.dy0
        if dy0 is None:
            if not starts_at_rest and needs_state:
                raise ValueError(
                    f"robot_state: dy0 is None, but {what}'s DMP starts with the robot's "
                    f"velocity; give dy0 with shape {list(shape)}"
                )
            dy0 = np.zeros(shape)
        return {ky: info.y0, kdy: dy0}
    if info is None:
        if needs_state:
            raise ValueError(
                f"robot_state: {what}'s DMP starts from the robot's state; give "
                f"ndp.RobotState(y0, dy0) or a mapping with {ky!r}, {kdy!r} (shape "
                f"{list(shape)} each)"
            )
        return {ky: np.zeros(shape), kdy: np.zeros(shape)}
    if not isinstance(info, Mapping):
        raise ValueError(
            "info: expected the env's info dict, a mapping with "
            f"{ky!r} and {kdy!r}, or an ndp.RobotState; got {type(info).__name__}"
        )
    return info
