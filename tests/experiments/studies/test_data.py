"""The shipped study files: every one loads, a few known facts, and the constants that code
reads from :mod:`ndp.experiments.studies` agree with the data (the grids the Python modules
generated before the studies became data, rebuilt here from those constants)."""

from __future__ import annotations

import re
from pathlib import Path

from ndp.experiments import studies
from ndp.experiments.studies import (
    AR1_CORR,
    BC_DEMOS,
    CONVERGED_ARGS,
    CONVERGED_LRS,
    CONVERGED_MODELS,
    FIRST_HELD,
    HEAD_ABLATION_COMMANDED,
    HEAD_LRS,
    HEADS,
    LIVE,
    MECHANISM_BASES,
    NDP_SETTINGS_AXES,
    OFF_POLICY_UTD1,
    PARAM_NOISE_DISPLACEMENT,
    PARAM_NOISE_LOG_STD,
    REGIME_KS,
    RELEASE_ALL_MW,
    RELEASE_FIXED,
    RELEASE_METHODS,
    RELEASE_OPTIMISER,
    RELEASE_RATIO,
    RELEASE_V1,
    STUDIES,
    THROW_DEFAULTS,
    get_study,
    k_args,
)
from ndp.experiments.studies.loader import DATA_DIR, load_study, study_files


def _args(study: str) -> dict[str, tuple[str, ...]]:
    return {a.label: a.args for a in get_study(study).arm_specs()}


def test_every_file_is_one_study_named_as_its_file():
    files = study_files()
    assert len(files) == len(STUDIES) == 22
    for f in files:
        assert load_study(f).name == f.stem
    assert {f.stem for f in files} == set(STUDIES)
    assert all(f.parent == DATA_DIR for f in files)


def test_known_facts():
    five = get_study("paper-five")
    assert five.task_list() == ("throw", "pick", "push-v3", "soccer-v3", "faucet-open-v3")
    assert (five.steps, five.seeds, five.kind, five.budgets) == (300_000, (0, 1, 2), "rl",
                                                                (0.25, 0.5, 1.0))  # fmt: skip
    dyne = next(a for a in five.arm_specs() if a.label == "dyne")
    assert dyne.pending_method and dyne.in_default and dyne.algo == "dyne"
    assert get_study("mt50").summary == ("over-tasks",)
    assert get_study("il-robot").kind == "bc" and get_study("il-robot").steps == 100
    assert get_study("digits-head").steps == 500 and len(get_study("digits-head").selection) == 9
    rg = get_study("ndp-regimes")
    assert rg.readings == "ndp.experiments.report.regimes:regimes_readings"
    assert len(rg.arm_specs()) == 23 and len(rg.conditions) == 9
    cond = get_study("release-conditions").conditions[3]
    assert cond.unequal and cond.overrides == (("faucet-open-v3", "ppo", "ppo-v1-fixed"),)
    ppo_fixed = next(a for a in get_study("release-goals-1m").arm_specs() if a.label == "ppo-fixed")
    assert ppo_fixed.tasks == ("throw",) and ppo_fixed.args == RELEASE_FIXED
    assert get_study("sac-critic").steps == 40_000
    assert sum(len(s.arm_specs()) for s in STUDIES.values()) == 208


def test_the_metaworld_task_set_is_built_only_when_asked():
    mt50 = get_study("mt50")
    assert repr(mt50.tasks) == "task_set 'metaworld'"
    from ndp.envs.metaworld_env import metaworld_env_names

    assert mt50.task_list() == tuple(metaworld_env_names()) and len(mt50.task_list()) == 50


def test_paper_constants_agree_with_the_data():
    from ndp.dmp.basis import RBF_FUNCTIONS

    abl = _args("ablations")
    rbf = {lb for lb in abl if lb.startswith("rbf-")}
    assert rbf == {f"rbf-{k.replace('_', '-')}" for k in RBF_FUNCTIONS if k != "gaussian"}
    for prefix, option, key in (("n", "--n-basis", "n_basis"), ("steps", "--dmp-steps",
                                "dmp_steps"), ("k", "--k", "k")):  # fmt: skip
        values = [lb[len(prefix) :] for lb in abl if re.fullmatch(rf"{prefix}\d+", lb)]
        assert values and str(THROW_DEFAULTS[key]) not in values  # the reference is "ndp"
        assert all(abl[f"{prefix}{v}"] == (option, v) for v in values)
    head = _args("ndp-head-ablation")
    assert head["ndp-commanded"] == HEAD_ABLATION_COMMANDED
    for lb in ("ndp-meanclip", "ndp-goalforcing", "ndp-gs1", "ndp-gripdmp", "ndp-paramnoise"):
        assert head[lb][: len(HEAD_ABLATION_COMMANDED)] == HEAD_ABLATION_COMMANDED


def test_release_constants_agree_with_the_data():
    rc = _args("release-conditions")
    for suffix, args in (("", ()), ("-v1", RELEASE_V1), ("-v1-fixed", RELEASE_V1 + RELEASE_FIXED),
                         ("-v1-ropt", RELEASE_V1 + RELEASE_OPTIMISER)):  # fmt: skip
        for m in RELEASE_METHODS:
            assert rc[m + suffix] == args
    assert len(rc) == 4 * len(RELEASE_METHODS) == 12
    assert RELEASE_METHODS == ("ndp", "ppo-multi", "ppo")
    ex = _args("release-explained")
    assert ex["ppo-rall"] == RELEASE_ALL_MW
    assert ex["ndp-rall"] == (*RELEASE_ALL_MW, *FIRST_HELD)
    assert ex["ndp-rall-rr"] == (*RELEASE_ALL_MW, *FIRST_HELD, *RELEASE_RATIO)
    assert ex["ppo-multi-rall"] == (*RELEASE_ALL_MW, *FIRST_HELD, *LIVE)
    assert ex["ndp-v1-rel-fh"] == (*RELEASE_V1, "--goals", "release", *FIRST_HELD)


def test_regime_constants_agree_with_the_data():
    rg = _args("ndp-regimes")
    assert tuple(int(lb[5:]) for lb in rg if re.fullmatch(r"ndp-k\d+", lb)) == REGIME_KS
    ar1 = ("--noise", "ar1", "--noise-corr", AR1_CORR)
    for k in REGIME_KS:
        assert rg[f"ndp-k{k}"] == rg[f"ppo-multi-k{k}"] == k_args(k)
        noise = ("--param-noise", "--init-log-std")
        assert rg[f"ndp-param-k{k}"] == (*k_args(k), *noise, PARAM_NOISE_LOG_STD)
        assert rg[f"ndp-paramd-k{k}"] == (*k_args(k), *noise, PARAM_NOISE_DISPLACEMENT[k])
        assert rg[f"ndp-ar1-k{k}"] == rg[f"ppo-multi-ar1-k{k}"] == (*k_args(k), *ar1)
    settings = _args("ndp-settings")
    expected = {"ndp": ()} | {f"ndp-{o}{v}".replace(".", "p"): (f"--{o}", v)
                              for o, values in NDP_SETTINGS_AXES for v in values}  # fmt: skip
    assert settings == expected
    mech = _args("ndp-mechanism")
    for k in (10, 20):
        for b in (*MECHANISM_BASES, "pca"):
            assert mech[f"ppo-multi-{b}-k{k}"] == (*k_args(k), *LIVE, "--chunk-basis", b)
    bases = {lb.split("-")[2] for lb in mech if re.fullmatch(r"ppo-multi-\w+-k\d+", lb)}
    assert bases - {"live", "pca"} == set(MECHANISM_BASES)
    off = _args("off-policy")
    assert off["ndp-sac-live-utd1-k5"] == off["sac-chunk-live-utd1-k5"] == (*LIVE, *OFF_POLICY_UTD1)


def test_imitation_constants_agree_with_the_data():
    bc = get_study("il-robot").arm_specs()
    assert {a.args[-1] for a in bc} == {str(n) for n in BC_DEMOS} and len(bc) == 4 * len(BC_DEMOS)
    conv = {a.label: (a.algo, a.args) for a in get_study("digits-converged").arm_specs()}
    assert conv == {f"{m}-lr{lr}": (algo, ("--lr", lr, *CONVERGED_ARGS))
                    for m, algo in CONVERGED_MODELS for lr in CONVERGED_LRS}  # fmt: skip
    head = {a.label: (a.algo, a.args) for a in get_study("digits-head").arm_specs()}
    assert head == {f"{m}-{h}-lr{lr}": (algo, ("--lr", lr, *args, *CONVERGED_ARGS))
                    for m, algo in CONVERGED_MODELS for h, args in HEADS
                    for lr in HEAD_LRS}  # fmt: skip


def test_the_package_reexports_the_registry_and_the_constants():
    assert studies.STUDIES is studies.registry.STUDIES
    assert studies.REGIME_KS is studies.constants.REGIME_KS


def test_the_study_files_ship_with_the_package():
    import fnmatch

    from ndp.experiments.studies.loader import _toml

    root = Path(__file__).resolve().parents[3]
    data = _toml().loads((root / "pyproject.toml").read_text())
    globs = data["tool"]["setuptools"]["package-data"]["ndp.experiments.studies"]
    package = DATA_DIR.parent
    for f in study_files():
        rel = f.relative_to(package).as_posix()
        assert any(fnmatch.fnmatch(rel, g) for g in globs), rel
