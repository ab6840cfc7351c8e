"""DMPLayer under torch.export: dynamic batch, the eager values, checks kept in eager mode."""

from __future__ import annotations

import pytest
import torch

from ndp.dmp import DMPConfig, DMPLayer, dmp_rollout
from ndp.dmp.integrate import _linear_map

CONFIGS = {
    "rl": DMPConfig(n_basis=6, a_z=10.0, steps=35, subsample=7, scale_by_goal=False),
    "paper": DMPConfig(n_basis=10, a_z=25.0, steps=60, subsample=3, rbf="inverse_quadric"),
    "only_g": DMPConfig(n_basis=4, a_z=15.0, steps=20, only_g=True, forcing="supplement"),
    "learn_az": DMPConfig(n_basis=5, a_z=10.0, steps=12, subsample=3, learn_az=True),
}


def _inputs(cfg: DMPConfig, b: int, d: int = 3, seed: int = 0) -> tuple[torch.Tensor, ...]:
    gen = torch.Generator().manual_seed(seed)
    goal, y0, dy0 = (torch.randn(b, d, generator=gen) for _ in range(3))
    weights = torch.randn(b, d, cfg.n_basis, generator=gen)
    if cfg.learn_az:
        return goal, weights, y0, dy0, 1.0 + 20.0 * torch.rand(b, generator=gen)
    return goal, weights, y0, dy0


@pytest.mark.parametrize("name", list(CONFIGS))
def test_torch_export_matches_eager_at_every_batch_size(name):
    cfg = CONFIGS[name]
    layer = DMPLayer(cfg)
    args = _inputs(cfg, 4)
    batch = torch.export.Dim("batch")
    program = torch.export.export(layer, args, dynamic_shapes=tuple({0: batch} for _ in args))
    exported = program.module()
    for b in (1, 4, 9):
        new = _inputs(cfg, b, seed=b)
        got, want = exported(*new), layer(*new)
        assert type(got).__name__ == "DMPTrajectory"
        for field, g, w in zip(("pos", "vel", "acc"), got, want, strict=True):
            assert g.shape == w.shape == (b, cfg.n_out, 3), field
            torch.testing.assert_close(g, w, rtol=0.0, atol=1e-6, msg=f"{name} {field} B={b}")


def test_exported_positions_and_the_eager_layer_after_export():
    cfg = DMPConfig(n_basis=7, a_z=12.0, steps=42, subsample=6)  # a config seen nowhere else

    class Positions(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.dmp = DMPLayer(cfg)

        def forward(self, goal, weights, y0, dy0):
            return self.dmp.positions(goal, weights, y0, dy0)

    mod = Positions()
    args = _inputs(cfg, 3)
    batch = torch.export.Dim("batch")
    program = torch.export.export(mod, args, dynamic_shapes=tuple({0: batch} for _ in args))
    new = _inputs(cfg, 5, seed=1)
    torch.testing.assert_close(program.module()(*new), mod(*new), rtol=0.0, atol=1e-6)
    # tracing cached no fake tensor: the eager paths still run and still check their inputs
    assert type(_linear_map(cfg, None, torch.device("cpu"), torch.float32)) is torch.Tensor
    torch.testing.assert_close(dmp_rollout(*new, cfg=cfg).pos, mod(*new), rtol=0.0, atol=1e-6)
    bad = list(new)
    bad[1] = bad[1].clone()
    bad[1][0, 0, 0] = float("nan")
    with pytest.raises(FloatingPointError, match="weights"):
        mod.dmp(*bad)
    # the recorded graph has no finite check (a graph cannot raise): NaN in, NaN out
    assert torch.isnan(program.module()(*bad)[0]).any()


@pytest.mark.filterwarnings("ignore::torch.jit.TracerWarning", "ignore::DeprecationWarning")
def test_jit_trace_still_matches():
    cfg = CONFIGS["rl"]
    layer = DMPLayer(cfg)

    class Pos(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.dmp = layer

        def forward(self, goal, weights, y0, dy0):
            return self.dmp.positions(goal, weights, y0, dy0)

    traced = torch.jit.trace(Pos(), _inputs(cfg, 4))
    new = _inputs(cfg, 4, seed=2)
    torch.testing.assert_close(traced(*new), layer.positions(*new), rtol=0.0, atol=1e-6)
