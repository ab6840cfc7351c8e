"""``ndp rl train``'s habits: --config FILE (a run's config.json or a YAML / JSON
hyperparameter file, options overriding it), --algo X --help showing X's options only, and a
learner's option that X does not read refused naming the methods that do."""

from __future__ import annotations

import json

import pytest

from ndp.cli import main
from ndp.rl.cli import config_from_file, unread_learner_message


def test_config_file_yaml_and_json_with_options_overriding(tmp_path, capsys):
    hp = tmp_path / "hp.yaml"
    hp.write_text("task: point-mass\nalgo: ppo-multi\nppo:\n  lr: 0.0001\npolicy:\n  k: 4\n")
    cfg = config_from_file(str(hp))
    assert (cfg.task, cfg.algo, cfg.ppo.lr, cfg.policy.k) == ("point-mass", "ppo-multi", 1e-4, 4)
    # a run's config.json: everything taken, its run_dir not reused
    saved = tmp_path / "config.json"
    saved.write_text(json.dumps({**cfg.to_dict(), "run_dir": str(tmp_path / "old")}))
    again = config_from_file(str(saved))
    assert again.run_dir is None and again.ppo.lr == 1e-4
    assert "its run_dir is not reused" in capsys.readouterr().err
    run = tmp_path / "run"
    argv = ["rl", "train", "--config", str(hp), "--steps", "64", "--num-envs", "2",
            "--ppo.lr", "0.0003", "--run-dir", str(run), "--no-progress", "--no-tensorboard",
            "--vector", "sync", "--eval-every", "0"]  # fmt: skip
    code = main(argv)
    if code == 2 and "--ppo.lr" in capsys.readouterr().err:  # the flat option name
        argv[argv.index("--ppo.lr")] = "--lr"
        code = main(argv)
    assert code == 0
    written = json.loads((run / "config.json").read_text())
    assert written["algo"] == "ppo-multi" and written["policy"]["k"] == 4
    assert written["ppo"]["lr"] == 3e-4  # the command line overrides the file


def test_config_file_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("ppo:\n  lrr: 0.1\n")
    with pytest.raises(ValueError, match=r"^config: unknown field 'ppo.lrr' \(known here: "):
        config_from_file(str(bad))
    with pytest.raises(ValueError, match=r"^config: expected a .json, .yaml or .yml file"):
        config_from_file(str(tmp_path / "hp.toml"))
    with pytest.raises(ValueError, match=r"^config: cannot read "):
        config_from_file(str(tmp_path / "absent.yaml"))
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match=r"expected a mapping of fields, got list"):
        config_from_file(str(tmp_path / "list.yaml"))
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(ValueError, match=r"is not valid JSON"):
        config_from_file(str(tmp_path / "broken.json"))


def test_help_of_one_algorithm_shows_only_its_options(capsys):
    assert main(["rl", "train", "--algo", "ppo", "--help"]) == 0
    ppo = capsys.readouterr().out
    assert main(["rl", "train", "--algo", "sac", "--help"]) == 0
    sac = capsys.readouterr().out
    assert main(["rl", "train", "--help"]) == 0
    every = capsys.readouterr().out
    assert "--sac-lr" not in ppo and "--td3-" not in ppo and "--clip" in ppo
    assert "--sac-lr" in sac and "--td3-" not in sac
    assert "--sac-lr" in every and "--td3-lr" in every
    assert "Shown: the options --algo ppo reads" in ppo.replace("\n", " ").replace("│", " ")
    for text in (ppo, sac, every):  # the run-directory options are listed, not only in prose
        assert "--resume RUN_DIR" in text and "--config FILE" in text
        assert "--overwrite " in text and "--no-overwrite" not in text  # a plain switch
        assert "run options" in text


def test_the_listed_run_flags_are_the_ones_train_parses(capsys):
    """What help lists under "run options" is what ``train_command`` pops before the config:
    each works on the command line (the pairs refused together are named)."""
    from dataclasses import fields

    from ndp.rl.cli import TrainFlags

    assert [f.name for f in fields(TrainFlags)] == ["resume", "overwrite", "config"]
    assert main(["rl", "train", "--overwrite", "--resume", "some/run"]) == 2
    assert "--overwrite: cannot be combined with --resume" in capsys.readouterr().err
    assert main(["rl", "train", "--config", "hp.yaml", "--resume", "some/run"]) == 2
    assert "--config: a resumed run keeps its own config" in capsys.readouterr().err


def test_a_learner_option_the_method_does_not_read_is_refused(tmp_path, capsys):
    code = main(["rl", "train", "--task", "point-mass", "--algo", "ppo", "--sac-lr", "1e-3",
                 "--run-dir", str(tmp_path / "r")])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    assert "ppo does not read sac.lr=0.001 (read by --algo sac / sac-chunk / ndp-sac)" in err
    assert not (tmp_path / "r").exists()
    assert "(read by --algo td3)" in unread_learner_message("ppo", ["td3.tau=0.01"])


def test_the_committed_headline_configs_are_the_study_arms():
    """configs/headline/*.yaml give exactly the config the ndp-regimes arm's command gives (the
    fair-live headline), so `ndp rl train --config FILE --seed S` reruns a headline run."""
    from pathlib import Path

    from ndp.experiments.studies import get_study
    from ndp.rl.config import TrainConfig
    from ndp.runs.cli import parse_config

    root = Path(__file__).resolve().parents[2] / "configs" / "headline"
    st = get_study("ndp-regimes")
    arms = {a.label: a for a in st.arm_specs()}
    files = sorted(root.glob("*.yaml"))
    assert len(files) == 6
    for f in files:
        task, _, method = f.stem.partition("-v3-") if "-v3-" in f.stem else f.stem.partition("-")
        task = task + "-v3" if "-v3-" in f.stem else task
        arm = arms[method if method == "ppo" else f"{method}-nostale"]
        want = parse_config(TrainConfig, ["--task", task, "--algo", arm.algo, "--steps",
                                          str(st.steps), "--num-envs", "4", *arm.args],
                            prog="x")  # fmt: skip
        assert config_from_file(str(f)) == want, f.name
