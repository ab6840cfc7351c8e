"""Publish trained policies (``zoo/``): for each task x method, the best seed of a finished study.

For every task and method the finished runs ``RUNS/<task>-<method>-s<seed>`` of the given seeds
are ranked by their deterministic success over ``--select-episodes`` episodes (the report's
cached ``eval-det-e<N>.json``, episode seeds 10,000 on); the best one (ties: the lower seed) is
exported (``ndp.export_policy``: safetensors + JSON, no pickle) to ``OUT/<task>-<method>`` and
evaluated again, from the export, over ``--episodes`` fresh episodes (seeds 20,000 on, disjoint
from the selection's, so the published number is not the maximum over seeds it was picked by).
``OUT/README.md`` and ``OUT/zoo.json`` list every policy with its source run, training commit,
selection and published success, and the command, commit and date. An existing export is
replaced only after the new one is complete. A grid that does not cover every policy the
index already lists is refused (``--replace-index`` drops those), as is one without any runs.

    python benchmarks/zoo.py --runs-dir RUNS --out zoo
    python benchmarks/zoo.py --runs-dir RUNS OTHER_RUNS --rule best-method --always ndp \
        --tasks push-v3 throw --methods ndp ppo-multi ppo sac --seeds 0 1 2 --out zoo

``--rule best-method`` publishes per task only the method with the highest mean deterministic
success area over ``--seeds`` (the studies' metric; every seed finished), and the methods of
``--always``; each row keeps its seed context (every candidate's per-seed areas, mean and IQM),
and the card says "seed i of n; n-seed IQM X".
    python benchmarks/zoo.py --cards --out zoo     # only README.md files and policy.json specs

Each policy also gets its model card (``OUT/<policy>/README.md``, Hugging Face format:
``ndp.rl.card``) from its ``policy.json`` and its row of the index, and its ``policy.json`` the
task's spec (``"spec"``, so it loads without the simulators) where it lacks one; ``--cards``
does only that and rewrites ``OUT/README.md`` from ``OUT/zoo.json`` (no runs needed; the
weights are never touched).

The zoo ships inside the package (``src/ndp/zoo/policies``; ``zoo/`` in a checkout points
there): load one with ``ndp.load_policy("zoo:push-v3-ndp")`` (docs/policies.md, "Trained policies").
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

TASKS = ("push-v3", "soccer-v3", "faucet-open-v3", "throw", "pick", "reach-v3")
METHODS = ("ndp", "ppo", "ppo-multi", "vices", "dyne")
SELECT_SEED = 10_000
"""First episode seed of the selection (the report's ``--eval-episodes`` seeds)."""
PUBLISH_SEED = 20_000
"""First episode seed of the published evaluation (disjoint from the selection's)."""


def find_run(runs: list[Path], task: str, method: str, seed: int) -> Path | None:
    """The run ``<task>-<method>-s<seed>`` in the first of ``runs`` that holds it, or None."""
    for root in runs:
        run = root / f"{task}-{method}-s{seed}"
        if run.is_dir():
            return run
    return None


SELECTIONS = ("checkpoint", "final-eval")
"""How the seed of a task x method is chosen: ``checkpoint``: the final checkpoint's
deterministic success over ``--select-episodes`` episodes (seeds 10,000 on; needs every seed's
checkpoint); ``final-eval``: the run's last periodic deterministic evaluation in its
metrics.csv (the final policy's success at any step on the study's fixed evaluation seeds;
ties: the higher deterministic success area), which archived runs (metrics only) keep."""


def pick_best(
    runs: list[Path], task: str, method: str, seeds: list[int], episodes: int,
    select: str = "checkpoint",
) -> Any:  # fmt: skip
    """(seed, run, selection success) of the best finished run by ``select`` (SELECTIONS;
    ties: the lower seed), or None when none finished."""
    from ndp.experiments.report import det_success
    from ndp.experiments.rows import det_numbers
    from ndp.experiments.study import is_finished
    from ndp.runs import read_metrics

    best, best_key = None, None
    for seed in seeds:
        run = find_run(runs, task, method, seed)
        if run is None or not is_finished(run, kind="rl"):
            continue
        if select == "final-eval":
            d = det_numbers(read_metrics(run))
            key = (d["det_final"], d["det_area"])
        else:
            key = (det_success(run, episodes), 0.0)
        if best_key is None or key > best_key:
            best, best_key = (seed, run, float(key[0])), key
    return best


TIMING_COLUMNS = ("charts/env_steps_per_s",)
"""Metrics columns that measure wall-clock speed (with every ``time/*`` column): the only ones
a re-run of the same command at the same commit may change."""


def learning_rows(run: Path) -> list[dict[str, str]]:
    """The run's metrics.csv rows without the wall-clock columns."""
    import csv

    with (run / "metrics.csv").open(newline="") as f:
        return [
            {k: v for k, v in row.items() if not k.startswith("time/") and k not in TIMING_COLUMNS}
            for row in csv.DictReader(f)
        ]


def retrain_command(run: Path, into: Path) -> str:
    """The command that trains ``run`` again into ``into/<run name>``, from its first session's
    recorded command line, with the commit to check out."""
    import shlex

    from ndp.provenance import user_command
    from ndp.runs.layout import provenance_sessions

    first = (provenance_sessions(run) or [None])[0]
    if not isinstance(first, dict) or not isinstance(first.get("argv"), list):
        return f"(no provenance.json in {run}: its command is not recorded)"
    argv = [str(a) for a in first["argv"]]
    i = argv.index("--run-dir") if "--run-dir" in argv else None
    if i is not None:
        argv[i + 1] = str(into / run.name)
    return f"git checkout {str(first.get('commit'))[:7]} && " + shlex.join(user_command(argv))


def exportable(run: Path, retrained: Path | None) -> tuple[Path, bool]:
    """The run to export for the chosen ``run``: itself when it holds its checkpoint, else its
    re-run ``retrained/<name>`` when that finished with the same learning metrics (every
    metrics.csv column but wall-clock ones equal, row by row: the same policy); (run, whether
    it is a verified re-run). Raises SystemExit naming the re-run command otherwise."""
    from ndp.experiments.study import is_finished

    if (run / "checkpoint.pt").is_file():
        return run, False
    where = retrained / run.name if retrained is not None else None
    if (
        where is None
        or not (where / "checkpoint.pt").is_file()
        or not is_finished(where, kind="rl")
    ):
        raise SystemExit(
            f"zoo: {run} holds no checkpoint (an archived run); train it again with "
            f"--retrained DIR: {retrain_command(run, retrained or Path('RETRAINED'))}"
        )
    if learning_rows(where) != learning_rows(run):
        raise SystemExit(
            f"zoo: {where} does not reproduce {run} (their metrics.csv differ outside the "
            "wall-clock columns); it is not the study's policy, so it is not published"
        )
    return where, True


def det_areas(runs: list[Path], task: str, method: str, seeds: list[int]) -> dict[int, float]:
    """Each seed's deterministic success area (the studies' metric: the mean of the periodic
    deterministic evaluations, ``ndp.experiments.rows.det_numbers``); empty unless every seed
    has a finished run with evaluations."""
    import math

    from ndp.experiments.rows import det_numbers
    from ndp.experiments.study import is_finished
    from ndp.runs import read_metrics

    out = {}
    for seed in seeds:
        run = find_run(runs, task, method, seed)
        if run is None or not is_finished(run, kind="rl"):
            return {}
        area = det_numbers(read_metrics(run))["det_area"]
        if math.isnan(area):
            return {}
        out[seed] = float(area)
    return out


def choose_methods(
    runs: list[Path], task: str, methods: list[str], seeds: list[int], always: list[str],
    arms: dict[str, str] | None = None,
) -> tuple[list[str], dict[str, Any]]:  # fmt: skip
    """The methods published for ``task`` under the best-method rule: the one with the highest
    mean deterministic success area over ``seeds`` among ``methods`` that have every seed
    (ties: the earlier in ``methods``), then those of ``always`` that have runs; and the
    context of the choice (each candidate's per-seed areas, mean and IQM). ``arms``: a
    method's run label where it differs from its name."""
    from ndp.experiments.report import stats

    context: dict[str, Any] = {}
    for m in methods:
        areas = det_areas(runs, task, (arms or {}).get(m, m), seeds)
        if areas:
            v = list(areas.values())
            context[m] = {"det_area": areas, "mean": float(sum(v) / len(v)),
                          "iqm": stats.iqm([[a] for a in v])}  # fmt: skip
    if not context:
        return [], context
    best = max(context, key=lambda m: (context[m]["mean"], -methods.index(m)))
    chosen = [best, *(m for m in always if m != best and m in context)]
    return chosen, context


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument(
        "--runs-dir",
        nargs="+",
        help="folders of the study's run directories, searched in order (not with --cards)",
    )
    p.add_argument(
        "--cards",
        action="store_true",
        help="only (re)write the model cards, the policies' task specs and OUT/README.md from "
        "OUT/zoo.json and each policy.json",
    )
    p.add_argument("--tasks", nargs="+", default=list(TASKS))
    p.add_argument(
        "--methods",
        nargs="+",
        default=list(METHODS),
        help="methods: run labels (RUNS/<task>-<label>-s<seed>), or NAME=LABEL to publish the "
        "runs of arm LABEL as <task>-NAME (ndp=ndp-nostale)",
    )
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument(
        "--rule",
        choices=("every-method", "best-method"),
        default="every-method",
        help="every-method: a policy per task x method; best-method: per task only the method "
        "with the highest mean deterministic success area over --seeds (every seed needed), "
        "plus --always",
    )
    p.add_argument(
        "--always",
        nargs="*",
        default=[],
        metavar="METHOD",
        help="with --rule best-method: methods published on every task beside the best one",
    )
    p.add_argument(
        "--select",
        choices=SELECTIONS,
        default="checkpoint",
        help="how a task x method's seed is chosen: checkpoint (its final checkpoint over "
        "--select-episodes episodes) or final-eval (the run's last periodic deterministic "
        "evaluation, kept by archived runs)",
    )
    p.add_argument(
        "--retrained",
        metavar="DIR",
        help="where a chosen run without its checkpoint (archived) was trained again by the "
        "same command at the same commit; its re-run is published only if its metrics equal "
        "the archived run's",
    )
    p.add_argument(
        "--replay",
        action="store_true",
        help="also record each policy's first published episode as <policy>/replay.gif "
        "(160 px, real time; the card shows it)",
    )
    p.add_argument("--select-episodes", type=int, default=20)
    p.add_argument("--episodes", type=int, default=50)
    p.add_argument(
        "--min-success", type=float, default=0.5, help="publish only a selection success >= this"
    )
    p.add_argument("--out", default="zoo")
    p.add_argument(
        "--replace-index",
        action="store_true",
        help="let this grid's index drop the published policies it does not cover (their "
        "directories are removed); without it such a grid is refused",
    )
    args = p.parse_args(argv)
    bad = [m for m in args.methods if m.count("=") > 1 or m.startswith("=") or m.endswith("=")]
    if bad:
        p.error(f"--methods: expected NAME or NAME=LABEL, got {' '.join(bad)}")
    arms = dict(m.split("=", 1) if "=" in m else (m, m) for m in args.methods)
    args.methods = list(arms)
    if args.cards:
        index = Path(args.out) / "zoo.json"
        if not index.is_file():
            p.error(f"--cards: {index} does not exist (publish the zoo first)")
        write_cards(Path(args.out))
        return 0
    if not args.runs_dir:
        p.error("--runs-dir: required (unless --cards)")
    for name in ("select_episodes", "episodes"):
        if getattr(args, name) < 1:
            p.error(
                f"--{name.replace('_', '-')}: expected an integer >= 1, got {getattr(args, name)}"
            )
    if not 0.0 <= args.min_success <= 1.0:
        p.error(f"--min-success: expected a number in [0, 1], got {args.min_success}")
    from ndp.experiments.sweep import check_tasks

    try:
        args.tasks = check_tasks(args.tasks)
    except ValueError as exc:
        p.error(f"--tasks: {exc}")
    runs, out = [Path(r) for r in args.runs_dir], Path(args.out)
    retrained = Path(args.retrained) if args.retrained else None
    if retrained is not None and not retrained.is_dir():
        p.error(f"--retrained: {retrained} is not a directory")
    for r in runs:
        if not r.is_dir():
            p.error(f"--runs-dir: {r} is not a directory")
    unknown = [m for m in args.always if m not in args.methods]
    if unknown:
        p.error(f"--always: {', '.join(unknown)} not among --methods ({' '.join(args.methods)})")
    index = out / "zoo.json"
    earlier = json.loads(index.read_text())["policies"] if index.is_file() else []
    grid = {(t, m) for t in args.tasks for m in args.methods}
    outside = [r["policy"] for r in earlier if (r["task"], r["method"]) not in grid]
    if outside and not args.replace_index:
        p.error(
            f"--tasks / --methods: {index} lists policies this grid does not cover "
            f"({', '.join(outside)}); name their tasks and methods too, or pass --replace-index "
            "to drop them"
        )
    found = [
        (t, m)
        for t, m in sorted(grid)
        for r in runs
        if any(r.glob(f"{t}-{arms[m]}-s*/metrics.csv"))
    ]
    if not found:
        p.error(
            f"--runs-dir: no runs of {' / '.join(args.tasks)} x {' / '.join(args.methods)} in "
            f"{' '.join(map(str, runs))} (expected RUNS/<task>-<method>-s<seed>); nothing written"
        )

    plan = {}
    for task in args.tasks:
        publish, context = choose_methods(runs, task, args.methods, args.seeds, args.always, arms)
        plan[task] = (list(args.methods) if args.rule == "every-method" else publish, context)
    dropped = [
        r["policy"]
        for r in earlier
        if (r["task"], r["method"]) in grid and r["method"] not in plan[r["task"]][0]
    ]
    if dropped and not args.replace_index:
        p.error(
            f"--rule {args.rule}: {index} lists policies this rule does not choose "
            f"({', '.join(dropped)}); pass --replace-index to drop them"
        )
    outside += dropped

    import torch

    torch.set_num_threads(1)
    from ndp.io import atomic_write_text
    from ndp.provenance import git_commit, portable_command, portable_path
    from ndp.rl.card import REPLAY_NAME
    from ndp.rl.evaluate import evaluate_policy, render
    from ndp.rl.policy import export_policy, load_policy
    from ndp.runs import run_commits

    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    left_out: list[str] = []
    for task in args.tasks:
        publish, context = plan[task]
        for method in publish:
            best = pick_best(
                runs, task, arms[method], args.seeds, args.select_episodes, args.select
            )
            if best is None:
                kept = [r for r in earlier if (r["task"], r["method"]) == (task, method)]
                kept = [r for r in kept if (out / r["policy"]).is_dir()]
                rows += [{**r, "carried_over": True} for r in kept]
                print(f"[zoo] {task} x {method}: no finished run of seeds {args.seeds}"
                      + ("; the published policy stays" if kept else ""), flush=True)  # fmt: skip
                continue
            seed, run, sel = best
            if sel < args.min_success:
                left_out.append(f"{task} x {method} (best: {sel:.2f}, seed {seed})")
                continue
            name = f"{task}-{method}"
            tmp = out / f".{name}.tmp"
            shutil.rmtree(tmp, ignore_errors=True)
            source, rerun = exportable(run, retrained)
            export_policy(source, tmp)
            ev = evaluate_policy(load_policy(tmp), args.episodes, True, PUBLISH_SEED)
            if args.replay:  # the first published episode, as the card shows it
                render(tmp, tmp / REPLAY_NAME, seed=PUBLISH_SEED, width=160, height=160)
            final = out / name
            old = out / f".{name}.old"
            if final.exists():
                final.rename(old)
            tmp.rename(final)
            shutil.rmtree(old, ignore_errors=True)
            cfg = json.loads((run / "config.json").read_text())
            row = {"policy": name, "task": task, "method": method, "arm": arms[method],
                   "seed": seed, "source_run": portable_path(run),
                   "trained_at": run_commits(source), "selection": args.select,
                   "steps": cfg.get("steps"), "k": cfg.get("policy", {}).get("k"),
                   "selection_success": sel, "success": ev["success_any"],
                   "success_final": ev["success_final"],
                   "episode_return": ev["episode_return"]}  # fmt: skip
            if rerun:
                row["retrained_run"] = portable_path(source)
                row["reproduces_source"] = True
            if method in context:
                row["seed_context"] = {"seeds": args.seeds, **context[method],
                                       "candidates": {m: round(c["mean"], 4)
                                                      for m, c in context.items()},
                                       "best_method": publish[0] == method}  # fmt: skip
            rows.append(row)
            print(f"[zoo] {name}: seed {seed}, selection {sel:.2f}, published "
                  f"{ev['success_any']:.2f}", flush=True)  # fmt: skip
    if not any(not r.get("carried_over") for r in rows) and not left_out:
        raise SystemExit(f"zoo: no finished runs of this grid in {runs}; nothing written")
    import shlex

    given = list(argv if argv is not None else sys.argv[1:])
    cmd = "python benchmarks/zoo.py " + shlex.join(portable_command(given))
    meta = {"command": cmd, "commit": git_commit(), "date": time.strftime("%Y-%m-%d"),
            "select_episodes": args.select_episodes, "episodes": args.episodes,
            "min_success": args.min_success, "rule": args.rule, "select": args.select,
            "policies": rows,
            "not_published": left_out}  # fmt: skip
    atomic_write_text(out / "zoo.json", json.dumps(meta, indent=2) + "\n")
    md = zoo_readme(meta)
    atomic_write_text(out / "README.md", md)
    write_cards(out, readme=False)
    for name in outside:  # --replace-index: dropped from the index just written
        shutil.rmtree(out / name, ignore_errors=True)
    print(md)
    return 0


def zoo_readme(meta: dict[str, Any]) -> str:
    """``OUT/README.md``: the table of the index ``meta`` (zoo.json)."""
    rows, left_out = meta["policies"], meta.get("not_published") or []
    md = [
        "# Trained policies",
        "",
        f"Generated by `{meta['command']}` at commit {meta['commit']}, {meta['date']} (from run "
        "directories on the development machine; each row names its source run and training "
        "commit).",
        "",
        (
            'Load one with `ndp.load_policy("zoo:<policy>")` (or `ndp rl eval zoo/<policy>`, '
            "`ndp rl render zoo/<policy>` in a checkout); the policies ship with the package "
            "(`ndp.zoo.list()`), each with its model card (`<policy>/README.md`); the format is "
            'in docs/policies.md, "Trained policies". '
        )
        + _rule_text(meta)
        + (
            f"Each is the seed with {_selection_text(meta)} of its task x method; "
            f"**success** is measured again from the export over {meta['episodes']} other "
            f"episodes (seeds {PUBLISH_SEED:,} on), deterministic, success at any step; its 95% "
            "interval (Wilson) is in the card."
        ),
        "",
        "| policy | task | method | seed | env steps | trained at | selection success | "
        "success | final success | return |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        note = " (from an earlier run of this script)" if r.get("carried_over") else ""
        md.append(
            f"| `{r['policy']}`{note} | {r['task']} | {r['method']} | {r['seed']} | "
            f"{r['steps']:,} | "
            f"{', '.join(r['trained_at']) or 'not recorded'} | {r['selection_success']:.2f} | "
            f"{r['success']:.2f} | {r['success_final']:.2f} | {r['episode_return']:.1f} |"
        )
    if left_out:
        md += ["", f"Not published (no seed reached {meta['min_success']:.2f} in the "
               "selection): " + "; ".join(left_out) + "."]  # fmt: skip
    return "\n".join(md) + "\n"


def _selection_text(meta: dict[str, Any]) -> str:
    """How the index ``meta`` chose each policy's seed, in words."""
    if meta.get("select") == "final-eval":
        return (
            "the best final deterministic evaluation in its run's metrics (the final policy on "
            "the study's fixed evaluation episodes; ties: the higher success area)"
        )
    return (
        f"the best deterministic success over {meta['select_episodes']} episodes (seeds "
        f"{SELECT_SEED:,} on)"
    )


def _rule_text(meta: dict[str, Any]) -> str:
    """The README's sentence on which methods a task publishes (``meta['rule']``)."""
    if meta.get("rule") != "best-method":
        return "Every task x method of the grid with a finished run is published. "
    return (
        "Per task, the method with the highest mean deterministic success area (the mean of "
        "the periodic deterministic evaluations: the studies' metric) over the grid's seeds, "
        "every seed finished, is published (the rule, not a hand choice; each row's "
        "`seed_context` in zoo.json lists every candidate's mean), with the methods named "
        "always. "
    )


def seed_context_text(row: dict[str, Any]) -> str:
    """ "seed i of n; n-seed IQM X (mean Y), this seed Z" for a row with ``seed_context``."""
    c = row.get("seed_context")
    if not c:
        return ""
    n, area = len(c["seeds"]), c["det_area"]
    own = area.get(str(row["seed"]), area.get(row["seed"]))
    best = " the best method of its task by this rule;" if c.get("best_method") else ""
    return (
        f"Seed {row['seed']} of {n} ({', '.join(map(str, c['seeds']))});{best} deterministic "
        f"success area: {n}-seed IQM {c['iqm']:.2f}, mean {c['mean']:.2f}"
        + (f", this seed {own:.2f}" if own is not None else "")
        + "."
    )


def card_evaluation(row: dict[str, Any], meta: dict[str, Any]) -> dict[str, Any]:
    """A zoo policy's published evaluation in the card's terms (``ndp.rl.card``)."""
    return {
        "success": row["success"],
        "episodes": meta["episodes"],
        "deterministic": True,
        "first_seed": PUBLISH_SEED,
        "success_final": row.get("success_final"),
        "episode_return": row.get("episode_return"),
        "command": meta["command"],
        "protocol": (
            f"The policy is the seed with {_selection_text(meta)} "
            f"({row['selection_success']:.2f}) among its study's runs ({row.get('source_run')}"
            + (
                f"; trained again by the same command at the same commit into "
                f"{row['retrained_run']}, whose metrics equal the study run's"
                if row.get("reproduces_source")
                else ""
            )
            + "); the success above is measured again from the export on other episodes, so it is "
            "not the maximum it was selected by. " + seed_context_text(row)
        ).strip(),
        "zoo": True,
    }


def write_cards(out: Path, readme: bool = True) -> list[Path]:
    """Each indexed policy's model card (``OUT/<policy>/README.md``) and, where its
    ``policy.json`` lacks it, the task's spec (``"spec"``, from the task table; nothing else in
    the file changes); ``readme``: also ``OUT/README.md`` from ``OUT/zoo.json``."""
    from ndp.io import atomic_write_text
    from ndp.rl.card import write_card
    from ndp.rl.envs import resolve_task
    from ndp.schema import spec_record

    meta = json.loads((out / "zoo.json").read_text())
    written = []
    for row in meta["policies"]:
        d = out / row["policy"]
        pmeta = json.loads((d / "policy.json").read_text())
        if "spec" not in pmeta:
            pmeta["spec"] = spec_record(resolve_task(pmeta["config"]["task"]).spec)
            atomic_write_text(d / "policy.json", json.dumps(pmeta, indent=1) + "\n")
        card_meta = dict(pmeta)
        if "training" not in card_meta and row.get("trained_at"):
            card_meta["training"] = {"commands": [], "commits": list(row["trained_at"])}
        write_card(d, card_meta, card_evaluation(row, meta), date=meta.get("date"))
        written.append(d / "README.md")
    if readme:
        atomic_write_text(out / "README.md", zoo_readme(meta))
    return written


if __name__ == "__main__":
    sys.exit(main())
