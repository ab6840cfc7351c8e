"""A report's provenance: the command, this checkout's commit and the date, the commits and
environment fingerprints the runs were trained at (:func:`provenance`), and the header lines
that mark lost commits and MIXED tables (:func:`provenance_lines`)."""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from typing import TypedDict

from ndp.experiments.report.cells import CsvRow
from ndp.experiments.rows import RunInfo
from ndp.provenance import commit_in_history, fingerprint_text, git_commit

LOST = "lost: not in this repository's history"
"""How a table marks a run's commit that no ref of the repository reaches
(:func:`ndp.provenance.commit_in_history`)."""


def commits_text(commits: Sequence[str]) -> str:
    """The runs' commits for a table's header, each one the repository's history lacks marked
    ``(lost: ...)``; ``not recorded`` for none."""
    if not commits:
        return "not recorded"
    return ", ".join(c + (f" ({LOST})" if commit_in_history(c) is False else "") for c in commits)


def environments(infos: Sequence[RunInfo]) -> list[tuple[str, int]]:
    """The distinct environment fingerprints of the runs' sessions, each with how many runs
    have it (a run resumed under another fingerprint counts under both), most runs first."""
    count: dict[str, int] = {}
    for i in infos:
        for fp in {fingerprint_text(f) for f in i.fingerprints} or {"not recorded"}:
            count[fp] = count.get(fp, 0) + 1
    return sorted(count.items(), key=lambda kv: (-kv[1], kv[0]))


def per_commit(infos: Sequence[RunInfo]) -> dict[str, int]:
    """How many runs have a session at each commit (a run resumed at another commit counts
    under both)."""
    count: dict[str, int] = {}
    for i in infos:
        for c in i.commits:
            count[c] = count.get(c, 0) + 1
    return dict(sorted(count.items()))


class ReportProvenance(TypedDict):
    """A report's provenance (what :func:`ndp.experiments.report.provenance.provenance` returns)."""

    command: str
    commit: str
    date: str
    run_commits: list[str]
    run_environments: list[tuple[str, int]]
    n_runs: int
    runs_per_commit: dict[str, int]


class ReportResult(ReportProvenance):
    """What :func:`ndp.experiments.report.report` returns: its provenance, the numbers and the
    paths it wrote."""

    seeds: list[int]
    budgets: list[int]
    rows: list[CsvRow]
    markdown: str
    csv: str
    section_csv: list[str]
    png: list[str]
    missing: list[tuple[str, str, list[int]]]


def stamp(prov: ReportProvenance) -> dict[str, str]:
    """The columns every row of a report's CSVs ends with: command, commit and date."""
    return {"command": prov["command"], "commit": prov["commit"], "date": prov["date"]}


def figure_foot(prov: ReportProvenance) -> str:
    """The line under every figure of a report: command, commit and date."""
    return f"{prov['command']}  |  commit {prov['commit']}  |  {prov['date']}"


def provenance_lines(prov: ReportProvenance) -> list[str]:
    """The header's lines on the runs' environments, and a MIXED warning when the runs were
    trained at several commits or under several environment fingerprints."""
    envs: list[tuple[str, int]] = prov.get("run_environments", [])
    total = prov.get("n_runs", sum(n for _, n in envs))
    if len(envs) == 1:
        lines = [f"Runs' environment: {envs[0][0]} (every run).  "]
    else:
        each = (f"{fp} ({n} run{'' if n == 1 else 's'})" for fp, n in envs)
        lines = ["Runs' environments: " + "; ".join(each) + ".  "]
    mixed = []
    commits = prov.get("run_commits", [])
    if len(commits) > 1:
        per = prov.get("runs_per_commit", {})
        named = [
            f"{c}: {per[c]} run{'' if per[c] == 1 else 's'}" if c in per else c for c in commits
        ]
        mixed.append(f"{len(commits)} commits ({', '.join(named)})")
    if len(envs) > 1:
        mixed.append(f"{len(envs)} environment fingerprints (above)")
    if mixed:
        lines.append(
            f"**MIXED: the {total} runs of this table were trained at "
            + " and ".join(mixed)
            + ". Their differences can come from the code or the environment as well as the "
            "method; the per-run record is each run's provenance.json.**  "
        )
    return lines


def provenance(command: str, runs: Sequence[RunInfo]) -> ReportProvenance:
    """A report's provenance: ``command``, this checkout's commit and the date, and of the
    ``runs`` (the finished runs it reads) their commits, environments and count."""
    return {
        "command": command,
        "commit": git_commit(),
        "date": dt.datetime.now().strftime("%Y-%m-%d %H:%M"),
        "run_commits": sorted({x for i in runs for x in i.commits}),
        "run_environments": environments(runs),
        "n_runs": len(runs),
        "runs_per_commit": per_commit(runs),
    }
