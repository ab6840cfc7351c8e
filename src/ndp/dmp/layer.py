"""DMPLayer: the DMP integrator as a parameter-free ``torch.nn.Module``."""

from __future__ import annotations

import dataclasses
from typing import Any

import torch
from torch import nn

from ndp.dmp.config import DMPConfig
from ndp.dmp.integrate import DMPTrajectory, _linear_map_f64, dmp_positions, dmp_rollout


class DMPLayer(nn.Module):
    """Differentiable, batched DMP integrator to drop into any network.

    Example::

        layer = DMPLayer(DMPConfig(n_basis=30, a_z=25.0, steps=300))
        traj = layer(goal, weights, y0)          # goal [B, D], weights [B, D, N], y0 [B, D]
        loss = ((traj.pos - demo) ** 2).mean()   # traj.pos [B, 301, D]

    Args:
        config: integrator settings; keyword overrides are applied on top of it.
        check_finite: raise ``FloatingPointError`` when an input holds NaN or Inf (one
            reduction per input; switch off only where the caller checks itself). Tensors on
            the meta device hold no values: they are not checked, and the layer returns
            meta tensors of the output shapes (shape inference).
        **overrides: any :class:`DMPConfig` field, e.g. ``n_basis=6``.
    """

    def __init__(
        self, config: DMPConfig | None = None, check_finite: bool = True, **overrides: Any
    ) -> None:
        super().__init__()
        config = config or DMPConfig()
        fields = [f.name for f in dataclasses.fields(DMPConfig)]
        for name in overrides:
            if name in ("device", "dtype"):
                raise ValueError(
                    f"{name}: DMPLayer holds no parameters; its outputs follow the inputs' "
                    "device and dtype (meta tensors in: shapes out)"
                )
            if name not in fields:
                import difflib

                close = difflib.get_close_matches(name, fields, n=3, cutoff=0.6)
                names = close or fields
                hint = ("close names: " if close else "known: ") + ", ".join(names)
                raise ValueError(f"{name}: not a DMPConfig field; {hint}")
        self.config = dataclasses.replace(config, **overrides) if overrides else config
        self.check_finite = check_finite
        # the fixed-a_z linear map, built now (eagerly) so that torch.export only reads it
        self._map_f64 = None if self.config.learn_az else _linear_map_f64(self.config, None)

    def forward(
        self,
        goal: torch.Tensor,
        weights: torch.Tensor | None,
        y0: torch.Tensor,
        dy0: torch.Tensor | None = None,
        a_z: torch.Tensor | None = None,
    ) -> DMPTrajectory:
        """Integrate; see :func:`ndp.dmp.dmp_rollout` for shapes.

        Args:
            goal: [B, D]. weights: [B, D, N]. y0, dy0: [B, D].
            a_z: per-sample [B] / [B, 1] / [B, D] when ``config.learn_az`` (clamped).

        Returns:
            :class:`DMPTrajectory` of [B, n_out, D] tensors.
        """
        return dmp_rollout(
            goal,
            weights,
            y0,
            dy0,
            self.config,
            a_z=a_z,
            check=self.check_finite,
            linear_map=self._map_f64,
        )

    def positions(
        self,
        goal: torch.Tensor,
        weights: torch.Tensor | None,
        y0: torch.Tensor,
        dy0: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """Positions only, [B, n_out, D] (fixed a_z; a third of the work of :meth:`forward`)."""
        return dmp_positions(
            goal, weights, y0, dy0, self.config, check=self.check_finite, linear_map=self._map_f64
        )

    def extra_repr(self) -> str:
        c = self.config
        return (
            f"n_basis={c.n_basis}, a_z={'learned' if c.learn_az else c.a_z}, steps={c.steps}, "
            f"subsample={c.subsample}, rbf={c.rbf}, forcing={c.forcing}, only_g={c.only_g}"
        )
