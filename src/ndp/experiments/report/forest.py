"""The forest plot of the package's answer: NDP minus each baseline, one row per study and task.

Read from the committed CSVs of the study reports (``docs/results/<study>/<name>-conditions.csv``,
written by ``ndp report``), never from runs: ``ndp report docs/results --overview --out
docs/results/overview/forest`` regenerates it on any clone. Each row is one pairwise difference
of a study's table (the mean difference of a metric between an NDP arm and a baseline, with its
Welch 95% t-interval, over the seeds of that table), chosen by :data:`FOREST_ROWS`: the 10-seed
headline first, then the release's conditions, the regimes and the off-policy learners.

Usage over your own reports::

    from ndp.experiments.report.forest import ForestSpec, read_forest, forest_plot
    rows = read_forest("docs/results", [ForestSpec("mine", "my_study/my-conditions.csv",
                                                   "fair", "push-v3", "ndp vs ppo")])
    forest_plot(rows, "forest.png")
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ndp.io import atomic_savefig, atomic_write_text

__all__ = [
    "FOREST_ROWS",
    "ForestRow",
    "ForestSpec",
    "forest_markdown",
    "forest_plot",
    "read_forest",
]


@dataclass(frozen=True)
class ForestSpec:
    """Which row of which committed conditions CSV a forest row shows."""

    group: str
    """The section of the plot (a study and the rule its arms ran under)."""
    csv: str
    """The conditions CSV, relative to the results root (``docs/results``)."""
    condition: str
    """The CSV's ``condition`` column."""
    task: str
    """The CSV's ``task`` column (``over A, B`` for the stratified rows over tasks)."""
    pair: str
    """The CSV's ``method`` column of a pairwise row, ``"A vs B"`` (A: the NDP arm)."""
    metric: str = "det_area"
    """The CSV's ``metric`` column: ``det_area`` (deterministic success area) or ``area``
    (training-episode success area)."""


@dataclass(frozen=True)
class ForestRow:
    """One difference read from a committed CSV."""

    spec: ForestSpec
    diff: float
    """Mean of A minus mean of B (per task; stratified mean over tasks)."""
    low: float
    """Lower end of the Welch 95% t-interval of the difference."""
    high: float
    """Upper end."""
    n: int
    """Seeds per arm."""
    source: str
    """The command, commit and date of the report the CSV came from."""

    @property
    def label(self) -> str:
        """``<task>: NDP vs <baseline> (<condition>, n = <n>)``, the plot's row label."""
        a, b = self.spec.pair.split(" vs ")
        task = "both tasks" if self.spec.task.startswith("over ") else self.spec.task
        who = "" if a == "ndp" else f"{a} "
        return f"{task}: {who}vs {b} ({self.spec.condition}; n = {self.n})"


_PAIRS = ("ndp vs ppo-multi", "ndp vs ppo")
XLIM = (-0.8, 0.5)
"""The plot's x range; an interval beyond it ends in an arrow head at the edge."""
_BOTH = "over push-v3, throw"


def _rows(group: str, csv_path: str, condition: str, tasks: Sequence[str],
          pairs: Sequence[str] = _PAIRS, metric: str = "det_area") -> list[ForestSpec]:  # fmt: skip
    return [ForestSpec(group, csv_path, condition, t, p, metric) for t in tasks for p in pairs]


FOREST_ROWS: tuple[ForestSpec, ...] = (
    # the headline: every method on the env's own reward, 10 seeds (fair-live)
    *_rows("headline, 10 seeds, one reward rule for every method (the env's own)",
           "ndp_regimes/headline_live-conditions.csv", "live reward, k = 5",
           ("push-v3", "throw", _BOTH)),
    # the same at the paper's rule (stale-world reward for the chunked methods)
    *_rows("headline, 10 seeds, stale-world reward for NDP and PPO-multi (the paper's rule)",
           "ndp_regimes/headline-conditions.csv", "white, k = 5",
           ("push-v3", "throw", _BOTH)),
    # the 2021 release's conditions, 3 seeds, training-episode success area
    *_rows("release conditions, 3 seeds (training-episode success area)",
           "release_explained/release_explained-conditions.csv", "release-all",
           ("push-v3", "soccer-v3", "faucet-open-v3"), metric="area"),
    # where NDP's structure could win, 3 seeds, pooled over push-v3 and Throw
    *[s for cond in ("white, k = 10", "white, k = 20", "NDP parameter noise, k = 5",
                     "AR(1), k = 5", "live reward, k = 5", "NDP tuned (N 10), k = 5")
      for s in _rows("regimes, 3 seeds (both tasks)", "ndp_regimes/ndp_regimes-conditions.csv",
                     cond, (_BOTH,))],
    # off-policy: NDP-SAC against the on-policy learners, 3 seeds, both tasks
    *_rows("off-policy, 3 seeds (both tasks)", "off_policy/off_policy-conditions.csv", "k = 5",
           (_BOTH,), ("ndp-sac vs ppo-multi", "ndp-sac vs ppo")),
)  # fmt: skip
"""The rows of the README's forest plot, in order."""


def _float(row: dict[str, str], key: str, path: Path) -> float:
    try:
        return float(row[key])
    except (KeyError, ValueError):
        raise ValueError(f"{path}: column {key!r} missing or not a number in {row}") from None


def read_forest(root: str | Path, specs: Sequence[ForestSpec] = FOREST_ROWS) -> list[ForestRow]:
    """The rows of ``specs`` read from the CSVs under ``root``.

    Raises:
        ValueError: a CSV missing, or a spec that matches no row or several (naming both).
    """
    root = Path(root)
    cache: dict[Path, list[dict[str, str]]] = {}
    out = []
    for s in specs:
        path = root / s.csv
        if path not in cache:
            if not path.is_file():
                raise ValueError(f"csv: expected a committed conditions CSV, {path} is missing")
            with path.open(newline="") as f:
                cache[path] = list(csv.DictReader(f))
        hits = [
            r
            for r in cache[path]
            if r.get("condition") == s.condition
            and r.get("task") == s.task
            and r.get("method") == s.pair
            and r.get("metric") == s.metric
        ]
        if len(hits) != 1:
            raise ValueError(
                f"{path}: expected one row for condition {s.condition!r}, task {s.task!r}, "
                f"pair {s.pair!r}, metric {s.metric!r}; found {len(hits)}"
            )
        r = hits[0]
        n = r.get("n_seeds") or "0"
        source = f"`{r.get('command', '?')}` at {r.get('commit', '?')}, {r.get('date', '?')}"
        out.append(
            ForestRow(
                s,
                _float(r, "diff_mean", path),
                _float(r, "diff_t_low", path),
                _float(r, "diff_t_high", path),
                int(float(n)),
                source,
            )
        )
    return out


def forest_plot(rows: Sequence[ForestRow], path: str | Path, title: str | None = None) -> Path:
    """Draw ``rows`` (top to bottom, grouped by :attr:`ForestSpec.group`) with their intervals
    and a vertical line at zero; written atomically as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels: list[str] = []
    ys: list[float] = []
    heads: list[tuple[float, str]] = []
    y, group = 0.0, None
    for r in rows:
        if r.spec.group != group:
            group = r.spec.group
            y += 0.6
            heads.append((y, group))
            y += 1.0
        ys.append(y)
        labels.append(r.label)
        y += 1.0
    fig, ax = plt.subplots(figsize=(9.5, 0.28 * y + 1.2))
    colors = {"ppo-multi": "tab:orange", "ppo": "tab:green"}
    lo_x, hi_x = XLIM
    for r, yy in zip(rows, ys, strict=True):
        base = r.spec.pair.split(" vs ")[1]
        c = colors.get(base, "tab:blue")
        ax.plot([max(r.low, lo_x), min(r.high, hi_x)], [yy, yy], color=c, lw=1.6)
        ax.plot([r.diff], [yy], "o", color=c, ms=4.5)
        for end, x, mark in ((r.low, lo_x, "<"), (r.high, hi_x, ">")):
            if (end < x) if mark == "<" else (end > x):  # the interval runs off the axis
                ax.plot([x], [yy], mark, color=c, ms=5)
    ax.set_xlim(lo_x, hi_x)
    ax.axvline(0.0, color="black", lw=0.8)
    for yy, g in heads:
        ax.text(0.0, yy, g, transform=ax.get_yaxis_transform(), ha="left", va="center",
                fontsize=8.5, fontweight="bold")  # fmt: skip
    ax.set_yticks(ys, labels, fontsize=7.5)
    ax.set_ylim(y, 0)
    ax.set_xlabel(
        "NDP minus baseline: success area (95% t-interval); < 0: NDP behind\n"
        "orange: vs PPO-multi; green: vs PPO"
    )
    ax.set_title(title or "Does NDP beat its baselines? Every study's difference", fontsize=10)
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    out = atomic_savefig(fig, path, dpi=110)
    plt.close(fig)
    return out


def forest_markdown(rows: Sequence[ForestRow], header: Sequence[str] = ()) -> str:
    """The rows as a Markdown table (difference, interval, whether it excludes zero) with each
    row's source report."""
    lines = [*header, "| group | row | NDP - baseline | 95% t-interval | excludes 0 | source |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        ex = "below" if r.high < 0 else ("above" if r.low > 0 else "no")
        lines.append(
            f"| {r.spec.group} | {r.label} | {r.diff:+.3f} | [{r.low:+.3f}, {r.high:+.3f}] | "
            f"{ex} | {r.source} |"
        )
    return "\n".join(lines) + "\n"


def write_overview(
    root: str | Path, out: str | Path, command: str, commit: str, date: str
) -> list[Path]:
    """``ndp report ROOT --overview --out OUT``: ``OUT.png`` (the forest plot), ``OUT.md`` and
    ``OUT.csv`` from :data:`FOREST_ROWS` under ``root``."""
    rows = read_forest(root)
    stem = Path(out)
    stem.parent.mkdir(parents=True, exist_ok=True)
    png = forest_plot(rows, stem.with_name(stem.name + ".png"))
    head = [
        "# Every study's NDP minus baseline difference (the README's forest plot)",
        "",
        f"Command: `{command}`  ",
        f"Commit: {commit}, date: {date}. Read from the committed CSVs under the results root; "
        "each row's source report is in its last column.",
        "",
    ]
    md = stem.with_name(stem.name + ".md")
    atomic_write_text(md, forest_markdown(rows, head))
    lines = ["group,condition,task,pair,metric,n,diff,t_low,t_high,source"]
    for r in rows:
        s = r.spec
        src = r.source.replace('"', "'")
        lines.append(f'"{s.group}","{s.condition}","{s.task}","{s.pair}",{s.metric},{r.n},'
                     f'{r.diff},{r.low},{r.high},"{src}"')  # fmt: skip
    csv_path = stem.with_name(stem.name + ".csv")
    atomic_write_text(csv_path, "\n".join(lines) + "\n")
    return [png, md, csv_path]
