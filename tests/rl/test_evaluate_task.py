"""Evaluation refuses a policy in an env of another task (same observation and action sizes:
nothing else would say), unless forced."""

from __future__ import annotations

import pytest

import ndp
from ndp.rl.evaluate import check_env_task, env_task, run_episode
from policy_fixtures import fixture_policy


def test_a_reach_policy_in_the_push_env_is_refused_unless_forced():
    pol = ndp.load_policy(fixture_policy("reach-v3-ndp"))
    push = ndp.make_env("push-v3", k=pol.cfg.k, horizon=10)
    try:
        assert env_task(push) == "push-v3"
        with pytest.raises(ValueError, match=r"^env: the policy was trained on 'reach-v3', the "
                           r"env runs 'push-v3'; pass force=True"):  # fmt: skip
            run_episode(pol, push, seed=0, deterministic=True)
        row = run_episode(pol, push, seed=0, deterministic=True, force=True)
        assert row["episode_length"] == 10
    finally:
        push.close()
    own = pol.make_env(horizon=10)
    try:
        check_env_task(pol, own)  # its own task: accepted
        assert run_episode(pol, own, seed=0, deterministic=True)["episode_length"] == 10
    finally:
        own.close()
