"""The study file loader: a well-formed file gives the Study the sweep reads, and a malformed
one is refused with one line naming the file and the key."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ndp.experiments.studies import ArmSpec, Condition, Study
from ndp.experiments.studies.loader import (
    TASK_SETS,
    load_studies,
    load_study,
    register_task_set,
)

GOOD = '''
name = "tiny"
title = "A tiny study"
doc = """\\
two words \\
joined"""
tasks = ["point-mass"]
seeds = [0, 1]
steps = 4_096
budgets = [0.5, 1]
summary = ["over-tasks"]
readings = "ndp.experiments.report.regimes:regimes_readings"

[[arms]]
label = "ndp"
algo = "ndp"

[[arms]]
label = "ppo-k"
algo = "ppo"
args = ["--lr", "0.001"]
note = "PPO"
in_default = false
tasks = ["point-mass"]

[[conditions]]
name = "fair"
note = "both"
methods = [["ndp", "ndp"], ["ppo", "ppo-k"]]
unequal = true
overrides = [["point-mass", "ppo", "ppo-k"]]

[[selection]]
model = "ndp"
arms = ["ndp"]
'''


def _write(tmp_path: Path, text: str, name: str = "tiny.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _refused(tmp_path: Path, text: str, match: str) -> str:
    p = _write(tmp_path, text)
    with pytest.raises(ValueError) as e:
        load_study(p)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{p}: ")
    assert re.search(match, msg), msg
    return msg


def test_a_well_formed_file_gives_the_study(tmp_path):
    s = load_study(_write(tmp_path, GOOD))
    assert isinstance(s, Study)
    assert (s.name, s.title, s.doc) == ("tiny", "A tiny study", "two words joined")
    assert s.task_list() == ("point-mass",)
    assert (s.seeds, s.steps, s.kind, s.budgets) == ((0, 1), 4096, "rl", (0.5, 1.0))
    assert s.summary == ("over-tasks",)
    assert s.arm_specs() == (
        ArmSpec("ndp", "ndp"),
        ArmSpec("ppo-k", "ppo", ("--lr", "0.001"), "PPO", in_default=False, tasks=("point-mass",)),
    )
    assert s.conditions == (
        Condition("fair", "both", (("ndp", "ndp"), ("ppo", "ppo-k")), True,
                  (("point-mass", "ppo", "ppo-k"),)),
    )  # fmt: skip
    assert s.selection == (("ndp", ("ndp",)),)
    from ndp.experiments.report.regimes import regimes_readings

    assert s.readings_fn() is regimes_readings


def test_defaults_are_the_study_dataclass_defaults(tmp_path):
    text = 'name = "m"\ntitle = "t"\ndoc = "d"\ntasks = ["x"]\n[[arms]]\nlabel = "a"\nalgo = "x"\n'
    s = load_study(_write(tmp_path, text))
    assert (s.seeds, s.steps, s.kind, s.budgets) == ((0, 1, 2), 300_000, "rl", (0.25, 0.5, 1.0))
    assert (s.summary, s.conditions, s.selection, s.readings) == ((), (), (), None)


def test_unknown_keys_are_named_with_the_close_ones(tmp_path):
    _refused(tmp_path, GOOD.replace("seeds =", "sedes ="), r": sedes: unknown key .*mean seeds")
    _refused(tmp_path, GOOD.replace('note = "PPO"', 'nte = "PPO"'), r": arms\[1\]\.nte: unknown")
    _refused(tmp_path, GOOD.replace("unequal", "unequel"), r": conditions\[0\]\.unequel: unknown")
    _refused(tmp_path, GOOD.replace('model = "ndp"', 'models = "ndp"'), r"selection\[0\]\.models")


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("steps = 4_096", 'steps = "4096"', r": steps: expected an integer, got a string"),
        ("steps = 4_096", "steps = true", r": steps: expected an integer, got a boolean"),
        ("seeds = [0, 1]", "seeds = [0, 1.5]", r": seeds: expected a list of integers"),
        ('tasks = ["point-mass"]\nseeds', 'tasks = "point-mass"\nseeds',
         r": tasks: expected a list of strings, got a string"),
        ('args = ["--lr", "0.001"]', 'args = ["--lr", 0.001]', r": arms\[1\]\.args: expected a"),
        ("in_default = false", 'in_default = "no"', r": arms\[1\]\.in_default: expected true or"),
        ('[["ndp", "ndp"], ["ppo", "ppo-k"]]', '[["ndp"], ["ppo", "ppo-k"]]',
         r": conditions\[0\]\.methods: expected a list of \[method, arm label\] pairs"),
        ("budgets = [0.5, 1]", 'budgets = ["half"]', r": budgets: expected a list of numbers"),
        ('title = "A tiny study"', "title = 3", r": title: expected a string, got int"),
    ],
)  # fmt: skip
def test_wrong_types_are_named(tmp_path, old, new, match):
    assert old in GOOD
    _refused(tmp_path, GOOD.replace(old, new), match)


def test_missing_keys_and_bad_values_are_named(tmp_path):
    _refused(tmp_path, GOOD.replace('title = "A tiny study"\n', ""), r": title: missing")
    _refused(tmp_path, GOOD.replace('label = "ndp"\n', ""), r": arms\[0\]\.label: missing")
    _refused(tmp_path, GOOD.replace('tasks = ["point-mass"]\nseeds', "seeds"),
             r": tasks: give exactly one of tasks .* and task_set")  # fmt: skip
    _refused(tmp_path, GOOD.replace('tasks = ["point-mass"]\nseeds', 'task_set = "nope"\nseeds'),
             r": task_set: unknown task set 'nope' \(known: .*metaworld")  # fmt: skip
    entry = "ndp.experiments.report.regimes:regimes_readings"
    _refused(tmp_path, GOOD.replace(entry, "regimes_readings"), r": readings: .* is not")
    _refused(tmp_path, GOOD.replace("title", "title = 1\ntitle", 1), r"line 4")  # TOML syntax


def test_an_arm_label_defined_twice_is_refused(tmp_path):
    text = GOOD.replace('label = "ppo-k"', 'label = "ndp"')
    _refused(tmp_path, text, r": arms\[1\]\.label: arm 'ndp' is defined twice in study 'tiny'")


def test_a_study_name_defined_twice_is_refused_naming_both_files(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first = _write(tmp_path / "a", GOOD)
    second = _write(tmp_path / "b", GOOD, "other.toml")
    assert list(load_studies([first])) == ["tiny"]
    with pytest.raises(ValueError) as e:
        load_studies([first, second])
    assert str(e.value) == f"{second}: name: study 'tiny' is defined twice (also in {first})"


def test_a_registered_task_set_is_resolved_when_asked(tmp_path, monkeypatch):
    monkeypatch.setitem(TASK_SETS, "__probe", "no.such.module:tasks")
    text = GOOD.replace('tasks = ["point-mass"]\nseeds', 'task_set = "__probe"\nseeds')
    s = load_study(_write(tmp_path, text))  # nothing imported yet
    with pytest.raises(ValueError, match="does not name a function"):
        s.task_list()
    monkeypatch.setitem(TASK_SETS, "__probe", lambda: ["point-mass", "throw"])
    assert s.task_list() == ("point-mass", "throw")
    with pytest.raises(ValueError, match="task_set: '__probe' is registered already"):
        register_task_set("__probe", lambda: ())


def test_the_example_of_docs_architecture_loads(tmp_path):
    root = Path(__file__).resolve().parents[3]
    doc = (root / "docs" / "architecture.md").read_text()
    blocks = re.findall(r"^```toml\n(.*?)^```$", doc, re.MULTILINE | re.DOTALL)
    assert len(blocks) == 1
    s = load_study(_write(tmp_path, blocks[0], "my-study.toml"))
    assert s.name == "my-study" and [a.label for a in s.arm_specs()] == ["ndp-k10", "ppo-multi-k10"]
    assert s.conditions[0].methods == (("ndp", "ndp-k10"), ("ppo-multi", "ppo-multi-k10"))
