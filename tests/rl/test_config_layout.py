"""The run's own fields (discount, update size, observation normaliser) left PPO's section: every
config.json written before, with them under "ppo", still loads, resumes, seeds a --config run
and is read by the report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from ndp import runs as ck
from ndp.cli import main as ndp_main
from ndp.rl.config import MOVED_FROM_PPO, TrainConfig, current_layout, load_config
from ndp.runs import read_metrics

DATA = Path(__file__).resolve().parents[1] / "data"
OLD_PPO_KEYS = ["lr", "adam_eps", "gamma", "gae_lambda", "ent_coef", "vf_coef", "max_grad_norm",
                "epochs", "minibatches", "clip", "clip_value_loss", "steps_per_update",
                "norm_obs", "norm_return", "norm_adv", "adv_norm_scope", "clip_obs",
                "clip_reward", "anneal_lr"]  # fmt: skip
"""The "ppo" section of a config.json written before (version fc4683c), in its order."""


def older_layout(d: dict) -> dict:
    """``d`` (this version's config dict) as versions before wrote it: the run's fields inside
    the "ppo" section, in that section's order."""
    d = dict(d)
    moved = {name: d.pop(name) for name in MOVED_FROM_PPO}
    ppo = {**d["ppo"], **moved}
    d["ppo"] = {name: ppo[name] for name in OLD_PPO_KEYS}
    return d


def test_a_config_json_written_by_an_older_version_loads():
    """tests/data/rl_config_fc4683c.json: the resolved config of a SAC run (``--gamma 0.98
    --steps-per-update 200``) as version fc4683c wrote it, the run fields under "ppo"."""
    old = json.loads((DATA / "rl_config_fc4683c.json").read_text())
    assert {"gamma", "steps_per_update", "norm_obs", "clip_obs"} <= set(old["ppo"])
    cfg = TrainConfig.from_dict(old)
    assert (cfg.gamma, cfg.steps_per_update, cfg.norm_obs, cfg.clip_obs) == (0.98, 200, True, 10.0)
    assert cfg.algo == "sac" and cfg.ppo.lr == 3e-4
    again = json.loads(json.dumps(older_layout(cfg.to_dict())))  # the helper below
    # fields added since fc4683c (e.g. td3.init) are absent from the file and take defaults
    assert _keys_of(again, old) == old and "init" in again["td3"]


def _keys_of(d: dict, like: dict) -> dict:
    """``d`` restricted, section by section, to the keys ``like`` has."""
    return {k: _keys_of(d[k], v) if isinstance(v, dict) else d[k] for k, v in like.items()}


def test_current_layout_moves_the_run_fields_out_of_ppo():
    cfg = TrainConfig(task="point-mass", algo="sac", gamma=0.98, steps_per_update=200,
                      norm_obs=False, clip_obs=5.0)  # fmt: skip
    old = older_layout(cfg.to_dict())
    assert not set(MOVED_FROM_PPO) & set(old) and old["ppo"]["gamma"] == 0.98
    assert current_layout(old) == cfg.to_dict()
    assert TrainConfig.from_dict(old) == cfg
    assert current_layout(cfg.to_dict()) == cfg.to_dict()  # this layout: unchanged
    # given twice with two values: refused, naming the field
    with pytest.raises(ValueError, match=r"config: gamma is given twice"):
        TrainConfig.from_dict({**cfg.to_dict(), "ppo": {**cfg.to_dict()["ppo"], "gamma": 0.9}})


def _rewrite_older(run) -> None:
    """The run's config.json and its checkpoint's config in the layout of older versions."""
    path = run / "config.json"
    path.write_text(json.dumps(older_layout(json.loads(path.read_text())), indent=2))
    state = ck.load_checkpoint(run / "checkpoint.pt")
    state["config"] = older_layout(state["config"])
    ck.save_checkpoint(run / "checkpoint.pt", state, kind="rl")


def test_a_run_written_in_the_older_layout_loads_resumes_and_reports(tmp_path, capsys):
    """An off-policy run (SAC) with a discount and update size of its own, its config.json and
    checkpoint rewritten as older versions wrote them: it loads with the same values, resumes
    (a change of the discount still refused by name), seeds a new run through --config, and
    the report identifies it."""
    run = tmp_path / "sac"
    base = ["rl", "train", "--task", "point-mass", "--algo", "sac", "--gamma", "0.98",
            "--steps-per-update", "200", "--sac-random-steps", "100", "--sac-batch-size", "32",
            "--vector", "sync", "--no-progress", "--no-tensorboard", "--eval-every", "0",
            "--seed", "3"]  # fmt: skip
    assert ndp_main([*base, "--steps", "400", "--run-dir", str(run)]) == 0
    new = load_config(run / "config.json")
    assert (new.gamma, new.steps_per_update) == (0.98, 200)
    saved = json.loads((run / "config.json").read_text())
    assert saved["gamma"] == 0.98 and "gamma" not in saved["ppo"]
    _rewrite_older(run)
    assert "gamma" not in json.loads((run / "config.json").read_text())
    assert load_config(run / "config.json") == new

    # resume: a changed discount is refused by name, a longer budget continues the run
    assert ndp_main(["rl", "train", "--resume", str(run), "--gamma", "0.9"]) == 2
    assert "gamma: 0.98 in the checkpoint, 0.9 now" in capsys.readouterr().err
    assert ndp_main(["rl", "train", "--resume", str(run), "--steps", "800", "--no-progress"]) == 0
    state = ck.load_checkpoint(run / "checkpoint.pt")
    assert state["update"] == 4 and state["config"]["gamma"] == 0.98
    assert [int(r["update"]) for r in read_metrics(run)] == [1, 2, 3, 4]
    assert isinstance(state["model"], dict) and all(
        torch.isfinite(t).all() for t in state["model"].values()
    )

    # --config FILE: an older config.json (or a hyperparameter file with "ppo": {"gamma": ...})
    older = tmp_path / "older.json"
    older.write_text(json.dumps(older_layout(new.to_dict())))
    other = tmp_path / "other"
    argv = ["rl", "train", "--config", str(older), "--steps", "200", "--run-dir", str(other),
            "--no-progress"]  # fmt: skip
    assert ndp_main(argv) == 0
    assert load_config(other / "config.json").gamma == 0.98
    hyper = tmp_path / "hyper.json"
    hyper.write_text(json.dumps({"algo": "sac", "task": "point-mass", "ppo": {"gamma": 0.95}}))
    from ndp.rl.cli import config_from_file

    assert config_from_file(str(hyper)).gamma == 0.95

    # the report reads the older config.json's keys (task, algo, seed, steps)
    from ndp.experiments.report.runs import run_info

    info = run_info(run)
    assert info is not None and (info.task, info.algo, info.seed) == ("point-mass", "sac", 3)
