"""The registered family of ``ndp report --compare``: Holm over the whole family, the pooled
rows, the paired test beside, and the errors naming ``compare``."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from ndp.experiments.report import family, paired, stats


def _cell(task: str, label: str, values: list[float]) -> SimpleNamespace:
    return SimpleNamespace(
        task=task, label=label,
        numbers={s: {"det_area": v, "area": v / 2} for s, v in enumerate(values)},
    )  # fmt: skip


def _cells() -> list[SimpleNamespace]:
    rng = np.random.default_rng(0)
    out = []
    for task, shift in (("push-v3", 0.3), ("throw", 0.0)):
        out.append(_cell(task, "a", list(0.5 + shift + 0.05 * rng.standard_normal(5))))
        out.append(_cell(task, "b", list(0.5 + 0.05 * rng.standard_normal(5))))
        out.append(_cell(task, "c", list(0.5 + 0.05 * rng.standard_normal(5))))
    return out


def test_parse_pairs() -> None:
    assert family.parse_pairs(["a:b", "c:b"]) == [("a", "b"), ("c", "b")]
    for bad in ("ab", "a:", ":b", "a:a", "a:b:c"):
        with pytest.raises(ValueError, match=r"^compare: expected pairs"):
            family.parse_pairs([bad])
    with pytest.raises(ValueError, match="named twice"):
        family.parse_pairs(["a:b", "a:b"])


def test_check_pairs_names_unknown_labels() -> None:
    with pytest.raises(ValueError, match=r"^compare: zz is not a method of this report"):
        family.check_pairs([("a", "zz")], ["a", "b"])
    family.check_pairs([("a", "b")], ["a", "b"])


def test_family_holm_over_every_row_and_paired_beside() -> None:
    cells, seeds = _cells(), list(range(5))
    md, rows = family.family_section(cells, seeds, [("a", "b"), ("c", "b")], pooled=True)
    assert len(rows) == 6  # 2 pairs x (2 tasks + pooled)
    assert {r["holm_m"] for r in rows} == {6}
    raw = [r["p_two_sided"] for r in rows]
    assert np.allclose([r["p_holm"] for r in rows], stats.holm(raw))
    push = next(r for r in rows if r["task"] == "push-v3" and r["a"] == "a")
    a = np.array([cells[0].numbers[s]["det_area"] for s in seeds])
    b = np.array([cells[1].numbers[s]["det_area"] for s in seeds])
    assert push["diff_mean"] == pytest.approx(float(a.mean() - b.mean()))
    assert push["p_two_sided"] == pytest.approx(stats.permutation_tests(a, b).two_sided)
    assert push["p_paired"] == pytest.approx(paired.paired_sign_flip(a, b).p)
    # a shift of 0.3 against noise 0.05, 5 + 5 runs: the smallest exact two-sided p, 2 / 252
    assert push["p_two_sided"] == pytest.approx(2 / 252)
    pooled = [r for r in rows if r["task"] == family.ALL_TASKS]
    assert len(pooled) == 2 and pooled[0]["diff_mean"] == pytest.approx(
        np.mean([r["diff_mean"] for r in rows if r["a"] == "a" and r["task"] != "all tasks"])
    )
    header = next(line for line in md if line.startswith("| task"))
    rule = md[md.index(header) + 1]
    assert header.count("|") == rule.count("|")  # the table's rule has its header's columns
    assert all(line.count("|") == header.count("|") for line in md if line.startswith("| push"))


def test_family_leaves_out_an_arm_missing_a_seed() -> None:
    cells = _cells()
    del cells[2].numbers[4]  # arm c on push-v3 lacks seed 4
    md, rows = family.family_section(cells, list(range(5)), [("a", "b"), ("c", "b")])
    assert [r["method"] for r in rows] == ["a vs b", "a vs b", "c vs b"]
    assert {r["holm_m"] for r in rows} == {3}
    assert any("Left out of the family" in line and "c" in line for line in md)


def test_holm_over_the_pooled_rows_only_describes_the_per_task_rows() -> None:
    """The mechanism reading's family: the pooled rows only (2 tests); per-task rows keep their
    p-values but get no Holm p and no verdict word."""
    md, rows = family.family_section(_cells(), list(range(5)), [("a", "b"), ("c", "b")],
                                     pooled=True, holm_over="pooled")  # fmt: skip
    pooled = [r for r in rows if r["task"] == family.ALL_TASKS]
    per_task = [r for r in rows if r["task"] != family.ALL_TASKS]
    assert {r["holm_m"] for r in pooled} == {2} and {r["holm_m"] for r in per_task} == {0}
    assert np.allclose(
        [r["p_holm"] for r in pooled], stats.holm([r["p_two_sided"] for r in pooled])
    )
    assert all(np.isnan(r["p_holm"]) and not r["significant"] for r in per_task)
    assert sum("- (description)" in line for line in md) == 4
    assert "Registered family (2 tests" in md[0]
    with pytest.raises(ValueError, match=r"^holm_over: 'pooled' leaves no row in the family"):
        family.family_section(_cells(), list(range(5)), [("a", "b")], holm_over="pooled")
    with pytest.raises(ValueError, match=r"^holm_over: expected one of all, pooled, tasks"):
        family.family_section(_cells(), list(range(5)), [("a", "b")], holm_over="some")
