"""Models: shapes, the DMP start point, gradients through the integrator, CNN-DMP targets."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from ndp.dmp import DMPLayer
from ndp.il.models import CNNDMPModel, CNNModel, ModelConfig, NDPModel, build_model
from ndp.il.synthetic import SyntheticConfig, generate_synthetic


@pytest.fixture(scope="module")
def batch() -> tuple[torch.Tensor, torch.Tensor]:
    images, trajs, _ = generate_synthetic(SyntheticConfig(n_samples=20, seed=2))
    return torch.from_numpy(images.astype(np.float32) / 255.0), torch.from_numpy(trajs)


@pytest.mark.parametrize("kind", ["ndp", "cnn", "cnn-dmp"])
def test_output_shapes(kind: str, batch) -> None:
    torch.manual_seed(0)
    x, y = batch
    model = build_model(ModelConfig(kind=kind))
    pred = model.predict(x[:4], y[:4, 0])
    assert pred.shape == (4, 301, 2)
    assert torch.isfinite(pred).all()
    if kind == "cnn-dmp":
        assert isinstance(model, CNNDMPModel)
        targets = model.fit_targets(y)
        loss, p = model.loss(x[:4], y[:4], targets[:4])
    else:
        loss, p = model.loss(x[:4], y[:4])
    assert loss.ndim == 0 and p.shape == (4, 301, 2)


def test_dmp_models_start_at_y0(batch) -> None:
    x, y = batch
    for model in (NDPModel(ModelConfig()), CNNDMPModel(ModelConfig(kind="cnn-dmp"))):
        pred = model.predict(x[:5], y[:5, 0])
        assert torch.allclose(pred[:, 0], y[:5, 0])


def test_ndp_gradients_reach_encoder_through_dmp(batch) -> None:
    torch.manual_seed(0)
    x, y = batch
    model = NDPModel(ModelConfig())
    loss, _ = model.loss(x[:4], y[:4])
    loss.backward()
    g = model.encoder.conv1.weight.grad
    assert g is not None and torch.isfinite(g).all() and g.abs().sum() > 0


def test_amplitude_parameterisation_roundtrip() -> None:
    torch.manual_seed(0)
    model = NDPModel(ModelConfig())
    raw = torch.randn(3, 62, dtype=torch.float64)
    y0 = torch.rand(3, 2, dtype=torch.float64) * 40
    goal, w = model.params(raw, y0)
    assert goal.shape == (3, 2) and w.shape == (3, 2, 30)
    back = model.raw_from_params(goal, w, y0)
    assert torch.allclose(back, raw, atol=1e-9)
    # the forcing amplitude w (g - y0) is what the head predicts, whatever g - y0 is
    assert not model.dmp.config.scale_by_goal
    assert torch.allclose(w, 1000.0 * raw.view(3, 2, 31)[..., 1:], atol=1e-9)


def test_weights_parameterisation() -> None:
    model = NDPModel(ModelConfig(forcing_param="weights", weight_scale=10.0))
    raw = torch.randn(2, 62)
    _, w = model.params(raw, torch.zeros(2, 2))
    assert torch.allclose(w, 10.0 * raw.view(2, 2, 31)[..., 1:])
    with pytest.raises(ValueError, match="forcing_param"):
        ModelConfig(forcing_param="nope")
    with pytest.raises(ValueError, match="model: expected one of"):
        ModelConfig(kind="rnn")


def test_cnn_dmp_targets_reproduce_demos(batch) -> None:
    _, y = batch
    model = CNNDMPModel(ModelConfig(kind="cnn-dmp"))
    targets = model.fit_targets(y)
    assert targets.shape == (20, 62)
    model.set_target_stats(targets)
    pos = model.integrate(targets, y[:, 0])
    err = ((pos - y) ** 2).mean(dim=(1, 2))
    assert float(err.max()) < 0.3  # ridge-regularised fit, still sub-pixel
    # standardised targets: the loss is zero when the head outputs them exactly
    z = (targets - model.target_mean) / model.target_std
    assert torch.allclose(z.mean(0), torch.zeros(62), atol=1e-4)


def test_cnn_regresses_points_without_y0(batch) -> None:
    x, y = batch
    model = CNNModel(ModelConfig(kind="cnn"))
    a = model.predict(x[:2], y[:2, 0])
    b = model.predict(x[:2], torch.zeros(2, 2))
    assert torch.equal(a, b)


def test_ndp_overfits_a_few_digits(batch) -> None:
    torch.manual_seed(0)
    x, y = batch
    model = NDPModel(ModelConfig())
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    first = None
    for _ in range(80):
        loss, _ = model.loss(x, y)
        opt.zero_grad()
        loss.backward()
        opt.step()
        first = first if first is not None else loss.item()
    assert loss.item() < 0.5 * first, (first, loss.item())


def test_amplitude_rollout_equals_the_papers_form_and_has_finite_gradients() -> None:
    torch.manual_seed(1)
    model = NDPModel(ModelConfig())
    raw = 0.1 * torch.randn(4, 62, dtype=torch.float64)
    y0 = 10 + 20 * torch.rand(4, 2, dtype=torch.float64)
    goal, amp = model.params(raw, y0)
    paper = DMPLayer(dataclasses.replace(model.dmp.config, scale_by_goal=True))
    direct = paper(goal, amp / (goal - y0).unsqueeze(-1), y0).pos
    assert torch.allclose(model.integrate(raw, y0), direct, atol=1e-6)
    # gradient stays finite and moderate when g - y0 is exactly zero in one coordinate
    half = model.cfg.frame / 2
    raw2 = raw.clone()
    raw2.view(4, 2, 31)[0, 0, 0] = (y0[0, 0] - half) / half
    raw2.requires_grad_(True)
    model.integrate(raw2, y0).sum().backward()
    assert torch.isfinite(raw2.grad).all() and raw2.grad.abs().max() < 1e6


def test_paper_network_preset_is_the_release_head_for_every_model():
    """--network paper: the release's 100-200-128-64 ReLU head, for NDP, CNN and CNN-DMP alike
    (capacity held equal); a conflicting --head-hidden is refused."""
    import pytest
    import torch

    from ndp.il.config import PAPER_HEAD, ModelConfig
    from ndp.il.models import build_model

    for kind in ("ndp", "cnn", "cnn-dmp"):
        cfg = ModelConfig(kind=kind, network="paper")
        assert cfg.head_hidden == PAPER_HEAD == (100, 200, 128, 64)
        model = build_model(cfg)
        widths = [m.out_features for m in model.head.modules() if isinstance(m, torch.nn.Linear)]
        assert widths[:4] == [100, 200, 128, 64]
        assert ModelConfig(kind=kind).head_hidden == ()  # the default stays linear
    with pytest.raises(ValueError, match="head_hidden: the 'paper' network's head"):
        ModelConfig(network="paper", head_hidden=(10,))
    with pytest.raises(ValueError, match="network: expected one of default, paper"):
        ModelConfig(network="release")
