"""Config defaults (what actually runs), resolution, CLI parsing and bad input."""

from __future__ import annotations

import dataclasses
import json
import re

import pytest

from ndp.envs.presets import NDP_PRESETS
from ndp.policies import NDPHeadConfig, PolicyConfig
from ndp.rl import envs as rl_envs
from ndp.rl.config import (
    PPOConfig,
    TrainConfig,
    resolve_config,
)
from ndp.rl.dyne.config import DyneConfig
from ndp.rl.run import open_run


def test_resolved_defaults_are_the_supplements():
    cfg = resolve_config(TrainConfig(task="push-v3", algo="ndp"))
    p, pol = cfg.ppo, cfg.policy
    assert (p.lr, p.adam_eps, cfg.gamma, p.gae_lambda) == (3e-4, 1e-5, 0.99, 0.95)
    assert (p.ent_coef, p.vf_coef, p.max_grad_norm) == (0.0, 0.5, 0.5)
    assert (p.epochs, p.minibatches, p.clip, cfg.steps_per_update) == (10, 32, 0.1, 2048)
    assert cfg.norm_obs and cfg.clip_obs == 10.0 and p.norm_return
    assert pol.hidden == (100, 100) and pol.activation == "tanh"
    assert pol.head == "ndp" and pol.k == 5 and pol.ndp.dmp_steps == 35
    assert (pol.ndp.n_basis, pol.ndp.a_z) == (NDP_PRESETS["push-v3"].n_basis, 10.0)
    assert cfg.env_steps_per_update >= 2048
    assert cfg.env_steps_per_update - 2048 < cfg.k * cfg.num_envs


@pytest.mark.parametrize("algo,head,k", [("ppo", "step", 1), ("ppo-multi", "multi", 5)])
def test_resolution_per_method(algo, head, k):
    cfg = resolve_config(TrainConfig(task="throw", algo=algo))
    assert cfg.policy.head == head and cfg.policy.k == k
    assert cfg.policy.ndp.n_basis is None and not cfg.policy.ndp.param_noise


def test_trainer_runs_what_the_config_says(tmp_path):
    opened = open_run(
        TrainConfig(
            task="point-mass",
            algo="ndp",
            run_dir=str(tmp_path / "r"),
            progress=False,
            tensorboard=False,
        )
    )
    tr = opened.learner
    try:
        g = tr.opt.param_groups[0]
        assert g["lr"] == 3e-4 and g["eps"] == 1e-5
        dmp = tr.model.head.dmp.config
        assert (dmp.steps, dmp.subsample, dmp.n_basis, dmp.a_z) == (35, 7, 6, 5.0)
        assert tr.k == 5 and tr.T * tr.k * tr.num_envs >= 2048
        assert [m.out_features for m in tr.model.actor.net if hasattr(m, "out_features")] == [
            100,
            100,
            2 * 7,
        ]
        assert tr.model.critic.net[-1].out_features == 5  # k value heads
        saved = json.loads((tmp_path / "r" / "config.json").read_text())
        assert saved["ppo"]["ent_coef"] == 0.0 and saved["policy"]["ndp"]["dmp_steps"] == 35
    finally:
        opened.close()


def test_cli_parses_every_field_flat_and_roundtrips():
    from ndp.runs.cli import parse_config

    args = ["--task", "soccer-v3", "--algo", "ppo-multi", "--k", "3", "--lr", "1e-3",
            "--hidden", "64", "64", "--no-norm-obs", "--horizon", "None", "--goal-scale", "2",
            "--clip-value-loss", "--dmp-state", "measured"]  # fmt: skip
    cfg = parse_config(TrainConfig, args, prog="ndp rl train")
    assert cfg.task == "soccer-v3" and cfg.algo == "ppo-multi" and cfg.policy.k == 3
    assert cfg.ppo.lr == 1e-3 and not cfg.norm_obs and cfg.ppo.epochs == 10
    assert cfg.policy.hidden == (64, 64) and cfg.horizon is None
    assert cfg.policy.ndp.goal_scale == 2.0 and cfg.ppo.clip_value_loss
    assert cfg.policy.dmp_state == "measured"
    assert TrainConfig.from_dict(cfg.to_dict()) == cfg


def test_every_train_field_is_an_option_of_ndp_rl_train(capsys):
    """Every TrainConfig / PPOConfig / PolicyConfig / NDPHeadConfig field has its --flag in
    --help, except the derived head; each help line carries the field's docstring."""
    from ndp.cli import main

    assert main(["rl", "train", "--help"]) == 0
    text = capsys.readouterr().out
    classes = (TrainConfig, PPOConfig, PolicyConfig, NDPHeadConfig, DyneConfig)
    names = [f.name for c in classes for f in dataclasses.fields(c)]
    assert len(names) == len(set(names))  # flat options: no two fields share a name
    nested = ("ppo", "policy", "dyne", "ndp")
    missing = [
        n for n in names if n not in (*nested, "head") and f"--{n.replace('_', '-')}" not in text
    ]
    assert not missing
    assert "--head" not in text and "Entropy bonus coefficient" in text


def test_cli_bad_value_names_the_option(capsys):
    from ndp.cli import main

    assert main(["rl", "train", "--lr", "abc"]) == 2
    assert "--lr" in capsys.readouterr().err
    assert main(["rl", "train", "--algo", "ddpg"]) == 2
    assert "algo" in capsys.readouterr().err


def _no_env(*a, **k):
    raise AssertionError("an environment was built")


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"task": "pussh-v3"}, "push-v3"),
        ({"algo": "ddpg"}, "algo"),
        ({"steps": 0}, "steps"),
        ({"num_envs": 0}, "num_envs"),
        ({"policy": {"k": 0}}, "k"),
        ({"policy": {"n_basis": 0}}, "n_basis"),
        ({"ppo": {"clip": 0.0}}, "clip"),
        ({"gamma": 1.5}, "gamma: expected a number in \\[0, 1\\]"),
        ({"ppo": {"gamma": 1.5}}, "gamma"),  # the layout of configs written before
        ({"steps_per_update": 0}, "steps_per_update"),
        ({"reward_version": "v3"}, "reward_version: expected one of v1, v2, got 'v3'"),
        ({"task": "throw", "reward_version": "v1"}, "reward_version: 'v1' exists for Meta-World"),
        ({"task": "assembly-v3", "reward_version": "v1"}, "reward_version: assembly-v3's v1"),
        ({"goals": "one"}, "goals: expected one of random, per-seed, release, as-release"),
        ({"execution": "first"}, "execution: expected one of all, first-held"),
    ],
)
def test_bad_input_fails_before_any_env(monkeypatch, tmp_path, kwargs, match):
    monkeypatch.setattr(rl_envs, "make_vector_env", _no_env)
    with pytest.raises(ValueError, match=match):
        if "policy" in kwargs:
            kwargs = {"policy": PolicyConfig.from_dict(kwargs["policy"])}
        if "ppo" in kwargs:  # a config.json's section (an older layout's too: from_dict)
            open_run(TrainConfig.from_dict({"run_dir": str(tmp_path), **kwargs}))
        open_run(TrainConfig(run_dir=str(tmp_path), **kwargs))


def test_docs_preset_table_matches_the_task_table():
    """docs/rl.md's preset table is the task table's (TaskSpec.ndp), row by row."""
    from pathlib import Path

    from ndp.envs import TASKS
    from ndp.envs.presets import DEFAULT

    text = (Path(__file__).parents[2] / "docs" / "rl.md").read_text()
    block = text[text.index("## Per-task NDP presets") :]
    lines = block.splitlines()[1:30]
    rows = [ln for ln in lines if ln.startswith("| ") and not ln.startswith("| task")]
    rows = rows[: next(i for i, r in enumerate(rows) if r.startswith("| any other")) + 1]
    seen = 0
    for row in rows:
        name, n, a_z, steps, gs, frame = (c.strip() for c in row.strip("|").split("|"))
        pre = DEFAULT if name == "any other task" else TASKS[name.split(" ")[0]].ndp
        assert (int(n), float(a_z), 5 * pre.steps_per_substep, float(gs), frame) == (
            pre.n_basis,
            pre.a_z,
            int(steps),
            pre.goal_scale,
            f"{pre.dmp_state}, {pre.dmp_velocity}",
        ), name
        seen += 1
    assert seen >= 8


@pytest.mark.parametrize(
    ("task", "algo", "frame"),
    [
        ("push-v3", "ndp", ("measured", "state")),
        ("soccer-v3", "ndp", ("measured", "state")),
        ("button-press-v3", "ndp", ("measured", "state")),  # a task without its own row
        ("throw", "ndp", ("commanded", "zero")),
        ("pick", "ndp", ("commanded", "zero")),
        ("point-mass", "ndp", ("commanded", "zero")),
        ("push-v3", "ppo", ("measured", "state")),  # every method records the same frame
        ("throw", "ppo-multi", ("commanded", "zero")),
    ],
)
def test_the_dmp_frame_comes_from_the_task_preset(task, algo, frame):
    from ndp.rl.config import resolve_config

    cfg = resolve_config(TrainConfig(task=task, algo=algo))
    assert (cfg.policy.dmp_state, cfg.policy.dmp_velocity) == frame


def test_an_explicit_dmp_frame_wins_and_old_configs_keep_theirs():
    from ndp.policies.config import PolicyConfig
    from ndp.rl.config import resolve_config

    mine = PolicyConfig(dmp_state="commanded", dmp_velocity="zero")
    cfg = resolve_config(TrainConfig(task="push-v3", policy=mine))
    assert (cfg.policy.dmp_state, cfg.policy.dmp_velocity) == ("commanded", "zero")
    # a config.json written before the two keys existed ran the commanded frame at rest
    old = cfg.to_dict()
    del old["policy"]["dmp_state"], old["policy"]["dmp_velocity"]
    back = TrainConfig.from_dict(old)
    assert (back.policy.dmp_state, back.policy.dmp_velocity) == ("commanded", "zero")
    with pytest.raises(ValueError, match="dmp_state"):
        PolicyConfig(dmp_state="mocap")


def test_task_options_reach_every_env_of_the_run_and_its_evaluation(tmp_path):
    """goals='fixed' and reward_version are recorded in config.json, every training env gets the
    run's fixed goal (drawn from its seed), and the trained policy's env is the same task."""
    from ndp.envs import fixed_goal_seed
    from ndp.rl.evaluate import load_policy

    run = tmp_path / "r"
    cfg = TrainConfig(
        task="push-v3", algo="ppo-multi", goals="fixed", reward_version="v1", seed=3,
        steps=200, num_envs=2, vector="sync", run_dir=str(run), progress=False,
        tensorboard=False,
    )  # fmt: skip
    opened = open_run(cfg)
    tr = opened.learner
    try:
        for env in tr.envs.envs:
            base = env.unwrapped
            assert base.fixed_goal == fixed_goal_seed(3) and base.reward_version == "v1"
        opened.train()
    finally:
        opened.close()
    saved = json.loads((run / "config.json").read_text())
    assert saved["goals"] == "per-seed" and saved["reward_version"] == "v1"  # 'fixed': old name
    env = load_policy(run).make_env()
    assert env.unwrapped.fixed_goal == fixed_goal_seed(3)
    assert env.unwrapped.reward_version == "v1"
    env.close()
    # a config written before the options existed runs the defaults
    old = {k: v for k, v in saved.items() if k not in ("goals", "reward_version")}
    back = TrainConfig.from_dict(old)
    assert (back.goals, back.reward_version) == ("random", "v2")
    assert back.env_options() == {"reward_version": "v2"}


def test_ndp_head_options_given_to_a_method_without_it_are_named():
    from ndp.rl.config import unused_head_options

    head = NDPHeadConfig(n_basis=3, forcing="goal")
    ppo = TrainConfig(task="point-mass", algo="ppo", policy=PolicyConfig(ndp=head))
    assert unused_head_options(ppo) == ["n_basis=3", "forcing='goal'"]
    assert unused_head_options(dataclasses.replace(ppo, algo="ndp")) == []
    assert unused_head_options(TrainConfig(task="point-mass", algo="ppo-multi")) == []
    # still accepted, and cleared from what the run records
    assert resolve_config(ppo).policy.ndp.n_basis is None


def test_every_evaluation_starts_at_one_seed():
    """ndp rl eval / render, the Python API, the smoothness study and the report's cache share
    ``EVAL_SEED`` (one constant, not a literal per module)."""
    import inspect

    from ndp.cli import build_parser
    from ndp.experiments import smoothness
    from ndp.rl import evaluate as ev
    from ndp.rl.config import EVAL_SEED

    for fn in (
        ev.evaluate,
        ev.evaluate_policy,
        ev.render,
        smoothness.rollout_paths,
        smoothness.run_smoothness,
        smoothness.smoothness_of_runs,
    ):
        assert inspect.signature(fn).parameters["seed"].default == EVAL_SEED, fn.__name__
    parser = build_parser()
    for command in ("eval", "render"):
        args = parser.parse_args(["rl", command, "RUN"])
        assert args.seed == EVAL_SEED, command


@pytest.mark.parametrize(
    ("algo", "k", "message"),
    [
        ("ppo", 5, "k: --algo ppo runs one action per decision (k = 1), got k=5"),
        ("ppo-repeat", None, None),
        ("sac", 5, "k: --algo sac decides every 1 env step(s) on point-mass, got k=5"),
        ("ppo", 1, None),
        ("ppo-multi", 10, None),
    ],
)
def test_a_k_the_method_cannot_run_is_refused_not_dropped(algo, k, message):
    """``--algo ppo --k 5`` used to train at k = 1 without a word (k's default was 5, so a
    given 5 could not be told from none); k now defaults to the method's."""
    cfg = TrainConfig(task="point-mass", algo=algo, policy=PolicyConfig(k=k))
    if message is None:
        resolved = resolve_config(cfg)
        assert resolved.k == (k if k is not None else (1 if algo == "ppo" else 5))
        assert cfg.k == resolved.k  # an unresolved config reports the method's k
    else:
        with pytest.raises(ValueError, match=re.escape(message)):
            resolve_config(cfg)


def test_networks_given_are_kept_and_left_out_are_the_methods():
    def nets(algo, **kw):
        p = resolve_config(TrainConfig(task="point-mass", algo=algo, policy=PolicyConfig(**kw)))
        return p.policy.hidden, p.policy.activation

    assert nets("ppo") == ((100, 100), "tanh")
    assert nets("sac") == ((256, 256), "relu")
    assert nets("dyne") == ((400, 300), "relu")
    # PPO's sizes asked for explicitly are no longer taken for "not given" by SAC / Dyn-E
    assert nets("sac", hidden=(100, 100), activation="tanh") == ((100, 100), "tanh")
    assert nets("dyne", hidden=(100, 100)) == ((100, 100), "relu")
    # an unresolved config (None: the method's) round-trips through its dict
    assert PolicyConfig.from_dict(dataclasses.asdict(PolicyConfig())) == PolicyConfig()


def test_ndp_head_options_given_to_ppo_are_named_on_the_command_line(tmp_path, capsys):
    from ndp.cli import main

    run = tmp_path / "r"
    args = ["rl", "train", "--algo", "ppo", "--task", "point-mass", "--n-basis", "3",
            "--steps", "64", "--steps-per-update", "64", "--num-envs", "2", "--run-dir",
            str(run), "--no-progress", "--no-tensorboard", "--eval-every", "0"]  # fmt: skip
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "ndp: note: n_basis=3: options of the NDP head, which --algo ppo does not run" in err
    assert main([*args[:3], "ppo", *args[4:6], "--k", "5", "--run-dir", str(tmp_path / "b")]) == 2
    assert "k: --algo ppo runs one action per decision (k = 1), got k=5" in capsys.readouterr().err
    assert not (tmp_path / "b").exists()  # refused before any run folder


def test_options_of_another_learner_are_named_not_dropped():
    from ndp.rl.config import LEARNER_SECTIONS, unused_method_options
    from ndp.rl.methods import METHOD_RUN_FIELDS, METHODS
    from ndp.rl.sac.config import SACConfig

    def unused(algo, **sections):
        return unused_method_options(TrainConfig(task="point-mass", algo=algo, **sections))

    assert unused("ppo", sac=SACConfig(lr=1e-3)) == ["sac.lr=0.001"]
    assert unused("ndp", ppo=PPOConfig(lr=1e-4)) == []
    # the run's discount, iteration size and observation clip are every method's; PPO's
    # section is PPO's alone; the observation normaliser is read by PPO and Dyn-E, not SAC
    run_fields = {"gamma": 0.95, "steps_per_update": 1024, "clip_obs": 5.0}
    for algo in ("sac", "td3", "dyne", "ppo"):
        assert unused(algo, **run_fields) == []
    assert unused("sac", ppo=PPOConfig(clip=0.2)) == ["ppo.clip=0.2"]
    assert unused("dyne", sac=SACConfig(tau=0.01)) == ["sac.tau=0.01"]
    assert unused("sac", norm_obs=False) == unused("td3", norm_obs=False) == ["norm_obs=False"]
    assert unused("dyne", norm_obs=False) == unused("ndp", norm_obs=False) == []
    # no off-policy learner reads PPO's section (or a field of it)
    for m in METHODS.values():
        if m.learner is not None:
            assert not [r for r in m.reads if r.split(".")[0] == "ppo"], m.name
    # every method's list names real sections and fields
    for m in METHODS.values():
        for entry in m.reads:
            section, _, name = entry.partition(".")
            if section in METHOD_RUN_FIELDS:
                continue
            assert section in LEARNER_SECTIONS, (m.name, entry)
            if name:
                fields = {f.name for f in dataclasses.fields(getattr(TrainConfig(), section))}
                assert name in fields, (m.name, entry)
