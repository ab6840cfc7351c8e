"""Trained policies act without the simulators: load + act(obs, robot_state) on the core install.

The reference actions (tests/data/zoo_reference_actions.npz) were recorded from every policy
the zoo held then, now the fixtures tests/fixtures/policies (the zoo is regenerated with other
weights), on real observations and robot states of its env, with the loader as it was before
exports recorded their task spec (the task table built the head then). On one machine both
paths must give the same actions bit for bit: the env path (the task table) in this process,
and the recorded spec in a process where importing gymnasium, mujoco, metaworld or dm_control
raises ImportError. Against the recording, made on another machine whose CPU may run other
matrix kernels (the 400-300 Dyn-E decoder differs in the last bits between an Intel and an AMD
machine), they must agree to 1e-5.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import ndp
from ndp.schema import PolicySpec, check_record, spec_record
from policy_fixtures import fixture_names, fixture_policy

ROOT = Path(__file__).resolve().parents[2]
SRC = Path(ndp.__file__).resolve().parents[1]
REF = ROOT / "tests" / "data" / "zoo_reference_actions.npz"
SIMULATORS = ("gymnasium", "mujoco", "metaworld", "dm_control")

BLOCKED_SCRIPT = r"""
import importlib.abc
import json
import sys

BLOCKED = set(SIMULATORS)


class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {name!r} (blocked by the test)", name=name)
        return None


assert not [m for m in sys.modules if m.partition(".")[0] in BLOCKED]
sys.meta_path.insert(0, Block())
sys.path.insert(0, SRC)

import numpy as np
import ndp

assert ndp.__file__.startswith(SRC), ndp.__file__
ref = np.load(REF)
out, arrays = {}, {}
for name, path in POLICIES.items():
    key = name.replace("-", "_")
    pol = ndp.load_policy(path)
    assert pol.simulator_free, type(pol.spec)
    obs, y0, dy0 = ref[key + "__obs"], ref[key + "__y0"], ref[key + "__dy0"]
    ky, kdy = pol.state_keys
    det, det_state, det_batch = [], [], pol.act(obs, {ky: y0, kdy: dy0})
    sto = []
    for i in range(len(obs)):
        det.append(pol.act(obs[i], {ky: y0[i], kdy: dy0[i]}))
        det_state.append(pol.act(obs[i], ndp.RobotState(y0[i], dy0[i])))
        seed_i = 100 + (i // 3) * 10 + i % 3  # as recorded: two episodes of three decisions
        pol.reset(seed=seed_i)
        sto.append(pol.act(obs[i], ndp.RobotState(y0[i], dy0[i]), deterministic=False))
    arrays[key + "__det"], arrays[key + "__det_state"] = np.stack(det), np.stack(det_state)
    arrays[key + "__det_batch"], arrays[key + "__sto"] = det_batch, np.stack(sto)
    out[name] = True
    if name == "push-v3-ndp":
        try:
            pol.make_env()
        except ModuleNotFoundError as exc:
            out["make_env_error"] = str(exc)

# an export older than the recorded spec says what it needs, in one line
try:
    ndp.load_policy(OLD_EXPORT)
except ModuleNotFoundError as exc:
    out["old_export_error"] = str(exc)
out["blocked_imported"] = sorted(m for m in sys.modules if m.partition(".")[0] in BLOCKED)
np.savez(ACTIONS, **arrays)
print("RESULT " + json.dumps(out))
"""


def _old_export(tmp_path: Path) -> Path:
    """The push-v3-ndp fixture as exports were before ``"spec"`` (the field removed)."""
    old = tmp_path / "old-push"
    shutil.copytree(fixture_policy("push-v3-ndp"), old)
    meta = json.loads((old / "policy.json").read_text())
    meta.pop("spec")
    (old / "policy.json").write_text(json.dumps(meta))
    return old


def test_fixture_policies_act_without_the_simulators_bit_identical(tmp_path):
    script = BLOCKED_SCRIPT
    for name, value in {
        "SIMULATORS": repr(SIMULATORS),
        "SRC": repr(str(SRC)),
        "REF": repr(str(REF)),
        "POLICIES": repr({name: str(fixture_policy(name)) for name in fixture_names()}),
        "OLD_EXPORT": repr(str(_old_export(tmp_path))),
        "ACTIONS": repr(str(tmp_path / "actions.npz")),
    }.items():
        script = script.replace(name, value)
    r = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"OMP_NUM_THREADS": "1"},
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    line = next(x for x in r.stdout.splitlines() if x.startswith("RESULT "))
    out = json.loads(line[len("RESULT ") :])
    assert out.pop("blocked_imported") == []
    assert "needs the simulators, the [envs] extra" in out.pop("make_env_error")
    old = out.pop("old_export_error")
    assert "records no task spec" in old and "[envs]" in old and "\n" not in old
    assert sorted(out) == fixture_names() and len(out) == 17
    got = np.load(tmp_path / "actions.npz")
    for name in out:
        key = name.replace("-", "_")
        ref = _reference(name)
        # the recorded spec's actions equal the task table's, in this process, bit for bit
        here = _env_path_actions(name, ref)
        for form in ("det", "det_state", "sto"):
            np.testing.assert_array_equal(got[f"{key}__{form}"], here[form], err_msg=name)
        # a batch of E runs other matrix kernels than E single rows: equal up to rounding
        _close(got[f"{key}__det_batch"], here["det"], name)
        # and both are the recorded actions (made on another machine: up to its kernels)
        _close(here["det"], ref["det"], name)
        _close(here["sto"], ref["sto"], name)


def _close(a: np.ndarray, b: np.ndarray, name: str) -> None:
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-5, err_msg=name)


def _env_path_actions(name: str, ref: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The fixture policy ``name`` loaded through the task table (simulators importable), acting
    on the recorded observations and robot states as the blocked process does."""
    pytest.importorskip("metaworld")
    pol = ndp.load_policy(fixture_policy(name))
    assert not pol.simulator_free
    det, sto = [], []
    for i in range(len(ref["obs"])):
        state = ndp.RobotState(ref["y0"][i], ref["dy0"][i])
        det.append(pol.act(ref["obs"][i], state))
        pol.reset(seed=100 + (i // 3) * 10 + i % 3)
        sto.append(pol.act(ref["obs"][i], state, deterministic=False))
    return {"det": np.stack(det), "det_state": np.stack(det), "sto": np.stack(sto)}


def _reference(name: str) -> dict[str, np.ndarray]:
    ref = np.load(REF)
    key = name.replace("-", "_")
    return {f: ref[f"{key}__{f}"] for f in ("obs", "y0", "dy0", "det", "sto")}


@pytest.mark.parametrize("name", ["push-v3-ndp", "throw-ndp", "throw-vices", "soccer-v3-ppo"])
def test_the_env_path_gives_the_recorded_actions(name):
    pytest.importorskip("metaworld")
    from ndp.envs import TaskSpec

    pol = ndp.load_policy(fixture_policy(name))
    assert isinstance(pol.spec, TaskSpec) and not pol.simulator_free
    # the recorded spec is the task table's row
    assert (
        spec_record(pol.spec)
        == json.loads((fixture_policy(name) / "policy.json").read_text())["spec"]
    )
    ref = _reference(name)
    ky, kdy = pol.state_keys
    for i in range(len(ref["obs"])):
        info = {ky: ref["y0"][i], kdy: ref["dy0"][i], "success": False}
        _close(pol.act(ref["obs"][i], info), ref["det"][i], name)


def test_an_export_without_the_spec_still_loads_with_the_simulators(tmp_path):
    pytest.importorskip("metaworld")
    pol = ndp.load_policy(_old_export(tmp_path))
    assert not pol.simulator_free
    ref = _reference("push-v3-ndp")
    for i in range(len(ref["obs"])):
        got = pol.act(ref["obs"][i], {"dmp_y0": ref["y0"][i], "dmp_dy0": ref["dy0"][i]})
        _close(got, ref["det"][i], "push-v3-ndp")


def test_export_records_the_spec_training_and_a_card(tmp_path):
    pytest.importorskip("metaworld")
    out = ndp.export_policy(fixture_policy("throw-ndp"), tmp_path / "again")
    meta = json.loads((out / "policy.json").read_text())
    pol = ndp.load_policy(out)
    assert meta["spec"] == spec_record(pol.spec) and meta["spec"]["dmp_dofs"] == 7
    check_record(meta["spec"])
    assert (out / "README.md").read_text().startswith("---\nlibrary_name:")
    # a recorded spec that disagrees with the task table is named in a warning
    meta["spec"]["action_scale"] = [0.2] * 7
    (out / "policy.json").write_text(json.dumps(meta))
    with pytest.warns(UserWarning, match="differs from the task table's in action_scale"):
        ndp.load_policy(out)


def test_robot_state_forms_and_refusals():
    # commanded frame, DMP at rest (dmp_velocity zero)
    pol = ndp.load_policy(fixture_policy("throw-ndp"))
    ref = _reference("throw-ndp")
    obs, y0, dy0 = ref["obs"][0], ref["y0"][0], ref["dy0"][0]
    want = pol.act(obs, ndp.RobotState(y0, dy0))
    _close(want, ref["det"][0], "throw-ndp")
    # at rest, dy0 is not read: None is allowed
    np.testing.assert_array_equal(pol.act(obs, ndp.RobotState(y0)), want)
    with pytest.raises(ValueError, match="DMP starts from the robot's state"):
        pol.act(obs)
    with pytest.raises(ValueError, match=r"'cmd_y0' expected shape \[7\], got \[4\]"):
        pol.act(obs, ndp.RobotState(y0[:4], dy0))
    with pytest.raises(ValueError, match="got list"):
        pol.act(obs, [y0, dy0])
    push = ndp.load_policy(fixture_policy("push-v3-ndp"))  # measured frame with its velocity
    p = _reference("push-v3-ndp")
    with pytest.raises(ValueError, match="dy0 is None, but this policy's DMP starts with"):
        push.act(p["obs"][0], ndp.RobotState(p["y0"][0]))
    # heads without a DMP ignore the state: act(obs) works
    ppo = ndp.load_policy(fixture_policy("soccer-v3-ppo"))
    assert not ppo.needs_robot_state and push.needs_robot_state
    s = _reference("soccer-v3-ppo")
    _close(ppo.act(s["obs"][0]), s["det"][0], "soccer-v3-ppo")


def test_recorded_spec_is_checked_field_by_field():
    rec = json.loads((fixture_policy("push-v3-ndp") / "policy.json").read_text())["spec"]
    spec = PolicySpec.from_record(rec)
    assert spec.controller is not None and spec.dmp_dofs == 4
    cases = [
        ({k: v for k, v in rec.items() if k != "control_dt"}, "missing field 'control_dt'"),
        ({**rec, "action_low": [-1.0] * 3}, "action_low: expected 4 values, got 3"),
        ({**rec, "dmp_dofs": True}, "dmp_dofs: expected int, got bool"),
        ({**rec, "action_scale": [0.01, 0.01, float("nan"), 0.0]}, "expected finite numbers"),
        ({**rec, "actuation": "hydraulic"}, "expected 'position' or 'torque'"),
    ]
    for bad, msg in cases:
        with pytest.raises(ValueError, match=msg):
            PolicySpec.from_record(bad, "spec")
    torque = json.loads((fixture_policy("throw-vices") / "policy.json").read_text())["spec"]
    tspec = PolicySpec.from_record(torque)
    assert tspec.actuation == "torque" and tspec.controller is None
    with pytest.raises(ValueError, match="torque-actuated"):
        tspec.inverse_controller(None)
