"""TD3's pure functions against hand-written formulas, and its settings' one-line errors."""

from __future__ import annotations

import pytest
import torch

from ndp.rl.td3.config import TD3Config
from ndp.rl.td3.losses import (
    actor_loss,
    actor_update_due,
    critic_loss,
    exploration_action,
    smoothed_target_action,
    td3_target,
)


def test_target_smoothing_clips_the_noise_then_the_action():
    p = torch.tensor([[0.0, 0.9, -0.95, 0.3]])
    noise = torch.tensor([[0.7, 0.3, -0.2, -0.1]])
    got = smoothed_target_action(p, noise, clip=0.5)
    # by hand: noise -> [0.5, 0.3, -0.2, -0.1]; sum -> [0.5, 1.2, -1.15, 0.2]; clip to [-1, 1]
    assert torch.allclose(got, torch.tensor([[0.5, 1.0, -1.0, 0.2]]))
    assert torch.equal(smoothed_target_action(p, torch.zeros_like(p), 0.0), p)


def test_the_target_takes_the_smaller_twin():
    ret = torch.tensor([1.0, -2.0, 0.5])
    w = torch.tensor([0.99, 0.0, 0.5])  # the second transition ended at a terminal state
    q1 = torch.tensor([10.0, 3.0, -4.0])
    q2 = torch.tensor([8.0, 5.0, -1.0])
    expected = torch.tensor([1.0 + 0.99 * 8.0, -2.0, 0.5 + 0.5 * -4.0])
    assert torch.allclose(td3_target(ret, w, q1, q2), expected)


def test_critic_and_actor_losses_by_hand():
    q1, q2, y = torch.tensor([1.0, 2.0]), torch.tensor([0.0, 4.0]), torch.tensor([1.0, 1.0])
    # mse(q1, y) = (0 + 1) / 2; mse(q2, y) = (1 + 9) / 2
    assert float(critic_loss(q1, q2, y)) == pytest.approx(0.5 + 5.0)
    assert float(actor_loss(torch.tensor([3.0, -1.0]))) == pytest.approx(-1.0)


def test_exploration_noise_is_clipped_to_the_bounds():
    got = exploration_action(torch.tensor([[0.95, -0.5]]), torch.tensor([[0.1, -0.1]]))
    assert torch.allclose(got, torch.tensor([[1.0, -0.6]]))


def test_the_actor_updates_every_policy_delay_critic_steps():
    assert [s for s in range(1, 11) if actor_update_due(s, 2)] == [2, 4, 6, 8, 10]
    assert sum(actor_update_due(s, 3) for s in range(1, 31)) == 10
    assert all(actor_update_due(s, 1) for s in range(1, 5))


def test_defaults_are_sb3s_and_bad_values_name_the_field():
    c = TD3Config()
    assert (c.lr, c.batch_size, c.buffer_size, c.tau) == (1e-3, 256, 1_000_000, 0.005)
    assert (c.policy_delay, c.target_noise, c.target_noise_clip) == (2, 0.2, 0.5)
    assert (c.expl_noise, c.random_steps, c.init) == (0.1, 5000, "torch")
    for kw, msg in (({"tau": 0.0}, "tau: expected a number in (0, 1]"),
                    ({"policy_delay": 0}, "policy_delay: expected an integer >= 1"),
                    ({"target_noise": -0.1}, "target_noise: expected a finite number >= 0"),
                    ({"lr": 0.0}, "lr: expected a finite number > 0")):  # fmt: skip
        with pytest.raises(ValueError, match=msg.replace("(", r"\(").replace("]", r"\]")):
            TD3Config(**kw)
