"""Tests for ndp.nets: MLP and MnistCNN."""

from __future__ import annotations

import pytest
import torch

from ndp.nets import MLP, MnistCNN


def test_mlp_shapes_and_layers() -> None:
    m = MLP(5, [100, 100], 3)
    out = m(torch.randn(7, 5))
    assert out.shape == (7, 3)
    linears = [x for x in m.modules() if isinstance(x, torch.nn.Linear)]
    assert [lin.out_features for lin in linears] == [100, 100, 3]
    assert all(isinstance(x, torch.nn.Tanh) for x in m.net if not isinstance(x, torch.nn.Linear))


def test_mlp_layer_norm_normalises_each_hidden_layer_and_is_off_by_default() -> None:
    plain = MLP(5, [16, 16], 1, "relu")
    assert not any(isinstance(x, torch.nn.LayerNorm) for x in plain.modules())
    names = [f"net.{i}.{w}" for i in (0, 2, 4) for w in ("weight", "bias")]
    assert list(plain.state_dict()) == names  # checkpoints of the plain MLP still load
    m = MLP(5, [16, 16], 1, "relu", layer_norm=True)
    kinds = [type(x).__name__ for x in m.net]
    assert kinds == ["Linear", "LayerNorm", "ReLU", "Linear", "LayerNorm", "ReLU", "Linear"]
    x = 1000.0 * torch.randn(64, 5)  # a far-out input: the hidden features keep unit scale
    h = m.net[1](m.net[0](x))
    assert torch.allclose(h.mean(-1), torch.zeros(64), atol=1e-4)
    assert torch.allclose(h.std(-1, unbiased=False), torch.ones(64), atol=1e-3)


def test_mlp_orthogonal_init_and_out_gain() -> None:
    torch.manual_seed(0)
    m = MLP(50, [64], 10, activation="relu", out_gain=0.01)
    w0 = m.net[0].weight  # [64, 50]: orthonormal columns scaled by sqrt(2)
    gram = w0.T @ w0
    assert torch.allclose(gram, 2.0 * torch.eye(50), atol=1e-4)
    w_out = m.net[-1].weight  # [10, 64]: orthonormal rows scaled by 0.01
    assert torch.allclose(w_out @ w_out.T, 1e-4 * torch.eye(10), atol=1e-7)
    assert torch.all(m.net[0].bias == 0)


def test_mlp_no_hidden_and_bad_args() -> None:
    m = MLP(4, [], 2)
    assert m(torch.randn(3, 4)).shape == (3, 2)
    with pytest.raises(ValueError, match="activation"):
        MLP(4, [8], 2, activation="nope")
    with pytest.raises(ValueError, match="positive"):
        MLP(0, [8], 2)


def test_mlp_gradients_flow() -> None:
    m = MLP(3, [16, 16], 1)
    m(torch.randn(5, 3)).sum().backward()
    assert all(p.grad is not None and torch.isfinite(p.grad).all() for p in m.parameters())


def test_mnist_cnn_shapes_and_resize() -> None:
    enc = MnistCNN()
    assert enc.flat_dim == 800
    assert enc(torch.rand(4, 28, 28)).shape == (4, 200)
    assert enc(torch.rand(4, 1, 40, 40)).shape == (4, 200)
    n_params = sum(p.numel() for p in enc.parameters())
    # conv1 20*25+20, conv2 50*20*25+50, fc 800*200+200
    assert n_params == 520 + 25050 + 160200
    with pytest.raises(ValueError, match="expected images"):
        enc(torch.rand(2, 3, 28, 28))
