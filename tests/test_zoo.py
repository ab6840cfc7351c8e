"""The published trained policies (zoo/, made by benchmarks/zoo.py) load and act."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

ZOO = Path(__file__).resolve().parents[1] / "zoo"
META = json.loads((ZOO / "zoo.json").read_text()) if (ZOO / "zoo.json").is_file() else None
POLICIES = [r["policy"] for r in META["policies"]] if META else []


def test_the_index_lists_exactly_the_published_directories():
    assert META is not None, "zoo/zoo.json is missing (python benchmarks/zoo.py)"
    dirs = sorted(p.name for p in ZOO.iterdir() if p.is_dir() and not p.name.startswith("."))
    assert sorted(POLICIES) == dirs
    readme = (ZOO / "README.md").read_text()
    for name in POLICIES:
        assert f"`{name}`" in readme, name
    assert META["commit"] and META["command"].startswith("python benchmarks/zoo.py")


@pytest.mark.parametrize("name", POLICIES)
def test_a_published_policy_loads_and_acts_in_its_env(name):
    from ndp import load_policy

    row = next(r for r in META["policies"] if r["policy"] == name)
    pol = load_policy(ZOO / name)
    # VICES acts in the torque-actuated variant of its task (e.g. throw-joint)
    assert pol.spec.name in (row["task"], f"{row['task']}-joint", f"{row['task']}-osc")
    env = pol.make_env()
    try:
        obs, info = env.reset(seed=0)
        pol.reset()
        act = pol.act(obs, info, deterministic=True)
        assert act.shape == (pol.exec_k, pol.spec.action_dim)
        low, high = np.asarray(pol.spec.action_low), np.asarray(pol.spec.action_high)
        assert np.isfinite(act).all() and (act >= low - 1e-6).all() and (act <= high + 1e-6).all()
        env.step(act)
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize("name", POLICIES)
def test_a_published_policy_reaches_its_published_success(name):
    from ndp import load_policy
    from ndp.rl.evaluate import evaluate_policy

    row = next(r for r in META["policies"] if r["policy"] == name)
    ev = evaluate_policy(load_policy(ZOO / name), META["episodes"], True, 20_000)
    assert abs(ev["success_any"] - row["success"]) <= 0.1, (ev, row)


def _zoo_script():
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "bench_zoo", Path(__file__).resolve().parents[1] / "benchmarks" / "zoo.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_zoo_script_refuses_bad_grids_before_writing_anything(tmp_path, capsys):
    zoo = _zoo_script()
    runs, out = tmp_path / "runs", tmp_path / "zoo"
    runs.mkdir()
    (runs / "push-v3-ndp-s0").mkdir()
    (runs / "push-v3-ndp-s0" / "metrics.csv").write_text("update\n")
    cases = [
        (["--tasks", "psh-v3"], "--tasks: task: unknown"),  # with the close match
        (["--tasks", "soccer-v3"], "--runs-dir: no runs of soccer-v3 x"),
    ]
    for extra, msg in cases:
        with pytest.raises(SystemExit) as exc:
            zoo.main(["--runs-dir", str(runs), "--out", str(out), *extra])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert msg in err, err
    # an index listing a policy outside the grid: refused unless --replace-index
    out.mkdir()
    (out / "throw-ppo").mkdir()
    row = {"policy": "throw-ppo", "task": "throw", "method": "ppo"}
    (out / "zoo.json").write_text(json.dumps({"policies": [row]}))
    with pytest.raises(SystemExit) as exc:
        zoo.main(["--runs-dir", str(runs), "--out", str(out), "--tasks", "push-v3"])
    assert exc.value.code == 2
    assert "lists policies this grid does not cover (throw-ppo)" in capsys.readouterr().err
    # a grid whose runs are all unfinished writes nothing (the index and policy stay)
    with pytest.raises(SystemExit, match="no finished runs of this grid"):
        zoo.main(["--runs-dir", str(runs), "--out", str(out), "--tasks", "push-v3", "throw"])
    assert json.loads((out / "zoo.json").read_text()) == {"policies": [row]}
    assert (out / "throw-ppo").is_dir()
