"""Training callbacks (ndp.runs.callbacks): called by the run driver after every update; a
stop is checkpointed and resumes; the ready ones (StopAtSuccess, CheckpointEvery); a real RL
run stopped at a success threshold."""

from __future__ import annotations

import pytest
from tests.runs.test_driver import ToyRecipe

from ndp.runs import load_checkpoint
from ndp.runs.callbacks import Callback, CheckpointEvery, StopAtSuccess
from ndp.runs.driver import Run, run
from ndp.runs.session import read_manifest


class Recorder(Callback):
    def __init__(self, stop_at: int | None = None, budget: int = 6) -> None:
        self.budget = budget
        self.updates: list[int] = []
        self.evals: list[int] = []
        self.stop_at = stop_at

    def on_update(self, row, ctx):
        self.updates.append(ctx.step)
        assert ctx.budget == self.budget and ctx.run_dir.is_dir()

    def on_eval(self, row, ctx):
        self.evals.append(ctx.step)

    def should_stop(self, row, ctx):
        return self.stop_at is not None and ctx.step >= self.stop_at


def test_callbacks_see_every_update_and_a_stop_is_checkpointed_and_resumes(tmp_path):
    rec = Recorder(stop_at=3)
    out = run(ToyRecipe(tmp_path / "r", every=4), callbacks=[rec])
    assert out["step"] == 3 and rec.updates == [1, 2, 3] and rec.evals == []
    # the stop at 3 is not on the cadence (4): the driver saved it anyway
    assert load_checkpoint(tmp_path / "r" / "checkpoint.pt", kind="toy")["step"] == 3
    assert not read_manifest(tmp_path / "r").finished
    again = Recorder()
    assert run(ToyRecipe(tmp_path / "r", every=4), resume=True, callbacks=[again])["step"] == 6
    assert again.updates == [4, 5, 6]


def test_checkpoint_every_saves_beside_the_cadence(tmp_path):
    cb = CheckpointEvery(1)
    with Run(ToyRecipe(tmp_path / "r", every=100)) as opened:
        opened.train(callbacks=[cb])
    assert [p.name for p in cb.paths] == ["checkpoint.pt"] * 6


def test_stop_at_success_counts_consecutive_evaluations():
    cb = StopAtSuccess(0.5, patience=2)
    seen = []
    for v in (0.6, 0.2, 0.7, 0.9):
        cb.on_eval({"eval/success_any": v}, None)  # type: ignore[arg-type]
        seen.append(cb.should_stop({}, None))  # type: ignore[arg-type]
    assert seen == [False, False, False, True]


def test_bad_callbacks_are_one_line_and_touch_nothing(tmp_path):
    with pytest.raises(ValueError, match=r"^callbacks: expected ndp.runs.callbacks.Callback "
                       r"instances, got function at index 0"):  # fmt: skip
        run(ToyRecipe(tmp_path / "r"), callbacks=[lambda row: None])
    assert not (tmp_path / "r").exists()
    with pytest.raises(ValueError, match=r"^threshold: expected a success rate in \[0, 1\]"):
        StopAtSuccess(1.5)
    with pytest.raises(ValueError, match=r"^n: expected an integer >= 1"):
        CheckpointEvery(0)


def test_an_rl_run_stops_at_its_first_evaluation_that_reaches_the_threshold(tmp_path):
    """ndp.rl.run.train with StopAtSuccess(0.0): the first periodic evaluation reaches it, the
    run stops there with a checkpoint, and ndp.rl.run.resume finishes it."""
    from ndp.rl.config import PPOConfig, TrainConfig
    from ndp.rl.run import resume, train

    cfg = TrainConfig(task="point-mass", algo="ndp", steps=2080, num_envs=2,
                      steps_per_update=260, ppo=PPOConfig(minibatches=2),
                      run_dir=str(tmp_path / "rl"), progress=False, tensorboard=False,
                      vector="sync", eval_every=520, eval_episodes=1)  # fmt: skip
    rec = Recorder(budget=8)
    row = train(cfg, callbacks=[StopAtSuccess(0.0), rec])
    assert rec.evals and rec.updates[-1] == rec.evals[0] < 8
    assert "eval/success_any" in row
    ckpt = load_checkpoint(tmp_path / "rl" / "checkpoint.pt", kind="rl")
    assert int(ckpt["update"]) == rec.evals[0]
    resume(tmp_path / "rl")
    assert read_manifest(tmp_path / "rl").finished
