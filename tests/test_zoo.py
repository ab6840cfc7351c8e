"""The published trained policies (package data ndp/zoo/policies, zoo/ in a checkout; made by
benchmarks/zoo.py) load and act, by path and by name, also from a built wheel."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest

import ndp

ROOT = Path(__file__).resolve().parents[1]
ZOO = Path(str(ndp.zoo.root()))
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
    assert ndp.zoo.list() == POLICIES
    # the checkout's zoo/ is the package's folder
    assert (ROOT / "zoo").resolve() == ZOO.resolve()


@pytest.mark.parametrize("name", POLICIES)
def test_every_zoo_card_shows_command_commit_steps_and_a_measured_evaluation(name):
    import re

    card = (ZOO / name / "README.md").read_text()
    head = card.split("---")[1]
    fields = dict(re.findall(r"^([a-z_0-9]+): (.*)$", head, flags=re.M))
    assert fields["command"].startswith('"ndp rl train '), fields["command"]
    assert re.fullmatch(r'\["[0-9a-f]{7,40}"\]', fields["training_commits"]), fields
    assert int(fields["budget_env_steps"]) > 0
    assert 0.0 <= float(fields["success_rate"]) <= 1.0 and int(fields["episodes"]) >= 50
    assert "not recorded" not in head, head
    row = next(r for r in META["policies"] if r["policy"] == name)
    # the policy is a seed of a multi-seed study, said on the card
    assert row["seed_context"]["seeds"] and f"Seed {row['seed']} of " in card


def test_zoo_names_load_and_unknown_names_are_one_line_with_close_names():
    pol = ndp.load_policy("zoo:push-v3-ndp")
    assert pol.cfg.task == "push-v3" and pol.cfg.algo == "ndp"
    assert ndp.zoo.path("zoo:push-v3-ndp") == ndp.zoo.path("push-v3-ndp") == ZOO / "push-v3-ndp"
    row = next(r for r in ndp.zoo.index()["policies"] if r["policy"] == "throw-ndp")
    assert ndp.zoo.info("throw-ndp") == row and 0.0 <= row["success"] <= 1.0
    for bad, close in (("zoo:push-v3-npd", "push-v3-ndp"), ("zoo:trow-ppo", "throw-ppo")):
        with pytest.raises(ValueError) as exc:
            ndp.load_policy(bad)
        msg = str(exc.value)
        assert "\n" not in msg and close in msg and "ndp.zoo.list()" in msg, msg
    with pytest.raises(ValueError, match="none close"):
        ndp.zoo.card("zzzzzzzz")


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


def _fake_run(root: Path, name: str, evals: list[float]) -> None:
    """A finished RL run directory whose periodic deterministic evaluations are ``evals``."""
    d = root / name
    d.mkdir(parents=True)
    manifest = {"kind": "rl", "task": name.split("-")[0], "label": "x", "seed": 0,
                "budget": 100, "unit": "env_steps", "done": 100, "finished": True,
                "reason": "budget"}  # fmt: skip
    (d / "run.json").write_text(json.dumps(manifest))
    _write_metrics(d, evals)


def _write_metrics(d: Path, evals: list[float], seconds: str | None = None) -> None:
    """``d``'s metrics.csv: one row per evaluation; ``seconds``: also the wall-clock columns."""
    timing = ",time/update_s,charts/env_steps_per_s" if seconds is not None else ""
    lines = ["update,global_step,eval/success_any" + timing]
    cells = f",{seconds},{seconds}" if seconds is not None else ""
    lines += [f"{i + 1},{(i + 1) * 10},{v}{cells}" for i, v in enumerate(evals)]
    (d / "metrics.csv").write_text("\n".join(lines) + "\n")


def test_the_best_method_rule_picks_the_highest_mean_area_and_needs_every_seed(tmp_path):
    zoo = _zoo_script()
    a, b = tmp_path / "a", tmp_path / "b"
    # ndp: areas 0.2 / 0.4 (mean 0.3); ppo: 0.5 / 0.3 (mean 0.4), its seed 1 in a second folder
    _fake_run(a, "throw-ndp-s0", [0.0, 0.4])
    _fake_run(a, "throw-ndp-s1", [0.4, 0.4])
    _fake_run(a, "throw-ppo-s0", [0.5, 0.5])
    _fake_run(b, "throw-ppo-s1", [0.2, 0.4])
    # sac lacks seed 1: not a candidate
    _fake_run(b, "throw-sac-s0", [1.0, 1.0])
    chosen, ctx = zoo.choose_methods([a, b], "throw", ["ndp", "ppo", "sac"], [0, 1], ["ndp"])
    assert chosen == ["ppo", "ndp"]
    assert set(ctx) == {"ndp", "ppo"}
    assert ctx["ppo"]["mean"] == pytest.approx(0.4)
    assert ctx["ndp"]["det_area"] == {0: pytest.approx(0.2), 1: pytest.approx(0.4)}
    # the card's sentence names the seed, the seed count, the IQM and this seed's area
    row = {"seed": 1, "seed_context": {"seeds": [0, 1], **ctx["ndp"], "best_method": False}}
    text = zoo.seed_context_text(row)
    assert text.startswith("Seed 1 of 2 (0, 1);") and "this seed 0.40" in text
    assert "2-seed IQM 0.30" in text and "best method" not in text
    # seed 0 alone: ppo 0.5 against ndp 0.2; a task without runs chooses nothing
    chosen, _ = zoo.choose_methods([a, b], "throw", ["ppo", "ndp"], [0], [])
    assert chosen == ["ppo"]
    assert zoo.choose_methods([a], "push-v3", ["ndp"], [0], ["ndp"]) == ([], {})


def test_final_eval_selection_and_a_rerun_published_only_when_it_reproduces(tmp_path):
    zoo = _zoo_script()
    a, again = tmp_path / "a", tmp_path / "again"
    # final evaluations 0.6 / 0.6 / 0.2: seeds 0 and 1 tie, seed 1's area is higher
    _fake_run(a, "push-v3-ndp-nostale-s0", [0.0, 0.6])
    _fake_run(a, "push-v3-ndp-nostale-s1", [0.4, 0.6])
    _fake_run(a, "push-v3-ndp-nostale-s2", [1.0, 0.2])
    seed, run, sel = zoo.pick_best([a], "push-v3", "ndp-nostale", [0, 1, 2], 20, "final-eval")
    assert (seed, run.name, sel) == (1, "push-v3-ndp-nostale-s1", pytest.approx(0.6))
    # an archived run (no checkpoint): refused with the command that trains it again
    prov = [{"argv": ["/x/src/ndp/cli.py", "rl", "train", "--task", "push-v3", "--seed", "1",
                      "--run-dir", str(run)], "commit": "7b7d5e46d0"}]  # fmt: skip
    (run / "provenance.json").write_text(json.dumps(prov))
    with pytest.raises(SystemExit) as exc:
        zoo.exportable(run, again)
    msg = str(exc.value)
    assert "holds no checkpoint" in msg and "git checkout 7b7d5e4 && ndp rl train" in msg, msg
    run_dir = msg.split("--run-dir ")[1]  # portable: no machine path, whatever the cwd
    assert run_dir.endswith("again/push-v3-ndp-nostale-s1") and not run_dir.startswith("/")
    # a re-run whose learning metrics differ is not the study's policy
    _fake_run(again, run.name, [0.4, 0.7])
    (again / run.name / "checkpoint.pt").write_bytes(b"")
    with pytest.raises(SystemExit, match="does not reproduce"):
        zoo.exportable(run, again)
    # the same rows up to the wall-clock columns: published from the re-run
    for d, secs in ((run, "1.5"), (again / run.name, "2.5")):
        _write_metrics(d, [0.4, 0.6], secs)
    assert zoo.exportable(run, again) == (again / run.name, True)
    # a run with its checkpoint is exported as it is
    (run / "checkpoint.pt").write_bytes(b"")
    assert zoo.exportable(run, None) == (run, False)


def test_method_names_map_to_run_labels(tmp_path, capsys):
    zoo = _zoo_script()
    a = tmp_path / "a"
    _fake_run(a, "throw-ndp-nostale-s0", [0.2, 0.4])
    _fake_run(a, "throw-ppo-s0", [0.5, 0.5])
    arms = {"ndp": "ndp-nostale", "ppo": "ppo"}
    chosen, ctx = zoo.choose_methods([a], "throw", ["ndp", "ppo"], [0], ["ndp"], arms)
    assert chosen == ["ppo", "ndp"] and ctx["ndp"]["mean"] == pytest.approx(0.3)
    with pytest.raises(SystemExit) as exc:
        zoo.main(["--runs-dir", str(a), "--out", str(tmp_path / "z"), "--methods", "ndp=",
                  "--tasks", "throw"])  # fmt: skip
    assert exc.value.code == 2
    assert "--methods: expected NAME or NAME=LABEL, got ndp=" in capsys.readouterr().err


WHEEL_SCRIPT = r"""
import sys

sys.path.insert(0, SITE)  # the unpacked wheel, ahead of any other ndp
import ndp

assert ndp.__file__.startswith(SITE), ndp.__file__
assert len(ndp.zoo.list()) == N_POLICIES == len(ndp.zoo.index()["policies"])
pol = ndp.load_policy("zoo:push-v3-ndp")
import numpy as np

act = pol.act(np.zeros(39), ndp.RobotState(np.zeros(4), np.zeros(4)))
assert act.shape == (pol.exec_k, 4), act.shape
assert ndp.zoo.card("throw-ndp").startswith("---")
print("WHEEL OK", str(ndp.zoo.path("push-v3-ndp")))
"""


def test_the_wheel_ships_the_zoo_and_loads_it_by_name(tmp_path):
    """``pip wheel`` of a copy of the source (no build isolation: the installed setuptools, no
    network; the build's folders stay out of the checkout), then the wheel unpacked as an
    install would and used from another directory: zoo:push-v3-ndp by name."""
    import shutil

    source, wheels = tmp_path / "source", tmp_path / "wheels"
    source.mkdir()
    for f in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy2(ROOT / f, source / f)
    junk = shutil.ignore_patterns("__pycache__", "*.egg-info", "*.pyc")
    shutil.copytree(ROOT / "src", source / "src", ignore=junk)
    r = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
         "-w", str(wheels), str(source)],
        capture_output=True, text=True, timeout=600, check=False, cwd=tmp_path,
    )  # fmt: skip
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    (wheel,) = wheels.glob("neural_dynamic_policies-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        for name in POLICIES:
            for f in ("policy.json", "policy.safetensors", "README.md"):
                assert f"ndp/zoo/policies/{name}/{f}" in names, (name, f)
        assert {"ndp/zoo/__init__.py", "ndp/zoo/policies/zoo.json"} <= names
        assert "ndp/zoo/policies/README.md" in names
        site = tmp_path / "site"
        zf.extractall(site)
    work = tmp_path / "elsewhere"
    work.mkdir()
    script = WHEEL_SCRIPT.replace("SITE", repr(str(site))).replace("N_POLICIES", str(len(POLICIES)))
    r = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        capture_output=True, text=True, timeout=300, check=False, cwd=work,
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"OMP_NUM_THREADS": "1"},
    )  # fmt: skip
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    assert f"WHEEL OK {site}" in r.stdout
