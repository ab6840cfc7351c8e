"""A learner owns its settings: one register_learner call adds its TrainConfig section, its
options and its methods; ndp.rl.config names no learner section."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import pytest

from ndp.rl import config as rl_config
from ndp.rl.config import TrainConfig
from ndp.rl.methods import BUILTIN_HEADS, SETTINGS, Method, Settings, register_learner, section
from ndp.runs.cli import cli


def test_builtin_sections_are_fields_of_train_config_in_registration_order():
    names = [f.name for f in dataclasses.fields(TrainConfig)]
    assert names[-len(SETTINGS) :] == list(SETTINGS)
    assert {"dyne", "sac"} <= set(SETTINGS)
    assert names.index("ppo") < names.index("policy") < names.index("dyne") < names.index("sac")


def test_config_module_names_no_learner_section():
    src = Path(rl_config.__file__).read_text()
    code = "\n".join(line for line in src.splitlines() if not line.strip().startswith(("#",)))
    for name in SETTINGS:
        assert not re.search(rf"\b{name}\s*[:=(]", code), name
        assert f'"{name}"' not in code, name


def test_old_configs_load_and_to_dict_keeps_the_nested_sections():
    from ndp.rl.sac.config import SACConfig

    cfg = TrainConfig(task="point-mass", algo="sac", sac=SACConfig(lr=1e-3))
    d = cfg.to_dict()
    assert d["sac"]["lr"] == 1e-3 and isinstance(d["dyne"], dict)
    assert TrainConfig.from_dict(d) == cfg
    old = {k: v for k, v in d.items() if k not in SETTINGS}  # written before any section
    assert TrainConfig.from_dict(old) == TrainConfig(task="point-mass", algo="sac")
    assert section(cfg, SACConfig).lr == 1e-3
    with pytest.raises(ValueError, match=r"config: .*no_such"):
        TrainConfig.from_dict({**d, "sac": {"no_such": 1}})


def test_a_section_after_train_config_is_built_is_refused_with_one_line():
    @dataclass(frozen=True)
    class Late:
        x: Annotated[int, cli(name="late-x")] = 1
        """x."""

    with pytest.raises(ValueError, match=r"settings: 'late' registered after ndp\.rl\.config"):
        register_learner(Settings("late", Late, "late", "late."))
    assert "late" not in SETTINGS
    with pytest.raises(ValueError, match="name: settings 'sac' are already registered"):
        register_learner(Settings("sac", Late, "late", "again."))
    with pytest.raises(ValueError, match="name: method 'sac' is already registered"):
        register_learner(None, Method("sac", "squashed", "again"))


def test_settings_check_the_flag_prefix_and_the_class():
    @dataclass(frozen=True)
    class Bad:
        lr: Annotated[float, cli(name="lr")] = 1.0
        """lr."""

    with pytest.raises(ValueError, match=r"flag_prefix: Bad\.lr's option --lr does not start"):
        Settings("bad", Bad, "bad", "bad.")
    with pytest.raises(ValueError, match="name: expected an identifier"):
        Settings("ppo", Bad, "", "taken.")

    @dataclass
    class Mutable:
        x: int = 1

    with pytest.raises(ValueError, match="cls: expected a frozen dataclass"):
        Settings("m", Mutable, "", "m.")


def test_builtin_heads_are_the_registered_heads():
    from ndp.policies.heads import HEAD_BUILDERS

    assert set(BUILTIN_HEADS) <= set(HEAD_BUILDERS)


def test_the_registry_and_the_config_import_no_torch():
    code = (
        "import sys; import ndp.rl.config, ndp.rl.methods; "
        "assert 'torch' not in sys.modules, 'torch'; "
        "assert {'dyne', 'sac'} <= set(ndp.rl.methods.SETTINGS)"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_ppo_settings_live_with_the_on_policy_learner_and_saved_configs_round_trip(tmp_path):
    """PPOConfig is defined in ndp.rl.onpolicy.config (its learner's package) and re-exported
    by ndp.rl.config; the section keeps its name, its place and its config.json key "ppo"."""
    import json

    from ndp.rl.config import PPOConfig as Reexported
    from ndp.rl.onpolicy.config import PPOConfig

    assert Reexported is PPOConfig and PPOConfig.__module__ == "ndp.rl.onpolicy.config"
    assert "ppo" not in SETTINGS  # a reserved section of the run, not a registered one
    cfg = TrainConfig(task="point-mass", algo="ndp", ppo=PPOConfig(lr=1e-3, clip=0.2))
    path = tmp_path / "config.json"
    path.write_text(json.dumps(cfg.to_dict()))
    saved = json.loads(path.read_text())
    assert saved["ppo"]["lr"] == 1e-3 and saved["ppo"]["clip"] == 0.2
    back = TrainConfig.from_dict(saved)
    assert back == cfg and type(back.ppo) is PPOConfig
    # a config.json written before the run fields left "ppo" still loads
    old = {**saved, "ppo": {**saved["ppo"], "gamma": 0.9}}
    del old["gamma"]
    assert TrainConfig.from_dict(old) == dataclasses.replace(cfg, gamma=0.9)
