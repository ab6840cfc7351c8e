"""Method registry: a new on-policy method is one head + one registration, then it trains."""

from __future__ import annotations

import json

import pytest
import torch

from ndp.cli import main as ndp_main
from ndp.policies.distributions import SubActionGaussian
from ndp.policies.heads import HEAD_BUILDERS, ActionHead, register_head
from ndp.rl.logger import METRICS
from ndp.rl.methods import METHODS, Method, register_method
from ndp.runs.session import CountsUpdates


class RepeatHead(ActionHead):
    """A toy method: one raw action per decision, held for the k sub-steps (action repeat)."""

    def __init__(self, k: int, action_dim: int) -> None:
        super().__init__()
        self.k, self.action_dim, self.n_params = k, action_dim, action_dim
        self.log_std = torch.nn.Parameter(torch.zeros(action_dim))

    def distribution(self, raw, y0=None, dy0=None):
        mean = raw.unsqueeze(1).expand(-1, self.k, -1)
        return SubActionGaussian(mean, self.log_std), {}


@pytest.fixture
def repeat_method():
    register_head("repeat")(lambda cfg, spec: RepeatHead(cfg.k, spec.action_dim))
    register_method(Method("toy-repeat", "repeat", "PPO with each action held for k steps"))
    yield
    METHODS.pop("toy-repeat")
    HEAD_BUILDERS.pop("repeat")


def test_a_registered_toy_method_trains_through_the_cli(tmp_path, repeat_method):
    run = tmp_path / "run"
    rc = ndp_main(
        [
            "rl",
            "train",
            "--task",
            "point-mass",
            "--algo",
            "toy-repeat",
            "--k",
            "3",
            "--steps",
            "600",
            "--steps-per-update",
            "300",
            "--minibatches",
            "2",
            "--vector",
            "sync",
            "--run-dir",
            str(run),
            "--no-progress",
            "--no-tensorboard",
        ]
    )
    assert rc == 0
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["algo"] == "toy-repeat" and cfg["policy"]["head"] == "repeat"
    assert cfg["policy"]["k"] == 3 and cfg["policy"]["ndp"]["n_basis"] is None
    assert (run / "checkpoint.pt").is_file()


def test_registry_rejects_duplicates_and_unknown_heads():
    with pytest.raises(ValueError, match="already registered"):
        register_method(Method("ppo", "step", "again"))
    with pytest.raises(ValueError, match="not a registered head"):
        register_method(Method("x", "nope", "no head"))
    with pytest.raises(ValueError, match="already registered"):
        register_head("ndp")(lambda cfg, spec: None)
    assert set(METHODS) >= {"ppo", "ppo-multi", "ndp"}


def test_a_learner_entry_point_is_checked_at_registration_and_imported_at_build():
    for bad in ("ndp.rl.dyne.DyneLearner", ":x", "ndp.rl.dyne:", "not a module:x"):
        with pytest.raises(ValueError, match="learner: expected a callable or an entry point"):
            Method("x", "step", "bad entry point", learner=bad)
    m = Method("x", "step", "missing", learner="ndp.rl.no_such_module:Learner")
    with pytest.raises(ValueError, match=r"learner: method 'x' names .*no_such_module"):
        m.build_learner(None, None)
    got = Method("x", "step", "ok", learner="collections:namedtuple")
    assert got.build_learner("P", ["a"])._fields == ("a",)  # the entry point, called
    assert Method("x", "step", "shared trainer").build_learner(None, None) is None
    # the built-in that uses one names a real class (not imported by the registry itself)
    assert METHODS["dyne"].learner == "ndp.rl.dyne:DyneLearner"


class RandomSearch(CountsUpdates):
    """A toy learner (hill climbing on the actor's weights) written against the public seams
    only: an ``RLLearner`` built from the resolved config and the run session, its envs from
    ``make_vector_env``, a state with the policy checkpoint keys. The run driver opens, seeds,
    drives and checkpoints it; its runs are then evaluated by ``ndp rl eval`` like PPO's."""

    columns = METRICS

    def __init__(self, cfg, session):
        import numpy as np

        from ndp.policies import build_actor_critic
        from ndp.rl.envs import make_vector_env, resolve_task
        from ndp.rl.normalize import ObsNormalizer

        self.cfg, self.session = cfg, session
        task = resolve_task(cfg.task)
        self.envs = make_vector_env(task, cfg.k, cfg.num_envs, vector="sync")
        self.obs_dim = int(np.prod(self.envs.single_observation_space.shape))
        self.model = build_actor_critic(self.obs_dim, task.spec, cfg.policy)
        self.norm = ObsNormalizer(self.obs_dim, enabled=False)
        self.update = self.global_step = 0
        self.best = None

    def _score(self, seed):
        obs, _ = self.envs.reset(seed=[seed + i for i in range(self.cfg.num_envs)])
        total, steps = 0.0, 0
        for _ in range(self.cfg.decisions_per_env):
            o = torch.as_tensor(obs, dtype=torch.float32).reshape(self.cfg.num_envs, -1)
            with torch.no_grad():
                dist, _ = self.model.distribution(o, torch.zeros(len(o), 2), torch.zeros(len(o), 2))
            obs, r, _, _, _ = self.envs.step(dist.mean.clamp(-1, 1).numpy())
            total, steps = total + float(r.sum()), steps + self.cfg.num_envs * self.cfg.k
        return total / self.cfg.num_envs, steps

    def iterate(self):
        if self.best is None:
            self.best, _ = self._score(0)
        keep = {k: v.clone() for k, v in self.model.state_dict().items()}
        with torch.no_grad():
            for prm in self.model.actor.parameters():
                prm.add_(0.05 * torch.randn_like(prm))
        score, n = self._score(0)
        if score < self.best:
            self.model.load_state_dict(keep)
        self.best = max(self.best, score)
        self.update, self.global_step = self.update + 1, self.global_step + n
        return {"update": self.update, "global_step": self.global_step,
                "charts/episode_return": self.best}  # fmt: skip

    def state_dict(self):
        return {"model": self.model.state_dict(), "obs_norm": self.norm.state_dict(),
                "obs_dim": self.obs_dim, "update": self.update, "global_step": self.global_step,
                "best": self.best}  # fmt: skip

    def load_state_dict(self, state):
        self.model.load_state_dict(state["model"])
        self.update, self.global_step = state["update"], state["global_step"]
        self.best = state["best"]

    def close(self):
        self.envs.close()


def test_a_registered_learner_trains_and_its_run_evaluates(tmp_path, capsys):
    from ndp.rl.methods import POLICY_CHECKPOINT_KEYS
    from ndp.runs import load_checkpoint, read_metrics

    register_method(Method("random-search", "step", "hill climbing", learner=RandomSearch))
    try:
        run = tmp_path / "rs"
        args = ["rl", "train", "--task", "point-mass", "--algo", "random-search", "--steps",
                "400", "--steps-per-update", "80", "--run-dir", str(run),
                "--no-progress"]  # fmt: skip
        assert ndp_main(args) == 0
        rows = read_metrics(run)
        assert (
            len(rows) == 5 and rows[-1]["charts/episode_return"] >= rows[0]["charts/episode_return"]
        )
        assert set(POLICY_CHECKPOINT_KEYS) <= set(load_checkpoint(run, kind="rl"))
        capsys.readouterr()
        assert ndp_main(["rl", "eval", str(run), "--episodes", "2", "--mode", "deterministic"]) == 0
        out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert out["episodes"] == 2 and 0.0 <= out["success_any"] <= 1.0
    finally:
        METHODS.pop("random-search")
