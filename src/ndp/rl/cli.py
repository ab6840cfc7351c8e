"""``ndp rl train | eval | render | export | diagnose``: thin entry points over :mod:`ndp.rl`.

Examples::

    ndp rl train --task push-v3 --algo ndp --steps 500000 --seed 0
    ndp rl train --resume runs/push-v3-ndp-s0
    ndp rl eval runs/push-v3-ndp-s0 --episodes 20
    ndp rl eval runs/push-v3-ndp-s0 --exec-k 5 25 --mode deterministic
    ndp rl render runs/push-v3-ndp-s0 --out push.mp4
    ndp rl fit-basis runs/push-v3-ppo-multi-s0 --decisions 2000 --out basis.npz
    ndp rl diagnose --jacobian zoo:push-v3-ndp --png push-spectrum.png
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Annotated

from ndp.rl.config import EVAL_SEED, FRESH_EVAL_SEED, TrainConfig

TRAIN_NOTES = (
    "Unset NDP fields come "
    "from the per-task preset of the task table (ndp.envs.presets); the resolved config is "
    "saved as RUN_DIR/config.json. "
    "--resume RUN_DIR continues a killed run: the other options are then taken from its "
    "config.json, and only --steps (extends the budget), --progress, --tensorboard, --vector, "
    "--env-workers and --device may change. A directory that holds a run is refused unless "
    "--overwrite (which names the files it removes). --config FILE starts from a run's "
    "config.json or a hyperparameter file (JSON / YAML, sections nested; configs/ has the "
    "headline's), the options given overriding it. With --algo X, --help shows only the "
    "options X reads; a learner's option that X does not read is refused."
)


def method_lines() -> list[str]:
    """One line per registered method, ``name: description`` (from :data:`ndp.rl.methods.METHODS`,
    the one list; help strings and ``ndp rl methods`` are generated from it)."""
    from ndp.rl.methods import METHODS

    return [f"{m.name}: {m.description}" for m in METHODS.values()]


def train_description() -> str:
    """``ndp rl train --help``'s description. It names no method: the list is the registry's
    (``ndp rl methods``), which imports torch, and help imports nothing heavy."""
    return (
        "Train a policy with --algo a registered method (ndp rl methods lists them, a line "
        "each). " + TRAIN_NOTES
    )


# the public signature unsubscripted (as ndp.il.cli's): the API reference evaluates it at run
# time, where argparse's class is not generic
def add_subparser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``rl`` with sub-commands ``train``, ``methods``, ``eval``, ``export``,
    ``fit-basis``, ``render`` and ``diagnose``."""
    rl = sub.add_parser(
        "rl", help="reinforcement learning: NDP and its baselines (ndp rl methods lists them)"
    )
    rl_sub = rl.add_subparsers(dest="rl_command", metavar="SUBCOMMAND")
    rl_sub.required = True

    # listed here for `ndp rl --help`; the options are parsed by CONFIG_COMMANDS["rl train"]
    rl_sub.add_parser("train", help="train a policy (ndp rl train --help: every option)")

    ms = rl_sub.add_parser("methods", help="list the registered methods (--algo values)")
    ms.set_defaults(func=_cmd_methods)
    for add in (_add_eval, _add_export, _add_push, _add_fit_basis, _add_render, _add_diagnose):
        add(rl_sub)


def _add_eval(rl_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """``ndp rl eval RUN_DIR``: success over N episodes, per mode and ``--exec-k``."""
    ev = rl_sub.add_parser("eval", help="success of a trained run over N episodes")
    ev.add_argument("run_dir", metavar="RUN_DIR")
    ev.add_argument("--episodes", type=int, default=10, help="episodes per mode (default 10)")
    ev.add_argument(
        "--seed",
        type=int,
        default=EVAL_SEED,
        help=f"first episode seed (default {EVAL_SEED:,}, the periodic evaluation's; re-score "
        f"final policies on fresh seeds with --seed {FRESH_EVAL_SEED})",
    )
    ev.add_argument(
        "--save",
        action="store_true",
        help="also write each evaluation into the run (eval-<det|sto>-e<N>-s<seed>.json: the "
        "protocol, success with its Wilson 95%% interval, return), read by reports and cards",
    )
    ev.add_argument(
        "--mode",
        choices=("both", "deterministic", "stochastic"),
        default="both",
        help="act with the mean, by sampling, or both (default both)",
    )
    ev.add_argument(
        "--exec-k",
        type=int,
        nargs="+",
        default=None,
        metavar="K2",
        help="run each decision (same duration) as K2 = k * m sub-steps of an env step m times "
        "shorter, m a divisor of the simulator steps per env step (Meta-World: K2 in k, 5k; "
        "Jaco: k, 2k, 5k, 10k); several values: one JSON line each. Success compares across "
        "K2, the return does not (docs/policies.md, 'Inference at a higher rate')",
    )
    ev.set_defaults(func=_cmd_eval)


def _add_export(rl_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """``ndp rl export RUN_DIR OUT_DIR``: a trained run's policy as safetensors or ONNX."""
    ex = rl_sub.add_parser(
        "export",
        help="export a trained run's policy (safetensors + JSON, no pickle; or one ONNX graph)",
    )
    ex.add_argument("run_dir", metavar="RUN_DIR")
    ex.add_argument("out", metavar="OUT_DIR", help="new directory for the export")
    ex.add_argument(
        "--format",
        choices=("safetensors", "onnx"),  # ndp.rl.policy.EXPORT_FORMATS (torch-free here)
        default="safetensors",
        help="safetensors: policy.safetensors + policy.json, loaded by ndp.load_policy "
        "(default); onnx: policy.onnx, the whole deterministic decision (normaliser, actor, "
        "head, DMP, action bounds) as one graph with inputs obs, y0, dy0 and output actions "
        "(needs the [onnx] extra; docs/policies.md, 'Export formats')",
    )
    ex.add_argument(
        "--replay",
        action="store_true",
        help="also record one deterministic episode of the policy (episode seed 10,000, 160 px, "
        "real time) as OUT_DIR/replay.gif, which the card shows (needs the simulators)",
    )
    ex.set_defaults(func=_cmd_export)


def _add_push(rl_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """``ndp rl push SOURCE ORG/NAME``: upload a policy to the Hugging Face Hub."""
    pu = rl_sub.add_parser(
        "push",
        help="upload a run's policy (exported, with its card) or an export folder to the "
        "Hugging Face Hub; load it back with ndp.load_policy('hf://ORG/NAME')",
    )
    pu.add_argument("source", metavar="RUN_DIR|EXPORT_DIR|zoo:NAME")
    pu.add_argument("repo_id", metavar="ORG/NAME", help="the model repository (created if missing)")
    pu.add_argument("--private", action="store_true", help="create the repository private")
    pu.add_argument("--message", default=None, help="the commit message")
    pu.set_defaults(func=_cmd_push)


def _add_fit_basis(rl_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """``ndp rl fit-basis RUN_DIR... --out FILE``: PPO-multi's 'pca' chunk basis."""
    fb = rl_sub.add_parser(
        "fit-basis",
        help="fit PPO-multi's 'pca' chunk basis (--chunk-basis pca) to trained PPO-multi runs",
        description="Record the k sub-action means of every decision of trained PPO-multi "
        "policies acting in their env, and save per DoF the top 1 + N principal directions "
        "(uncentred) with their provenance in one .npz file for ndp rl train --algo ppo-multi "
        "--chunk-basis pca --chunk-basis-file FILE (docs/policies.md, 'Chunk bases').",
    )
    fb.add_argument("run_dirs", nargs="+", metavar="RUN_DIR", help="PPO-multi runs (or exports)")
    fb.add_argument("--out", required=True, metavar="FILE", help="the .npz file to write")
    fb.add_argument(
        "--decisions", type=int, default=2000, help="decisions recorded per run (default 2000)"
    )
    fb.add_argument(
        "--n-basis",
        type=int,
        default=None,
        metavar="N",
        help="1 + N directions per DoF (default: the task's NDP preset, as the head reads it)",
    )
    fb.add_argument("--seed", type=int, default=EVAL_SEED, help="first episode's reset seed")
    fb.add_argument("--stochastic", action="store_true", help="sample actions (default: mean)")
    fb.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    fb.set_defaults(func=_cmd_fit_basis)


def _add_render(rl_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """``ndp rl render RUN_DIR``: an mp4 of a trained run (or two, side by side)."""
    rd = rl_sub.add_parser("render", help="render a trained run to mp4")
    rd.add_argument("run_dir", metavar="RUN_DIR")
    rd.add_argument(
        "--out",
        default=None,
        help="mp4 path, or a looping GIF: PATH.gif (default RUN_DIR/video.mp4)",
    )
    rd.add_argument("--episodes", type=int, default=1, help="episodes to record (default 1)")
    rd.add_argument("--seed", type=int, default=EVAL_SEED, help="first episode seed")
    rd.add_argument("--stochastic", action="store_true", help="sample actions (default: mean)")
    rd.add_argument(
        "--compare",
        metavar="RUN_DIR_B",
        default=None,
        help="a second run of the same task, shown to the right on the same seeds",
    )
    rd.add_argument(
        "--exec-k",
        type=int,
        default=None,
        metavar="K2",
        help="render each decision as K2 sub-steps of the same duration (as ndp rl eval "
        "--exec-k; with --compare, both runs); default: as trained",
    )
    rd.add_argument(
        "--width",
        type=int,
        default=None,
        metavar="PX",
        help="frame width in px (default: the env's, 480 for the robots; with --compare, "
        "each run's)",
    )
    rd.add_argument(
        "--height",
        type=int,
        default=None,
        metavar="PX",
        help="frame height in px (default: the env's, 480 for the robots)",
    )
    rd.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing --out (default: refused, nothing rendered; the run's own "
        "RUN_DIR/video.mp4 is always replaced)",
    )
    rd.set_defaults(func=_cmd_render)


def _add_diagnose(rl_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """``ndp rl diagnose``: the handicap or (``--jacobian``) conditioning diagnostic."""
    dg = rl_sub.add_parser(
        "diagnose",
        help="the NDP head's handicaps on a rollout, or (--jacobian) the conditioning of its "
        "map from raw outputs to sub-actions",
        description="Without --jacobian: the handicap diagnostic of one policy (intended vs "
        "executed displacement, the gripper's noise leak; docs/rl.md). With --jacobian: the "
        "Jacobian of the k sub-action means w.r.t. the head's raw outputs at raw = 0, at the "
        "fresh network's outputs and along a trained policy's deterministic episodes: singular "
        "values, condition number over the reachable directions, goal / weight shares, "
        "saturated tanh outputs (docs/rl.md, 'The conditioning of the action map').",
    )
    add_diagnose_arguments(dg)
    dg.set_defaults(func=diagnose_command)


def add_diagnose_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``ndp rl diagnose`` (and ``python -m ndp.experiments.diagnose``)."""
    p.add_argument(
        "runs",
        nargs="*",
        metavar="RUN",
        help="trained policies: run directories, exports or zoo:NAME (--jacobian: any number)",
    )
    p.add_argument("--run", action="append", default=[], help="a trained policy (as RUN)")
    p.add_argument(
        "--task",
        action="append",
        default=[],
        help="a fresh policy on this task (repeatable with --jacobian)",
    )
    p.add_argument("--algo", default="ndp", help="the method of a fresh policy (default ndp)")
    p.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="FIELD=VALUE",
        help="policy-config overrides of a fresh policy, e.g. mean_clip=true param_map=whitened",
    )
    p.add_argument("--seed", type=int, default=0, help="the (first) episode seed (default 0)")
    p.add_argument(
        "--decisions", type=int, default=300, help="handicaps: decisions to run (default 300)"
    )
    p.add_argument(
        "--jacobian",
        action="store_true",
        help="the conditioning of the head's map instead of the handicaps (JSON)",
    )
    p.add_argument(
        "--episodes",
        type=int,
        default=3,
        help="--jacobian: deterministic episodes per rollout, every decision read (default 3)",
    )
    p.add_argument(
        "--png",
        default=None,
        metavar="PATH",
        help="--jacobian: also write a figure of the singular-value spectra (a panel per policy)",
    )


def _overrides(items: list[str]) -> dict[str, object]:
    """``FIELD=VALUE`` items as a dict (values read as JSON, else as plain strings)."""
    out: dict[str, object] = {}
    for item in items:
        name, eq, val = item.partition("=")
        if not eq or not name:
            raise ValueError(f"set: expected FIELD=VALUE, got {item!r}")
        try:
            out[name] = json.loads(val)
        except json.JSONDecodeError:
            out[name] = val  # a plain string such as forcing=goal
    return out


def diagnose_command(args: argparse.Namespace) -> int:
    """``ndp rl diagnose``: print the handicap diagnostic, or the conditioning reports, as JSON."""
    runs = list(args.runs) + list(args.run)
    sources = [(None, r) for r in runs] + [(t, None) for t in args.task]
    overrides = _overrides(args.set)
    if not sources:
        raise ValueError("runs: give a trained policy (RUN) or --task T (a fresh policy)")
    if overrides and not args.task:
        raise ValueError(
            "set: the overrides are of a fresh policy's config (--task); a run's is its own"
        )
    if args.png is not None and not args.jacobian:
        raise ValueError("--png: the figure is of the --jacobian diagnostic")
    if args.jacobian:
        from ndp.io import check_output_path

        if args.png is not None:
            check_output_path(args.png, "png")  # before the rollouts
        from ndp.rl.diagnose import jacobian_diagnostic, plot_spectra

        reports = [
            jacobian_diagnostic(
                task, args.algo, run, args.episodes, args.seed, **(overrides if run is None else {})
            )
            for task, run in sources
        ]
        out: dict[str, object] = {"jacobian": reports}
        if args.png is not None:
            out["png"] = str(plot_spectra(reports, args.png))
        print(json.dumps(out, indent=1))
        return 0
    if len(sources) != 1:
        raise ValueError(
            f"runs: the handicap diagnostic reads one policy, got {len(sources)} (--jacobian "
            "reads several)"
        )
    from ndp.rl.diagnose import diagnose

    task, run = sources[0]
    print(
        json.dumps(diagnose(task, args.algo, run, args.decisions, args.seed, **overrides), indent=1)
    )
    return 0


def diagnose_main(argv: list[str] | None = None) -> int:
    """``python -m ndp.experiments.diagnose``: ``ndp rl diagnose`` under its earlier name."""
    p = argparse.ArgumentParser(
        prog="python -m ndp.experiments.diagnose", description="ndp rl diagnose (its options)"
    )
    add_diagnose_arguments(p)
    return diagnose_command(p.parse_args(argv))


def train_command(argv: list[str]) -> int:
    """``ndp rl train [--resume RUN_DIR | --overwrite] [options of TrainConfig]``."""
    from ndp.runs.cli import pop_flag, pop_option
    from ndp.runs.signals import report_stop, stop_on_sigterm

    resume_dir, rest = pop_option(argv, "--resume")
    overwrite, rest = pop_flag(rest, "--overwrite")
    config_file, rest = pop_option(rest, "--config")
    if overwrite and resume_dir is not None:
        raise ValueError("--overwrite: cannot be combined with --resume (replace or continue)")
    if config_file is not None and resume_dir is not None:
        raise ValueError("--config: a resumed run keeps its own config (give options to change)")
    prog = "ndp rl train"
    if "-h" in rest or "--help" in rest:
        _help(rest, prog, config_file)  # exits
    run_name = resume_dir or "RUN_DIR"
    try:
        with stop_on_sigterm():
            if resume_dir is not None:
                metrics = _resume_run(resume_dir, rest, prog)
                if not metrics:
                    return 0
            else:
                cfg = _new_run_config(rest, prog, config_file)
                run_name = cfg.run_dir or "."
                # the trainer (torch, the simulators) is imported only once the options are parsed
                from ndp.rl.run import train

                metrics = train(cfg, overwrite=overwrite, resolved=True)
    except FloatingPointError as exc:  # ndp.rl.onpolicy.trainer.TrainingDivergedError
        print(f"ndp: error: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (ndp.runs.signals.Terminated)
        return report_stop(exc, f"ndp rl train --resume {run_name}", run_name)
    keys = ("update", "global_step", "charts/success_any", "charts/episode_return")
    print(json.dumps({k: metrics.get(k) for k in keys}))
    return 0


def _resume_run(resume_dir: str, rest: list[str], prog: str) -> dict[str, float]:
    """``--resume RUN_DIR``: continue the run with the options given over its saved config
    (``config.json``, read once here); the run driver refuses, naming each field with both
    values, an option that would change the run (:func:`ndp.rl.run.resume_run`). Its metrics,
    or an empty dict (said on stderr) when its budget is already spent."""
    from ndp.rl.config import load_config
    from ndp.runs import RunDir
    from ndp.runs.cli import parse_config

    saved = load_config(RunDir(resume_dir).config)
    saved = dataclasses.replace(saved, run_dir=str(resume_dir))
    cfg = parse_config(TrainConfig, rest, prog=prog, description=train_description(), default=saved)
    from ndp.rl.run import resume_run

    metrics = resume_run(cfg)
    if not metrics:
        print(
            f"ndp: nothing to do: {resume_dir} has finished its budget; --resume "
            "with a larger --steps extends it",
            file=sys.stderr,
        )
    return metrics


def _new_run_config(rest: list[str], prog: str, config_file: str | None) -> TrainConfig:
    """A new run's config: the options over ``--config FILE`` (or the defaults), a learner's
    option that the method does not read refused, resolved once, here (the run directory
    every message names is the one the run writes: an alias task or VICES's task variant
    gives the canonical row). Options of a part the method does not run are noted on stderr."""
    from ndp.rl.config import (
        resolve_config,
        unused_basis_options,
        unused_head_options,
        unused_method_options,
    )
    from ndp.runs.cli import parse_config

    base = config_from_file(config_file) if config_file is not None else None
    cfg = parse_config(TrainConfig, rest, prog=prog, description=train_description(), default=base)
    unused = unused_head_options(cfg)  # before resolving, which clears them
    unused_basis = unused_basis_options(cfg)
    other = unused_method_options(cfg)
    if other:  # a learner's option that this method does not read: refused
        raise ValueError(unread_learner_message(cfg.algo, other))
    cfg = resolve_config(cfg)
    if unused:
        print(f"ndp: note: {', '.join(unused)}: options of the NDP head, which "
              f"--algo {cfg.algo} does not run; not used", file=sys.stderr)  # fmt: skip
    if unused_basis:
        print(f"ndp: note: {', '.join(unused_basis)}: options of PPO-multi's "
              f"chunk basis, which --algo {cfg.algo} does not run; not used",
              file=sys.stderr)  # fmt: skip
    return cfg


def config_from_file(path: str) -> TrainConfig:
    """``--config FILE``: a run's ``config.json`` or a hyperparameter file (JSON / YAML, some
    fields, sections nested) over the defaults; the command line's options then override it.
    A file's ``run_dir`` is dropped (said on stderr): a config re-run writes a new run.

    Raises:
        ValueError: an unreadable file or an unknown field (one line naming ``config``).
    """
    from ndp.rl.config import current_layout
    from ndp.runs.cli import merge_config_dict, read_config_file

    data = current_layout(read_config_file(path))  # an older config.json's layout too
    if data.pop("run_dir", None) is not None:
        print(f"ndp: note: --config {path}: its run_dir is not reused (a new run directory)",
              file=sys.stderr)  # fmt: skip
    merged = merge_config_dict(TrainConfig().to_dict(), data)
    merged["run_dir"] = None
    return TrainConfig.from_dict(merged)


def unread_learner_message(algo: str, options: list[str]) -> str:
    """The refusal of learner options that ``--algo`` does not read, naming the methods that
    read each section."""
    from ndp.rl.methods import METHODS

    parts = []
    for opt in options:  # "sac.lr=0.001", or a run field's "norm_obs=False"
        section = opt.split("=", 1)[0].split(".", 1)[0]
        readers = [m.name for m in METHODS.values() if section in m.reads]
        parts.append(f"{opt} (read by --algo {' / '.join(readers) or 'none'})")
    return (
        f"options: --algo {algo} does not read {'; '.join(parts)}; drop them or choose a "
        "method that reads them"
    )


def _help(rest: list[str], prog: str, config_file: str | None) -> None:
    """``ndp rl train [--algo X] --help``: with ``--algo``, only the options X reads (the run's,
    PPO's, the policy's and X's learner section); without, every option. Exits."""
    from ndp.rl.config import help_config_class
    from ndp.runs.cli import parse_config, pop_option

    algo, _ = pop_option(rest, "--algo")
    cls = help_config_class(algo) if algo is not None else TrainConfig
    what = f"the options --algo {algo} reads" if algo is not None else "every option"
    shown = with_run_flags(cls)
    parse_config(shown, rest, prog=prog, description=f"{train_description()} Shown: {what}.")
    raise SystemExit(0)


def _flag(metavar: str | None) -> object:
    """Annotation: the option's metavar in help, or for ``metavar=None`` a plain on-switch
    (no ``--no-`` twin); None where tyro, an extra, is absent."""
    try:
        import tyro.conf
    except ImportError:  # pragma: no cover - the layer-only install prints no help
        return None
    return tyro.conf.FlagCreatePairsOff if metavar is None else tyro.conf.arg(metavar=metavar)


@dataclasses.dataclass(frozen=True)
class TrainFlags:
    """The options of ``ndp rl train`` that choose what happens to the run directory rather
    than how the run trains (parsed by :func:`train_command` before the config; listed in
    ``--help`` through :func:`with_run_flags`)."""

    resume: Annotated[str | None, _flag("RUN_DIR")] = None
    """Continue a killed or stopped run from its last checkpoint; the options are then taken
    from its config.json and only --steps, --progress, --tensorboard, --vector, --env-workers
    and --device may change."""
    overwrite: Annotated[bool, _flag(None)] = False
    """Replace the run in --run-dir (the files it removes are named; other files stay); not with
    --resume."""
    config: Annotated[str | None, _flag("FILE")] = None
    """Start from a run's config.json or a hyperparameter file (JSON / YAML, sections nested;
    configs/ has the headline's); the options given override it."""


def with_run_flags(cls: type) -> type:
    """``cls`` (a train config class) with :class:`TrainFlags` as a section ``run`` of its
    help: what ``ndp rl train --help`` parses to print ``--resume``, ``--overwrite`` and
    ``--config`` among the listed options. Only help uses it; runs never hold these fields."""
    from ndp.runs.cli import cli

    doc = "what happens to the run directory: continue it, replace it, or start from a file"
    field = dataclasses.field(default_factory=TrainFlags)
    return dataclasses.make_dataclass(
        "TrainConfig",
        [("run", Annotated[TrainFlags, cli(help=doc)], field)],
        bases=(cls,),
        frozen=True,
        namespace={"__module__": cls.__module__, "__qualname__": "TrainConfig"},
    )


CONFIG_COMMANDS = {"rl train": train_command}
"""Commands whose options are a typed config (see ndp.cli)."""


def _cmd_methods(args: argparse.Namespace) -> int:
    for line in method_lines():
        print(line)
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
    from ndp.rl.evaluate import check_save_target, evaluate, save_evaluation

    modes = {"both": (True, False), "deterministic": (True,), "stochastic": (False,)}[args.mode]
    values = args.exec_k if args.exec_k is not None else [None]
    if args.exec_k is not None:  # every value checked before the first evaluation runs
        from ndp.rl.exec_k import substeps_for
        from ndp.rl.policy import load_policy

        trained = load_policy(args.run_dir)
        for k2 in values:
            substeps_for(trained, k2)
    if args.save:  # refused before anything is evaluated
        check_save_target(args.run_dir)
    for det in modes:
        for k2 in values:
            result = evaluate(args.run_dir, args.episodes, det, args.seed, k2)
            out: dict[str, object] = dict(result)
            if args.save:
                out["saved"] = str(save_evaluation(args.run_dir, result, args.seed))
            print(json.dumps(out), flush=True)
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from ndp.rl.policy import export_policy

    replay = None
    if args.replay:  # recorded first, into the new folder, so that the card shows it
        from ndp.rl.card import REPLAY_NAME, check_export_dir
        from ndp.rl.evaluate import render

        # the export's own refusals before anything is written (a run's folder, its files)
        written = (
            ("policy.onnx",) if args.format == "onnx" else ("policy.safetensors", "policy.json")
        )
        check_export_dir(Path(args.out), written)
        replay = render(args.run_dir, Path(args.out) / REPLAY_NAME, width=160, height=160)["path"]
    out = export_policy(args.run_dir, args.out, format=args.format)
    printed = {"export": str(out), "format": args.format}
    print(json.dumps({**printed, "replay": replay} if replay else printed))
    return 0


def _cmd_push(args: argparse.Namespace) -> int:
    from ndp.rl.hub import push_policy

    res = push_policy(args.source, args.repo_id, private=args.private, message=args.message)
    print(json.dumps(res))
    return 0


def _cmd_fit_basis(args: argparse.Namespace) -> int:
    from ndp.rl.fit_basis import fit_basis

    summary = fit_basis(
        args.run_dirs,
        args.out,
        decisions=args.decisions,
        n_basis=args.n_basis,
        seed=args.seed,
        deterministic=not args.stochastic,
        overwrite=args.overwrite,
    )
    print(json.dumps(summary))
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from ndp.rl.evaluate import render

    out = render(
        args.run_dir,
        args.out,
        args.episodes,
        not args.stochastic,
        args.seed,
        args.compare,
        args.exec_k,
        width=args.width,
        height=args.height,
        overwrite=args.overwrite,
    )
    print(json.dumps(out))
    return 0
