"""The protocol between the chunked env and everything that reads its ``info``: the step
info's schema (:class:`ChunkInfo`, from which the vector envs derive their shared arrays,
:func:`info_schema`) and the keys of the DMP start, in one place.

:class:`ndp.envs.ChunkedEnv` reports the robot state a DMP can start from in two frames
(docs/envs.md): the **measured** state (``dmp_y0`` / ``dmp_dy0``: the robot as MuJoCo has it)
and the **commanded** state (``cmd_y0`` / ``cmd_dy0``: the target the actions move). A policy's
``dmp_state`` ('commanded' or 'measured', the task preset's unless set) says which it starts
from. The trainers, ``Policy.act``, the ONNX export, the SB3 wrapper, Dyn-E and the demo
recorder read the keys through :func:`dmp_start_keys` / :func:`dmp_start`, so the two frames
are named nowhere else. This module imports nothing heavy (no gymnasium, no torch).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np


def _f(shape: tuple[str, ...], dtype: type[np.generic], doc: str) -> dict[str, object]:
    """A :class:`ChunkInfo` field's metadata: its per-env shape in the symbols ``k``
    (sub-steps), ``k+1`` and ``D`` (DMP DoF), its dtype and what it is."""
    return {"shape": shape, "dtype": dtype, "doc": doc}


@dataclass(frozen=True)
class ChunkInfo:
    """The info of one :class:`ndp.envs.ChunkedEnv` step, key by key (``as_dict()`` is the
    gymnasium info dict; units physical; k sub-steps, D DMP DoF)."""

    sub_rewards: np.ndarray = field(
        metadata=_f(("k",), np.float64, "sub-step rewards, stale-world rule applied")
    )
    sub_rewards_live: np.ndarray = field(
        metadata=_f(("k",), np.float64, "sub-step rewards of the live world")
    )
    sub_mask: np.ndarray = field(metadata=_f(("k",), np.float64, "1 for the sub-steps that ran"))
    sub_success: np.ndarray = field(
        metadata=_f(("k",), np.float64, "the task's success flag per sub-step")
    )
    success: bool = field(metadata=_f((), np.bool_, "success at the decision's last sub-step"))
    success_decision: bool = field(
        metadata=_f((), np.bool_, "success at any sub-step of the decision")
    )
    success_any: bool = field(
        metadata=_f((), np.bool_, "success at any step of the episode so far")
    )
    robot_pos: np.ndarray = field(
        metadata=_f(("k+1", "D"), np.float64, "measured state before and after each sub-step")
    )
    robot_vel: np.ndarray = field(metadata=_f(("k+1", "D"), np.float64, "its velocity"))
    dmp_y0: np.ndarray = field(
        metadata=_f(("D",), np.float64, "measured DMP start of the next decision")
    )
    dmp_dy0: np.ndarray = field(metadata=_f(("D",), np.float64, "its velocity"))
    cmd_y0: np.ndarray = field(
        metadata=_f(("D",), np.float64, "commanded DMP start of the next decision")
    )
    cmd_dy0: np.ndarray = field(metadata=_f(("D",), np.float64, "its velocity"))
    n_substeps: int = field(
        metadata=_f((), np.int64, "sub-steps that ran (< k when the episode ended)")
    )
    sim_unstable: bool = field(
        metadata=_f((), np.bool_, "the simulator became unstable (episode truncated)")
    )
    ctrl_gains_clipped: int = field(metadata=_f((), np.int64, "torque tasks: gain entries clipped"))
    ctrl_torque_saturated: int = field(
        metadata=_f((), np.int64, "torque tasks: saturated torque entries")
    )
    ctrl_nonfinite: int = field(
        metadata=_f((), np.int64, "torque tasks: non-finite torques replaced")
    )

    def as_dict(self) -> dict[str, Any]:
        """The gymnasium info dict (the same objects, not copies)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


CHUNK_INFO_KEYS = tuple(f.name for f in dataclasses.fields(ChunkInfo))
"""Every key of a chunked step's info, in order."""


def info_schema(k: int, dof: int) -> dict[str, tuple[tuple[int, ...], type[np.generic]]]:
    """Key -> (per-env shape, dtype) of :class:`ChunkInfo` for ``k`` sub-steps and ``dof`` DMP
    DoF (the shared arrays of :class:`ndp.envs.vector.WorkerVectorEnv`)."""
    size = {"k": int(k), "k+1": int(k) + 1, "D": int(dof)}
    return {
        f.name: (tuple(size[s] for s in f.metadata["shape"]), f.metadata["dtype"])
        for f in dataclasses.fields(ChunkInfo)
    }


DMP_FRAMES = ("commanded", "measured")
"""The frames a DMP can start from (``PolicyConfig.dmp_state``)."""
DMP_START_KEYS: dict[str, tuple[str, str]] = {
    "commanded": ("cmd_y0", "cmd_dy0"),
    "measured": ("dmp_y0", "dmp_dy0"),
}
"""Frame -> the chunked env's info keys of the DMP start (position [D], velocity [D])."""


def dmp_start_keys(frame: str) -> tuple[str, str]:
    """The info keys (position, velocity) of the DMP start in ``frame``.

    Raises:
        ValueError: not one of :data:`DMP_FRAMES`.
    """
    if frame not in DMP_START_KEYS:
        raise ValueError(f"dmp_state: expected one of {', '.join(DMP_FRAMES)}, got {frame!r}")
    return DMP_START_KEYS[frame]


def frame_of_keys(position_key: str) -> str:
    """The frame whose position key is ``position_key`` (inverse of :func:`dmp_start_keys`)."""
    for frame, (ky, _) in DMP_START_KEYS.items():
        if ky == position_key:
            return frame
    raise ValueError(f"position_key: expected one of cmd_y0, dmp_y0, got {position_key!r}")


def dmp_start(
    info: Mapping[str, object], frame: str, n: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The DMP start (y0, dy0) in ``frame`` from a chunked env's info (one env: [D] each) or a
    vector env's (``n`` envs: [n, D] each), as float64 arrays.

    Raises:
        ValueError: the info lacks the frame's keys (named).
    """
    ky, kdy = dmp_start_keys(frame)
    if ky not in info or kdy not in info:
        raise ValueError(
            f"info: expected the chunked env's {ky!r} and {kdy!r}, got keys {sorted(info)[:8]}"
        )
    y0 = np.asarray(info[ky], dtype=np.float64)
    dy0 = np.asarray(info[kdy], dtype=np.float64)
    if n is not None:
        y0, dy0 = y0.reshape(n, -1), dy0.reshape(n, -1)
    return y0, dy0
