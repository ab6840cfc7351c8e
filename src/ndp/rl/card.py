"""Model cards of exported policies: ``README.md`` in the Hugging Face model-card format.

A card is YAML front matter between ``---`` lines, then a short text. The front matter has the
Hub's keys (``library_name``, ``license``, ``tags``, and a ``model-index`` with the success rate
when one was measured) and plain keys a script can read without knowing the Hub's schema:
``task``, ``method``, ``success_rate``, ``success_rate_ci95`` (the Wilson score interval,
``ndp.experiments.report.stats.wilson_interval``), ``episodes``, ``budget_env_steps``, ``seeds``,
``command``, ``commit``. Whatever the export does not record is written ``"not recorded"``.

Every export writes its card (:func:`ndp.rl.policy.export_policy`); the zoo's are written by
``benchmarks/zoo.py`` (``--cards`` rewrites them from each policy's ``policy.json`` and the
zoo's index). The YAML is written here without a YAML library (the core install has none); the
tests parse it with PyYAML.
"""

from __future__ import annotations

import datetime as dt
import json
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypedDict

import numpy as np

from ndp.checks import check_int
from ndp.io import atomic_write_text
from ndp.policies.config import DMP_HEADS
from ndp.rl.methods import METHODS
from ndp.runs.layout import CHECKPOINT_NAME, CONFIG_NAME, METRICS_NAME


class CardEvaluation(TypedDict, total=False):
    """What a card reports as measured (``evaluation`` of :func:`card_fields`, ``Policy.export``
    and :func:`ndp.rl.policy.export_policy`); ``success`` and ``episodes`` make a result."""

    success: float
    """Success rate (success at any step of an episode)."""
    episodes: int
    """Episodes it was measured over."""
    deterministic: bool
    """Acting with the mode (default True), else sampling."""
    first_seed: int
    """The first episode's reset seed."""
    success_final: float | None
    """Success at the final step."""
    episode_return: float | None
    """Mean return."""
    command: str
    """The command that measured it."""
    protocol: str
    """How it was measured, in words."""
    zoo: bool
    """A policy shipped with the package (its card loads it as ``zoo:NAME``)."""


NOT_RECORDED = "not recorded"
"""The value of a card field the export does not record."""

LICENSE = "mit"
LIBRARY = "neural-dynamic-policies"

_METHODS = {
    "ndp": "NDP (Neural Dynamic Policies: the actor's output is the goal and forcing weights of "
    "a DMP integrated over each k-step decision)",
    "ppo": "PPO (one action per env step)",
    "ppo-multi": "PPO-multi (k actions per decision, no DMP)",
    "vices": "VICES (PPO on an impedance controller's targets and gains)",
    "vices-pos": "VICES in end-effector space",
    "vices-low-freq": "VICES, one decision per k env steps",
    "dyne": "Dyn-E (TD3 in a learned embedding of k-action sequences)",
}


Z95 = 1.959963984540054
"""The standard normal's 97.5% quantile: two-sided 95% intervals."""


COMMANDED_SOURCE = (
    "the commanded state, not the measured robot: the targets the actions move and their "
    "commanded rate (the chunked env's info `cmd_y0` / `cmd_dy0`: on Meta-World the mocap "
    "target the hand follows and the last gripper command, on Jaco the joint and finger "
    "targets of its position servos), in the units above"
)
"""How a card names the robot state of a policy whose DMP starts from the commanded state."""


def robot_state_source(dmp_state: str | None, spec: Mapping[str, object]) -> str:
    """Where the robot state a policy reads comes from: the task's measured source
    (``spec['y0_source']``) for ``dmp_state`` 'measured', :data:`COMMANDED_SOURCE` for
    'commanded'."""
    if dmp_state == "commanded":
        return COMMANDED_SOURCE
    return str(spec.get("y0_source"))


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a success rate (95% for the default ``z``).

    For ``k`` successes in ``n`` episodes, ``p = k / n``:
    ``(p + z^2 / 2n -+ z sqrt(p (1 - p) / n + z^2 / 4n^2)) / (1 + z^2 / n)``. Unlike the normal
    (Wald) interval it stays inside [0, 1] and is not empty at p = 0 or 1 (0 of 10: [0, 0.278]),
    which is where trained policies' success rates often are.

    Raises:
        ValueError: ``n < 1`` or ``successes`` outside ``0..n``.
    """
    n = check_int("n", n, 1)
    if isinstance(successes, bool) or int(successes) != successes or not 0 <= successes <= n:
        raise ValueError(f"successes: expected an integer in 0..{n}, got {successes!r}")
    p = successes / n
    z2 = z * z
    denom = 1.0 + z2 / n
    centre = (p + z2 / (2 * n)) / denom
    half = z * float(np.sqrt(p * (1 - p) / n + z2 / (4 * n * n))) / denom
    lo = 0.0 if successes == 0 else max(0.0, centre - half)
    hi = 1.0 if successes == n else min(1.0, centre + half)
    return lo, hi


def wilson_ci(success: float, episodes: int) -> tuple[float, float]:
    """The 95% Wilson interval of a success rate measured over ``episodes`` episodes."""
    k = round(float(success) * int(episodes))
    return wilson_interval(k, int(episodes))


def card_fields(
    meta: dict[str, Any], evaluation: CardEvaluation | None = None, name: str | None = None
) -> dict[str, Any]:
    """The front matter of a card, as a dict.

    Args:
        meta: the export's ``policy.json``.
        evaluation: what was measured, if anything: ``success`` (rate, success at any step),
            ``episodes``, and optionally ``deterministic``, ``first_seed``, ``success_final``,
            ``episode_return``, ``command`` (that measured it), ``protocol`` (in words).
        name: the policy's name (default ``<task>-<algo>``).
    """
    cfg = meta.get("config", {})
    spec = meta.get("spec") or {}
    training = meta.get("training") or {}
    task, algo = str(meta["task"]), str(meta["algo"])
    family = spec.get("family")
    tags = ["reinforcement-learning", "robotics", LIBRARY, "dynamic-movement-primitives"]
    tags += [t for t in (family, task, algo) if t and t not in tags]
    fields: dict[str, Any] = {
        "library_name": LIBRARY,
        "license": LICENSE,
        "tags": tags,
        "pipeline_tag": "reinforcement-learning",
        "task": task,
        "method": algo,
    }
    if evaluation and evaluation.get("success") is not None and evaluation.get("episodes"):
        p, n = float(evaluation["success"]), int(evaluation["episodes"])
        lo, hi = wilson_ci(p, n)
        fields["success_rate"] = round(p, 4)
        fields["success_rate_ci95"] = [round(lo, 4), round(hi, 4)]
        fields["episodes"] = n
    else:
        fields["success_rate"] = NOT_RECORDED
        fields["success_rate_ci95"] = NOT_RECORDED
        fields["episodes"] = NOT_RECORDED
    # what the run trained (its run.json, through the export's training record); the
    # requested --steps for exports made before the record had it
    trained = training.get("env_steps_trained")
    steps = trained if isinstance(trained, int) else cfg.get("steps")
    fields["budget_env_steps"] = int(steps) if isinstance(steps, int) else NOT_RECORDED
    seed = cfg.get("seed")
    fields["seeds"] = [int(seed)] if isinstance(seed, int) else NOT_RECORDED
    commands = training.get("commands") or []
    fields["command"] = commands[0] if len(commands) == 1 else (commands or NOT_RECORDED)
    fields["commit"] = str(meta.get("commit") or NOT_RECORDED)
    commits = training.get("commits") or []
    fields["training_commits"] = [str(c) for c in commits] or NOT_RECORDED
    if evaluation:
        fields["evaluation_command"] = str(evaluation.get("command") or NOT_RECORDED)
    if evaluation and fields["success_rate"] != NOT_RECORDED:
        mode = "deterministic" if evaluation.get("deterministic", True) else "stochastic"
        metric_name = f"success rate ({mode}, {fields['episodes']} episodes)"
        fields["model-index"] = [
            {
                "name": name or f"{task}-{algo}",
                "results": [
                    {
                        "task": {
                            "type": "reinforcement-learning",
                            "name": "Reinforcement Learning",
                        },
                        "dataset": {"type": task, "name": task},
                        "metrics": [
                            {
                                "type": "success_rate",
                                "value": fields["success_rate"],
                                "name": metric_name,
                                "verified": False,
                            }
                        ],
                    }
                ],
            }
        ]
    return fields


EVAL_RESULTS_DIR = ".eval_results"
"""The folder of a card's evaluation results in the Hugging Face Hub's ``.eval_results/``
format (one YAML file per benchmark, each a list of results)."""


def eval_results(
    meta: dict[str, Any], evaluation: CardEvaluation | None, date: str | None = None
) -> dict[str, str]:
    """The ``.eval_results/`` files of an export: ``{file name: YAML text}``, one file named
    after the task holding the measured success rate, or nothing where no evaluation was
    recorded (a card never claims a number it does not have).

    Each entry has the Hub's fields: ``dataset.id`` (the task's gymnasium id, ``ndp/<task>``;
    not a Hub dataset, so it shows on the model page but joins no leaderboard), ``task_id``
    (the metric: success at any step of an episode, deterministic or stochastic policy),
    ``value`` (the rate in [0, 1]), ``date`` and ``notes`` (episodes, first episode seed, the
    95% Wilson interval, the command that measured it)."""
    fields = card_fields(meta, evaluation)
    if evaluation is None or fields["success_rate"] == NOT_RECORDED:
        return {}
    task = str(meta["task"])
    mode = "deterministic" if evaluation.get("deterministic", True) else "stochastic"
    lo, hi = fields["success_rate_ci95"]
    notes = (f"success at any step, {mode} policy, {fields['episodes']} episodes"
             + (f" from seed {evaluation['first_seed']}" if "first_seed" in evaluation else "")
             + f"; 95% Wilson interval [{lo}, {hi}]; measured by: "
             + str(fields.get("evaluation_command", NOT_RECORDED)))  # fmt: skip
    entry: dict[str, Any] = {
        "dataset": {"id": f"ndp/{task}", "task_id": f"success_any_{mode}"},
        "value": fields["success_rate"],
    }
    if date:
        entry["date"] = date
    entry["notes"] = notes
    return {f"{task}.yaml": to_yaml([entry]) + "\n"}


def check_export_dir(out: Path, files: tuple[str, ...]) -> None:
    """Refuse an export's folder before any work: a training run's folder (an export beside a
    checkpoint would make ``ndp.load_policy`` read the folder as the export), or one that
    already holds a file the export writes (``files``, the model card ``README.md`` or its
    ``.eval_results/``): nothing already there is overwritten. FileExistsError naming
    ``out_dir``."""
    run_files = [n for n in (CHECKPOINT_NAME, METRICS_NAME, CONFIG_NAME) if (out / n).exists()]
    if run_files:
        raise FileExistsError(
            f"out_dir: {out} is a training run's folder (it holds {run_files[0]}); export to a "
            f"new folder"
        )
    there = [n for n in (*files, "README.md", EVAL_RESULTS_DIR) if (out / n).exists()]
    if there:
        raise FileExistsError(
            f"out_dir: {out} already holds {there[0]} (an export writes "
            f"{', '.join((*files, 'README.md'))}); choose another folder"
        )


def write_card(
    out: str | Path,
    meta: dict[str, Any],
    evaluation: CardEvaluation | None,
    onnx: bool = False,
    date: str | None = None,
) -> None:
    """Write an export's model card ``README.md`` and its ``.eval_results/`` files (a stale
    results file of an earlier card is replaced, never left beside a card without results);
    ``date``: when the results were measured (ISO; default today)."""
    out = Path(out)
    replay = REPLAY_NAME if (out / REPLAY_NAME).is_file() else None
    card = model_card(meta, evaluation, out.name, onnx=onnx, replay=replay)
    atomic_write_text(out / "README.md", card)
    files = eval_results(meta, evaluation, date or dt.date.today().isoformat())
    folder = out / EVAL_RESULTS_DIR
    if folder.is_dir():
        shutil.rmtree(folder)
    for name, text in files.items():
        folder.mkdir(exist_ok=True)
        atomic_write_text(folder / name, text)


def to_yaml(obj: object, indent: int = 0) -> str:
    """Block YAML of JSON-like data (dicts, lists, strings, numbers, booleans, None); strings
    are written as JSON strings, which YAML reads as double-quoted scalars."""
    pad = " " * indent
    if isinstance(obj, dict):
        lines = []
        for k, v in obj.items():
            if isinstance(v, (dict, list)) and v and not _flat(v):
                lines.append(f"{pad}{k}:\n{to_yaml(v, indent + 2)}")
            else:
                lines.append(f"{pad}{k}: {_scalar(v)}")
        return "\n".join(lines)
    if isinstance(obj, list):
        lines = []
        for v in obj:
            if isinstance(v, dict) and v:
                body = to_yaml(v, indent + 2)
                lines.append(f"{pad}- {body[indent + 2 :]}")
            else:
                lines.append(f"{pad}- {_scalar(v)}")
        return "\n".join(lines)
    return pad + _scalar(obj)


def _flat(v: object) -> bool:
    """A list of scalars (written in flow style, ``[a, b]``)."""
    return isinstance(v, list) and all(not isinstance(x, (dict, list)) for x in v)


def _scalar(v: object) -> str:
    if isinstance(v, bool) or v is None:
        return json.dumps(v)
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, list):
        return "[" + ", ".join(_scalar(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{}"
    return json.dumps(str(v), ensure_ascii=False)


REPLAY_NAME = "replay.gif"
"""A recorded episode beside a card (``ndp rl render POLICY --out POLICY/replay.gif``; the
zoo's with ``benchmarks/zoo.py --replay``), shown by the card when the folder holds it."""


def model_card(
    meta: dict[str, Any],
    evaluation: CardEvaluation | None = None,
    name: str | None = None,
    onnx: bool = False,
    replay: str | None = None,
) -> str:
    """The ``README.md`` of an export: front matter (:func:`card_fields`) and a short text
    (``onnx``: of an ONNX export, whose use differs; ``replay``: the file name of a recorded
    episode beside the card, shown under the result)."""
    fields = card_fields(meta, evaluation, name)
    name = name or f"{meta['task']}-{meta['algo']}"
    cfg = meta.get("config", {})
    pol = cfg.get("policy", {})
    spec = meta.get("spec") or {}
    k = pol.get("k", NOT_RECORDED)
    algo = str(meta["algo"])
    registered = METHODS.get(algo)
    method = _METHODS.get(algo, registered.description if registered is not None else algo)
    lines = ["---", to_yaml(fields), "---", "", f"# {name}", ""]
    lines += [
        f"A policy for the `{meta['task']}` task. Method: {method}. Trained with the "
        f"`{LIBRARY}` package (not on PyPI yet: install it from a clone, see its README): "
        f"{_budget(fields)}, "
        f"seed {_seq(fields['seeds'])}, k = {k} (env steps per decision).",
        "",
        "## Result",
        "",
        _result_text(fields, evaluation),
        "",
        *_replay_lines(replay),
        "## Use",
        "",
        *(_onnx_use(name) if onnx else _torch_use(name, evaluation)),
        "",
    ]
    if spec:
        units = ", ".join(
            f"{n} ({u})"
            for n, u in zip(spec.get("dof_names", []), spec.get("dof_units", []), strict=False)
        )
        lines += [
            f"Observation: {spec.get('obs_dim')} numbers (as the env returns them; index by "
            "index: docs/observations.md). Robot "
            f"state (`policy.state_keys`, D = {spec.get('dmp_dofs')}): {units}; "
            f"{robot_state_source(pol.get('dmp_state'), spec)}. Actions: "
            f"[k, {spec.get('action_dim')}] in "
            f"[{min(spec.get('action_low', [0]))}, {max(spec.get('action_high', [0]))}], one per "
            f"env step of {spec.get('control_dt')} s.",
            "",
        ]
    if pol.get("head") in DMP_HEADS:
        head = pol.get("ndp") or pol  # nested since NDPHeadConfig; flat in older exports
        lines += [
            f"DMP: N = {head.get('n_basis')} basis functions, a_z = {head.get('a_z')}, "
            f"{head.get('dmp_steps')} integration steps per decision, started from the "
            f"{pol.get('dmp_state')} state ({pol.get('dmp_velocity')} velocity).",
            "",
        ]
    lines += [
        (
            "Files: `policy.onnx` (the graph, with the policy's metadata: task, spec, resolved "
            "training config, commit) and this card; no torch is needed to run it."
            if onnx
            else "Files: `policy.safetensors` (weights), `policy.json` (format, resolved "
            "training config, observation normaliser, task spec, versions, commit); they load "
            "without unpickling anything."
        ),
        "",
        *_training_section(fields, cfg),
        *_citation_section(),
    ]
    return "\n".join(lines)


BIBTEX = """@inproceedings{bahl2020ndp,
  title     = {Neural Dynamic Policies for End-to-End Sensorimotor Learning},
  author    = {Bahl, Shikhar and Mukadam, Mustafa and Gupta, Abhinav and Pathak, Deepak},
  booktitle = {Advances in Neural Information Processing Systems},
  volume    = {33},
  year      = {2020},
  url       = {https://arxiv.org/abs/2012.02788}
}"""
"""The method's paper (CITATION.cff's preferred citation), as every card cites it."""

LINKS = (
    ("Paper", "https://arxiv.org/abs/2012.02788"),
    ("The authors' code (2021)", "https://github.com/shikharbahl/neural-dynamic-policies"),
)
"""The card's links (pyproject's [project.urls]; this package's own repository address is
added there when it is published)."""


def hyperparameters(cfg: Mapping[str, Any], prefix: str = "") -> list[tuple[str, object]]:
    """The resolved training config as (dotted key, value) rows, leaves only, in its order
    (nested sections flattened: ``policy.ndp.n_basis``); empty sections are left out."""
    rows: list[tuple[str, object]] = []
    for key, value in cfg.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            rows += hyperparameters(value, name + ".")
        else:
            rows.append((name, value))
    return rows


def _training_section(fields: Mapping[str, Any], cfg: Mapping[str, Any]) -> list[str]:
    """The card's "Training": the command, the commits, the trained steps and every setting."""
    command = fields["command"]
    commands = command if isinstance(command, list) else [command]
    lines = ["## Training", ""]
    if command == NOT_RECORDED:
        lines += ["Command: not recorded (the export predates recorded commands).", ""]
    else:
        lines += ["```bash", *(str(c) for c in commands), "```", ""]
    lines += [
        f"Commits: {_seq(fields['training_commits'])}; trained: {_budget(fields)}.",
        "",
    ]
    rows = hyperparameters(cfg)
    if rows:
        lines += [
            "<details><summary>Hyperparameters (the resolved config, policy.json)</summary>",
            "",
            "| setting | value |",
            "|---|---|",
            *(f"| `{k}` | `{json.dumps(v)}` |" for k, v in rows),
            "",
            "</details>",
            "",
        ]
    return lines


def _citation_section() -> list[str]:
    """The card's "Citation": the paper's BibTeX and the links."""
    return [
        "## Citation",
        "",
        "```bibtex",
        BIBTEX,
        "```",
        "",
        "Links: " + "; ".join(f"[{t}]({u})" for t, u in LINKS) + ". This package: not on PyPI "
        "yet; its repository address is added to its metadata when it is published.",
        "",
    ]


def _replay_lines(replay: str | None) -> list[str]:
    """The card's line showing the recorded episode ``replay`` beside it (none without one)."""
    if not replay:
        return []
    return [
        f"![one episode, deterministic actions]({replay}) (`{replay}`: one episode, "
        "deterministic actions, in real time)",
        "",
    ]


def _seq(v: object) -> str:
    return ", ".join(str(x) for x in v) if isinstance(v, list) else str(v)


def _budget(fields: Mapping[str, object]) -> str:
    b = fields["budget_env_steps"]
    return f"{b:,} env steps" if isinstance(b, int) else f"budget {NOT_RECORDED}"


def _torch_use(name: str, evaluation: CardEvaluation | None) -> list[str]:
    return [
        "```python",
        "import ndp",
        "",
        f'policy = ndp.load_policy("{_load_path(name, evaluation)}")',
        "# with the simulator ([envs] extra): the env the policy was trained for",
        "env = policy.make_env()",
        "obs, info = env.reset(seed=0)",
        "obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))",
        "# without one: the robot state the DMP starts from, [D] each",
        "# actions = policy.act(obs, ndp.RobotState(y0, dy0))   # [k, A]",
        "```",
    ]


def _onnx_use(name: str) -> list[str]:
    return [
        "`policy.onnx` is the whole deterministic decision as one graph (inputs `obs` [E, O], "
        "`y0`, `dy0` [E, D], float32; output the k sub-actions [E, k, A], float32). Run it with "
        "onnxruntime alone, or through the package ([onnx] extra), which checks the inputs as "
        "the torch policy does:",
        "",
        "```python",
        "import ndp",
        "",
        f'policy = ndp.load_policy("{name}")   # an OnnxPolicy',
        "actions = policy.act(obs, ndp.RobotState(y0, dy0))   # [k, A]; or the env's info",
        "```",
    ]


def _load_path(name: str, evaluation: CardEvaluation | None) -> str:
    if evaluation and evaluation.get("zoo"):
        return f"zoo:{name}"
    return name


def _result_text(fields: dict[str, Any], evaluation: CardEvaluation | None) -> str:
    if fields["success_rate"] == NOT_RECORDED:
        return (
            "Success rate: not recorded (measure it with `ndp rl eval` on the training run, "
            "or `ndp.rl.evaluate.evaluate_policy(ndp.load_policy(...), episodes)`)."
        )
    assert evaluation is not None
    lo, hi = fields["success_rate_ci95"]
    mode = "deterministic" if evaluation.get("deterministic", True) else "stochastic"
    text = (
        f"Success (at any step of an episode) {fields['success_rate']:.2f} over "
        f"{fields['episodes']} episodes, 95% Wilson interval [{lo:.2f}, {hi:.2f}], {mode} "
        "actions"
    )
    if evaluation.get("first_seed") is not None:
        text += f", episode seeds {evaluation['first_seed']} on"
    text += "."
    extra = []
    final, ret = evaluation.get("success_final"), evaluation.get("episode_return")
    if final is not None:
        extra.append(f"success at the final step {float(final):.2f}")
    if ret is not None:
        extra.append(f"mean return {float(ret):.1f}")
    if extra:
        text += " Also: " + ", ".join(extra) + "."
    if evaluation.get("protocol"):
        text += " " + str(evaluation["protocol"])
    return text
