"""Help strings list the methods from the registry (one list; VICES was once missing)."""

from __future__ import annotations

from ndp.cli import main as ndp_main
from ndp.rl.cli import method_lines, train_description
from ndp.rl.methods import METHODS, Method, register_method


def test_ndp_rl_methods_lists_every_registered_method(capsys):
    assert ndp_main(["rl", "methods"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in out] == list(METHODS)
    assert {"ndp", "ppo", "ppo-multi", "dyne", "vices", "vices-pos", "vices-low-freq"} <= set(
        METHODS
    )


def test_a_newly_registered_method_appears_in_the_help_without_editing_it():
    register_method(Method("toy-help", "step", "a method registered by a test"))
    try:
        assert "toy-help: a method registered by a test" in method_lines()
    finally:
        del METHODS["toy-help"]
    # the help names no method (it would go stale, and help imports nothing heavy); it points
    # to the generated list
    assert "ndp rl methods" in train_description()
    assert not any(f"'{name}'" in train_description() for name in METHODS)
