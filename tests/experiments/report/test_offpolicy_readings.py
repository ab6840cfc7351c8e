"""The off-policy study's pre-registered readings applied by code
(ndp.experiments.report.offpolicy): the critic-input rule on both sides of its margin, reading
B's three verdicts, reading C's ahead / behind / level, reading D, and waiting for arms."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from ndp.experiments import studies
from ndp.experiments.report import offpolicy as op

SEEDS = (0, 1, 2)
TASKS = ("push-v3", "throw")
ARMS = ("sac", "sac-chunk-k5", "ndp-sac-k5", "ndp-sac-act-k5", "ndp-k5", "ppo-multi-k5", "ppo")


def _cells(det, skip=(), arms=ARMS):
    """Fake cells: ``det[(task, arm)]`` or ``det[arm]`` is the det. area of every seed (default
    0.2), spread by +-0.01 over seeds so that permutation tests are not all ties; ``skip``
    holds (task, arm) pairs with no runs (``ndp-sac-act-k5`` runs on push-v3 only)."""
    out = []
    for task in TASKS:
        for arm in arms:
            push_only = arm == "ndp-sac-act-k5" or "-ln-" in arm
            if (task, arm) in skip or (push_only and task != "push-v3"):
                continue
            v = det.get((task, arm), det.get(arm, 0.2))
            nums = {s: {"det_area": v + 0.01 * (s - 1)} for s in SEEDS}
            out.append(SimpleNamespace(task=task, label=arm, numbers=nums))
    return out


def _row(rows, reading, item=None):
    return next(r for r in rows if r["reading"] == reading and (item is None or r["item"] == item))


def test_the_study_registers_its_readings():
    assert studies.get_study("off-policy").readings is not None


@pytest.mark.parametrize(
    ("params", "actions", "kept"),
    [(0.30, 0.34, "params"), (0.30, 0.36, "actions"), (0.40, 0.20, "params")],
)
def test_reading_a_keeps_params_unless_actions_is_more_than_the_margin_above(params, actions, kept):
    md, rows = op.off_policy_readings(
        _cells({"ndp-sac-k5": params, "ndp-sac-act-k5": actions}), SEEDS
    )
    assert _row(rows, "A")["verdict"] == kept
    assert f"keep **{kept}**" in "\n".join(md)


def test_keeping_actions_makes_b_to_d_wait_for_its_throw_runs():
    md, rows = op.off_policy_readings(_cells({"ndp-sac-act-k5": 0.6}), SEEDS)
    text = "\n".join(md)
    assert _row(rows, "A")["verdict"] == "actions"
    assert "waits for `ndp-sac-act-k5` and `sac-chunk-k5`" in text
    assert not any(r["reading"] in ("B", "C", "D") for r in rows)
    assert "ndp-sac-act-k5" in text.split("these readings wait for")[1]


def test_reading_b_helps_when_ndp_sac_beats_chunked_sac_on_both_tasks():
    _, rows = op.off_policy_readings(_cells({"ndp-sac-k5": 0.5}), SEEDS)
    b = _row(rows, "B")
    assert b["verdict"] == "helps"
    assert b["value"] == pytest.approx(0.3)
    assert b["p_greater"] == pytest.approx(1 / 400)  # every run above on both tasks


def test_reading_b_does_not_help_and_mixed():
    _, rows = op.off_policy_readings(_cells({"sac-chunk-k5": 0.5}), SEEDS)
    assert _row(rows, "B")["verdict"] == "does not help"
    # ahead on push-v3, behind on Throw
    det = {("push-v3", "ndp-sac-k5"): 0.5, ("throw", "sac-chunk-k5"): 0.5}
    _, rows = op.off_policy_readings(_cells(det), SEEDS)
    assert _row(rows, "B")["verdict"] == "mixed"


def test_reading_c_names_ahead_behind_and_level():
    det = {"ndp-sac-k5": 0.4, "sac": 0.6, "ndp-k5": 0.4}
    md, rows = op.off_policy_readings(_cells(det), SEEDS)
    assert _row(rows, "C", "ndp-sac-k5 vs sac")["verdict"] == "behind"
    assert _row(rows, "C", "ndp-sac-k5 vs ppo")["verdict"] == "ahead"
    # identical runs: neither p is small
    assert _row(rows, "C", "ndp-sac-k5 vs ndp-k5")["verdict"] == "level"
    assert "| SAC (k = 1) | `sac` | -0.20 |" in "\n".join(md)


def test_reading_c_names_each_p_by_its_direction_and_adds_the_convention():
    """'behind' rests on p(it > NDP-SAC), the other learner above NDP-SAC: the table says so
    in its headings; beside the registered verdict, the two-sided p Holm-adjusted over the
    five pairs (every SAC run above every NDP-SAC run on both tasks: one-sided 1/400,
    two-sided 2/400, Holm x5 = 0.025) and the test's label."""
    md, rows = op.off_policy_readings(_cells({"ndp-sac-k5": 0.4, "sac": 0.6}), SEEDS)
    text = "\n".join(md)
    assert ("| against | arm | NDP-SAC - it | one-sided p(NDP-SAC > it) | one-sided p(it > "
            "NDP-SAC) | reading (registered rule) | p (two-sided) | Holm p |") in text  # fmt: skip
    sac = _row(rows, "C", "ndp-sac-k5 vs sac")
    assert sac["p_less"] == pytest.approx(1 / 400) and sac["p_greater"] == pytest.approx(1.0)
    assert sac["p_two_sided"] == pytest.approx(2 / 400)
    assert sac["p_holm"] == pytest.approx(5 * 2 / 400)
    assert sac["p_method"] == "exact permutation (all 400 splits)"
    line = next(ln for ln in md if ln.startswith("| SAC (k = 1) |"))
    assert (
        "| behind | 0.005 | 0.025 | **NDP-SAC behind** | exact permutation (all 400 splits) |"
        in line
    )
    b = next(ln for ln in md if ln.startswith("**B."))
    assert (
        "one-sided p(NDP-SAC > chunked SAC) = " in b and "one-sided p(chunked SAC > NDP-SAC)" in b
    )


def test_reading_d_compares_what_the_learner_adds_to_each_action_space():
    det = {"ndp-sac-k5": 0.5, "ndp-k5": 0.2, "sac-chunk-k5": 0.3, "ppo-multi-k5": 0.2}
    md, rows = op.off_policy_readings(_cells(det), SEEDS)
    assert _row(rows, "D")["value"] == pytest.approx(0.3 - 0.1)
    assert "the learner lifts the DMP head more" in "\n".join(md)


def test_readings_wait_while_seeds_are_missing():
    cells = _cells({})
    for c in cells:
        if c.label == "sac":
            del c.numbers[2]
    md, rows = op.off_policy_readings(cells, SEEDS)
    text = "\n".join(md)
    assert "| SAC (k = 1) | `sac` | (waits) |" in text
    assert "these readings wait for (seeds missing in this report): sac." in text
    assert _row(rows, "B")["verdict"] == "does not help"  # level everywhere: not above


def _log(path, q, ret, alpha=None):
    """A run directory whose metrics.csv has one row per update (``sac/q`` left out when
    ``q`` is None: an on-policy run)."""
    import csv

    path.mkdir(parents=True)
    cols = ["update", "global_step", "charts/episode_return"]
    cols += [] if q is None else ["sac/q", "sac/alpha"]
    with (path / "metrics.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for i, r in enumerate(ret):
            row = [i + 1, 1000 * (i + 1), r]
            row += [] if q is None else [q[i], (alpha or [0.1] * len(ret))[i]]
            w.writerow(row)
    return SimpleNamespace(path=path)


def test_critic_health_flags_a_value_estimate_far_above_the_returns(tmp_path):
    """A critic whose estimate runs away (peak 5,000 against returns of at most 40) is called
    diverged; one that stays near its returns is not; an on-policy run has no critic row. The
    section says it is a diagnostic and changes no reading."""
    cells = [
        SimpleNamespace(task="push-v3", label="ndp-sac-k5", numbers={}, runs={
            0: _log(tmp_path / "a", [10, 800, 5000, 300], [5, 20, 40, 12], [1.0, 9.0, 170.0, 5.0]),
            1: _log(tmp_path / "b", [10, 30, 35, 39], [5, 20, 40, 12]),
        }),
        SimpleNamespace(task="push-v3", label="ppo", numbers={},
                        runs={0: _log(tmp_path / "c", None, [5, 20, 40, 12])}),
    ]  # fmt: skip
    md, rows = op.critic_health(cells)
    assert [(r["item"], r["verdict"]) for r in rows] == [
        ("ndp-sac-k5 s0", "diverged"),
        ("ndp-sac-k5 s1", "ok"),
    ]
    bad = rows[0]
    assert bad["q_peak"] == 5000 and bad["q_peak_step"] == 3000 and bad["return_peak"] == 40
    assert bad["alpha_peak"] == 170.0 and bad["alpha_final"] == 5.0
    text = "\n".join(md)
    assert "| push-v3 | ndp-sac-k5 | 0 | 5,000 | 3,000 | 40 | 170 | 5 | **diverged** |" in text
    assert "Diverged: 1 of 2 runs (push-v3 ndp-sac-k5 s0)." in text
    assert "not a pre-registered reading" in text
    # a reading's rows come first; the diagnostic's rows follow them in the same CSV
    _, all_rows = op.off_policy_readings(cells, SEEDS)
    assert [r["reading"] for r in all_rows if r["reading"] == "critic"] == ["critic", "critic"]


def test_a_report_over_fewer_seeds_marks_its_verdicts_interim():
    md, _ = op.off_policy_readings(_cells({}), (0,))
    assert any(line.startswith("**Interim: seeds 0 of the registered 0 1 2.**") for line in md)
    md, _ = op.off_policy_readings(_cells({}), SEEDS)
    assert not any("Interim" in line for line in md)


def _health_cells(tmp_path, plain, ln, unfinished=()):
    """sac-critic cells: per arm, one run per seed whose critic runs away (peak 5,000 against
    returns of at most 40) where the flag is True; ``unfinished`` holds (arm, seed) pairs whose
    run has not finished."""
    cells = []
    for arm, flags in (("ndp-sac-k5", plain), ("ndp-sac-ln-k5", ln)):
        runs = {}
        for s, bad in enumerate(flags):
            q = [10, 800, 5000, 300] if bad else [10, 30, 35, 39]
            log = _log(tmp_path / f"{arm}-{s}", q, [5, 20, 40, 12])
            runs[s] = SimpleNamespace(path=log.path, finished=(arm, s) not in unfinished)
        cells.append(SimpleNamespace(task="push-v3", label=arm, numbers={}, runs=runs))
    return cells


@pytest.mark.parametrize(
    ("plain", "ln", "verdict"),
    [
        ((True, True, False), (False, False, False), "stops the runaway"),
        ((True, True, True), (True, True, False), "does not stop the runaway"),
        ((True, True, True), (True, False, False), "partly stops the runaway"),
        ((True, False, False), (False, False, False), "partly stops the runaway"),
    ],
)
def test_the_layer_norm_reading_counts_diverged_critics(tmp_path, plain, ln, verdict):
    md, rows = op.critic_study_readings(_health_cells(tmp_path, plain, ln), SEEDS)
    assert _row(rows, "layer-norm")["verdict"] == verdict
    assert f"LayerNorm **{verdict}**" in "\n".join(md)
    assert studies.get_study("sac-critic").readings is not None


def test_the_layer_norm_reading_waits_for_unfinished_runs(tmp_path):
    cells = _health_cells(tmp_path, (True,) * 3, (False,) * 3, unfinished={("ndp-sac-ln-k5", 2)})
    md, rows = op.critic_study_readings(cells, SEEDS)
    assert not any(r["reading"] == "layer-norm" for r in rows)
    assert "finished runs: ndp-sac-k5 3 of 3, ndp-sac-ln-k5 2 of 3" in "\n".join(md)


LN = (*ARMS, "ndp-sac-ln-k5", "sac-chunk-ln-k5")


@pytest.mark.parametrize(
    ("ndp_ln", "chunk_ln", "verdict"),
    [(0.50, 0.20, "helps"), (0.20, 0.20, "does not help"), (0.205, 0.20, "mixed")],
)
def test_reading_e_compares_the_heads_under_layer_norm_critics(ndp_ln, chunk_ln, verdict):
    det = {("push-v3", "ndp-sac-ln-k5"): ndp_ln, ("push-v3", "sac-chunk-ln-k5"): chunk_ln,
           ("push-v3", "ndp-sac-k5"): 0.01, ("push-v3", "sac-chunk-k5"): 0.10}  # fmt: skip
    md, rows = op.off_policy_readings(_cells(det, arms=LN), SEEDS)
    e = _row(rows, "E")
    assert e["verdict"] == verdict and e["task"] == "push-v3"
    if verdict == "helps":  # every NDP-SAC run above every chunked run: p = 1/20, allowed
        assert e["p_greater"] == pytest.approx(0.05)
    text = "\n".join(md)
    assert f"Verdict: **{verdict}**. What LayerNorm changes" in text
    assert f"`ndp-sac-ln-k5` - `ndp-sac-k5` {ndp_ln - 0.01:+.2f}" in text


def test_reading_e_without_its_optional_arms_says_so_and_waits_for_nothing():
    md, rows = op.off_policy_readings(_cells({}), SEEDS)
    text = "\n".join(md)
    assert "**E. The DMP head with LayerNorm critics** (post-hoc, push-v3): no runs" in text
    assert not any(r["reading"] == "E" for r in rows) and "wait for" not in text
    # one LayerNorm arm with runs: E waits for the other and names it
    md, _ = op.off_policy_readings(_cells({}, arms=(*ARMS, "ndp-sac-ln-k5")), SEEDS)
    assert "these readings wait for (seeds missing in this report): sac-chunk-ln-k5." in "\n".join(
        md
    )
