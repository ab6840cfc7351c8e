"""Low-level controllers as data of the task table: trajectory points -> env actions.

A controller maps a trajectory of the DMP-driven coordinates, ``traj`` [..., k+1, D] in physical
units (``traj[..., 0, :]`` = the state where the decision starts), to the k actions the env
executes, [..., k, A]. It is a frozen dataclass held by ``TaskSpec.controller``, so a task with
another actuation (for example VICES's operational-space impedance control) is a table row with
another controller, not an edit of ``TaskSpec``. :data:`CONTROLLERS` names the kinds.

- :class:`DeltaController` (Meta-World's mocap hand, Jaco's joint-position targets, the toy
  point mass): ``a[t] = (p[t+1] - p[t]) / scale`` for delta DoF and ``a[t] = p[t+1]`` for DoF whose
  action is the value itself (Meta-World's gripper command), optionally clipped to the bounds.
  It is linear, so the NDP head can fold it into the DMP's linear map (``linear_parts``).

The module is torch only (no simulator), so that a trained policy rebuilds its head from the
task data its export records (``ndp.schema.PolicySpec``); the task table imports it as
``ndp.envs.controllers``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import ClassVar

import torch

from ndp.checks import plain_numbers


@dataclass(frozen=True)
class DeltaController:
    """Actions are consecutive differences / scale (delta DoF) or the values (absolute DoF)."""

    kind: ClassVar[str] = "delta"
    scale: tuple[float, ...]
    """Physical change per unit action, per DoF (ignored where ``absolute``)."""
    absolute: tuple[bool, ...]
    """True where the action is the trajectory value itself."""
    low: tuple[float, ...]
    """Action lower bounds."""
    high: tuple[float, ...]
    """Action upper bounds."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        n = len(self.scale)
        if not (len(self.absolute) == len(self.low) == len(self.high) == n) or n == 0:
            raise ValueError(
                f"controller: expected scale, absolute, low, high of one equal length, got "
                f"{len(self.scale)}, {len(self.absolute)}, {len(self.low)}, {len(self.high)}"
            )
        if any(s <= 0 for s, a in zip(self.scale, self.absolute, strict=True) if not a):
            raise ValueError(f"scale: expected > 0 for every delta DoF, got {self.scale}")

    @functools.cached_property
    def linear_parts(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """(scale, absolute, low, high) [D] tensors (scale 1 where absolute)."""
        scale = torch.tensor(
            [1.0 if a else s for s, a in zip(self.scale, self.absolute, strict=True)]
        )
        return (scale, torch.tensor(self.absolute), torch.tensor(self.low), torch.tensor(self.high))

    def __call__(
        self, traj: torch.Tensor, robot_pos: torch.Tensor | None = None, clip: bool = True
    ) -> torch.Tensor:
        """Actions [..., k, D] of a trajectory [..., k+1, D].

        Args:
            traj: trajectory points in physical units.
            robot_pos: optional measured start [..., D] replacing ``traj[..., 0, :]``.
            clip: clip to ``[low, high]``. A policy's Gaussian *mean* should not be clipped
                (the noise added afterwards would be biased toward the centre and saturated
                sub-steps would pass no gradient); only the executed sample is clipped, by the
                trainer and by ``ChunkedEnv``.
        """
        scale, absolute, low, high = self.linear_parts
        if traj.dim() < 2 or traj.shape[-2] < 2:
            raise ValueError(
                f"traj: expected shape [..., k+1, D] with k >= 1, got {tuple(traj.shape)}"
            )
        if traj.shape[-1] != scale.shape[0]:
            raise ValueError(f"traj: expected last dim {scale.shape[0]}, got {traj.shape[-1]}")
        if robot_pos is not None:
            traj = torch.cat([robot_pos.unsqueeze(-2).to(traj), traj[..., 1:, :]], dim=-2)
        dev, dt = traj.device, traj.dtype
        delta = (traj[..., 1:, :] - traj[..., :-1, :]) / scale.to(dev, dt)
        act = torch.where(absolute.to(dev), traj[..., 1:, :], delta)
        if not clip:
            return act
        return torch.maximum(torch.minimum(act, high.to(dev, dt)), low.to(dev, dt))


CONTROLLERS: dict[str, type] = {DeltaController.kind: DeltaController}
"""Controller kind -> class (a new actuation registers its class here)."""
