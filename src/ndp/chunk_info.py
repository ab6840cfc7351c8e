"""The protocol between the chunked env and everything that reads its ``info``: the keys of
the DMP start, in one place.

:class:`ndp.envs.ChunkedEnv` reports the robot state a DMP can start from in two frames
(docs/envs.md): the **measured** state (``dmp_y0`` / ``dmp_dy0``: the robot as MuJoCo has it)
and the **commanded** state (``cmd_y0`` / ``cmd_dy0``: the target the actions move). A policy's
``dmp_state`` ('commanded' or 'measured', the task preset's unless set) says which it starts
from. The trainers, ``Policy.act``, the ONNX export, the SB3 wrapper, Dyn-E and the demo
recorder read the keys through :func:`dmp_start_keys` / :func:`dmp_start`, so the two frames
are named nowhere else. This module imports nothing heavy (no gymnasium, no torch).
"""

from __future__ import annotations

from typing import Any

import numpy as np

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


def dmp_start(info: Any, frame: str, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
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
