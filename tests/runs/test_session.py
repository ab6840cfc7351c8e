"""The run skeleton (ndp.runs.session): create-or-resume, RNG state, checkpoints, the
divergence message, run.json, and the PPO / Dyn-E trainers running inside it."""

from __future__ import annotations

import dataclasses
import json
import random

import numpy as np
import pytest
import torch

from ndp.runs.session import (
    MANIFEST_NAME,
    Learner,
    LearnerDefaults,
    Manifest,
    RunSession,
    TrainingDivergedError,
    checkpoint_due,
    global_rng_state,
    nonfinite_parameter,
    read_manifest,
    seed_everything,
    write_manifest,
)


@dataclasses.dataclass(frozen=True)
class Cfg:
    lr: float = 1e-3
    steps: int = 10
    run_dir: str = ""


SAFE = ("steps",)


class Counter(LearnerDefaults):
    """A minimal Learner: one parameter, a step counter, a draw from every global RNG."""

    def __init__(self) -> None:
        self.step = 0
        self.w = torch.zeros(2)
        self.draws: list[tuple[float, float, float]] = []

    def state_dict(self):
        return {"step": self.step, "w": self.w.clone()}

    def load_state_dict(self, state):
        self.step, self.w = int(state["step"]), state["w"].clone()

    def iterate(self):
        self.step += 1
        self.w += 1
        self.draws.append((random.random(), float(np.random.rand()), float(torch.rand(()))))  # noqa: NPY002
        return {"step": self.step}

    def close(self):
        pass


def _open(tmp_path, resume=False, cfg=None, kind="rl"):
    cfg = cfg or Cfg(run_dir=str(tmp_path / "r"))
    return RunSession.open(
        tmp_path / "r",
        kind=kind,
        config=cfg,
        config_from_dict=lambda d: Cfg(**d),
        safe_on_resume=SAFE,
        resume=resume,
    )


def _run(tmp_path, stop, resume=False, cfg=None):
    session, ckpt = _open(tmp_path, resume, cfg)
    seed_everything(0)
    lr = Counter()
    if ckpt is not None:
        lr.load_state_dict(ckpt)
        session.restored(ckpt, lr.step)
    cfg = cfg or Cfg(run_dir=str(tmp_path / "r"))
    session.start(dataclasses.asdict(cfg))

    def save_if_due():
        if checkpoint_due(lr.step, 2, cfg.steps):
            session.save(lr.state_dict(), lr.step, dataclasses.asdict(cfg))

    while lr.step < stop:  # the driver's loop (ndp.runs.driver.drive), by hand
        lr.iterate()
        save_if_due()
    return session, lr


def test_a_counter_is_a_learner_and_the_cadence_is_every_n_and_the_last():
    assert isinstance(Counter(), Learner)
    assert [s for s in range(1, 8) if checkpoint_due(s, 3, 7)] == [3, 6, 7]


def test_a_resumed_run_draws_the_same_numbers_as_an_uninterrupted_one(tmp_path):
    _, whole = _run(tmp_path / "a", 6)
    _run(tmp_path / "b", 4)  # stops at a checkpoint (4), then resumes to 6
    _, rest = _run(tmp_path / "b", 6, resume=True, cfg=Cfg(run_dir=str(tmp_path / "b" / "r")))
    assert rest.step == 6 and torch.equal(rest.w, whole.w)
    assert rest.draws == whole.draws[4:]  # python, numpy and torch generators restored


def test_create_refuses_a_run_and_resume_refuses_another_config_or_kind(tmp_path):
    _run(tmp_path, 2)
    with pytest.raises(ValueError, match="already holds a checkpoint"):
        _open(tmp_path)
    other = Cfg(lr=1e-2, run_dir=str(tmp_path / "r"))
    with pytest.raises(ValueError, match=r"lr: 0\.001 in the checkpoint, 0\.01 now"):
        _open(tmp_path, resume=True, cfg=other)
    with pytest.raises(ValueError, match="expected an imitation one"):
        _open(tmp_path, resume=True, kind="il")
    # a safe field and the location may change
    moved = Cfg(steps=20, run_dir="elsewhere")
    _, ckpt = _open(tmp_path, resume=True, cfg=moved)
    assert (
        ckpt is not None and ckpt["step"] == 2 and set(ckpt["rng"]) == {"torch", "numpy", "python"}
    )


def test_the_divergence_error_names_the_last_good_checkpoint(tmp_path):
    session, _ = _open(tmp_path)
    session.hint = "Try a smaller --lr."
    e = session.diverged("loss is nan", step=0)
    assert isinstance(e, TrainingDivergedError) and isinstance(e, FloatingPointError)
    assert str(e).endswith(
        "The last good checkpoint is kept: none written yet. Try a smaller --lr."
    )
    session.save({"step": 4}, 4, {"lr": 1.0})
    e = session.diverged("gradient is inf", step=6)
    assert "training stopped at update 7: gradient is inf" in str(e)
    assert f"{session.run.checkpoint} (update 4)" in str(e)
    assert (
        nonfinite_parameter([("a", torch.ones(2)), ("b", torch.tensor([1.0, float("nan")]))]) == "b"
    )
    assert nonfinite_parameter([("a", torch.ones(2))]) is None


def test_the_manifest_round_trips_and_a_broken_one_is_one_line(tmp_path):
    m = Manifest("rl", "push-v3", "ndp", 0, 300_000, "env_steps", 300_000, True, "budget")
    write_manifest(tmp_path, m)
    assert read_manifest(tmp_path) == m
    assert read_manifest(tmp_path / "nowhere") is None
    (tmp_path / MANIFEST_NAME).write_text('{"kind": "rl", "colour": 1}')
    with pytest.raises(ValueError, match=r"run\.json: .* is not a run manifest .*colour"):
        read_manifest(tmp_path)
    (tmp_path / MANIFEST_NAME).write_text("[1, 2]")
    with pytest.raises(ValueError, match="not a run manifest"):
        read_manifest(tmp_path)


def test_global_rng_state_has_the_three_generators():
    seed_everything(3)
    state = global_rng_state()
    assert set(state) == {"torch", "numpy", "python"}


@pytest.mark.parametrize("algo", ["ndp", "dyne"])
def test_ppo_and_dyne_runs_write_run_json_and_finish_it(tmp_path, algo):
    pytest.importorskip("gymnasium")
    from ndp.rl.config import PPOConfig, TrainConfig
    from ndp.rl.run import RLLearner, open_run

    extra = {}
    if algo == "dyne":
        from ndp.rl.dyne.config import DyneConfig

        extra = {
            "dyne": DyneConfig(explore_steps=260, embed_updates=5, decoder_updates=5, batch_size=16)
        }
    cfg = TrainConfig(
        task="point-mass",
        algo=algo,
        steps=512,
        seed=1,
        run_dir=str(tmp_path / "r"),
        progress=False,
        tensorboard=False,
        vector="sync",
        steps_per_update=256,
        ppo=PPOConfig(minibatches=2),
        **extra,
    )
    opened = open_run(cfg)
    lr = opened.learner
    try:
        assert isinstance(lr, Learner) and isinstance(lr, RLLearner)
        started = read_manifest(tmp_path / "r")
        assert started is not None and not started.finished and started.done == 0
        opened.train(1)
        assert not read_manifest(tmp_path / "r").finished
        opened.train()
    finally:
        opened.close()
    m = read_manifest(tmp_path / "r")
    assert (m.kind, m.task, m.label, m.seed, m.unit) == ("rl", "point-mass", algo, 1, "env_steps")
    assert m.finished and m.reason == "budget" and m.budget == 520  # rounded up to whole decisions
    assert json.loads((tmp_path / "r" / MANIFEST_NAME).read_text())["done"] == m.done > 0


def test_sweeps_and_reports_read_what_run_json_says(tmp_path):
    """A run in a folder whose name says nothing is identified by its run.json, and run.json's
    ``finished`` is what a sweep counts (the older records are the fallback)."""
    from ndp.experiments.report import run_info
    from ndp.experiments.study import is_finished

    run = tmp_path / "my-favourite-run"
    run.mkdir()
    (run / "config.json").write_text(json.dumps({"algo": "ndp", "steps": 1000}))
    (run / "metrics.csv").write_text("update,global_step\n1,1000\n")
    m = Manifest("rl", "soccer-v3", "ndp", 7, 1000, "env_steps", 1000, False)
    write_manifest(run, m)
    info = run_info(run)
    assert info is not None and (info.task, info.seed, info.label) == ("soccer-v3", 7, "ndp")
    assert not is_finished(run)
    write_manifest(run, dataclasses.replace(m, finished=True, reason="budget"))
    assert is_finished(run)
    (run / MANIFEST_NAME).write_text("not json")  # unreadable: the older records decide
    assert not is_finished(run)  # no done.json, no checkpoint


def test_one_train_call_resolves_its_config_once(tmp_path, monkeypatch):
    pytest.importorskip("gymnasium")
    from ndp.rl import run as trainer_module
    from ndp.rl.config import PPOConfig, TrainConfig
    from ndp.rl.config import resolve_config as real

    calls = []

    def counting(cfg, spec=None):
        calls.append(cfg.algo)
        return real(cfg, spec)

    monkeypatch.setattr(trainer_module, "resolve_config", counting)
    cfg = TrainConfig(task="point-mass", algo="ndp", steps=256, run_dir=str(tmp_path / "r"),
                      progress=False, tensorboard=False, vector="sync",
                      steps_per_update=256, ppo=PPOConfig(minibatches=2))  # fmt: skip
    trainer_module.train(cfg, overwrite=True)
    assert calls == ["ndp"]
