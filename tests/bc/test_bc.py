"""Demonstrations and behaviour cloning on the robot tasks (toy task and Throw, end to end)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from ndp.bc.demos import collect, load_demos, save_demos
from ndp.bc.train import BCConfig, train_bc
from ndp.cli import main as ndp_main


@pytest.fixture(scope="module")
def toy_demos(tmp_path_factory):
    path = tmp_path_factory.mktemp("demos") / "pm.npz"
    save_demos(collect("point-mass", 20, seed=3), path)
    return path


def test_collection_is_deterministic_and_round_trips(tmp_path):
    a, b = collect("point-mass", 4, seed=7), collect("point-mass", 4, seed=7)
    for name in ("obs", "actions", "rewards", "robot_pos", "cmd_pos", "episode", "seeds"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.episode_success.all() and list(a.seeds) == [7, 8, 9, 10]
    save_demos(a, tmp_path / "d.npz")
    c = load_demos(tmp_path / "d.npz")
    for name in ("obs", "actions", "success", "robot_vel", "cmd_vel", "episode_success"):
        assert np.array_equal(getattr(a, name), getattr(c, name)), name
    assert c.task == "point-mass" and c.meta["expert"] == "PointMassExpert"
    assert c.first(2).n_episodes == 2 and set(c.first(2).episode) == {0, 1}


@pytest.mark.parametrize("model", ["ndp", "nn", "nn-step"])
def test_a_cloned_policy_reaches_the_experts_success(tmp_path, toy_demos, model):
    from ndp.rl.evaluate import evaluate

    run = tmp_path / model
    out = train_bc(BCConfig(demos=str(toy_demos), model=model, run_dir=str(run), epochs=30,
                            progress=False, tensorboard=False))  # fmt: skip
    assert out["final"]["train/loss"] < 0.05
    ev = evaluate(run, episodes=10, deterministic=True, seed=100)
    assert ev["success_any"] >= 0.9  # the expert: 1.0
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["algo"] == {"ndp": "ndp", "nn": "ppo-multi", "nn-step": "ppo"}[model]


def test_ndp_bc_gradient_reaches_goal_and_forcing_weights(toy_demos):
    from ndp.envs.spec import get_task_spec
    from ndp.policies import PolicyConfig, build_actor_critic
    from ndp.rl.config import TrainConfig, resolve_config

    d = load_demos(toy_demos)
    spec = get_task_spec("point-mass")
    cfg = resolve_config(TrainConfig(task="point-mass", algo="ndp", policy=PolicyConfig()), spec)
    torch.manual_seed(0)
    model = build_actor_critic(d.obs.shape[1], spec, cfg.policy)
    obs = torch.as_tensor(d.obs[:64])
    dist, _ = model.distribution(obs, torch.as_tensor(d.cmd_pos[:64], dtype=torch.float32),
                                 torch.zeros(64, 2))  # fmt: skip
    target = torch.as_tensor(d.actions[:64]).unsqueeze(1).expand_as(dist.mean)
    ((dist.mean - target) ** 2).mean().backward()
    last = [m for m in model.actor.net if hasattr(m, "weight")][-1]
    rows = last.weight.grad.norm(dim=1)  # one row per DMP parameter: D goals + D * N weights
    assert rows.shape[0] == 2 * (1 + cfg.policy.ndp.n_basis)
    assert (rows > 0).all(), rows


def test_cloned_policy_seeds_an_rl_run(tmp_path, toy_demos):
    run = tmp_path / "bc"
    train_bc(BCConfig(demos=str(toy_demos), run_dir=str(run), epochs=2, progress=False,
                      tensorboard=False))  # fmt: skip
    from ndp.runs.session import read_manifest

    m = read_manifest(run)  # a cloning run, finished, in the run session's manifest
    assert (m.kind, m.label, m.unit, m.budget, m.done, m.finished) == (
        "bc",
        "ndp",
        "epochs",
        2,
        2,
        True,
    )
    rc = ndp_main(["rl", "train", "--resume", str(run), "--steps", "4000", "--no-progress",
                   "--vector", "sync"])  # fmt: skip
    assert rc == 0
    m = read_manifest(run)  # now the PPO fine-tuning run it seeded
    assert (m.kind, m.label, m.unit, m.finished) == ("rl", "ndp", "env_steps", True)
    from ndp.runs import read_metrics

    assert [r["update"] for r in read_metrics(run)] == [1.0, 2.0]
    assert (run / "bc_metrics.csv").is_file()


@pytest.mark.parametrize(
    "edit,match",
    [
        (lambda z: z.pop("actions"), "no array 'actions'"),
        (lambda z: z.update(obs=z["obs"][:, :, None]), "obs: expected 2 dimensions"),
        (lambda z: z["rewards"].__setitem__(3, np.nan), "rewards: NaN"),
        (lambda z: z["actions"].__setitem__((0, 0), 3.0), r"actions: expected values in \[-1, 1\]"),
        (lambda z: z.update(episode=z["episode"][::-1].copy()), "episode: expected contiguous"),
        (lambda z: z.update(robot_pos=z["robot_pos"][:-1]), "robot_pos: expected"),
    ],
)
def test_bad_demonstration_files_name_the_field(tmp_path, toy_demos, edit, match, capsys):
    z = dict(np.load(toy_demos))
    edit(z)
    bad = tmp_path / "bad.npz"
    np.savez(bad, **z)
    with pytest.raises(ValueError, match=match):
        load_demos(bad)
    assert ndp_main(["il", "bc", "--demos", str(bad), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ndp: error:")


def test_collect_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "d.npz"
    out.write_bytes(b"keep")
    assert ndp_main(["il", "collect", "--task", "point-mass", "--episodes", "1",
                     "--out", str(out)]) == 2  # fmt: skip
    assert out.read_bytes() == b"keep" and "--overwrite" in capsys.readouterr().err


def test_throw_end_to_end_from_the_command_line(tmp_path, capsys):
    demos, run = tmp_path / "throw.npz", tmp_path / "bc-throw"
    assert ndp_main(["il", "collect", "--task", "throw", "--episodes", "2", "--out",
                     str(demos)]) == 0  # fmt: skip
    assert json.loads(capsys.readouterr().out)["success"] == 1.0
    assert ndp_main(["il", "bc", "--demos", str(demos), "--model", "ndp", "--epochs", "2",
                     "--out", str(run), "--no-progress", "--no-tensorboard"]) == 0  # fmt: skip
    capsys.readouterr()
    assert ndp_main(["rl", "eval", str(run), "--episodes", "1", "--mode", "deterministic"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["episodes"] == 1


def test_obs_normalisation_has_a_std_floor(tmp_path, toy_demos):
    """A feature that barely varies over the demonstrations is not divided by its tiny std: the
    normaliser's std is at least obs_std_floor (0: the demonstrations' own std)."""
    d = load_demos(toy_demos)
    raw = d.obs.astype(np.float64).var(0)
    runs = {}
    for floor in (0.0, 3.0):
        run = tmp_path / f"floor{floor}"
        train_bc(BCConfig(demos=str(toy_demos), model="nn", run_dir=str(run), epochs=1,
                          obs_std_floor=floor, progress=False, tensorboard=False))  # fmt: skip
        runs[floor] = torch.load(run / "checkpoint.pt", weights_only=False)["obs_norm"]["var"]
    assert np.allclose(runs[0.0], raw, rtol=1e-3)
    assert (raw < 9.0).any() and np.allclose(runs[3.0], np.maximum(raw, 9.0), rtol=1e-3)
    with pytest.raises(ValueError, match="obs_std_floor"):
        BCConfig(demos=str(toy_demos), obs_std_floor=-1.0)
    with pytest.raises(ValueError, match="obs_std_floor"):
        BCConfig(demos=str(toy_demos), obs_std_floor=float("inf"))
