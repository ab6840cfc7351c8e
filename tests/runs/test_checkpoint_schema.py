"""Checkpoint validation (ndp.runs.checkpoint.check_state) and the replay's load check: one line
naming the file, the key path and what was expected; schema versions."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from ndp.rl.replay import RingReplay
from ndp.runs.checkpoint import (
    INT,
    REAL,
    SCHEMA_VERSION,
    FiniteTensor,
    Holds,
    MayLack,
    OptimizerState,
    StateDict,
    check_state,
    load_checkpoint,
    save_checkpoint,
)


def _net_and_opt():
    net = torch.nn.Linear(3, 2)
    opt = torch.optim.Adam(net.parameters())
    net(torch.ones(1, 3)).sum().backward()
    opt.step()
    return net, opt


def _schema(net, opt):
    return {
        "model": StateDict(net.state_dict()),
        "update": INT,
        "algo": {
            "opt": OptimizerState(opt),
            "peak": MayLack((REAL, type(None))),
            "t": FiniteTensor(),
        },
    }


def _state(net, opt):
    return {"model": net.state_dict(), "update": 3,
            "algo": {"opt": opt.state_dict(), "peak": None, "t": torch.zeros(2)}}  # fmt: skip


def test_a_good_state_passes_and_optional_keys_may_be_absent():
    net, opt = _net_and_opt()
    state = _state(net, opt)
    check_state(state, _schema(net, opt), "run/checkpoint.pt")
    del state["algo"]["peak"]
    check_state(state, _schema(net, opt), "run/checkpoint.pt")


@pytest.mark.parametrize(
    ("spoil", "message"),
    [
        (lambda s: s["algo"].pop("opt"), r"run/checkpoint.pt: algo\.opt: missing \(expected an "),
        (lambda s: s.pop("update"), r"update: missing \(expected an integer\)"),
        (lambda s: s.update(update="3"), r"update: expected an integer, got str '3'"),
        (lambda s: s.update(update=True), r"update: expected an integer, got bool"),
        (
            lambda s: s["model"].update(weight=torch.zeros(2, 4)),
            r"model\.weight: expected shape \(2, 3\), got \(2, 4\)",
        ),
        (lambda s: s["model"].pop("bias"), r"model\.bias: missing"),
        (lambda s: s["model"].update(extra=torch.zeros(1)), r"model\.extra: unexpected"),
        (
            lambda s: s["model"]["weight"].__setitem__((0, 0), float("nan")),
            r"model\.weight: holds NaN/Inf",
        ),
        (
            lambda s: s["algo"]["opt"]["state"][0]["exp_avg"].__setitem__((0, 0), float("inf")),
            r"algo\.opt\.state\.0\.exp_avg: holds NaN/Inf",
        ),
        (
            lambda s: s["algo"]["opt"]["state"][0].update(exp_avg=torch.zeros(5)),
            r"algo\.opt\.state\.0\.exp_avg: expected shape \(2, 3\)",
        ),
        (
            lambda s: s["algo"]["opt"]["param_groups"][0]["params"].pop(),
            r"algo\.opt\.param_groups: expected 1 group\(s\) of \[2\] parameter",
        ),
        (lambda s: s["algo"].update(peak="high"), r"algo\.peak: expected Real or NoneType"),
        (lambda s: s.update(algo=[]), r"algo: expected a dict, got list"),
        (
            lambda s: s.update(schema_version=SCHEMA_VERSION + 1),
            rf"schema_version {SCHEMA_VERSION + 1} is newer than this version of ndp reads",
        ),
        (lambda s: s.update(schema_version="1"), r"schema_version: expected a positive integer"),
    ],
)
def test_each_mismatch_is_one_line_naming_the_file_and_the_key(spoil, message):
    net, opt = _net_and_opt()
    state = _state(net, opt)
    spoil(state)
    with pytest.raises(ValueError, match=message) as err:
        check_state(state, _schema(net, opt), "run/checkpoint.pt")
    assert "\n" not in str(err.value) and str(err.value).startswith("checkpoint run/checkpoint.pt")


def test_new_checkpoints_carry_the_version_old_ones_read_as_1_future_ones_are_refused(tmp_path):
    save_checkpoint(tmp_path / "a.pt", {"update": 1}, kind="rl")
    assert load_checkpoint(tmp_path / "a.pt")["schema_version"] == SCHEMA_VERSION
    torch.save({"update": 1, "kind": "rl"}, tmp_path / "old.pt")  # before the version was kept
    old = load_checkpoint(tmp_path / "old.pt")
    check_state(old, {"update": INT}, tmp_path / "old.pt")
    torch.save({"update": 1, "kind": "rl", "schema_version": 7}, tmp_path / "new.pt")
    with pytest.raises(ValueError, match=r"new\.pt: schema_version 7 is newer .* upgrade"):
        load_checkpoint(tmp_path / "new.pt")


def _ring():
    buf = RingReplay(4, {"obs": (2,), "term": ()})
    buf.add(obs=np.ones((3, 2)), term=np.zeros(3))
    return buf


@pytest.mark.parametrize(
    ("spoil", "message"),
    [
        (lambda d: d["data"]["obs"].__setitem__((1, 0), np.nan), "column obs holds NaN/Inf"),
        (lambda d: d["data"].pop("term"), "column term is missing"),
        (
            lambda d: d["data"].update(obs=np.ones((2, 2), np.float32)),
            r"column obs has shape \(2, 2\), expected 3 rows",
        ),
        (
            lambda d: d["data"].update(obs=np.ones((3, 3), np.float32)),
            r"column obs has shape \(3,\) in the checkpoint, \(2,\) now",
        ),
        (
            lambda d: d["data"].update(obs=np.ones((3, 2), np.int64)),
            "column obs has dtype int64, expected a float dtype",
        ),
        (lambda d: d.update(ptr=1), "write position 1 does not fit size 3"),
        (lambda d: d.update(size=9), "holds 9 decisions, expected 0 to the capacity 4"),
        (lambda d: d.update(size=2.0), "size: expected an integer"),
        (lambda d: d.update(capacity=8), "the buffer holds 8 decisions, expected 4"),
    ],
)
def test_the_replay_refuses_what_it_cannot_continue_from(spoil, message):
    d = _ring().state_dict()
    spoil(d)
    with pytest.raises(ValueError, match=f"replay: {message}"):
        RingReplay(4, {"obs": (2,), "term": ()}).load_state_dict(d)
    fresh = RingReplay(4, {"obs": (2,), "term": ()})
    rule = {"sac": {"replay": Holds(fresh.problem, "a replay buffer")}}
    with pytest.raises(ValueError, match=f"checkpoint f.pt: sac.replay: {message}"):
        check_state({"sac": {"replay": d}}, rule, "f.pt")


def test_a_wrapped_replay_and_one_saved_without_its_capacity_load():
    buf = _ring()
    buf.add(obs=np.zeros((2, 2)), term=np.ones(2))  # wraps: size 4, write position 1
    d = buf.state_dict()
    again = RingReplay(4, buf.shapes)
    again.load_state_dict(d)
    assert (again.size, again.ptr) == (4, 1)
    old = {k: v for k, v in _ring().state_dict().items() if k != "capacity"}
    RingReplay(4, buf.shapes).load_state_dict(old)
