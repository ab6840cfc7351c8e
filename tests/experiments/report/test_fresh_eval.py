"""``ndp report --eval-episodes N --eval-seed S``: final policies re-scored on chosen seeds, in
the file ``ndp rl eval --save`` writes (either command reads the other's), the default seed
keeping its own cache file; the seeds named in the table, and the argument errors."""

from __future__ import annotations

import csv
import json

import pytest

from ndp.cli import main
from ndp.experiments.report import FreshEval, report
from ndp.experiments.report.markdown import fresh_seeds_note


def _det(out):
    with out.with_suffix(".csv").open() as fh:
        (row,) = list(csv.DictReader(fh))
    return float(row["det_success_mean"])


def test_report_rescores_on_other_seeds_in_the_file_ndp_rl_eval_saves(tmp_path):
    runs = tmp_path / "runs"
    run = runs / "point-mass-ndp-s0"
    assert main(["rl", "train", "--task", "point-mass", "--steps", "520",
                 "--steps-per-update", "512", "--vector", "sync", "--run-dir", str(run),
                 "--no-progress", "--no-tensorboard"]) == 0  # fmt: skip
    rep = ["report", str(runs), "--no-plots", "--eval-episodes", "2"]
    assert main([*rep, "--eval-seed", "20000", "--out", str(tmp_path / "a")]) == 0
    saved = run / "eval-det-e2-s20000.json"
    by_report = json.loads(saved.read_text())
    assert not (run / "eval-det-e2.json").exists()
    assert by_report["protocol"]["seeds"] == [20_000, 20_001]
    md = (tmp_path / "a.md").read_text()
    assert "seeds 20,000 to 20,001, disjoint from the periodic evaluation's fixed seeds" in md
    assert "--eval-seed 20000" in md  # the command
    # ndp rl eval --save writes the same file with the same content (but its time stamp)
    saved.unlink()
    assert main(["rl", "eval", str(run), "--episodes", "2", "--seed", "20000",
                 "--mode", "deterministic", "--save"]) == 0  # fmt: skip
    by_eval = json.loads(saved.read_text())
    assert by_eval.pop("evaluated_at") and by_report.pop("evaluated_at")
    assert by_eval == by_report
    # the report reads that file rather than evaluating again
    saved.write_text(json.dumps({**by_eval, "success_any": 0.5}))
    assert main([*rep, "--eval-seed", "20000", "--out", str(tmp_path / "b")]) == 0
    assert _det(tmp_path / "b") == 0.5
    # the default seed keeps the report's own cache, evaluate()'s dict from seed 10,000
    assert main([*rep, "--out", str(tmp_path / "c")]) == 0
    cache = json.loads((run / "eval-det-e2.json").read_text())
    assert "protocol" not in cache and _det(tmp_path / "c") == cache["success_any"]
    assert sorted(p.name for p in run.glob("eval-det-*.json")) == [
        "eval-det-e2-s20000.json",
        "eval-det-e2.json",
    ]
    md = (tmp_path / "c.md").read_text()
    assert "seeds 10,000 to 10,001, overlapping the periodic evaluation's fixed seeds" in md


@pytest.mark.parametrize(
    "argv,message",
    [
        (["--eval-seed", "20000"], "--eval-seed: needs --eval-episodes N > 0"),
        (["--eval-episodes", "0", "--eval-seed", "10000"], "--eval-seed: needs --eval-episodes"),
        (["--eval-episodes", "2", "--eval-seed", "-1"], "--eval-seed: expected a seed >= 0"),
        (["--eval-episodes", "-1"], "--eval-episodes: expected an integer >= 0"),
    ],
)
def test_eval_seed_errors_are_one_line_naming_the_option(tmp_path, capsys, argv, message):
    # checked before any run is read: tmp_path holds none ("no runs found" otherwise)
    assert main(["report", str(tmp_path), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_library_refuses_a_seed_without_episodes_and_names_the_overlap(tmp_path):
    with pytest.raises(ValueError, match="eval_seed: needs eval_episodes > 0"):
        report([tmp_path], tmp_path / "r", "cmd", eval_seed=20_000)
    with pytest.raises(ValueError, match="eval_seed: expected an integer >= 0"):
        FreshEval(2, -1)
    # the periodic evaluation's fixed seeds: 10,000 .. 10,009
    assert FreshEval(100, 10_000).overlaps_periodic()
    assert FreshEval(5, 9_996).overlaps_periodic() and not FreshEval(5, 9_995).overlaps_periodic()
    assert FreshEval(2, 10_009).overlaps_periodic()
    assert not FreshEval(2, 10_010).overlaps_periodic()
    assert fresh_seeds_note(FreshEval(100, 20_000)) == (
        "seeds 20,000 to 20,099, disjoint from the periodic evaluation's fixed seeds "
        "(10,000 to 10,009 by default)"
    )
    assert FreshEval(100).cache_name == "eval-det-e100.json"
    assert FreshEval(100, 20_000).cache_name == "eval-det-e100-s20000.json"
