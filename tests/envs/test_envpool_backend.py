"""The EnvPool simulator backend (ndp.envs.envpool_backend): refusals, wiring, equivalence.

Tests that run EnvPool skip where it is not installed (the [envpool] extra)."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
import pytest

from ndp.envs import get_task_spec
from ndp.envs.envpool_backend import (
    BACKENDS,
    StdUniform,
    check_backend,
    envpool_available,
    envpool_task_id,
    import_envpool,
)
from ndp.envs.envpool_tasks import ENVPOOL_DIFFERING
from ndp.rl.config import TrainConfig, resolve_config

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "docs/results/envpool_equivalence/equivalence.csv"
needs_envpool = pytest.mark.skipif(not envpool_available(), reason="envpool not installed")


def test_backend_names_and_ids() -> None:
    assert BACKENDS == ("metaworld", "envpool")
    assert envpool_task_id("push-v3") == "MetaWorld/Push-v3"
    assert envpool_task_id("button-press-topdown-wall-v3") == "MetaWorld/ButtonPressTopdownWall-v3"
    with pytest.raises(ValueError, match=r"^backend: expected one of metaworld, envpool"):
        TrainConfig(task="push-v3", algo="ppo", backend="mujoco")


@pytest.mark.parametrize(
    ("task", "kw", "needle"),
    [
        ("throw", {}, "position-actuated Meta-World"),
        ("push-v3-osc", {}, "position-actuated Meta-World"),
        ("button-press-v3", {"k": 5, "stale_world": True}, "live reward only"),
        ("button-press-v3", {"reward_version": "v1"}, "v2 reward"),
        ("button-press-v3", {"fixed_goal": 3}, "fresh task configuration"),
        ("button-press-v3", {"substeps": 5}, "substeps=1"),
        ("button-press-v3", {"render_mode": "rgb_array"}, "does not render"),
    ],
)
def test_check_backend_refuses(task: str, kw: dict, needle: str) -> None:
    with pytest.raises(ValueError, match=r"^backend: 'envpool'") as info:
        check_backend("envpool", get_task_spec(task), **kw)
    assert needle in str(info.value)
    assert "\n" not in str(info.value)
    assert check_backend("metaworld", get_task_spec(task), **kw) == "metaworld"


def test_check_backend_accepts_live_runs() -> None:
    spec = get_task_spec("button-press-v3")
    assert check_backend("envpool", spec, k=1, stale_world=True) == "envpool"  # no rule at k=1
    assert check_backend("envpool", spec, k=5, stale_world=False) == "envpool"


def test_differing_tasks_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    import ndp.envs.envpool_tasks as tasks

    monkeypatch.setattr(tasks, "ENVPOOL_DIFFERING", frozenset({"button-press-v3"}))
    with pytest.raises(ValueError, match=r"^backend: 'envpool' differs from metaworld on button"):
        check_backend("envpool", get_task_spec("button-press-v3"))


def test_resolve_config_refuses_stale_rule() -> None:
    with pytest.raises(ValueError, match=r"^backend: .*--no-stale-world"):
        resolve_config(TrainConfig(task="button-press-v3", algo="ndp", backend="envpool"))
    with pytest.raises(ValueError, match=r"^backend: .*v2 reward"):
        resolve_config(TrainConfig(task="button-press-v3", algo="ppo", backend="envpool",
                                   reward_version="v1"))  # fmt: skip


def test_missing_envpool_install_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "envpool", None)  # import fails as if absent
    with pytest.raises(ImportError, match=r"^backend: 'envpool' needs EnvPool 1\.2\.5 \(pip"):
        import_envpool()
    with pytest.raises(ImportError, match=r"\[envpool\]"):
        resolve_config(TrainConfig(task="button-press-v3", algo="ppo", backend="envpool"))
    with pytest.raises(ValueError, match=r"^backend: 'envpool' differs from metaworld on push"):
        resolve_config(TrainConfig(task="push-v3", algo="ppo", backend="envpool"))


def test_differing_list_is_the_committed_table() -> None:
    with open(TABLE) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 50
    assert {r["task"] for r in rows if r["match"] != "True"} == set(ENVPOOL_DIFFERING)


@needs_envpool
def test_std_uniform_is_envpools_stream() -> None:
    """EnvPool's reach-v3 goals (observation[36:39]) are StdUniform's draws, reset by reset."""
    import envpool

    env = envpool.make_gymnasium("MetaWorld/Reach-v3", num_envs=2, seed=11,
                                 partially_observable=False)  # fmt: skip
    from metaworld.env_dict import ALL_V3_ENVIRONMENTS

    space = ALL_V3_ENVIRONMENTS["reach-v3"]()._random_reset_space
    streams = [StdUniform(11), StdUniform(12)]  # env i: seed + i
    for _ in range(2):
        obs, _ = env.reset()
        for i, s in enumerate(streams):
            vec = s.uniform(space.low, space.high, size=6)
            assert np.linalg.norm(vec[:2] - vec[3:5]) >= 0.15  # no rejection in these draws
            np.testing.assert_array_equal(obs[i, 36:39], vec[3:])
    env.close()


@needs_envpool
def test_make_env_and_vector_env_on_envpool() -> None:
    from ndp.envs import make_env
    from ndp.rl.envs import make_vector_env, resolve_task

    env = make_env("button-press-v3", backend="envpool", seed=3, horizon=5)
    obs, info = env.reset()
    assert obs.shape == (39,) and env.observation_space.shape == (39,)
    assert np.any(obs[36:39] != 0)  # the goal is visible
    for _ in range(5):
        obs, _r, term, trunc, info = env.step(np.zeros(4, dtype=np.float32))
    assert trunc and not term and set(info) >= {"success", "robot_pos", "robot_vel"}
    env.close()
    task = resolve_task("button-press-v3", backend="envpool")
    venv = make_vector_env(task, k=5, num_envs=2, stale_world=False, horizon=20)
    obs, _ = venv.reset(seed=[1, 2])
    obs, _r, term, trunc, info = venv.step(np.zeros((2, 5, 4), dtype=np.float32))
    assert obs.shape == (2, 39) and info["sub_rewards"].shape == (2, 5)
    venv.close()
    with pytest.raises(ValueError, match="world_snapshot"):  # backstop of the config check
        make_vector_env(task, k=5, num_envs=1, stale_world=True, horizon=20)


@needs_envpool
def test_equivalence_quick() -> None:
    """Three tasks, 60 steps: the backends agree within the stated tolerances."""
    from ndp.envs.envpool_equivalence import check_tasks

    tasks = [t for t in ("reach-v3", "assembly-v3", "basketball-v3") if t not in ENVPOOL_DIFFERING]
    rows = check_tasks(tasks, steps=60)
    assert [r["task"] for r in rows if not r["match"]] == []
    assert all(r["cmd_max_diff"] < 1e-6 for r in rows)


@needs_envpool
@pytest.mark.slow
def test_equivalence_all_tasks_match_the_table() -> None:
    """The full 50-task check reproduces the committed verdicts."""
    from ndp.envs.envpool_equivalence import check_tasks
    from ndp.envs.metaworld_env import metaworld_env_names

    rows = check_tasks(metaworld_env_names())
    assert {r["task"] for r in rows if not r["match"]} == set(ENVPOOL_DIFFERING)


def test_the_config_knows_the_backends_without_the_simulators():
    """TrainConfig checks ``backend`` from its own copy of the names (a config loads where
    gymnasium is not installed: tests/test_install.py); the copy is the backend's list."""
    from ndp.envs.envpool_backend import BACKENDS
    from ndp.rl import config

    assert config.BACKENDS == BACKENDS
