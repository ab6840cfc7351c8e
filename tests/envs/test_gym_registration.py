"""gymnasium ids: every task registered with its horizon, usable without importing ndp first."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

gym = pytest.importorskip("gymnasium")

import ndp  # noqa: E402
from ndp.envs import TASKS, TORQUE_TASKS, register_envs, register_torque_envs  # noqa: E402
from ndp.envs.factory import CHUNKED_KS  # noqa: E402

SRC = Path(ndp.__file__).resolve().parents[1]


def test_every_id_has_the_task_horizon_as_max_episode_steps():
    ids = set(register_envs()) | set(register_torque_envs())
    assert len(ids) == len(TASKS) * (1 + len(CHUNKED_KS)) + len(TORQUE_TASKS)
    for name, spec in TASKS.items():
        assert (
            gym.spec(spec.env_id).max_episode_steps
            == spec.horizon
            == 150 - 100 * (spec.family == "toy")
        ), name
        for k in CHUNKED_KS:
            chunked = gym.spec(f"ndp/{name}-k{k}")
            assert chunked.max_episode_steps == -(-spec.horizon // k), name  # ceil: 30 at k 5
            assert chunked.kwargs == {"name": name, "k": k}
    for name, spec in TORQUE_TASKS.items():
        assert gym.spec(spec.env_id).max_episode_steps == spec.horizon, name
    # string entry points: registering imports no env class
    assert gym.spec("ndp/push-v3").entry_point == "ndp.envs.factory:_make_registered"


def test_gymnasium_has_no_plugin_entry_points():
    # gymnasium 1.0 removed the `gymnasium.envs` entry-point plugins (0.26-0.29 loaded them on
    # `import gymnasium`), so ndp declares none; ids are made with the module prefix instead.
    # Should a later gymnasium load plugins again, this fails: declare the entry point then.
    from gymnasium.envs import registration

    assert not hasattr(registration, "load_plugin_envs")
    assert not hasattr(registration, "load_env_plugins")


SCRIPT = r"""
import json
import sys

sys.path.insert(0, SRC)
import gymnasium

assert "ndp" not in sys.modules
env = gymnasium.make("ndp.envs:ndp/reach-v3")  # the module prefix: gymnasium imports it
assert sys.modules["ndp"].__file__.startswith(SRC)
obs, info = env.reset(seed=0)
steps, truncated = 0, False
while not truncated:
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample() * 0)
    steps += 1
chunked = gymnasium.make("ndp/reach-v3-k5")  # registered now
chunked.reset(seed=0)
decisions, done = 0, False
while not done:
    _, _, term, trunc, info = chunked.step(chunked.action_space.sample() * 0)
    decisions += 1
    done = term or trunc
print("RESULT " + json.dumps({"max_steps": env.spec.max_episode_steps, "steps": steps,
                              "chunked_max": chunked.spec.max_episode_steps,
                              "decisions": decisions}))
"""


def test_make_by_module_prefix_without_importing_ndp_and_episodes_end_at_the_horizon():
    pytest.importorskip("metaworld")
    r = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(SCRIPT.replace("SRC", repr(str(SRC))))],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"OMP_NUM_THREADS": "1"},
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    out = json.loads(next(x for x in r.stdout.splitlines() if x.startswith("RESULT "))[7:])
    # the env's own horizon and gymnasium's TimeLimit end the episode at the same step
    assert out == {"max_steps": 150, "steps": 150, "chunked_max": 30, "decisions": 30}
