"""``ndp sweep`` and ``ndp report``: thin entry points over :mod:`ndp.experiments.sweep`,
:mod:`ndp.experiments.studies` and :mod:`ndp.experiments.report` (docs/experiments.md).

Examples::

    ndp sweep paper-five --seeds 0 --steps 20000              # a named study, local pool
    ndp sweep paper-five --backend ray                        # the same grid on a local Ray
    ndp sweep paper-five --backend ray --address HOST:6379    # ... on an existing cluster
    ndp sweep --tasks point-mass --methods ndp ppo --seeds 0 1 --steps 4096 -o lr=3e-4,1e-3
    ndp sweep ablations --skip-unavailable --dry-run          # what would run, and how
    ndp report runs/sweep/paper-five --out docs/results/paper-five

Nothing heavy is imported before the options are parsed (``--help`` answers at once).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

from ndp.checks import check_int
from ndp.experiments.run_kinds import run_kind

if TYPE_CHECKING:
    from ndp.experiments.study import Arm
    from ndp.experiments.sweep.jobs import Job

SWEEP_DESCRIPTION = (
    "Run a grid of training runs: a named STUDY, or --tasks x --methods x --seeds x overrides "
    "(-o KEY=V1,V2: several values make a grid axis). Every run is an ordinary run directory "
    "RUNS_DIR/<task>-<label>-s<seed>; finished runs are skipped, interrupted ones continue from "
    "their checkpoint, a failed run is retried once and then reported. Ctrl-C stops every run "
    "at its last checkpoint; the same command continues. Options after -- go to every run's "
    "trainer."
)
REPORT_DESCRIPTION = (
    "Tables (Markdown, CSV) and learning curves (PNG per task) from run directories: success at "
    "budgets, success area, final success and final live return per task x method, mean +- std "
    "over seeds; imitation runs: test MSE and DTW. Refuses when seeds are missing from a cell "
    "(--allow-missing marks them instead). Every output carries the command, commit and date."
)


def _study_epilog() -> str:
    from ndp.experiments.studies import STUDIES

    lines = ["studies (docs/experiments.md):"]
    for s in STUDIES.values():
        unit = run_kind(s.kind).unit
        lines.append(
            f"  {s.name:<12} {s.title} (default {s.steps:,} {unit}, seeds "
            f"{' '.join(map(str, s.seeds))})"
        )
    return "\n".join(lines)


def sweep_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="ndp sweep",
        description=SWEEP_DESCRIPTION,
        epilog=_study_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("study", nargs="?", metavar="STUDY", help="a named study (see below)")
    p.add_argument("--tasks", nargs="+", help="tasks (a study: instead of its own)")
    p.add_argument("--methods", nargs="+", help="methods (grid); a study: only its arms of these")
    p.add_argument("--arms", nargs="+", help="a study: only these arms (labels)")
    p.add_argument("--seeds", nargs="+", type=int, help="seeds (default: the study's, or 0)")
    p.add_argument(
        "--steps",
        "--epochs",
        dest="steps",
        type=int,
        help="budget per run: env steps (RL), epochs (imitation); default: the study's",
    )
    p.add_argument(
        "-o",
        "--override",
        action="append",
        default=[],
        metavar="KEY=V[,V...]",
        help="a trainer option for every run (one value) or a grid axis (several), e.g. "
        "lr=1e-3, k=3,5,7, param_noise=true",
    )
    p.add_argument(
        "--runs-dir", type=Path, help="default runs/sweep/<study> (grid: runs/sweep/grid)"
    )
    _sweep_run_options(p)
    _sweep_output_options(p)
    return p


def _sweep_run_options(p: argparse.ArgumentParser) -> None:
    """``ndp sweep``'s options on how the runs are executed (backend, jobs, retries, ...)."""
    p.add_argument("--backend", choices=("local", "ray"), default="local")
    p.add_argument(
        "--address", help="--backend ray: join this cluster (default: start a local Ray)"
    )
    p.add_argument("--jobs", type=int, help="runs at once (default: the cores; ray: its CPUs)")
    p.add_argument("--num-envs", type=int, default=4, help="parallel envs per RL run (default 4)")
    p.add_argument(
        "--vector",
        choices=("auto", "sync"),
        help="vector env of each RL run (default: sync with several jobs, auto with one)",
    )
    p.add_argument("--retries", type=int, default=1, help="retries of a failed run (default 1)")
    p.add_argument(
        "--no-wait-busy",
        dest="wait_busy",
        action="store_false",
        help="report runs that another sweep is training as busy (exit 1) instead of waiting "
        "for them after this sweep's own runs",
    )
    p.add_argument(
        "--progress-every", type=float, default=30.0, help="seconds between progress lines"
    )
    p.add_argument(
        "--skip-unavailable",
        action="store_true",
        help="leave out arms whose trainer options this version lacks",
    )


def _sweep_output_options(p: argparse.ArgumentParser) -> None:
    """``ndp sweep``'s options on what it prints and writes (dry run, list, report, archives)."""
    p.add_argument("--dry-run", action="store_true", help="list the runs and their state; run none")
    p.add_argument(
        "--report",
        type=Path,
        metavar="OUT",
        help="at the end, write the report OUT.md / OUT.csv / OUT-<task>.png",
    )
    p.add_argument("--list", action="store_true", help="list the studies with their arms")
    p.add_argument(
        "--pack",
        type=Path,
        metavar="ARCHIVE",
        help="at the end (with --dry-run: now), add the sweep's finished runs to ARCHIVE "
        "(.tar.gz, without checkpoints) so that a later session on another machine has them",
    )
    p.add_argument(
        "--pack-unfinished",
        action="store_true",
        help="with --pack: also add the unfinished runs that have a checkpoint, with it (the "
        "next machine's sweep resumes them there instead of starting them again)",
    )
    p.add_argument(
        "--unpack",
        type=Path,
        metavar="ARCHIVE",
        help="first restore the runs of ARCHIVE (--pack) into the runs directory (existing run "
        "directories are left as they are)",
    )


def report_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="ndp report", description=REPORT_DESCRIPTION)
    p.add_argument(
        "run_dirs",
        nargs="+",
        metavar="RUN_DIRS",
        help="run directories, or directories holding them",
    )
    p.add_argument("--out", type=Path, help="output stem (default FIRST_RUN_DIR/report)")
    p.add_argument(
        "--seeds", nargs="+", type=int, help="seeds every cell needs (default: all found)"
    )
    p.add_argument("--budgets", nargs="+", type=float, help="env steps for 'success @ b'")
    p.add_argument("--tasks", nargs="+", help="only these tasks, in this order")
    p.add_argument("--methods", nargs="+", help="only these method labels, in this order")
    p.add_argument(
        "--allow-missing",
        action="store_true",
        help="mark cells with missing seeds instead of refusing",
    )
    _report_output_options(p)
    _report_eval_options(p)
    return p


def _report_eval_options(p: argparse.ArgumentParser) -> None:
    """``ndp report``'s own deterministic evaluation of each finished RL run's final policy."""
    p.add_argument(
        "--eval-episodes",
        type=int,
        default=0,
        metavar="N",
        help="add each finished RL run's deterministic success over N fresh episodes "
        "(ndp rl eval; cached in the run as eval-det-eN.json; default 0: off)",
    )
    p.add_argument(
        "--eval-seed",
        type=int,
        default=None,
        metavar="S",
        help="with --eval-episodes N: episode seeds S .. S+N-1 (default 10,000, the periodic "
        "evaluation's fixed seeds; e.g. 20000: disjoint from them), read from or written to "
        "the run as eval-det-eN-sS.json, the file of ndp rl eval --episodes N --seed S "
        "--mode deterministic --save",
    )


def _report_output_options(p: argparse.ArgumentParser) -> None:
    """``ndp report``'s options on what the report shows and writes (title, plots, study, tests)."""
    p.add_argument("--title", default=None, help="the table's title (default: the study's)")
    p.add_argument("--no-plots", action="store_true", help="tables only")
    p.add_argument(
        "--overview",
        action="store_true",
        help="RUN_DIRS is the results root (docs/results): read the committed study CSVs, not "
        "runs, and write the forest plot of every study's NDP minus baseline difference "
        "(ndp.experiments.report.forest) to OUT.png / .md / .csv",
    )
    p.add_argument(
        "--study",
        metavar="NAME",
        help="the named study the runs belong to: with conditions (release-conditions), add the "
        "condition x method tables (bootstrap intervals, IQM, P(NDP > baseline), permutation "
        "p); with readings (ndp-regimes, ndp-regimes-1m, mt50-attribution), apply its "
        "pre-registered readings; "
        "without --methods, the study's arms (and those its conditions take from other "
        "studies' runs: off-policy) that have runs",
    )
    p.add_argument(
        "--compare",
        nargs="+",
        default=[],
        metavar="A:B",
        help="a registered family of tests: A - B per task for each pair of method labels, "
        "Holm-adjusted over the whole family, paired sign-flip p beside "
        "(<out>-family.csv)",
    )
    p.add_argument(
        "--compare-pooled",
        action="store_true",
        help="with --compare: each pair also over all tasks (stratified), in the same family",
    )
    p.add_argument(
        "--compare-holm",
        choices=("all", "pooled", "tasks"),
        default="all",
        help="with --compare: the rows the registered family holds (Holm over them); the "
        "others are descriptions: 'pooled' tests the rows over all tasks only (default all)",
    )


def _split_extra(argv: list[str]) -> tuple[list[str], list[str]]:
    if "--" in argv:
        i = argv.index("--")
        return argv[:i], argv[i + 1 :]
    return argv, []


def _pick(kind: str, requested: list[str] | None, known: list[str]) -> list[str]:
    from ndp.experiments.sweep import close_hint

    if not requested:
        return known
    for r in requested:
        if r not in known:
            raise ValueError(
                f"{kind}: {r!r} is not one of this study's {kind}{close_hint(r, known)}"
            )
    return list(requested)


class SweepGrid(TypedDict):
    """The sweep the options describe (:func:`build_grid`)."""

    name: str
    kind: str
    tasks: list[str]
    arms: list[Arm]
    seeds: list[int]
    steps: int
    budgets: list[float] | None
    notes: list[str]


def build_grid(args: argparse.Namespace, extra: list[str]) -> SweepGrid:
    """The sweep the options describe, validated (ValueError before anything starts)."""
    from ndp.experiments.sweep import apply_overrides, check_tasks, parse_overrides

    notes: list[str] = []
    if args.study:
        kind, name, arms, tasks, seeds, steps, budgets = _study_grid(args, notes)
    else:
        kind, name, arms, tasks, seeds, steps, budgets = _plain_grid(args)
    if steps < 1:
        raise ValueError(f"--steps: expected a budget >= 1, got {steps}")
    if any(s < 0 for s in seeds):
        raise ValueError(f"--seeds: expected seeds >= 0, got {seeds}")
    tasks = check_tasks(tasks, kind)
    overrides = parse_overrides(args.override, kind)
    arms = apply_overrides(arms, overrides, extra)
    kept = _trainable(arms, tasks, name, args.skip_unavailable, notes)
    return {
        "name": name,
        "kind": kind,
        "tasks": tasks,
        "arms": kept,
        "seeds": list(seeds),
        "steps": steps,
        "budgets": budgets,
        "notes": notes,
    }


_Grid = tuple[str, str, "list[Arm]", list[str], list[int], int, "list[float] | None"]
"""(kind, name, arms, tasks, seeds, steps, budgets) of a sweep before its checks."""


def _study_grid(args: argparse.Namespace, notes: list[str]) -> _Grid:
    """The grid of ``args.study`` narrowed by the options; its arms left out are noted in
    ``notes`` (an arm named with ``--arms`` that is not available: ValueError)."""
    from ndp.experiments.studies import get_study
    from ndp.experiments.sweep import check_methods

    study = get_study(args.study)
    kind, name = study.kind, study.name
    keep, pending = study.available()
    specs = {a.label: a for a in study.arm_specs()}
    labels = _pick("arms", args.arms, list(specs))
    if not args.arms:
        labels = [lb for lb in labels if specs[lb].in_default]
    for a, why in pending:
        if args.arms and a.label in args.arms:
            raise ValueError(f"{name}: arm {a.label!r} is not available: {why}")
        if a.label in labels:
            notes.append(f"{name}: arm {a.label!r} left out: {why}")
    have = {a.label for a in keep}
    arms = [specs[lb].arm() for lb in labels if lb in have]
    if args.methods:
        check_methods(args.methods)
        arms = [a for a in arms if a.algo in args.methods]
    tasks = list(args.tasks) if args.tasks else list(study.task_list())
    seeds = args.seeds if args.seeds is not None else list(study.seeds)
    steps = args.steps if args.steps is not None else study.steps
    return kind, name, arms, tasks, seeds, steps, [f * steps for f in study.budgets]


def _plain_grid(args: argparse.Namespace) -> _Grid:
    """The grid of ``--tasks`` x ``--methods`` without a study (one arm per method)."""
    from ndp.experiments.study import Arm
    from ndp.experiments.sweep import check_methods

    if args.arms:
        raise ValueError("--arms: only with a STUDY (a grid takes --methods)")
    if not args.tasks or not args.methods:
        raise ValueError(
            "sweep: name a STUDY, or give --tasks and --methods for a grid "
            "(ndp sweep --list shows the studies)"
        )
    methods = check_methods(args.methods)
    il = [m.startswith("il-") for m in methods]
    if any(il) and not all(il):
        raise ValueError("--methods: imitation (il-*) and RL methods cannot share one grid")
    kind = "il" if all(il) else "rl"
    seeds = args.seeds if args.seeds is not None else [0]
    steps = args.steps if args.steps is not None else run_kind(kind).default_budget
    return kind, "grid", [Arm(m, m) for m in methods], list(args.tasks), seeds, steps, None


def _trainable(
    arms: list[Arm], tasks: list[str], name: str, skip: bool, notes: list[str]
) -> list[Arm]:
    """The arms whose options the trainer knows; with ``skip`` the others are left out (and
    noted), else the first is refused (UnknownOptionError). ValueError when none is left."""
    from ndp.experiments.sweep import UnknownOptionError, check_arms

    kept = []
    for arm in arms:
        try:
            check_arms([arm], tasks, name)
        except UnknownOptionError as exc:
            if not skip:
                raise
            notes.append(
                f"{name}: arm {arm.label!r} left out: {exc.option} is unknown to the "
                f"trainer" + (f" (needs {arm.requires})" if arm.requires else "")
            )
            continue
        kept.append(arm)
    if not kept:
        raise ValueError(f"{name}: no arms left to run")
    return kept


def _pack(jobs: Sequence[Job], out: Path, unfinished: bool = False) -> None:
    """Write the finished runs of ``jobs`` to the archive ``out`` (``--pack``), and with
    ``unfinished`` those that have a checkpoint to resume from (``--pack-unfinished``)."""
    from ndp.experiments.study import is_finished
    from ndp.experiments.sweep.archive import CHECKPOINT, pack

    done, partial = [], []
    for j in jobs:
        if not j.run_dir.is_dir():
            continue
        if is_finished(j.run_dir, j.arm):
            done.append(j.run_dir)
        elif unfinished and (j.run_dir / CHECKPOINT).is_file():
            partial.append(j.run_dir)
    names = pack(done, out, unfinished=partial)
    more = f" and {len(partial)} unfinished ones with their checkpoint" if unfinished else ""
    print(f"pack: {len(done)} finished runs of this sweep{more} written to {out} "
          f"({len(names)} runs in the archive)", flush=True)  # fmt: skip


def sweep_command(argv: list[str]) -> int:
    """``ndp sweep [STUDY] [options] [-- trainer options]``."""
    own, extra = _split_extra(list(argv))
    args = sweep_parser().parse_args(own)
    if args.list:
        return _list_studies()
    _check_sweep_args(args)
    g = build_grid(args, extra)
    from ndp.experiments.study import default_vector
    from ndp.experiments.sweep import default_workers, make_jobs, plan_lines, run_sweep

    for n in g["notes"]:
        print(n, flush=True)
    runs_dir = args.runs_dir or Path("runs") / "sweep" / g["name"]
    from ndp.io import check_output_path

    # the same check in a dry run as in a real one (nothing is made in a dry run)
    made_here = not Path(runs_dir).exists()
    check_output_path(runs_dir, "runs_dir", folder=True, create=not args.dry_run)
    jobs_at_once = args.jobs or default_workers()
    vector = args.vector or default_vector(jobs_at_once)
    jobs = make_jobs(
        g["tasks"],
        g["arms"],
        g["seeds"],
        g["steps"],
        runs_dir,
        num_envs=args.num_envs,
        vector=vector,
    )
    from ndp.experiments.sweep import check_plan

    if args.unpack is not None:
        _unpack(args.unpack, Path(runs_dir))
    check_plan(jobs)
    if args.dry_run:
        print(f"{g['name']}: {len(jobs)} runs in {runs_dir} (dry run: nothing started)")
        print("\n".join(plan_lines(jobs)))
        if args.pack is not None:
            _pack(jobs, args.pack, args.pack_unfinished)
        return 0
    try:
        result = run_sweep(
            jobs,
            backend=args.backend,
            workers=args.jobs,
            address=args.address,
            retries=args.retries,
            wait_busy=args.wait_busy,
            progress_every=args.progress_every,
        )
    except BaseException:  # e.g. a Ray cluster that cannot be reached: no empty folder left
        if made_here and Path(runs_dir).is_dir() and not any(Path(runs_dir).iterdir()):
            Path(runs_dir).rmdir()
        raise
    if args.pack is not None:
        _pack(jobs, args.pack, args.pack_unfinished)
    if args.report is not None and not result.interrupted:
        _sweep_report(args, argv, g, jobs)
    return result.exit_code


def _check_sweep_args(args: argparse.Namespace) -> None:
    """The sweep's own options that need no study (ValueError naming the option)."""
    if args.jobs is not None:
        check_int("--jobs", args.jobs, 1)
    check_int("--retries", args.retries, 0)
    if args.pack_unfinished and args.pack is None:
        raise ValueError("--pack-unfinished: only with --pack ARCHIVE")
    if args.address and args.backend != "ray":
        raise ValueError("--address: only with --backend ray")


def _unpack(archive: Path, runs_dir: Path) -> None:
    """``--unpack``: restore the archive's runs into ``runs_dir`` (those there are kept)."""
    from ndp.experiments.sweep.archive import unpack

    restored, kept = unpack(archive, runs_dir)
    partial = sum(not (runs_dir / n / "done.json").is_file() for n in restored)
    print(f"unpack: {len(restored)} runs restored from {archive} into {runs_dir} "
          f"({partial} unfinished, to resume from their checkpoint); {len(kept)} already "
          "there, left as they are", flush=True)  # fmt: skip


def _sweep_report(
    args: argparse.Namespace, argv: list[str], g: SweepGrid, jobs: Sequence[Job]
) -> None:
    """``--report OUT``: the report of the sweep's runs (missing seeds marked)."""
    from ndp.experiments.report import report
    from ndp.experiments.studies import get_study
    from ndp.provenance import portable_command

    cmd = "ndp sweep " + shlex.join(portable_command(argv))
    unit = run_kind(g["kind"]).unit
    dirs = [j.run_dir for j in jobs if j.run_dir.is_dir()]
    out = report(
        dirs,
        args.report,
        cmd,
        seeds=g["seeds"],
        budgets=g["budgets"],
        allow_missing=True,
        title=f"{g['name']} ({g['steps']:,} {unit} per run)",
        study=args.study if args.study and get_study(args.study).conditions else None,
    )
    print(f"report: {out['markdown']}, {out['csv']}, {len(out['png'])} PNG")


def _list_studies() -> int:
    from ndp.experiments.studies import STUDIES

    for s in STUDIES.values():
        keep, pending = s.available()
        print(f"{s.name}: {s.title}\n  {s.doc}")
        print(f"  tasks: {' '.join(s.task_list())}")
        print("  arms: " + ", ".join(f"{a.label} ({' '.join(a.args) or a.algo})" for a in keep))
        if pending:
            print("  not yet available: " + ", ".join(f"{a.label} ({why})" for a, why in pending))
        unit = run_kind(s.kind).unit
        print(f"  seeds {' '.join(map(str, s.seeds))}, {s.steps:,} {unit} per run\n")
    return 0


def report_command(argv: list[str]) -> int:
    """``ndp report RUN_DIRS... [options]``."""
    from ndp.provenance import portable_command

    args = report_parser().parse_args(argv)
    from ndp.experiments.report import report
    from ndp.experiments.studies import get_study

    _check_eval_options(args)
    out = args.out or Path(args.run_dirs[0]) / "report"
    command = "ndp report " + shlex.join(portable_command(argv))
    if args.overview:
        return _overview(args, out, command)
    res = report(
        args.run_dirs,
        out,
        command,
        seeds=args.seeds,
        budgets=args.budgets,
        tasks=args.tasks,
        methods=args.methods,
        allow_missing=args.allow_missing,
        title=args.title or (get_study(args.study).title if args.study else "Report"),
        plots=not args.no_plots,
        eval_episodes=args.eval_episodes,
        eval_seed=args.eval_seed,
        study=args.study,
        compare=args.compare,
        compare_pooled=args.compare_pooled,
        compare_holm=args.compare_holm,
    )
    print(Path(res["markdown"]).read_text())
    written = [res["markdown"], res["csv"], *res["section_csv"], *res["png"]]
    print(f"wrote {', '.join(written)}")
    if res["missing"]:
        print(
            f"ndp report: WARNING: seeds missing from {len(res['missing'])} cells (marked)",
            file=sys.stderr,
        )
    return 0


def _check_eval_options(args: argparse.Namespace) -> None:
    """``--eval-episodes`` and ``--eval-seed`` checked before any run is read (one line naming
    the option)."""
    check_int("--eval-episodes", args.eval_episodes, 0)
    if args.eval_seed is None:
        return
    if args.eval_episodes == 0:
        raise ValueError(
            f"--eval-seed: needs --eval-episodes N > 0 (the report's own evaluation), got "
            f"--eval-seed {args.eval_seed} alone"
        )
    if args.eval_seed < 0:
        raise ValueError(f"--eval-seed: expected a seed >= 0, got {args.eval_seed}")


def _overview(args: argparse.Namespace, out: Path, command: str) -> int:
    """``ndp report RESULTS_ROOT --overview --out OUT``: the forest plot from committed CSVs."""
    import datetime as dt

    from ndp.experiments.report.forest import write_overview
    from ndp.provenance import git_commit

    if len(args.run_dirs) != 1:
        raise ValueError(
            f"run_dirs: --overview reads one results root (docs/results), got {args.run_dirs}"
        )
    date = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M")
    written = write_overview(args.run_dirs[0], out, command, git_commit(), date)
    print(Path(written[1]).read_text())
    print(f"wrote {', '.join(map(str, written))}")
    return 0


CONFIG_COMMANDS = {"sweep": sweep_command, "report": report_command}
"""Commands that parse their own options (see ndp.cli)."""


def add_subparser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``sweep`` and ``report`` for ``ndp --help`` (parsed by CONFIG_COMMANDS)."""
    sub.add_parser("sweep", help="run a study or a grid of runs (local pool or Ray), resumable")
    sub.add_parser("report", help="tables and learning curves from run directories")
