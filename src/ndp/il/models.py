"""Image-to-trajectory models on one CNN encoder: NDP, CNN and CNN-DMP.

All three share :class:`ndp.nets.MnistCNN` (28 x 28 input, 200 features) and a head
:class:`ndp.nets.MLP`; they differ only in what the head predicts and how the loss is taken:

- ``ndp``: the head predicts DMP parameters (g, w); the differentiable DMP layer integrates them
  from y0 = the demonstration's first point (dy0 = 0) into a 301-point trajectory; the loss is the
  trajectory mean squared error (gradients flow through the integrator).
- ``cnn``: the head regresses the 301 x 2 points directly; loss: trajectory MSE.
- ``cnn-dmp`` (Pahic et al. 2018): the head regresses DMP parameters fitted by least squares to
  each demonstration; the loss is on the (standardised) parameters; trajectories come from
  integrating the predicted parameters from y0.

Output parameterisation of the DMP models (``forcing_param``):

- ``"amplitude"`` (default): the head predicts the forcing amplitude a = w * (g - y0) per basis
  function, integrated by a DMP layer with ``scale_by_goal=False`` (f = sum phi_i a_i x). The
  released forcing term is f = sum phi_i w_i x (g - y0), so this is the same DMP, but the
  prediction target and the gradients stay bounded when g - y0 is near zero in a coordinate
  (closed digits such as 0 and 8, vertical strokes such as 1), where least-squares weights
  reach 1e5 - 1e7 on this data.
- ``"weights"``: the head predicts w directly (times ``weight_scale``), as in the paper.

Coordinates: the goal is predicted as ``frame/2 + frame/2 * o_g`` (pixels); forcing amplitudes
as ``amp_scale * o_a`` (pixels / s^2 in DMP time).
"""

from __future__ import annotations

import torch
from torch import nn

from ndp.dmp import DMPLayer, fit_dmp
from ndp.il.config import MODEL_KINDS, ModelConfig
from ndp.nets import MLP, MnistCNN

__all__ = [
    "MODEL_KINDS",
    "CNNDMPModel",
    "CNNModel",
    "ModelConfig",
    "NDPModel",
    "TrajectoryModel",
    "build_model",
]


class TrajectoryModel(nn.Module):
    """Base class: images [B, H, W] (+ y0 [B, 2]) -> trajectories [B, T, 2] in pixels.

    Subclasses implement :meth:`forward` (returning the trajectory and, for DMP models, the raw
    head output) and :meth:`loss`.
    """

    def __init__(self, cfg: ModelConfig, out_dim: int) -> None:
        super().__init__()
        self.cfg = cfg
        self.encoder = MnistCNN(out_dim=cfg.feat_dim, image_size=cfg.image_size)
        self.head = MLP(cfg.feat_dim, cfg.head_hidden, out_dim, activation="relu", out_gain=0.1)

    def features(self, images: torch.Tensor) -> torch.Tensor:
        """Encoder + head: images [B, H, W] -> raw outputs [B, out_dim]."""
        out: torch.Tensor = self.head(self.encoder(images))
        return out

    def predict(self, images: torch.Tensor, y0: torch.Tensor) -> torch.Tensor:
        """Trajectory [B, T, 2] in pixels for images [B, H, W] and start points y0 [B, 2]."""
        raise NotImplementedError

    def loss(
        self, images: torch.Tensor, demos: torch.Tensor, targets: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Training loss and predicted trajectories.

        Args:
            images: [B, H, W].
            demos: demonstrated trajectories [B, T, 2] in pixels.
            targets: per-sample regression targets (CNN-DMP's fitted parameters), or None.

        Returns:
            (scalar loss, predicted trajectory [B, T, 2]).
        """
        pred = self.predict(images, demos[:, 0])
        return ((pred - demos) ** 2).mean(), pred


class CNNModel(TrajectoryModel):
    """CNN baseline: the encoder regresses all T x 2 points (no y0, no DMP)."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__(cfg, cfg.n_points * 2)

    def predict(self, images: torch.Tensor, y0: torch.Tensor | None = None) -> torch.Tensor:
        raw = self.features(images).view(-1, self.cfg.n_points, 2)
        half = self.cfg.frame / 2
        return half + half * raw


class _DMPModel(TrajectoryModel):
    """Shared parts of NDP and CNN-DMP: raw outputs <-> (g, w) and integration."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__(cfg, 2 * (cfg.n_basis + 1))
        self.dmp = DMPLayer(cfg.dmp_config(), check_finite=False)

    def params(self, raw: torch.Tensor, y0: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Raw head outputs [B, 2 (N + 1)] -> goal [B, 2] and the layer's weights [B, 2, N].

        The weights are in the parameterisation of ``self.dmp``: forcing amplitudes (pixels)
        when ``forcing_param == "amplitude"``, the paper's w otherwise. ``y0`` is unused (kept
        for a uniform signature).
        """
        cfg = self.cfg
        n = cfg.n_basis
        raw = raw.view(-1, 2, n + 1)
        half = cfg.frame / 2
        goal = half + half * raw[..., 0]
        scale = cfg.amp_scale if cfg.forcing_param == "amplitude" else cfg.weight_scale
        return goal, scale * raw[..., 1:]

    def raw_from_params(
        self, goal: torch.Tensor, weights: torch.Tensor, y0: torch.Tensor
    ) -> torch.Tensor:
        """Inverse of :meth:`params`: goal [B, 2], weights [B, 2, N] -> raw [B, 2 (N + 1)]."""
        cfg = self.cfg
        half = cfg.frame / 2
        og = (goal - half) / half
        scale = cfg.amp_scale if cfg.forcing_param == "amplitude" else cfg.weight_scale
        ow = weights / scale
        return torch.cat([og.unsqueeze(-1), ow], dim=-1).reshape(goal.shape[0], -1)

    def integrate(self, raw: torch.Tensor, y0: torch.Tensor) -> torch.Tensor:
        """Raw outputs [B, 2 (N + 1)] and y0 [B, 2] -> positions [B, T, 2] (dy0 = 0)."""
        goal, weights = self.params(raw, y0)
        pos: torch.Tensor = self.dmp(goal, weights, y0).pos
        return pos

    def predict(self, images: torch.Tensor, y0: torch.Tensor) -> torch.Tensor:
        return self.integrate(self.features(images), y0)


class NDPModel(_DMPModel):
    """Neural Dynamic Policy: CNN -> MLP -> (g, w) -> DMP layer -> trajectory; trajectory loss."""


class CNNDMPModel(_DMPModel):
    """CNN-DMP (Pahic et al. 2018): regress least-squares-fitted DMP parameters.

    The targets are the raw-output form of fitted (g, w) (see :meth:`fit_targets`), standardised
    per output with the training set's mean and std (buffers ``target_mean``, ``target_std``),
    and the loss is their mean squared error.
    """

    # buffers registered in __init__
    target_mean: torch.Tensor
    target_std: torch.Tensor

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__(cfg)
        dim = 2 * (cfg.n_basis + 1)
        self.register_buffer("target_mean", torch.zeros(dim))
        self.register_buffer("target_std", torch.ones(dim))

    @torch.no_grad()
    def fit_targets(self, demos: torch.Tensor, chunk: int = 2000) -> torch.Tensor:
        """Least-squares DMP fit of demonstrations [n, T, 2] -> raw targets [n, 2 (N + 1)]."""
        out = []
        dcfg = self.cfg.dmp_config()
        for s in range(0, demos.shape[0], chunk):
            d = demos[s : s + chunk].to(torch.float64)
            goal, weights = fit_dmp(d, dcfg, ridge=self.cfg.fit_ridge)
            out.append(self.raw_from_params(goal, weights, d[:, 0]).to(demos.dtype))
        return torch.cat(out, dim=0)

    @torch.no_grad()
    def set_target_stats(self, targets: torch.Tensor) -> None:
        """Store per-output mean and std of the training targets [n, 2 (N + 1)]."""
        self.target_mean.copy_(targets.mean(dim=0))
        self.target_std.copy_(targets.std(dim=0).clamp_min(1e-6))

    def predict(self, images: torch.Tensor, y0: torch.Tensor) -> torch.Tensor:
        z = self.features(images)
        return self.integrate(z * self.target_std + self.target_mean, y0)

    def loss(
        self, images: torch.Tensor, demos: torch.Tensor, targets: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        if targets is None:
            raise ValueError("CNN-DMP needs fitted DMP parameters as targets")
        z = self.features(images)
        loss = ((z - (targets - self.target_mean) / self.target_std) ** 2).mean()
        with torch.no_grad():
            pred = self.integrate(z * self.target_std + self.target_mean, demos[:, 0])
        return loss, pred


def build_model(cfg: ModelConfig) -> TrajectoryModel:
    """Construct the model named by ``cfg.kind``."""
    if cfg.kind == "ndp":
        return NDPModel(cfg)
    if cfg.kind == "cnn":
        return CNNModel(cfg)
    return CNNDMPModel(cfg)
