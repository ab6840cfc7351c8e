"""Model cards (README.md, Hugging Face format) of the zoo and of every export; the Wilson
interval they report."""

from __future__ import annotations

import json
import math

import pytest

import ndp
from ndp.experiments.report.stats import wilson_interval
from ndp.rl.card import NOT_RECORDED, card_fields, model_card, to_yaml
from policy_fixtures import fixture_index, fixture_names, fixture_policy, fixture_row

yaml = pytest.importorskip("yaml")

REQUIRED = (
    "library_name",
    "license",
    "tags",
    "task",
    "method",
    "success_rate",
    "success_rate_ci95",
    "episodes",
    "budget_env_steps",
    "seeds",
    "command",
    "commit",
)


def front_matter(text: str) -> dict:
    """The YAML between the card's first two ``---`` lines, parsed."""
    lines = text.splitlines()
    assert lines[0] == "---", lines[:2]
    end = lines.index("---", 1)
    data = yaml.safe_load("\n".join(lines[1:end]))
    assert isinstance(data, dict)
    body = "\n".join(lines[end + 1 :])
    assert body.strip().startswith("# "), body[:80]
    return data


def test_wilson_interval_against_hand_computed_values():
    z = 1.959963984540054
    # 40 of 50: p = 0.8, z^2 / n = 0.0768292, centre = (0.8 + 0.0384146) / 1.0768292 = 0.7785953,
    # half = z * sqrt(0.0032 + 0.000384146) / 1.0768292 = 0.1089665
    lo, hi = wilson_interval(40, 50)
    assert lo == pytest.approx(0.7785953 - 0.1089665, abs=1e-6)
    assert hi == pytest.approx(0.7785953 + 0.1089665, abs=1e-6)
    # 0 of 10 and 10 of 10: the closed forms [0, z^2 / (n + z^2)] and [n / (n + z^2), 1]
    assert wilson_interval(0, 10) == (0.0, pytest.approx(z * z / (10 + z * z), abs=1e-12))
    assert wilson_interval(10, 10) == (pytest.approx(10 / (10 + z * z), abs=1e-12), 1.0)
    # 1 of 2, z = 1.96: centre 0.5, half = 1.96 sqrt(0.125 + 0.2401) / 2.9208 = 0.405527...
    lo, hi = wilson_interval(1, 2, z=1.96)
    half = 1.96 * math.sqrt(0.125 + 1.96**2 / 16) / (1 + 1.96**2 / 2)
    assert (lo, hi) == (pytest.approx(0.5 - half, abs=1e-12), pytest.approx(0.5 + half, abs=1e-12))
    assert half == pytest.approx(0.4055, abs=1e-4)
    for bad in ((3, 2), (-1, 5), (1, 0), (1.5, 4)):
        with pytest.raises(ValueError):
            wilson_interval(*bad)


@pytest.mark.parametrize("name", fixture_names())
def test_every_fixture_card_has_the_required_front_matter_and_the_published_numbers(name):
    """The fixtures (the zoo's exports as they were, with its index of then): every card's
    numbers are its index row's; an export that predates recorded commands says so."""
    d = fixture_policy(name)
    data = front_matter((d / "README.md").read_text())
    assert [k for k in REQUIRED if k not in data] == []
    assert data["license"] == "mit" and data["library_name"] == "neural-dynamic-policies"
    assert "reinforcement-learning" in data["tags"]
    row, index = fixture_row(name), fixture_index()
    meta = json.loads((d / "policy.json").read_text())
    assert data["task"] == meta["task"] and data["method"] == meta["algo"] == row["method"]
    assert data["success_rate"] == pytest.approx(row["success"])
    assert data["episodes"] == index["episodes"] == 50
    lo, hi = wilson_interval(round(row["success"] * 50), 50)
    assert data["success_rate_ci95"] == [pytest.approx(lo, abs=1e-4), pytest.approx(hi, abs=1e-4)]
    assert data["budget_env_steps"] == row["steps"] == meta["config"]["steps"]
    assert data["seeds"] == [row["seed"]]
    assert data["commit"] == meta["commit"]
    assert data["command"] == NOT_RECORDED  # these exports predate recorded commands
    assert data["training_commits"] == (row["trained_at"] or NOT_RECORDED)
    assert data["evaluation_command"] == index["command"]
    result = data["model-index"][0]["results"][0]
    assert result["metrics"][0]["type"] == "success_rate"
    assert result["metrics"][0]["value"] == pytest.approx(row["success"])
    assert data["model-index"][0]["name"] == name


@pytest.mark.parametrize("name", ndp.zoo.list())
def test_every_zoo_card_has_the_required_front_matter_and_the_published_numbers(name):
    """Whatever the zoo holds: each card's numbers are zoo.json's (success, episodes, its
    Wilson interval, seed, evaluation command), its training record the export's."""
    data = front_matter(ndp.zoo.card(name))
    assert [k for k in REQUIRED if k not in data] == []
    assert data["license"] == "mit" and data["library_name"] == "neural-dynamic-policies"
    assert "reinforcement-learning" in data["tags"]
    row, index = ndp.zoo.info(name), ndp.zoo.index()
    meta = json.loads((ndp.zoo.path(name) / "policy.json").read_text())
    assert data["task"] == meta["task"] and data["method"] == meta["algo"] == row["method"]
    assert 0.0 <= row["success"] <= 1.0
    assert data["success_rate"] == pytest.approx(row["success"])
    n = index["episodes"]
    assert data["episodes"] == n and n >= 1
    lo, hi = wilson_interval(round(row["success"] * n), n)
    assert data["success_rate_ci95"] == [pytest.approx(lo, abs=1e-4), pytest.approx(hi, abs=1e-4)]
    training = meta.get("training") or {}
    trained = training.get("env_steps_trained")
    steps = trained if isinstance(trained, int) else meta["config"]["steps"]
    assert data["budget_env_steps"] == steps and row["steps"] == meta["config"]["steps"]
    assert data["seeds"] == [row["seed"]]
    assert data["commit"] == meta["commit"]
    commands = training.get("commands") or []
    assert data["command"] == (commands[0] if len(commands) == 1 else commands or NOT_RECORDED)
    commits = training.get("commits") or row["trained_at"]
    assert data["training_commits"] == ([str(c) for c in commits] or NOT_RECORDED)
    assert data["evaluation_command"] == index["command"]
    result = data["model-index"][0]["results"][0]
    assert result["metrics"][0]["type"] == "success_rate"
    assert result["metrics"][0]["value"] == pytest.approx(row["success"])
    assert data["model-index"][0]["name"] == name


def test_an_export_card_says_not_recorded_and_reports_a_cached_evaluation(tmp_path):
    from ndp.rl.policy import cached_evaluation

    meta = json.loads((fixture_policy("throw-ndp") / "policy.json").read_text())
    bare = front_matter(model_card(meta, None, "mine"))
    assert [k for k in REQUIRED if k not in bare] == []
    for key in ("success_rate", "success_rate_ci95", "episodes", "command"):
        assert bare[key] == NOT_RECORDED, key
    assert "model-index" not in bare  # the Hub's results need a measured value
    # a run's cached deterministic evaluation (ndp report) is found and reported
    (tmp_path / "eval-det-e20.json").write_text(json.dumps({"success_any": 0.85}))
    (tmp_path / "eval-det-e5.json").write_text(json.dumps({"success_any": 1.0}))
    (tmp_path / "eval-det-ex.json").write_text("{")
    ev = cached_evaluation(tmp_path)
    assert ev["success"] == 0.85 and ev["episodes"] == 20
    meta["training"] = {"commands": ["ndp rl train --task throw --algo ndp"], "commits": ["abc"]}
    data = front_matter(model_card(meta, ev, "mine"))
    assert data["success_rate"] == 0.85 and data["episodes"] == 20
    assert data["success_rate_ci95"] == [round(x, 4) for x in wilson_interval(17, 20)]
    assert data["command"] == "ndp rl train --task throw --algo ndp"
    assert data["training_commits"] == ["abc"]
    assert card_fields(meta, ev)["model-index"][0]["name"] == "throw-ndp"


def test_the_yaml_writer_round_trips_awkward_strings():
    data = {
        "a": 'quote " and \\ backslash: colon # hash',
        "b": ["x: y", "- dash", "ünïcode", "", "null", "true", "1e5"],
        "c": {"d": [{"e": 1.5, "f": None, "g": False}], "h": []},
        "i": -0.0,
        "j": "line\nbreak",
    }
    assert yaml.safe_load(to_yaml(data)) == data


def test_cards_name_the_robot_state_the_policy_reads():
    """A policy whose DMP starts from the commanded state is not described with the measured
    source (the Jaco cards said 'from MuJoCo qpos/qvel'); every card links the observation
    layout."""
    import json

    from ndp.rl.card import COMMANDED_SOURCE
    from ndp.zoo import root

    for name in ("throw-ndp", "push-v3-ndp"):
        d = root() / name
        meta = json.loads((d / "policy.json").read_text())
        card = (d / "README.md").read_text()
        assert "docs/observations.md" in card
        if meta["config"]["policy"]["dmp_state"] == "commanded":
            assert COMMANDED_SOURCE in card and "from MuJoCo qpos/qvel" not in card
        else:
            assert meta["spec"]["y0_source"] in card


def test_every_export_writes_a_card_and_a_re_export_keeps_its_results(tmp_path):
    """The ONNX export writes a card too, with the evaluation it is given; a re-export of an
    export (given no evaluation) keeps the source's success figures and commit; cards link no
    page that does not exist (the package is not on PyPI)."""
    import json

    import ndp

    src = ndp.load_policy(fixture_policy("push-v3-ndp"))
    zoo_card = (fixture_policy("push-v3-ndp") / "README.md").read_text()
    assert "success_rate: 0.8" in zoo_card
    again = src.export(tmp_path / "again")
    card = (again / "README.md").read_text()
    meta = json.loads((again / "policy.json").read_text())
    assert "success_rate: 0.8" in card and "episodes: 50" in card
    assert meta["evaluation"]["success"] == 0.8 and meta["commit"] == "35cbbe6"
    assert 'commit: "35cbbe6"' in card
    onnx = src.export(tmp_path / "onnx", evaluation={"success": 0.5, "episodes": 10},
                      format="onnx")  # fmt: skip
    ocard = (onnx / "README.md").read_text()
    assert "success_rate: 0.5" in ocard and "episodes: 10" in ocard
    assert "OnnxPolicy" in ocard and "make_env" not in ocard
    for text in (card, ocard, zoo_card):
        assert "pypi.org" not in text


def _check_eval_results(folder, row: dict, index: dict) -> None:
    yaml = pytest.importorskip("yaml")
    task = json.loads((folder / "policy.json").read_text())["task"]  # VICES: torque
    files = list((folder / ".eval_results").glob("*.yaml"))
    assert [f.name for f in files] == [f"{task}.yaml"]
    (entry,) = yaml.safe_load(files[0].read_text())
    assert entry["dataset"] == {"id": f"ndp/{task}", "task_id": "success_any_deterministic"}
    assert entry["value"] == pytest.approx(row["success"])
    assert entry["date"] == index["date"]
    assert f"{index['episodes']} episodes" in entry["notes"] and "Wilson" in entry["notes"]


@pytest.mark.parametrize("name", ndp.zoo.list())
def test_every_zoo_policy_has_its_hub_eval_results_with_the_cards_number(name):
    _check_eval_results(ndp.zoo.path(name), ndp.zoo.info(name), ndp.zoo.index())


@pytest.mark.parametrize("name", fixture_names())
def test_every_fixture_policy_has_its_hub_eval_results_with_the_cards_number(name):
    index = fixture_index()
    assert index["episodes"] == 50  # as the fixtures were published
    _check_eval_results(fixture_policy(name), fixture_row(name), index)


def test_an_export_without_results_writes_no_eval_results_and_a_measured_one_does(tmp_path):
    yaml = pytest.importorskip("yaml")
    from ndp.rl.card import EVAL_RESULTS_DIR, eval_results, write_card

    meta = json.loads((fixture_policy("throw-ndp") / "policy.json").read_text())
    assert eval_results(meta, None) == {}
    out = tmp_path / "exp"
    out.mkdir()
    write_card(
        out, meta, {"success": 0.75, "episodes": 20, "first_seed": 10_000}, date="2026-01-02"
    )
    (entry,) = yaml.safe_load((out / EVAL_RESULTS_DIR / "throw.yaml").read_text())
    assert entry["value"] == 0.75 and entry["date"] == "2026-01-02"
    assert "from seed 10000" in entry["notes"]
    write_card(out, meta, None)  # re-written without results: the stale file goes
    assert not (out / EVAL_RESULTS_DIR).exists()
    assert (out / "README.md").is_file()


@pytest.mark.parametrize("fmt", ["safetensors", "onnx"])
def test_an_export_never_overwrites_a_file_nor_lands_in_a_run_folder(tmp_path, fmt):
    """A folder holding a README.md (a user's project), an earlier card's .eval_results/, or a
    training run (checkpoint, metrics, config): refused before anything is written, naming
    out_dir; the files there are unchanged."""
    src = ndp.load_policy(fixture_policy("push-v3-ndp"))
    for name, text in (("README.md", "mine\n"), ("checkpoint.pt", "ckpt"),
                       ("metrics.csv", "update\n"), ("config.json", "{}\n")):  # fmt: skip
        out = tmp_path / f"{fmt}-{name}"
        out.mkdir()
        (out / name).write_text(text)
        with pytest.raises(FileExistsError, match=r"^out_dir: .* (already holds|is a training)"):
            src.export(out, format=fmt)
        assert sorted(p.name for p in out.iterdir()) == [name]
        assert (out / name).read_text() == text
    results = tmp_path / f"{fmt}-results"
    (results / ".eval_results").mkdir(parents=True)
    with pytest.raises(FileExistsError, match=r"already holds \.eval_results"):
        src.export(results, format=fmt)
    first = src.export(tmp_path / f"{fmt}-new", format=fmt)  # a new folder: written
    other = "safetensors" if fmt == "onnx" else "onnx"
    with pytest.raises(FileExistsError, match="already holds"):  # not a second format beside it
        src.export(first, format=other)


@pytest.mark.parametrize("fmt", ["safetensors", "onnx"])
def test_a_card_names_the_files_its_folder_holds_and_the_graphs_dtypes(tmp_path, fmt):
    """Every file the card's 'Files:' line names is in the folder; the ONNX card states the
    graph's real input dtype (float32: feeding float64 is onnxruntime's INVALID_ARGUMENT)."""
    import re

    out = ndp.load_policy(fixture_policy("push-v3-ndp")).export(tmp_path / fmt, format=fmt)
    card = (out / "README.md").read_text()
    files_line = next(line for line in card.splitlines() if line.startswith("Files:"))
    named = set(re.findall(r"`([\w.]+\.(?:onnx|json|safetensors))`", files_line))
    assert named and named <= {p.name for p in out.iterdir()}, (named, files_line)
    if fmt == "onnx":
        onnx = pytest.importorskip("onnx")
        graph = onnx.load(str(out / "policy.onnx")).graph
        elem = {i.name: i.type.tensor_type.elem_type for i in graph.input}
        assert set(elem.values()) == {onnx.TensorProto.FLOAT}, elem
        assert "float64" not in card and "[E, D], float32" in card


def test_an_export_card_reads_the_saved_fresh_evaluation(tmp_path):
    """ndp rl eval --save's file reaches the export's card (the largest episode count), with the
    command that made it and its seeds."""
    from ndp.rl.policy import cached_evaluation

    run = tmp_path / "run"
    run.mkdir()
    (run / "eval-det-e10.json").write_text(json.dumps({"success_any": 0.3}))
    (run / "eval-det-e100-s20000.json").write_text(json.dumps({"success_any": 0.42}))
    ev = cached_evaluation(run)
    assert ev is not None and ev["episodes"] == 100 and ev["first_seed"] == 20000
    assert ev["success"] == 0.42 and "--seed 20000 --save" in ev["command"]


def test_card_and_progress_report_the_env_steps_trained_not_the_request(tmp_path):
    """--steps 300 trains whole updates (here 2,048 env steps): the export's card says what was
    trained (from run.json), and the progress bar's total is the same number."""
    from ndp.rl.config import PPOConfig, TrainConfig
    from ndp.rl.policy import export_policy
    from ndp.rl.progress import TrainProgress
    from ndp.rl.run import train

    cfg = TrainConfig(task="point-mass", algo="ppo", steps=300, num_envs=2, vector="sync",
                      run_dir=str(tmp_path / "run"), progress=False, tensorboard=False,
                      eval_every=0, steps_per_update=512, ppo=PPOConfig(minibatches=2))  # fmt: skip
    train(cfg)
    trained = cfg.num_updates * cfg.env_steps_per_update
    assert trained == 512 != cfg.steps
    card = (export_policy(tmp_path / "run", tmp_path / "out") / "README.md").read_text()
    assert "budget_env_steps: 512" in card
    with TrainProgress(tmp_path / "p", ["update", "global_step"], cfg, 0, 0, False) as prog:
        assert prog.bar.total == 512


def test_a_card_lists_the_training_command_every_setting_and_the_citation():
    from ndp.rl.card import BIBTEX, hyperparameters

    meta = json.loads((fixture_policy("throw-ndp") / "policy.json").read_text())
    meta["training"] = {"commands": ["ndp rl train --task throw --algo ndp --seed 0"],
                        "commits": ["abc1234"], "env_steps_trained": 300_000}  # fmt: skip
    card = model_card(meta)
    training = card.split("## Training")[1].split("## Citation")[0]
    assert "```bash\nndp rl train --task throw --algo ndp --seed 0\n```" in training
    assert "Commits: abc1234; trained: 300,000 env steps." in training
    rows = hyperparameters(meta["config"])
    # every leaf of the resolved config, nested sections dotted, each a row of the table
    assert ("policy.k", meta["config"]["policy"]["k"]) in rows
    assert len(rows) >= 20 and len({k for k, _ in rows}) == len(rows)
    for key, value in rows:
        assert f"| `{key}` | `{json.dumps(value)}` |" in training
    assert "```bibtex\n" + BIBTEX + "\n```" in card and "@inproceedings{bahl2020ndp," in BIBTEX
    assert "https://github.com/shikharbahl/neural-dynamic-policies" in card
    # an export without a recorded command says so instead of an empty block
    meta["training"] = {}
    assert "Command: not recorded" in model_card(meta).split("## Training")[1]


def test_a_card_shows_the_replay_beside_it_only_when_the_folder_holds_one(tmp_path):
    from ndp.rl.card import REPLAY_NAME, write_card

    meta = json.loads((fixture_policy("throw-ndp") / "policy.json").read_text())
    write_card(tmp_path, meta, None)
    assert REPLAY_NAME not in (tmp_path / "README.md").read_text()
    (tmp_path / REPLAY_NAME).write_bytes(b"GIF89a")
    write_card(tmp_path, meta, None)
    result = (tmp_path / "README.md").read_text().split("## Result")[1].split("## Use")[0]
    assert f"![one episode, deterministic actions]({REPLAY_NAME})" in result
