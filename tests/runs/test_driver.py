"""The one run driver (ndp.runs.driver): the lifecycle order, seeding once, restore, the
checkpoint cadence, the learner's own stop, finite-only checkpoints, close on every path, and
every trainer of the package going through it."""

from __future__ import annotations

import contextlib
import dataclasses
import random
import signal
from pathlib import Path

import numpy as np
import pytest
import torch

from ndp.runs import lock
from ndp.runs.checkpoint import load_checkpoint
from ndp.runs.driver import Run, RunPlan, run
from ndp.runs.session import (
    Learner,
    LearnerDefaults,
    Manifest,
    TrainingDivergedError,
    read_manifest,
)


@dataclasses.dataclass(frozen=True)
class Cfg:
    steps: int = 6
    lr: float = 0.1
    run_dir: str = ""

    @classmethod
    def from_dict(cls, d):
        return cls(**d)


class Toy(LearnerDefaults):
    """One weight, a step counter, a draw from every global RNG per step."""

    def __init__(self, events, stop_after=None):
        self.events, self.stop_after = events, stop_after
        self.step = 0
        self.w = torch.zeros(1)
        self.draws = []
        self.events.append(("build", self.draw()))

    @staticmethod
    def draw():
        return (random.random(), float(np.random.rand()), float(torch.rand(())))  # noqa: NPY002

    @property
    def stopped(self):
        return self.stop_after is not None and self.step >= self.stop_after

    def state_dict(self):
        return {"step": self.step, "w": self.w.clone()}

    def load_state_dict(self, state):
        self.events.append(("restore", state["step"]))
        self.step, self.w = int(state["step"]), state["w"].clone()

    def iterate(self):
        self.step += 1
        self.w += 1
        self.draws.append(self.draw())
        return {"step": float(self.step), "w": float(self.w)}

    def nonfinite(self):
        return None if bool(torch.isfinite(self.w).all()) else "w"

    def close(self):
        self.events.append(("close", self.step))


class ToyRecipe:
    def __init__(self, run_dir, cfg=None, every=2, stop_after=None):
        self.cfg = cfg or Cfg(run_dir=str(run_dir))
        self.events: list = []
        self.rows: list = []
        self.stop_after = stop_after
        self.plan = RunPlan(
            run_dir=Path(run_dir),
            kind="toy",
            unit="update",
            seed=3,
            budget=self.cfg.steps,
            config=self.cfg,
            config_dict=dataclasses.asdict(self.cfg),
            config_from_dict=Cfg.from_dict,
            safe_on_resume=("steps",),
            threads=1,
            checkpoint_every=every,
        )

    def check_checkpoint(self, ckpt):
        self.events.append(("check", ckpt["step"]))

    def build(self, session, fresh):
        assert session.run.path.is_dir() and lock._key(session.run.path) in lock._HELD
        self.events.append(("fresh", fresh))
        return Toy(self.events, self.stop_after)

    def manifest(self, learner):
        return Manifest(kind="toy", task="t", label="toy", seed=3, budget=self.cfg.steps,
                        unit="updates", done=learner.step,
                        finished=learner.step >= self.cfg.steps or learner.stopped)  # fmt: skip

    @contextlib.contextmanager
    def log(self, learner, session):
        self.events.append(("log", learner.step))
        yield self.rows.append

    def checkpoint_due(self, learner):
        return learner.step % self.plan.checkpoint_every == 0 or learner.step == self.plan.budget

    def summary(self, learner, last, session):
        return {"last": last, "step": learner.step}


def test_the_lifecycle_runs_in_order_and_seeds_once_before_the_build(tmp_path):
    r = ToyRecipe(tmp_path / "r")
    random.seed(99)
    out = run(r)
    assert out == {"last": {"step": 6.0, "w": 6.0}, "step": 6}
    names = [e[0] for e in r.events]
    assert names == ["fresh", "build", "log", "close"]
    # the build's draws are those of the plan's seed, whatever the caller's state was
    from ndp.runs.session import seed_everything

    seed_everything(3)
    assert r.events[1][1] == Toy.draw()
    assert [row["step"] for row in r.rows] == [1, 2, 3, 4, 5, 6]
    assert load_checkpoint(tmp_path / "r" / "checkpoint.pt", kind="toy")["step"] == 6
    m = read_manifest(tmp_path / "r")
    assert m is not None and m.finished and m.done == 6
    assert (tmp_path / "r" / "config.json").is_file()
    assert lock.holder(tmp_path / "r") is None


def test_a_resumed_run_checks_restores_and_continues_the_same_numbers(tmp_path):
    whole = ToyRecipe(tmp_path / "a")
    with Run(whole) as opened:
        opened.train()
        straight = opened.learner.draws
    part = ToyRecipe(tmp_path / "b")
    with Run(part) as opened:
        opened.train(4)  # checkpoint at 4 (every 2)
        first = list(opened.learner.draws)
    again = ToyRecipe(tmp_path / "b")
    with Run(again, resume=True) as opened:
        assert opened.learner.step == 4
        opened.train()
        rest = opened.learner.draws
    assert [e[0] for e in again.events][:4] == ["check", "fresh", "build", "restore"]
    assert ("fresh", False) in again.events
    assert first + rest == straight  # the global RNG state continues from the checkpoint


def test_the_learner_may_stop_before_its_budget(tmp_path):
    r = ToyRecipe(tmp_path / "r", stop_after=3)
    assert run(r)["step"] == 3
    assert read_manifest(tmp_path / "r").finished


def test_max_steps_stops_early_and_a_second_train_continues(tmp_path):
    r = ToyRecipe(tmp_path / "r")
    with Run(r) as opened:
        assert opened.train(2)["step"] == 2
        assert not read_manifest(tmp_path / "r").finished
        assert opened.train()["step"] == 6
    assert read_manifest(tmp_path / "r").finished


def test_a_non_finite_parameter_never_reaches_the_checkpoint(tmp_path):
    r = ToyRecipe(tmp_path / "r")
    with Run(r) as opened:
        opened.train(2)
        good = (tmp_path / "r" / "checkpoint.pt").read_bytes()
        opened.learner.w[0] = float("nan")
        with pytest.raises(TrainingDivergedError, match="parameter w holds NaN/Inf"):
            opened.train(2)
        assert (tmp_path / "r" / "checkpoint.pt").read_bytes() == good
    assert r.events[-1][0] == "close"
    assert lock.holder(tmp_path / "r") is None


def test_an_error_in_the_build_releases_the_lock_and_a_failed_step_closes(tmp_path):
    class Broken(ToyRecipe):
        def build(self, session, fresh):
            raise ValueError("build: no")

    with pytest.raises(ValueError, match="build: no"):
        run(Broken(tmp_path / "r"))
    assert lock.holder(tmp_path) is None and not lock._HELD

    class Failing(ToyRecipe):
        def build(self, session, fresh):
            toy = super().build(session, fresh)
            toy.iterate = lambda: (_ for _ in ()).throw(RuntimeError("step failed"))
            return toy

    f = Failing(tmp_path / "s")
    with pytest.raises(RuntimeError, match="step failed"):
        run(f)
    assert f.events[-1][0] == "close" and not lock._HELD


def test_sigterm_inside_the_run_stops_it_at_its_last_checkpoint(tmp_path):
    from ndp.runs.signals import Terminated

    class Killed(ToyRecipe):
        def build(self, session, fresh):
            toy = super().build(session, fresh)
            step = toy.iterate

            def iterate():
                row = step()
                if toy.step == 3:
                    signal.raise_signal(signal.SIGTERM)
                return row

            toy.iterate = iterate
            return toy

    k = Killed(tmp_path / "r")
    with pytest.raises(Terminated):
        run(k)
    assert load_checkpoint(tmp_path / "r" / "checkpoint.pt", kind="toy")["step"] == 2
    assert k.events[-1][0] == "close" and not lock._HELD


def test_a_resume_with_a_changed_config_is_refused_before_anything_is_built(tmp_path):
    with Run(ToyRecipe(tmp_path / "r")) as opened:
        opened.train(2)
    changed = ToyRecipe(tmp_path / "r", cfg=Cfg(lr=0.5, run_dir=str(tmp_path / "r")))
    with pytest.raises(ValueError, match=r"lr: 0\.1 in the checkpoint, 0\.5 now"):
        Run(changed, resume=True)
    assert changed.events == [] and not lock._HELD


def test_every_trainer_of_the_package_runs_through_the_driver():
    """The trainers' modules hold no lifecycle of their own: none opens a RunSession, seeds or
    drives a loop; each supplies a recipe to ndp.runs.driver."""
    root = Path(__file__).resolve().parents[2] / "src" / "ndp"
    trainers = ["rl/onpolicy/trainer.py", "rl/dyne/learner.py", "rl/sac/learner.py",
                "rl/td3/learner.py", "rl/offpolicy/loop.py", "rl/run.py", "il/train.py",
                "bc/train.py", "sb3/runs.py"]  # fmt: skip
    for rel in trainers:
        src = (root / rel).read_text()
        for lifecycle in ("RunSession.open(", "seed_everything(", "set_num_threads(cfg.torch",
                          " drive(", "session.start(", "session.finish("):  # fmt: skip
            assert lifecycle not in src, (rel, lifecycle)
    uses = [rel for rel in trainers if "ndp.runs.driver" in (root / rel).read_text()]
    assert set(uses) >= {"rl/run.py", "il/train.py", "bc/train.py", "sb3/runs.py"}


def test_the_learners_satisfy_the_one_protocol():
    from ndp.bc.train import CloningLearner
    from ndp.il.train import ImitationLearner
    from ndp.rl.dyne import DyneLearner
    from ndp.rl.onpolicy.trainer import Trainer
    from ndp.rl.sac.learner import SACLearner
    from ndp.rl.td3.learner import TD3Learner
    from ndp.sb3.runs import SB3Learner

    for cls in (Trainer, DyneLearner, SACLearner, TD3Learner, ImitationLearner, CloningLearner,
                SB3Learner):  # fmt: skip
        for name in ("step", "stopped", "state_dict", "load_state_dict", "iterate", "nonfinite",
                     "close"):  # fmt: skip
            assert hasattr(cls, name) or name == "step", (cls.__name__, name)
    assert isinstance(Toy([]), Learner)
