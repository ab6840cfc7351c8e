"""ndp-mechanism's pre-registered readings 2 (basis) and 3 (rewards) applied by code
(ndp.experiments.report.mechanism): each verdict on both sides of its rule, the better
baseline's choice, and waiting for arms."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from ndp.experiments.report import mechanism as mech

SEEDS = (0, 1, 2)


def _cells(values: dict[tuple[str, str], list[float]]):
    """Fake cells: ``values[(task, arm)]`` is the det. area of seeds 0, 1, 2."""
    return [
        SimpleNamespace(
            task=t, label=a, numbers={s: {"det_area": v} for s, v in zip(SEEDS, vs, strict=True)}
        )
        for (t, a), vs in values.items()
    ]


def _basis(k: int, free, dmp, dct, bspline, pca=None, ndp=None):
    """The basis pilot's cells at ``k`` (each argument: three seeds' values)."""
    out = {
        ("push-v3", mech.free_label(k)): free,
        ("push-v3", mech.basis_label("dmp", k)): dmp,
        ("push-v3", mech.basis_label("dct", k)): dct,
        ("push-v3", mech.basis_label("bspline", k)): bspline,
    }
    if pca is not None:
        out[("push-v3", mech.basis_label("pca", k))] = pca
    if ndp is not None:
        out[("push-v3", mech.ndp_label(k))] = ndp
    return out


def _row(rows, **match):
    return next(r for r in rows if all(r.get(k) == v for k, v in match.items()))


TIGHT = [0.19, 0.20, 0.21]  # mean 0.20, population std 0.0082


def _shift(vals, d):
    return [v + d for v in vals]


def test_dmp_within_the_spread_of_both_generic_bases_is_a_low_dimensional_basis():
    cells = _cells(_basis(10, TIGHT, _shift(TIGHT, 0.1), _shift(TIGHT, 0.105), _shift(TIGHT, 0.1)))
    md, rows = mech.mechanism_readings(cells, SEEDS)
    assert _row(rows, k=10, arm="dmp-basis")["verdict"] == "a low-dimensional basis, not the DMP"
    # each basis is 0.1 above free PPO-multi, far more than the spread: the second stage
    r = _row(rows, k=10, arm=mech.basis_label("dct", 10))
    assert r["side"] == "above" and r["diff"] == pytest.approx(0.105)
    assert "waits for pca" in "\n".join(md)


def test_dmp_below_both_generic_bases_is_a_poor_basis_and_a_generic_win_helps():
    cells = _cells(
        _basis(20, TIGHT, TIGHT, _shift(TIGHT, 0.1), _shift(TIGHT, 0.1), pca=_shift(TIGHT, 0.05))
    )
    _, rows = mech.mechanism_readings(cells, SEEDS)
    assert _row(rows, k=20, arm="dmp-basis")["verdict"] == "the DMP's span is a poor basis"
    assert _row(rows, k=20, arm="generic-bases")["verdict"] == "restriction helps at large k"


def test_one_generic_basis_on_the_other_side_gives_neither_restriction_verdict():
    cells = _cells(
        _basis(10, TIGHT, TIGHT, _shift(TIGHT, -0.1), _shift(TIGHT, -0.1), pca=_shift(TIGHT, 0.1))
    )
    _, rows = mech.mechanism_readings(cells, SEEDS)
    assert _row(rows, k=10, arm="generic-bases")["verdict"].startswith("neither")
    all_below = _cells(
        _basis(10, TIGHT, TIGHT, _shift(TIGHT, -0.1), _shift(TIGHT, -0.1), pca=_shift(TIGHT, -0.1))
    )
    _, rows = mech.mechanism_readings(all_below, SEEDS)
    assert _row(rows, k=10, arm="generic-bases")["verdict"] == "restriction hurts"


def test_the_spread_is_the_larger_std_of_the_two_arms():
    wide = [0.0, 0.2, 0.4]  # mean 0.2, population std 0.163
    cells = _cells(_basis(10, TIGHT, _shift(wide, 0.15), TIGHT, TIGHT, ndp=_shift(TIGHT, 0.15)))
    _, rows = mech.mechanism_readings(cells, SEEDS)
    r = _row(rows, k=10, arm=mech.basis_label("dmp", 10))
    assert r["spread"] == pytest.approx(0.163299, abs=1e-5)
    assert r["side"] == "within"  # +0.15 is inside the dmp arm's own spread
    nd = _row(rows, k=10, arm=mech.ndp_label(10), vs=mech.basis_label("dmp", 10))
    assert nd["side"] == "within" and nd["verdict"].startswith("level")


def test_a_missing_seed_makes_the_reading_wait_not_judge():
    vals = _basis(10, TIGHT, TIGHT, TIGHT, TIGHT)
    cells = _cells(vals)
    cells[1].numbers.pop(2)  # the dmp basis lacks seed 2
    md, rows = mech.mechanism_readings(cells, SEEDS)
    text = "\n".join(md)
    assert "waits for the dmp, dct and bspline arms" in text
    assert mech.basis_label("dmp", 10) in text.split("Arms reading 2 waits for")[1]
    assert not [r for r in rows if r.get("arm") == "dmp-basis"]


def _rewards(task, variant, ndp, pm, ppo):
    return {
        (task, f"ndp-{variant}"): ndp,
        (task, f"ppo-multi-{variant}"): pm,
        (task, f"ppo-{variant}"): ppo,
    }


def _all_rewards(**over):
    out = {}
    for t in mech.REWARD_TASKS:
        for v in mech.REWARD_VARIANTS:
            out.update(over.get(f"{t}:{v}", _rewards(t, v, TIGHT, TIGHT, TIGHT)))
    return out


def test_rewards_compares_ndp_with_the_better_baseline_and_applies_the_threshold():
    high = [0.5, 0.6, 0.7]
    cells = _cells(
        _all_rewards(**{"push-v3:sparse": _rewards("push-v3", "sparse", high, TIGHT, [0.3] * 3)})
    )
    md, rows = mech.mechanism_readings(cells, SEEDS)
    r = _row(rows, reading="3", task="push-v3", reward="sparse")
    assert r["vs"] == "ppo-sparse" and r["p_improvement"] == 1.0
    assert r["verdict"] == "should win here"
    assert "**should win here**" in "\n".join(md) and "push-v3 sparse (1.00)" in "\n".join(md)
    # a tie between two identical arms is P = 0.5, below the rule
    r = _row(rows, reading="3", task="reach-v3", reward="smooth")
    assert r["p_improvement"] == 0.5 and r["verdict"] == "no" and r["vs"] == "ppo-multi-smooth"


def test_no_cell_at_the_threshold_gives_the_registered_negative_answer():
    md, rows = mech.mechanism_readings(_cells(_all_rewards()), SEEDS)
    assert len([r for r in rows if r["reading"] == "3"]) == 4
    assert "neither a sparse success reward nor a priced smoothness" in "\n".join(md)


def test_just_below_the_threshold_is_not_a_win():
    # P(X > Y) = 6/9 = 0.667 < 0.7
    cells = _cells(
        _all_rewards(
            **{
                "reach-v3:sparse": _rewards(
                    "reach-v3", "sparse", [0.25, 0.5, 0.8], [0.2, 0.3, 0.7], [0.0, 0.0, 0.0]
                )
            }
        )
    )
    _, rows = mech.mechanism_readings(cells, SEEDS)
    r = _row(rows, reading="3", task="reach-v3", reward="sparse")
    assert r["vs"] == "ppo-multi-sparse"
    assert r["p_improvement"] == pytest.approx(6 / 9) and r["verdict"] == "no"


def test_readings_whose_arms_are_absent_say_so():
    md, rows = mech.mechanism_readings(_cells({("push-v3", "ndp-linear"): TIGHT}), SEEDS)
    text = "\n".join(md)
    assert "Reading 2 (basis): none of its arms" in text
    assert "Reading 3 (rewards): none of its arms" in text and rows == []


def test_the_study_registers_its_readings():
    from ndp.experiments import studies

    assert studies.get_study("ndp-mechanism").readings_fn() is mech.mechanism_readings
