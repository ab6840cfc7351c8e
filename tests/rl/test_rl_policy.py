"""Public policy API: ndp.load_policy on runs and exports, act(obs, info), ndp.make_env."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import ndp
from ndp.rl.config import PPOConfig, TrainConfig
from ndp.rl.run import train
from policy_fixtures import fixture_policy

FAST = PPOConfig(minibatches=4)  # with steps_per_update=512


@pytest.fixture(scope="module")
def push_run(tmp_path_factory):
    run = tmp_path_factory.mktemp("runs") / "push"
    train(
        TrainConfig(
            task="push-v3",
            algo="ndp",
            steps=520,
            num_envs=2,
            run_dir=str(run),
            progress=False,
            tensorboard=False,
            vector="sync",
            steps_per_update=512,
            ppo=FAST,
        )
    )
    return run


def test_load_policy_acts_from_the_env_info(push_run):
    policy = ndp.load_policy(push_run)
    assert policy.state_keys == ("dmp_y0", "dmp_dy0")  # push-v3: the measured frame (preset)
    env = policy.make_env()
    obs, info = env.reset(seed=0)
    policy.reset()
    act = policy.act(obs, info)
    assert act.shape == (5, 4) and np.all(np.abs(act) <= 1.0)
    obs, _, _, _, info = env.step(act)
    assert policy.act(obs, info).shape == (5, 4)
    batch = policy.act(
        np.stack([obs, obs]),
        {k: np.stack([v, v]) for k, v in info.items() if k in policy.state_keys},
    )
    # rows of one float32 batch may differ in the last bit (the BLAS kernel differs per row)
    np.testing.assert_allclose(batch[0], batch[1], rtol=1e-6, atol=1e-7)
    with pytest.raises(ValueError, match="dmp_y0"):
        policy.act(obs, {"success": False})
    with pytest.raises(ValueError, match="obs"):
        policy.act(obs[:10], info)
    env.close()


def test_export_loads_in_a_fresh_process_without_unpickling(push_run, tmp_path):
    out = ndp.export_policy(push_run, tmp_path / "export")
    meta = json.loads((out / "policy.json").read_text())
    assert meta["format"] == "ndp-policy" and meta["task"] == "push-v3"
    assert set(meta["versions"]) >= {"torch", "mujoco", "metaworld"}
    with pytest.raises(FileExistsError):
        ndp.export_policy(push_run, out)
    from ndp.cli import main as ndp_main

    assert ndp_main(["rl", "export", str(push_run), str(tmp_path / "cli-export")]) == 0
    assert (tmp_path / "cli-export" / "policy.safetensors").is_file()
    # the export acts exactly as the run does
    run_pol, exp_pol = ndp.load_policy(push_run), ndp.load_policy(out)
    env = ndp.make_env("push-v3", k=5, seed=3)
    obs, info = env.reset(seed=3)
    np.testing.assert_array_equal(run_pol.act(obs, info), exp_pol.act(obs, info))
    env.close()
    code = (
        "import sys, ndp\n"
        "pol = ndp.load_policy(sys.argv[1])\n"
        "env = pol.make_env()\n"
        "obs, info = env.reset(seed=0)\n"
        "done, n = False, 0\n"
        "while not done:\n"
        "    obs, r, term, trunc, info = env.step(pol.act(obs, info))\n"
        "    done, n = term or trunc, n + 1\n"
        "print(n, info['n_substeps'])\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code, str(out)], capture_output=True, text=True, check=True
    )
    assert res.stdout.split()[0] == "30"  # 150 env steps / k = 5 decisions


def test_act_refuses_a_deterministic_flag_that_is_not_a_bool():
    """A string such as "no" is truthy: it would silently act with the mode."""
    policy = ndp.load_policy(fixture_policy("reach-v3-ndp"))
    env = policy.make_env()
    obs, info = env.reset(seed=0)
    with pytest.raises(ValueError, match=r"^deterministic: expected True or False, got 'no'"):
        policy.act(obs, info, deterministic="no")  # type: ignore[arg-type]
    sampled = policy.act(obs, info, deterministic=np.bool_(False))  # numpy's bool is a bool
    assert sampled.shape == env.action_space.shape
    env.close()


def test_make_env_and_bad_paths(tmp_path):
    env = ndp.make_env("point-mass", k=3, seed=0)
    _, info = env.reset(seed=0)
    assert env.action_space.shape == (3, 2) and "cmd_y0" in info
    env.close()
    with pytest.raises(ValueError, match=r"^seed: expected None or an integer >= 0, got 'a'"):
        ndp.make_env("point-mass", k=3, seed="a")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^stale_world: expected True or False, got 'no'"):
        ndp.make_env("point-mass", k=3, stale_world="no")  # type: ignore[arg-type]
    with pytest.raises(FileNotFoundError, match="neither"):
        ndp.load_policy(tmp_path)
    (tmp_path / "policy.json").write_text(json.dumps({"format": "other", "version": 9}))
    with pytest.raises(ValueError, match="format"):
        ndp.load_policy(tmp_path)
    with pytest.raises(TypeError, match=r"^path: expected a folder path or 'zoo:NAME', got int 5"):
        ndp.load_policy(5)  # type: ignore[arg-type]
    assert ndp.DMPLayer.__name__ == "DMPLayer"
    with pytest.raises(AttributeError):
        _ = ndp.nope


def test_cli_export_with_a_replay_records_it_and_the_card_shows_it(push_run, tmp_path, capsys):
    from PIL import Image

    from ndp.cli import main

    out = tmp_path / "export"
    assert main(["rl", "export", str(push_run), str(out), "--replay"]) == 0
    printed = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert printed["replay"] == str(out / "replay.gif")
    with Image.open(out / "replay.gif") as im:
        assert im.size == (160, 160) and im.n_frames > 10
    assert "![one episode, deterministic actions](replay.gif)" in (out / "README.md").read_text()
    assert ndp.load_policy(out).cfg.task == "push-v3"  # the export itself is as without it


def test_cli_export_with_a_replay_refused_before_it_records_anything(push_run, capsys):
    from ndp.cli import main

    # the run's own folder: the export's refusal comes before the replay is recorded
    assert main(["rl", "export", str(push_run), str(push_run), "--replay"]) != 0
    assert "is a training run's folder" in capsys.readouterr().err
    assert not (push_run / "replay.gif").exists()
