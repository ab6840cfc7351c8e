"""`ndp rl eval --save`: the evaluation written into the run with its protocol and interval."""

from __future__ import annotations

import json

import pytest

from ndp.rl.evaluate import save_evaluation, wilson_interval


@pytest.mark.parametrize(
    "k,n,low,high",
    [
        (0, 10, 0.0, 0.2775),
        (5, 10, 0.2366, 0.7634),
        (10, 10, 0.7225, 1.0),
        (37, 100, 0.2818, 0.4678),
    ],
)
def test_wilson_interval_matches_published_values(k, n, low, high):
    """Values of the Wilson score interval at 95% (Newcombe 1998, table I; 37/100 as
    statsmodels' proportion_confint gives it)."""
    lo, hi = wilson_interval(k, n)
    assert lo == pytest.approx(low, abs=1e-4) and hi == pytest.approx(high, abs=1e-4)


def test_wilson_interval_refuses_bad_counts():
    with pytest.raises(ValueError, match="n: expected an integer >= 1"):
        wilson_interval(0, 0)
    with pytest.raises(ValueError, match=r"successes: expected an integer in 0..5"):
        wilson_interval(6, 5)


def test_save_evaluation_writes_protocol_and_interval(tmp_path):
    result = {"episodes": 100, "deterministic": True, "success_any": 0.37, "success_final": 0.2,
              "episode_return": 1.0, "episode_length": 150.0, "exec_k": 5, "m": 1}  # fmt: skip
    path = save_evaluation(tmp_path, result, 20_000)
    assert path.name == "eval-det-e100-s20000.json"
    data = json.loads(path.read_text())
    assert data["protocol"]["seeds"] == [20_000, 20_099]
    assert data["success_any_count"] == 37
    assert data["success_any_wilson95"] == pytest.approx([0.2818, 0.4678], abs=1e-4)
    # the same protocol again replaces the file; another seed is another file
    save_evaluation(tmp_path, {**result, "success_any": 0.5}, 20_000)
    assert json.loads(path.read_text())["success_any_count"] == 50
    assert save_evaluation(tmp_path, result, 10_000).name == "eval-det-e100-s10000.json"
    sto = save_evaluation(tmp_path, {**result, "deterministic": False, "exec_k": 25, "m": 5}, 1)
    assert sto.name == "eval-sto-e100-s1-k25.json"


def test_zoo_policies_get_a_clean_default_folder_and_no_saved_evaluation(tmp_path):
    from ndp.rl.evaluate import default_output_dir

    assert default_output_dir("zoo:push-v3-ndp").as_posix() == "push-v3-ndp"
    assert default_output_dir(tmp_path) == tmp_path
    with pytest.raises(ValueError, match="run_dir: --save writes into a run directory"):
        save_evaluation("zoo:push-v3-ndp", {"episodes": 1, "deterministic": True,
                                            "success_any": 1.0}, 0)  # fmt: skip


def test_cli_eval_save_refuses_a_zoo_policy_before_evaluating(capsys):
    from ndp.cli import main

    assert main(["rl", "eval", "zoo:push-v3-ndp", "--episodes", "1", "--save"]) != 0
    assert "run_dir: --save writes into a run directory" in capsys.readouterr().err
