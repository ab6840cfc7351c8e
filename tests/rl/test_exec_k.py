"""``ndp rl eval --exec-k K2``: a trained policy executed at a higher control rate.

Policies here are either tiny trained runs (point-mass, push-v3: one or a few updates) or
untrained actor-critics whose actor outputs a constant raw vector (the last layer's weights
zeroed, its bias drawn once): such a policy commands a sizeable, state-independent DMP every
decision, so the coarse and the fine executions can be compared decision by decision without
the closed loop amplifying small differences.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
import torch

from ndp.cli import main as ndp_main
from ndp.envs import finer_spec, get_task_spec, make_env, substep_factors
from ndp.envs.jaco import ARM_DELTA, FRAME_SKIP
from ndp.policies import PolicyConfig, build_actor_critic
from ndp.rl.config import PPOConfig, TrainConfig, resolve_config
from ndp.rl.envs import resolve_task
from ndp.rl.evaluate import evaluate_policy, exec_k_table
from ndp.rl.exec_k import dmp_steps_at, exec_k_values
from ndp.rl.normalize import ObsNormalizer
from ndp.rl.policy import Policy
from ndp.rl.run import train

os.environ.setdefault("MUJOCO_GL", "egl")

FAST = PPOConfig(steps_per_update=512, minibatches=4, lr=1e-3)


def constant_policy(task: str, algo: str, scale: float = 0.3, **policy: object) -> Policy:
    """An untrained policy whose actor outputs ``scale * U(-1, 1)`` raw values, the same at
    every observation (seeded)."""
    cfg = resolve_config(TrainConfig(task=task, algo=algo, policy=PolicyConfig.from_dict(policy)))
    spec = resolve_task(cfg.task).spec
    torch.manual_seed(0)
    model = build_actor_critic(spec.obs_dim, spec, cfg.policy)
    out = model.actor.net[-1]
    gen = torch.Generator().manual_seed(0)
    with torch.no_grad():
        out.weight.zero_()
        out.bias.copy_(scale * (2 * torch.rand(out.bias.shape, generator=gen) - 1))
    model.eval()
    obs_norm = ObsNormalizer(spec.obs_dim, cfg.ppo.clip_obs, cfg.ppo.norm_obs)
    return Policy(cfg, spec, model, obs_norm)


def rollout(pol: Policy, decisions: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(robot_pos rows [n, K + 1, D], cmd_y0 after each decision [n + 1, D]) of ``decisions``
    decisions from ``reset(seed)``."""
    env = pol.make_env()
    obs, info = env.reset(seed=seed)
    paths, cmds = [], [info["cmd_y0"]]
    for _ in range(decisions):
        obs, _, _, _, info = env.step(pol.act(obs, info))
        paths.append(info["robot_pos"])
        cmds.append(info["cmd_y0"])
    env.close()
    return np.array(paths), np.array(cmds)


@pytest.fixture(scope="module")
def toy_run(tmp_path_factory):
    run = tmp_path_factory.mktemp("execk") / "toy"
    train(
        TrainConfig(task="point-mass", algo="ndp", steps=2000, num_envs=4, run_dir=str(run),
                    progress=False, tensorboard=False, ppo=FAST, vector="sync")
    )  # fmt: skip
    return run


# ------------------------------------------------------------------ env side
def test_substep_factors_and_the_finer_row():
    push, throw, toy = (get_task_spec(n) for n in ("push-v3", "throw", "point-mass"))
    assert substep_factors(push) == (1, 5)  # 0.0125 / 0.0025
    assert substep_factors(throw) == (1, 2, 5, 10)  # 0.02 / 0.002
    assert substep_factors(toy) == (1,)  # no simulator step below the env step
    assert substep_factors(get_task_spec("push-v3-osc")) == (1,)  # torque rows
    assert finer_spec(push, 1) == push
    fine = finer_spec(push, 5)
    assert fine.control_dt == pytest.approx(0.0025) and fine.sim_dt == push.sim_dt
    assert fine.horizon == 750 and fine.action_absolute == push.action_absolute
    assert fine.action_scale == pytest.approx((0.002, 0.002, 0.002, 0.0))
    assert fine.controller.scale == pytest.approx((0.002, 0.002, 0.002, 0.0))
    with pytest.raises(ValueError, match=r"m \(substeps\): expected one of 1, 5"):
        finer_spec(push, 2)
    with pytest.raises(ValueError, match="expected one of 1 for 'point-mass'"):
        make_env("point-mass", substeps=5)


def test_metaworld_finer_env_moves_the_target_a_fifth_per_step():
    coarse, fine = make_env("push-v3"), make_env("push-v3", substeps=5)
    assert fine.horizon == 750 and fine.control_dt == pytest.approx(coarse.control_dt / 5)
    oc, _ = coarse.reset(seed=3)
    of, _ = fine.reset(seed=3)
    np.testing.assert_array_equal(oc, of)  # resets are unchanged
    a = np.array([0.6, -0.4, 0.3, 1.0], dtype=np.float32)
    start = fine.command_state()[0]
    of1, *_ = fine.step(a)
    np.testing.assert_allclose(fine.command_state()[0][:3] - start[:3], 0.002 * a[:3], atol=1e-9)
    assert fine.command_state()[0][3] == 1.0  # the gripper command is absolute
    for _ in range(4):
        of, *_ = fine.step(a)
    oc, *_ = coarse.step(a)
    np.testing.assert_allclose(fine.command_state()[0], coarse.command_state()[0], atol=1e-9)
    # previous-frame block: one coarse env step (5 fine ones) back, here the reset frame
    np.testing.assert_array_equal(of1[18:36], of[18:36])
    np.testing.assert_array_equal(of[18:36], oc[18:36])
    np.testing.assert_allclose(of[:3], oc[:3], atol=2e-3)  # the hand follows its target
    coarse.close()
    fine.close()


def test_jaco_finer_env_moves_the_targets_a_half_per_step():
    coarse, fine = make_env("throw"), make_env("throw", substeps=2)
    assert fine.horizon == 300 and fine._frame_skip == FRAME_SKIP // 2
    coarse.reset(seed=0)
    fine.reset(seed=0)
    a = np.linspace(-0.8, 0.8, 7)
    t0 = fine.joint_targets
    fine.step(a)
    np.testing.assert_allclose((fine.joint_targets - t0)[:6], a[:6] * ARM_DELTA / 2, atol=1e-12)
    fine.step(a)
    coarse.step(a)
    np.testing.assert_allclose(fine.joint_targets, coarse.joint_targets, atol=1e-12)
    coarse.close()
    fine.close()


# ------------------------------------------------------------------ m = 1 is plain eval
def test_exec_k_equal_to_k_reproduces_plain_eval(toy_run, capsys):
    argv = ["rl", "eval", str(toy_run), "--episodes", "3", "--mode", "deterministic"]
    assert ndp_main(argv) == 0
    plain = json.loads(capsys.readouterr().out)
    assert ndp_main([*argv, "--exec-k", "5"]) == 0
    same = json.loads(capsys.readouterr().out)
    assert plain == same and same["exec_k"] == 5 and same["m"] == 1
    pol = constant_policy("push-v3", "ndp")  # Meta-World too: identical success and return
    assert evaluate_policy(pol, 1) == evaluate_policy(pol.at_exec_k(5), 1)


# ------------------------------------------------------------------ NDP
def test_ndp_head_samples_the_same_dmp_finer():
    pol = constant_policy("push-v3", "ndp", scale=1.0)
    assert pol.cfg.policy.ndp.dmp_steps == 35 and dmp_steps_at(35, 25) == 175
    fine = pol.at_exec_k(25)
    hc, hf = pol.model.head, fine.model.head
    assert hc.k == 5 and hf.k == 25 and hf.dmp.config.steps == 175  # trained head untouched
    assert fine.model.actor is not pol.model.actor
    assert torch.equal(fine.model.actor.net[-1].bias, pol.model.actor.net[-1].bias)
    torch.manual_seed(1)
    raw = torch.randn(256, hc.n_params)
    y0, dy0 = torch.randn(256, 4) * 0.1, torch.zeros(256, 4)
    gc, wc, vc = hc._goal_weights_dy0(raw, y0, dy0)
    gf, wf, vf = hf._goal_weights_dy0(raw, y0, dy0)
    torch.testing.assert_close((gc, wc, vc), (gf, wf, vf))  # the same network outputs
    pc, pf = hc.dmp.positions(gc, wc, y0, vc), hf.dmp.positions(gf, wf, y0, vf)
    assert pc.shape == (256, 6, 4) and pf.shape == (256, 26, 4)
    # 35 -> 175 Euler steps: the same ODE, a finer discretisation; the end points move by
    # about 1 % of the decision's displacement (measured 0.94 % of the summed displacement
    # over 256 random outputs, hand xyz; at most 1.8 mm)
    move = (pc[:, -1, :3] - pc[:, 0, :3]).abs()
    end = (pf[:, -1, :3] - pc[:, -1, :3]).abs()
    rel = float(end.sum() / move.sum())
    assert 1e-3 < rel < 0.03, rel
    assert float((pf[:, ::5, :3] - pc[:, :, :3]).abs().max()) < 0.1 * float(move.max())
    # where K2 divides dmp_steps the trained integration is kept: the coarse points and the
    # coarse actions (mean of each step's m fine actions, per-step scale / m) are unchanged
    even = constant_policy("push-v3", "ndp", scale=1.0, dmp_steps=50)
    ev = even.at_exec_k(25)
    assert ev.model.head.dmp.config.steps == 50
    ac = even.model.head.decode(raw, y0, dy0)[0]
    af = ev.model.head.decode(raw, y0, dy0)[0]
    assert af.shape == (256, 25, 4)
    torch.testing.assert_close(af.reshape(256, 5, 5, 4)[..., :3].mean(2), ac[..., :3])
    torch.testing.assert_close(af[:, ::5, 3], ac[..., 3])  # the gripper command, held


@pytest.mark.parametrize("task", ["push-v3", "throw"])
def test_ndp_fine_path_follows_the_coarse_path(task):
    """Every 5th fine sub-step of the executed path (``info['robot_pos']``) against the coarse
    path, over 4 decisions that command several cm (push-v3) / tenths of a rad (Throw).

    Two differences are expected, and bound the tolerance: (1) the commanded path (mocap target,
    joint targets) moves by the Euler difference of 175 vs 35 steps per decision, about 1 % of
    the commanded displacement here (measured 1.0 % push-v3, 1.4 % Throw), allowed 3 % of the
    largest DoF's displacement; (2) the hand (joints) track a target that moves in 5 small
    increments per trained env step instead of one jump, so their lag at the coarse instants
    differs: measured up to 2.0 mm (push-v3) and 0.014 rad (Throw), allowed 0.3 of one trained
    env step's largest move (``action_scale``: 3 mm, 0.03 rad). Absolute DoF (the gripper) get
    the same command exactly."""
    pol = constant_policy(task, "ndp")
    fine = pol.at_exec_k(25)
    cp, cc = rollout(pol, 4)
    fp, fc = rollout(fine, 4)
    assert cp.shape[1] == 6 and fp.shape[1] == 26
    delta = ~np.array(pol.spec.action_absolute)
    scale = np.array(pol.spec.action_scale)
    path = np.abs(cc[-1] - cc[0])[delta].max()
    assert path > 5 * scale.max()  # a real motion: over 5 trained env steps at full speed
    d_cmd = np.abs(fc - cc)
    d_pos = np.abs(fp[:, ::5] - cp)
    assert np.all(d_cmd[:, delta] <= 0.03 * path)
    assert np.all(d_pos[..., delta] <= 0.03 * path + 0.3 * scale[delta])
    assert np.all(d_cmd[:, ~delta] == 0.0)


def test_finer_episode_lasts_the_same_seconds():
    pol = constant_policy("push-v3", "ndp")
    coarse, fine = evaluate_policy(pol, 1), evaluate_policy(pol.at_exec_k(25), 1)
    assert (coarse["episode_length"], fine["episode_length"]) == (150, 750)
    assert fine["episode_seconds"] == pytest.approx(coarse["episode_seconds"]) == 1.875
    assert (fine["exec_k"], fine["m"], coarse["exec_k"], coarse["m"]) == (25, 5, 5, 1)


# ------------------------------------------------------------------ PPO-multi, PPO, Dyn-E
@pytest.mark.parametrize(
    "task,algo,m", [("throw", "ppo-multi", 5), ("push-v3", "ppo-multi", 5),
                    ("throw", "ppo", 2), ("throw", "dyne", 2)]
)  # fmt: skip
def test_split_moves_the_same_displacement_per_decision(task, algo, m):
    pol = constant_policy(task, algo, scale=0.5)
    k = pol.cfg.k
    fine = pol.at_exec_k(k * m)
    assert fine.model is pol.model  # the model is shared; each action is held m steps
    env = pol.make_env()
    obs, info = env.reset(seed=0)
    np.testing.assert_array_equal(fine.act(obs, info), np.repeat(pol.act(obs, info), m, axis=0))
    env.close()
    _, cc = rollout(pol, 3)
    _, fc = rollout(fine, 3)
    np.testing.assert_allclose(np.diff(fc, axis=0), np.diff(cc, axis=0), atol=1e-9)


def test_ndp_hold_diagnostic_holds_the_trained_sub_actions():
    pol = constant_policy("throw", "ndp")
    held = pol.at_exec_k(50, hold=True)
    assert held.model is pol.model and held.substeps == 10
    env = pol.make_env()
    obs, info = env.reset(seed=0)
    np.testing.assert_array_equal(held.act(obs, info), np.repeat(pol.act(obs, info), 10, axis=0))
    env.close()
    _, cc = rollout(pol, 3)
    _, fc = rollout(held, 3)
    np.testing.assert_allclose(np.diff(fc, axis=0), np.diff(cc, axis=0), atol=1e-9)


# ------------------------------------------------------------------ refusals
def test_bad_exec_k_is_refused_with_the_allowed_values(toy_run, capsys, tmp_path):
    pol = constant_policy("push-v3", "ndp")
    assert exec_k_values(pol) == (5, 25)
    for bad in (10, 1, 0, True, "25", 125):
        with pytest.raises(ValueError, match=r"exec_k \(--exec-k\): expected one of 5, 25") as e:
            pol.at_exec_k(bad)  # type: ignore[arg-type]
        assert "\n" not in str(e.value)
    assert exec_k_values(constant_policy("throw", "ppo")) == (1, 2, 5, 10)
    with pytest.raises(ValueError, match="already an exec-k copy"):
        pol.at_exec_k(25).at_exec_k(25)
    with pytest.raises(ValueError, match="cannot be exported"):
        pol.at_exec_k(25).export(tmp_path / "exp")
    argv = ["rl", "eval", str(toy_run), "--episodes", "1", "--exec-k", "5", "25"]
    assert ndp_main(argv) == 2
    err = capsys.readouterr()
    assert err.out == ""  # checked before any evaluation runs
    assert "--exec-k): expected one of 5 for this ndp run on point-mass" in err.err


@pytest.mark.parametrize("algo", ["vices", "vices-low-freq"])
def test_vices_is_refused_with_its_reason(algo):
    pol = constant_policy("push-v3", algo)
    assert pol.spec.actuation == "torque"
    with pytest.raises(ValueError, match="impedance controller already computes torques"):
        pol.at_exec_k(pol.cfg.k)


# ------------------------------------------------------------------ CLI lists and the table
def test_cli_list_and_benchmark_table(tmp_path, capsys):
    import importlib.util
    from pathlib import Path

    run = tmp_path / "push"
    train(
        TrainConfig(task="push-v3", algo="ndp", steps=520, num_envs=2, run_dir=str(run),
                    progress=False, tensorboard=False, vector="sync",
                    ppo=PPOConfig(steps_per_update=512, minibatches=4))
    )  # fmt: skip
    capsys.readouterr()
    argv = ["rl", "eval", str(run), "--episodes", "1", "--mode", "deterministic"]
    assert ndp_main([*argv, "--exec-k", "5", "25"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    got = [(r["exec_k"], r["m"], r["episode_length"]) for r in lines]
    assert got == [(5, 1, 150), (25, 5, 750)]
    rows = exec_k_table([run], episodes=1, ndp_hold=True)
    got = [(r["exec_k"], r["m"], r["execution"]) for r in rows]
    assert got == [(5, 1, "trained"), (25, 5, "dmp"), (25, 5, "hold")]
    assert rows[0]["success_any"] == lines[0]["success_any"]
    assert len(exec_k_table([run], episodes=1, every=True)) == 2  # Meta-World: k, 5k
    path = Path(__file__).parents[2] / "benchmarks" / "exec_k.py"
    spec = importlib.util.spec_from_file_location("bench_exec_k", path)
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    prov = {"command": "python benchmarks/exec_k.py x", "commit": "abc1234", "date": "today"}
    md = bench.write_table(rows, tmp_path / "t", prov)
    assert md[2].startswith("Command: `python benchmarks/exec_k.py x`")
    assert "abc1234" in (tmp_path / "t.md").read_text()
    csv_lines = (tmp_path / "t.csv").read_text().splitlines()
    assert len(csv_lines) == 4 and csv_lines[0].endswith("command,commit,date")


def test_video_rate_plays_in_real_time_at_most_60_fps():
    from ndp.rl.evaluate import video_rate

    assert video_rate(0.05) == (1, 20)  # toy: every frame
    assert video_rate(0.0125) == (2, 40)  # Meta-World: 80 Hz -> every 2nd frame
    assert video_rate(0.0125 / 5) == (7, 57)  # Meta-World at m = 5 (400 Hz)
    assert video_rate(0.01) == (2, 50)  # Jaco at m = 2


def test_render_at_exec_k_records_the_finer_steps(tmp_path, capsys):
    import imageio.v3 as iio

    from ndp.cli import main

    run = tmp_path / "throw"
    assert main(["rl", "train", "--task", "throw", "--steps", "520", "--steps-per-update", "512",
                 "--horizon", "20", "--vector", "sync", "--run-dir", str(run), "--no-progress",
                 "--no-tensorboard"]) == 0  # fmt: skip
    capsys.readouterr()
    small = ["--width", "96", "--height", "72"]  # the frames' content is not what is tested
    assert main(["rl", "render", str(run), "--out", str(tmp_path / "a.mp4"), *small]) == 0
    coarse = json.loads(capsys.readouterr().out)
    assert main(["rl", "render", str(run), "--out", str(tmp_path / "b.mp4"), "--exec-k", "50",
                 *small]) == 0  # fmt: skip
    fine = json.loads(capsys.readouterr().out)
    assert (fine["width"], fine["height"]) == (96, 72)
    # 20 trained env steps of 0.02 s (50 Hz: every frame) vs 200 steps of 0.002 s (500 Hz:
    # every 9th frame at 56 fps): the same 0.4 s of motion in both videos
    assert (coarse["exec_k"], coarse["fps"], fine["exec_k"], fine["fps"]) == (5, 50, 50, 56)
    assert abs(coarse["frames"] / coarse["fps"] - fine["frames"] / fine["fps"]) < 0.05
    video = iio.imread(tmp_path / "b.mp4")
    assert video.shape[:3] == (fine["frames"], 72, 96)
    # a bad size is refused before anything is loaded or written
    assert main(["rl", "render", str(run), "--out", str(tmp_path / "d.mp4"), "--width", "0"]) == 2
    assert "width: expected an integer from 1 to 4096" in capsys.readouterr().err
    assert not (tmp_path / "d.mp4").exists()
    assert main(["rl", "render", str(run), "--out", str(tmp_path / "c.mp4"), "--exec-k", "7"]) == 2
    assert "exec_k" in capsys.readouterr().err and not (tmp_path / "c.mp4").exists()
    # an existing video is kept unless --overwrite
    before = (tmp_path / "a.mp4").read_bytes()
    assert main(["rl", "render", str(run), "--out", str(tmp_path / "a.mp4"), "--exec-k", "50",
                 *small]) == 2  # fmt: skip
    assert "out: " in capsys.readouterr().err and (tmp_path / "a.mp4").read_bytes() == before
    assert main(["rl", "render", str(run), "--out", str(tmp_path / "a.mp4"), "--exec-k", "50",
                 *small, "--overwrite"]) == 0  # fmt: skip
    assert (tmp_path / "a.mp4").read_bytes() != before
