"""The named studies of ``ndp sweep STUDY`` (docs/experiments.md describes each).

A :class:`Study` names its tasks, its arms (:class:`ndp.experiments.study.Arm`: a method and
``ndp rl train`` / ``ndp il train`` options), its seeds and its budget; ``ndp sweep`` runs the
grid (``--tasks``, ``--arms``, ``--seeds``, ``--steps`` narrow or change it) and ``ndp report``
tabulates it. Importing this module imports neither torch nor a simulator: the arms and the
task lists are built when a sweep asks for them (:meth:`Study.arm_specs`, :meth:`Study.task_list`).

Arms that need something this version may lack:

- ``pending_method`` arms (VICES, Dyn-E and their ablations, registered now) join their study
  only where their method is registered (``ndp.rl.methods.METHODS``); elsewhere the sweep
  leaves them out and says so;
- ``in_default=False`` arms run only when named with ``--arms``;
- arms with ``requires`` use trainer options (``--learn-az``, ``--only-g``); where
  ``ndp rl train`` does not know them, the sweep refuses the study before anything starts,
  naming the arm and the option (``--skip-unavailable`` leaves them out).
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class ArmSpec:
    """An arm as data (the :class:`ndp.experiments.study.Arm` is built on demand)."""

    label: str
    algo: str
    args: tuple[str, ...] = ()
    note: str = ""
    requires: str = ""
    """Trainer options the arm needs that may not exist yet (named when they are refused)."""
    pending_method: bool = False
    """The arm's method may not be registered yet: then the arm is left out (with a note)."""
    in_default: bool = True
    """Part of a plain ``ndp sweep STUDY``; False: only when named with ``--arms``."""
    tasks: tuple[str, ...] = ()
    """The tasks the arm runs on (``Arm.tasks``); empty: every task of the study."""

    def arm(self) -> Any:
        from ndp.experiments.study import Arm

        return Arm(self.label, self.algo, self.args, self.note, self.requires, self.tasks)


Readings = Callable[[Sequence[Any], Sequence[int]], tuple[list[str], list[dict[str, Any]]]]
"""A study's readings: (the report's RL cells, the seeds) -> (Markdown lines, CSV rows)."""


@dataclass(frozen=True)
class Condition:
    """A named setting of a study whose arms are shared between conditions: which arm (run
    label) stands for each method under it (``ndp report --conditions``)."""

    name: str
    note: str
    """What the condition is, for the tables."""
    methods: tuple[tuple[str, str], ...]
    """(method, arm label) pairs, in table order."""
    unequal: bool = False
    """The methods do not see the same task distribution or settings on purpose (a condition
    reproduced from the 2021 release): the report labels it so."""
    overrides: tuple[tuple[str, str, str], ...] = ()
    """(task, method, arm label): on that task the method's arm is this one instead (a
    condition that the release ran differently per task, e.g. its goal rule)."""


@dataclass(frozen=True)
class Study:
    """A named grid: tasks x arms x seeds at one budget."""

    name: str
    title: str
    doc: str
    """What the study measures and how to read it (docs/experiments.md has the same)."""
    tasks: Callable[[], tuple[str, ...]]
    arms: Callable[[], tuple[ArmSpec, ...]]
    seeds: tuple[int, ...] = (0, 1, 2)
    steps: int = 300_000
    """Budget per run: env steps (RL), epochs (imitation)."""
    kind: str = "rl"
    """'rl' (``ndp rl train`` runs) or 'il' (``ndp il train`` runs)."""
    budgets: tuple[float, ...] = (0.25, 0.5, 1.0)
    """Fractions of the budget at which the report gives the success."""
    summary: tuple[str, ...] = field(default=())
    """Extra report sections: 'over-tasks' (mean over tasks, NDP >= PPO count)."""
    conditions: tuple[Condition, ...] = field(default=())
    """Conditions over shared arms (the report's condition x method tables); empty: every
    arm is its own column."""
    selection: tuple[tuple[str, tuple[str, ...]], ...] = field(default=())
    """(model, candidate arm labels): the report picks per task the candidate with the lowest
    mean validation MSE and reports its test MSE (``ndp.experiments.report.selection``)."""
    readings: Readings | None = None
    """The study's pre-registered readings, applied by code to the report's RL cells and seeds
    (Markdown lines and CSV rows; e.g. :func:`ndp.experiments.report.regimes.regimes_readings`);
    the report adds them after its condition tables (``<out>-readings.csv``)."""

    def task_list(self) -> tuple[str, ...]:
        return tuple(self.tasks())

    def arm_specs(self) -> tuple[ArmSpec, ...]:
        return tuple(self.arms())

    def available(self) -> tuple[list[ArmSpec], list[tuple[ArmSpec, str]]]:
        """(the arms whose method is registered, [(arm, why it is left out)])."""
        from ndp.experiments.sweep import known_methods

        known = set(known_methods())
        keep, out = [], []
        for a in self.arm_specs():
            if a.algo in known:
                keep.append(a)
            elif a.pending_method:
                out.append((a, f"method {a.algo!r} is not registered in this version yet"))
            else:
                raise ValueError(
                    f"study {self.name}: arm {a.label!r} names unknown method {a.algo!r}"
                )
        return keep, out


# ----------------------------------------------------------------------------- the studies

PAPER_FIVE_TASKS = ("throw", "pick", "push-v3", "soccer-v3", "faucet-open-v3")


def _paper_five_arms() -> tuple[ArmSpec, ...]:
    return (
        ArmSpec("ndp", "ndp", (), "NDP (default head)"),
        ArmSpec("ppo", "ppo", (), "PPO"),
        ArmSpec("ppo-multi", "ppo-multi", (), "PPO-multi"),
        ArmSpec("vices", "vices", (), "VICES (impedance controller)", pending_method=True),
        ArmSpec(
            "dyne", "dyne", (), "Dyn-E (TD3 in a learned action embedding)", pending_method=True
        ),
        # the VICES ablations of the Throw study, here only when named (--arms), as in the
        # earlier benchmarks/rl_learning.py
        ArmSpec(
            "vices-pos",
            "vices-pos",
            (),
            "VICES in end-effector space (OSC) on every task",
            pending_method=True,
            in_default=False,
        ),
        ArmSpec(
            "vices-low-freq",
            "vices-low-freq",
            (),
            "VICES, one decision per k env steps",
            pending_method=True,
            in_default=False,
        ),
    )


def _mt50_tasks() -> tuple[str, ...]:
    from ndp.envs.metaworld_env import metaworld_env_names

    return tuple(metaworld_env_names())


def _mt50_arms() -> tuple[ArmSpec, ...]:
    return (ArmSpec("ndp", "ndp", (), "NDP (default head)"), ArmSpec("ppo", "ppo", (), "PPO"))


THROW_DEFAULTS = {"n_basis": 5, "k": 5, "dmp_steps": 35}
"""Throw's reference NDP (its preset: N 5, a_z 5; k 5, 35 integration steps per decision): the
``ndp`` arm; an ablation value equal to it is that arm, not a second run."""


def _ablation_arms() -> tuple[ArmSpec, ...]:
    from ndp.dmp.basis import RBF_FUNCTIONS  # one entry per kind: new kinds join the study

    arms = [ArmSpec("ndp", "ndp", (), "reference: Throw preset (gaussian RBF, N 5, k 5, 35 steps)")]
    arms += [
        ArmSpec(f"rbf-{kind.replace('_', '-')}", "ndp", ("--rbf", kind), f"RBF kind {kind}")
        for kind in RBF_FUNCTIONS
        if kind != "gaussian"
    ]
    arms += [
        ArmSpec(f"n{n}", "ndp", ("--n-basis", str(n)), f"N = {n} basis functions")
        for n in (2, 6, 10, 15, 20)
        if n != THROW_DEFAULTS["n_basis"]
    ]
    arms += [
        ArmSpec(f"steps{s}", "ndp", ("--dmp-steps", str(s)), f"{s} integration steps per decision")
        for s in (15, 25, 35, 45)
        if s != THROW_DEFAULTS["dmp_steps"]
    ]
    arms += [
        ArmSpec(f"k{k}", "ndp", ("--k", str(k)), f"k = {k} env steps per decision")
        for k in (3, 5, 7, 10, 15)
        if k != THROW_DEFAULTS["k"]
    ]
    arms += [
        ArmSpec(
            "learn-az",
            "ndp",
            ("--learn-az",),
            "learned a_z per sample, clamped to [0.5, 30], b_z = a_z / 4",
            requires="the RL NDP head's learned-a_z option (--learn-az)",
        ),
        ArmSpec(
            "only-g",
            "ndp",
            ("--only-g",),
            "only the goal is learned (no forcing term)",
            requires="the RL NDP head's goal-only option (--only-g)",
        ),
        ArmSpec(
            "vices-pos",
            "vices-pos",
            (),
            "VICES in end-effector space (OSC), the paper's vices-pos",
            pending_method=True,
        ),
        ArmSpec(
            "vices-low-freq",
            "vices-low-freq",
            (),
            "VICES, one decision per k env steps (NDP's rate)",
            pending_method=True,
        ),
    ]
    return tuple(arms)


RELEASE_TASKS = ("push-v3", "soccer-v3", "faucet-open-v3")
"""Meta-World tasks of the release-conditions study (the paper's three Meta-World tasks)."""
RELEASE_V1 = ("--reward-version", "v1")
RELEASE_FIXED = ("--goals", "fixed")
RELEASE_OPTIMISER = ("--ent-coef", "0.01", "--clip-value-loss")
"""The release's PPO settings that differ from ours: entropy 0.01, the clipped value loss."""
RELEASE_METHODS = ("ndp", "ppo-multi", "ppo")


def _release_arms() -> tuple[ArmSpec, ...]:
    """The distinct runs of the release-conditions study (conditions share them)."""
    arms = []
    for suffix, args, what in (
        ("", (), "fair: v2 rewards, random goals, our PPO settings"),
        ("-v1", RELEASE_V1, "v1 rewards, random goals"),
        ("-v1-fixed", RELEASE_V1 + RELEASE_FIXED, "v1 rewards, one fixed goal per run"),
        ("-v1-ropt", RELEASE_V1 + RELEASE_OPTIMISER,
         "v1 rewards, random goals, the release's entropy 0.01 and clipped value loss"),
    ):  # fmt: skip
        for m in RELEASE_METHODS:
            arms.append(ArmSpec(m + suffix, m, args, what))
    return tuple(arms)


def _condition(name: str, note: str, suffix: dict[str, str], unequal: bool = False) -> Condition:
    return Condition(name, note, tuple((m, m + suffix[m]) for m in RELEASE_METHODS), unequal)


RELEASE_CONDITIONS = (
    _condition("fair", "v2 rewards, random goals for every method (our default)",
               dict.fromkeys(RELEASE_METHODS, "")),
    _condition("v1", "v1 rewards for every method, random goals",
               dict.fromkeys(RELEASE_METHODS, "-v1")),
    _condition(
        "release-goals",
        "the release's condition: v1 rewards; fixed goals for NDP and PPO-multi, "
        "random goals for PPO",
        {"ndp": "-v1-fixed", "ppo-multi": "-v1-fixed", "ppo": "-v1"},
        unequal=True,
    ),
    Condition(
        "release-goals per task",
        "the release's goal rule task by task (corrected): v1 rewards; push and soccer fixed "
        "goals for NDP and PPO-multi, random for PPO (UNEQUAL); faucet-open fixed for every "
        "method (one goal per run and seed: the fixed-all arms)",
        (("ndp", "ndp-v1-fixed"), ("ppo-multi", "ppo-multi-v1-fixed"), ("ppo", "ppo-v1")),
        True,
        overrides=(("faucet-open-v3", "ppo", "ppo-v1-fixed"),),
    ),
    _condition("fixed-all", "v1 rewards, one fixed goal per run for every method",
               dict.fromkeys(RELEASE_METHODS, "-v1-fixed")),
    _condition("release-optimiser",
               "v1 rewards, random goals, entropy 0.01 and the clipped value loss for every method",
               dict.fromkeys(RELEASE_METHODS, "-v1-ropt")),
)  # fmt: skip
"""The conditions of the release-conditions study, each a method -> arm map over shared runs."""


HEAD_ABLATION_COMMANDED = ("--dmp-state", "commanded", "--dmp-velocity", "zero")
"""The frame the NDP head's handicap fixes were measured from (the default before the
per-task frame)."""


def _head_ablation_arms() -> tuple[ArmSpec, ...]:
    """The NDP head ablation (docs/results/ndp_ablation_*/): each fix of the first release's
    head switched off alone, from the commanded frame at rest; ``ndp-v0`` has every fix off."""
    c = HEAD_ABLATION_COMMANDED
    v0 = ("--mean-clip", "--forcing", "goal", "--goal-scale", "1", "--absolute-mode", "dmp",
          "--dmp-state", "measured", "--dmp-velocity", "state")  # fmt: skip
    return (
        ArmSpec("ndp", "ndp", (), "default NDP head"),
        ArmSpec("ppo", "ppo", (), "PPO, one action per step"),
        ArmSpec("ppo-multi", "ppo-multi", (), "PPO-multi, k raw actions per decision"),
        ArmSpec("ndp-commanded", "ndp", c, "commanded frame at rest"),
        ArmSpec("ndp-meanclip", "ndp", (*c, "--mean-clip"), "means clipped before the noise"),
        ArmSpec("ndp-goalforcing", "ndp", (*c, "--forcing", "goal"), "f proportional to (g - y0)"),
        ArmSpec("ndp-gs1", "ndp", (*c, "--goal-scale", "1"), "goal bound = k-step reach"),
        ArmSpec("ndp-gripdmp", "ndp", (*c, "--absolute-mode", "dmp"),
                "gripper DMP from the sampled command"),
        ArmSpec("ndp-velstate", "ndp", ("--dmp-state", "commanded", "--dmp-velocity", "state"),
                "commanded frame starting with its velocity"),
        ArmSpec("ndp-paramnoise", "ndp", (*c, "--param-noise"), "parameter-space exploration"),
        ArmSpec("ndp-v0", "ndp", v0, "every fix off (first release's head)"),
        ArmSpec("ndp-measured", "ndp", ("--dmp-state", "measured", "--dmp-velocity", "state"),
                "DMP from the measured robot and its velocity (= ndp on Meta-World)",
                in_default=False),
    )  # fmt: skip


PPO_VS_SB3_TASKS = ("reach-v3", "push-v3", "window-close-v3", "drawer-open-v3", "button-press-v3")


def _ppo_vs_sb3_arms() -> tuple[ArmSpec, ...]:
    return (
        ArmSpec("ppo", "ppo", (), "this package's PPO (k = 1)"),
        ArmSpec("sb3-ppo", "sb3-ppo", (), "Stable-Baselines3 2.x PPO"),
    )


def _sb3_ndp_arms() -> tuple[ArmSpec, ...]:
    return (
        ArmSpec("sb3-ndp", "sb3-ndp", (), "SB3 PPO with ndp.sb3.NDPPolicy (k = 5)"),
        ArmSpec("sb3-multi", "sb3-multi", (), "SB3 PPO with its MlpPolicy, k * A actions (k = 5)"),
    )


def _sac_vs_sb3_arms() -> tuple[ArmSpec, ...]:
    return (
        ArmSpec("sac", "sac", (), "this package's SAC (ndp.rl.sac; evaluation every 15,000 env "
                "steps)"),
        ArmSpec("sb3-sac", "sb3-sac", (), "Stable-Baselines3 2.x SAC, the same settings; 20 "
                "deterministic episodes at the end"),
    )  # fmt: skip


def _td3_vs_sb3_arms() -> tuple[ArmSpec, ...]:
    return (
        ArmSpec("td3", "td3", (), "this package's TD3 (ndp.rl.td3; evaluation every 15,000 env "
                "steps)"),
        ArmSpec("sb3-td3", "sb3-td3", (), "Stable-Baselines3 2.x TD3, the same settings; 20 "
                "deterministic episodes at the end"),
    )  # fmt: skip


OFF_POLICY_TASKS = ("push-v3", "throw")
"""Tasks of the off-policy study (those of ndp-regimes, whose fair on-policy arms it is read
beside)."""


def _off_policy_arms() -> tuple[ArmSpec, ...]:
    """SAC, chunked SAC and NDP-SAC at k = 5 (the chunk-size study has no best k yet)."""
    return (
        ArmSpec("sac", "sac", (), "SAC, one action per env step"),
        ArmSpec("sac-chunk-k5", "sac-chunk", (), "chunked SAC, k = 5 (critic of the chunk)"),
        ArmSpec("ndp-sac-k5", "ndp-sac", (), "NDP-SAC, k = 5, critic of (s, DMP parameters)"),
        # reading A's arm, registered on push-v3 only (docs/offpolicy.md); were A to keep the
        # actions input, B-D would need this arm on Throw too, by widening ``tasks``
        ArmSpec("ndp-sac-act-k5", "ndp-sac", ("--sac-critic-input", "actions"),
                "NDP-SAC, k = 5, critic of (s, the k actions)", in_default=False,
                tasks=("push-v3",)),
        # post-hoc (2026-12-05, after NDP-SAC's critic ran away on push-v3 and the sac-critic
        # study's first seed kept a LayerNorm critic bounded): both chunk learners with LayerNorm
        # critics, on push-v3 only, run only when named (reading E)
        ArmSpec("ndp-sac-ln-k5", "ndp-sac", ("--sac-critic-layer-norm",),
                "NDP-SAC, k = 5, critic of (s, DMP parameters), LayerNorm critics (post-hoc)",
                in_default=False, tasks=("push-v3",)),
        ArmSpec("sac-chunk-ln-k5", "sac-chunk", ("--sac-critic-layer-norm",),
                "chunked SAC, k = 5, LayerNorm critics (post-hoc)", in_default=False,
                tasks=("push-v3",)),
        # the confound arms of docs/rl-release.md part 3 (pre-registered 2026-12-06): the live
        # reward SAC at k = 1 always had, and one gradient step per stored decision (SAC's
        # replay ratio; the k-step arms take k per decision); run only when named
        *_live_arms(),
    )  # fmt: skip


OFF_POLICY_UTD1 = ("--sac-updates-per-step", "0.2")
"""One gradient step per stored decision at k = 5 (0.2 per env step; the default is k)."""


def _live_arms() -> tuple[ArmSpec, ...]:
    """Chunked SAC and NDP-SAC on the live reward, at k gradient steps and at one per decision."""
    live = ("--no-stale-world",)
    out = []
    for label, method, what in (("sac-chunk", "sac-chunk", "chunked SAC"),
                                ("ndp-sac", "ndp-sac", "NDP-SAC")):  # fmt: skip
        out += [
            ArmSpec(f"{label}-live-k5", method, live, f"{what}, k = 5, live reward",
                    in_default=False),
            ArmSpec(f"{label}-live-utd1-k5", method, (*live, *OFF_POLICY_UTD1),
                    f"{what}, k = 5, live reward, one gradient step per decision",
                    in_default=False),
        ]  # fmt: skip
    return tuple(out)


OFF_POLICY_CONDITIONS = (
    Condition("k = 5", "every learner at k = 5 env steps per decision (SAC and PPO: k = 1), white "
              "noise for the on-policy arms, 300k env steps; the on-policy arms are ndp-regimes' "
              "runs (read with both run directories)",
              (("sac", "sac"), ("sac-chunk", "sac-chunk-k5"), ("ndp-sac", "ndp-sac-k5"),
               ("ndp", "ndp-k5"), ("ppo-multi", "ppo-multi-k5"), ("ppo", "ppo"))),
    Condition("NDP-SAC's critic input", "NDP-SAC with the critic of (s, DMP parameters) against "
              "the critic of (s, the k actions) (docs/offpolicy.md: the rule to keep one)",
              (("ndp-sac (params)", "ndp-sac-k5"), ("ndp-sac (actions)", "ndp-sac-act-k5"))),
    Condition("LayerNorm critics (post-hoc)", "chunked SAC and NDP-SAC at k = 5 with LayerNorm "
              "after each hidden layer of their critics, beside the plain critics; push-v3 only; "
              "added 2026-12-05 after NDP-SAC's critic ran away (docs/offpolicy.md, reading E)",
              (("sac-chunk (LayerNorm)", "sac-chunk-ln-k5"),
               ("ndp-sac (LayerNorm)", "ndp-sac-ln-k5"), ("sac-chunk (plain)", "sac-chunk-k5"),
               ("ndp-sac (plain)", "ndp-sac-k5"))),
    Condition("live reward, k = 5", "every learner on the env's own reward at every sub-step "
              "(chunked SAC, NDP-SAC, NDP and PPO-multi with --no-stale-world; SAC and PPO: "
              "k = 1); docs/rl-release.md part 3, reading 4",
              (("sac", "sac"), ("sac-chunk", "sac-chunk-live-k5"), ("ndp-sac", "ndp-sac-live-k5"),
               ("ndp", "ndp-nostale"), ("ppo-multi", "ppo-multi-nostale"), ("ppo", "ppo"))),
    Condition("live reward, one update per decision", "chunked SAC and NDP-SAC on the live "
              "reward with one gradient step per stored decision (SAC's replay ratio), beside "
              "SAC; docs/rl-release.md part 3, reading 5",
              (("sac", "sac"), ("sac-chunk", "sac-chunk-live-utd1-k5"),
               ("ndp-sac", "ndp-sac-live-utd1-k5"))),
)  # fmt: skip
"""The off-policy study's table: its SAC arms beside ndp-regimes' fair on-policy arms."""


def _sac_critic_arms() -> tuple[ArmSpec, ...]:
    """NDP-SAC on push-v3 with LayerNorm critics and with the plain ones (study ``sac-critic``)."""
    return (
        ArmSpec("ndp-sac-ln-k5", "ndp-sac", ("--sac-critic-layer-norm",),
                "NDP-SAC, k = 5, critic of (s, DMP parameters), LayerNorm critics"),
        ArmSpec("ndp-sac-k5", "ndp-sac", (), "NDP-SAC, k = 5, critic of (s, DMP parameters), "
                "SAC's plain critics (off-policy's arm, short budget)"),
    )  # fmt: skip


def _sac_critic_readings(
    cells: Sequence[Any], seeds: Sequence[int]
) -> tuple[list[str], list[dict[str, Any]]]:
    """sac-critic's reading (:func:`ndp.experiments.report.offpolicy.critic_study_readings`)."""
    from ndp.experiments.report.offpolicy import critic_study_readings

    return critic_study_readings(cells, seeds)


RELEASE_1M_TASKS = ("push-v3", "throw")
"""The 1M-step stage of the release-conditions study: a Meta-World task and a Jaco task."""


def _release_1m_arms() -> tuple[ArmSpec, ...]:
    """Fair arms of the three methods, and NDP / PPO-multi on one fixed goal per run (v2
    rewards: Throw has no v1 reward, and the 300k screen isolates the goals as the condition
    that moves NDP against PPO)."""
    fair = tuple(ArmSpec(m, m, (), "fair: v2 rewards, random goals") for m in RELEASE_METHODS)
    fixed = tuple(
        ArmSpec(m + "-fixed", m, RELEASE_FIXED, "v2 rewards, one fixed goal per run")
        for m in ("ndp", "ppo-multi")
    )
    # the release fixed Throw's basket for every method (PPO too): the runs that make the
    # Throw rows of release-goals the release's rule (issue "release explained, part 2")
    ppo_throw = ArmSpec("ppo-fixed", "ppo", RELEASE_FIXED, "v2 rewards, one fixed goal per run "
                        "(Throw only: the release fixed Throw for every method)",
                        tasks=("throw",))  # fmt: skip
    return (*fair, *fixed, ppo_throw)


RELEASE_1M_CONDITIONS = (
    Condition("fair", "v2 rewards, random goals for every method (our default)",
              tuple((m, m) for m in RELEASE_METHODS)),
    Condition("release-goals",
              "the release's goal rule alone, per task: fixed goals for NDP and PPO-multi and "
              "random goals for PPO on push; fixed goals for every method on Throw (v2 rewards; "
              "one fixed goal per run)",
              (("ndp", "ndp-fixed"), ("ppo-multi", "ppo-multi-fixed"), ("ppo", "ppo")),
              True, overrides=(("throw", "ppo", "ppo-fixed"),)),
)  # fmt: skip
"""The conditions of release-goals-1m (release-goals is UNEQUAL on purpose, and labelled so)."""


EXPLAINED_TASKS = ("push-v3", "soccer-v3", "faucet-open-v3", "throw")
"""Tasks of release-explained: the paper's three Meta-World tasks and Throw."""
RELEASE_ALL_MW = (
    *RELEASE_V1,
    "--goals", "as-release",
    "--observation", "release9",
    *RELEASE_OPTIMISER,
    "--steps-per-update", "500",
)  # fmt: skip
"""Every release condition our code has, for one method on a Meta-World task: v1 rewards, the
release's goals for this method on this task (ndp.envs.release.release_goals), the 9-D
observation, entropy 0.01 and the clipped value loss, 500 env steps per update. Chunked methods
add the first-held execution and keep the stale-world reward: the release built NDP and
PPO-multi alike with ``reward_delay=T`` (its main_rl.py). The first release-all arm of PPO-multi
(``ppo-multi-rall``) took the live reward instead, on the mistaken reading that the stale rule
was NDP's only: it is kept, labelled as that deviation. Not reproducible here: the linear lr
decay over 25,000 updates (at 300k env steps it would have lowered the lr by 2.4%), the vendored
pre-v1 Meta-World and push's 4x timestep."""
FIRST_HELD = ("--execution", "first-held")
RELEASE_RATIO = ("--first-held-ratio", "release")
"""The release's PPO ratio under first-held execution, pi_j,new(a_0) / pi_0,old(a_0)."""


def _explained_arms() -> tuple[ArmSpec, ...]:
    """The runs of release-explained (docs/rl-release.md); an arm runs only on its tasks."""
    mw, push, throw = RELEASE_TASKS, ("push-v3",), ("throw",)
    rel_v1 = (*RELEASE_V1, "--goals", "release")
    rel = ("--goals", "release")
    return (
        # fair reference (the 300k screen's runs on Meta-World, archived; new on Throw)
        ArmSpec("ndp", "ndp", (), "fair: v2 rewards, random goals, all sub-actions executed"),
        ArmSpec("ppo-multi", "ppo-multi", (), "fair"),
        ArmSpec("ppo", "ppo", (), "fair"),
        # every release condition at once (Meta-World)
        ArmSpec("ndp-rall", "ndp", (*RELEASE_ALL_MW, *FIRST_HELD),
                "release-all: every release condition at once", tasks=mw),
        ArmSpec("ppo-multi-rall", "ppo-multi", (*RELEASE_ALL_MW, *FIRST_HELD, "--no-stale-world"),
                "release-all, deviation: PPO-multi on the live reward (the release gave it the "
                "stale rule)", tasks=mw),
        # release-all as released (issue "release explained, part 3"): PPO-multi on the stale
        # rule as the release ran it, and both chunked methods with the release's ratio
        ArmSpec("ppo-multi-rall-stale", "ppo-multi", (*RELEASE_ALL_MW, *FIRST_HELD),
                "release-all as released: PPO-multi on the stale-world reward", tasks=mw),
        ArmSpec("ndp-rall-rr", "ndp", (*RELEASE_ALL_MW, *FIRST_HELD, *RELEASE_RATIO),
                "release-all as released, with the release's first-held PPO ratio", tasks=mw),
        ArmSpec("ppo-multi-rall-rr", "ppo-multi", (*RELEASE_ALL_MW, *FIRST_HELD, *RELEASE_RATIO),
                "release-all as released (stale world), with the release's first-held PPO "
                "ratio", tasks=mw),
        ArmSpec("ppo-rall", "ppo", RELEASE_ALL_MW, "release-all (random goals on push / soccer)",
                tasks=mw),
        # the release's execution on push (v1, the release's one goal) ...
        ArmSpec("ndp-v1-rel", "ndp", rel_v1, "v1, the release's goal, all executed", tasks=push),
        ArmSpec("ndp-v1-rel-fh", "ndp", (*rel_v1, *FIRST_HELD), "v1, release goal, first held",
                tasks=push),
        ArmSpec("ppo-multi-v1-rel", "ppo-multi", rel_v1, "v1, release goal, all executed",
                tasks=push),
        ArmSpec("ppo-multi-v1-rel-fh", "ppo-multi", (*rel_v1, *FIRST_HELD),
                "v1, release goal, first held", tasks=push),
        ArmSpec("ppo-repeat-v1-rel", "ppo-repeat", rel_v1,
                "v1, release goal, PPO with its action held k = 5 steps", tasks=push),
        ArmSpec("ppo-v1-rel", "ppo", rel_v1, "v1, release goal", tasks=push, in_default=False),
        # ... and on Throw (the release's one basket place, for every method)
        ArmSpec("ndp-rel", "ndp", rel, "release basket, all executed", tasks=throw),
        ArmSpec("ndp-rel-fh", "ndp", (*rel, *FIRST_HELD), "release basket, first held",
                tasks=throw),
        ArmSpec("ppo-multi-rel", "ppo-multi", rel, "release basket, all executed", tasks=throw),
        ArmSpec("ppo-multi-rel-fh", "ppo-multi", (*rel, *FIRST_HELD),
                "release basket, first held", tasks=throw),
        ArmSpec("ppo-repeat-rel", "ppo-repeat", rel, "release basket, action held k = 5 steps",
                tasks=throw),
        ArmSpec("ppo-rel", "ppo", rel, "release basket", tasks=throw),
        # the release's 9-D observation alone (fair otherwise)
        ArmSpec("ndp-obs9", "ndp", ("--observation", "release9"), "9-D observation",
                tasks=("push-v3", "soccer-v3")),
        ArmSpec("ppo-multi-obs9", "ppo-multi", ("--observation", "release9"), "9-D observation",
                tasks=("push-v3", "soccer-v3")),
        ArmSpec("ppo-obs9", "ppo", ("--observation", "release9"), "9-D observation",
                tasks=("push-v3", "soccer-v3")),
    )  # fmt: skip


EXPLAINED_CONDITIONS = (
    Condition("fair", "v2 rewards, random goals for every method (our default)",
              (("ndp", "ndp"), ("ppo-multi", "ppo-multi"), ("ppo", "ppo"))),
    Condition("obs9", "the release's 9-D observation (hand, object, goal), fair otherwise",
              (("ndp", "ndp-obs9"), ("ppo-multi", "ppo-multi-obs9"), ("ppo", "ppo-obs9"))),
    Condition("release-all",
              "every release condition at once: v1 rewards, the release's goals per task (PPO "
              "random on push / soccer), first-held execution, 9-D observation, entropy 0.01, "
              "clipped value loss, 500 env steps per update; deviation: PPO-multi on the live "
              "reward (the release gave it the stale rule; see 'release-all as released')",
              (("ndp", "ndp-rall"), ("ppo-multi", "ppo-multi-rall"), ("ppo", "ppo-rall")),
              True),
    Condition("release-all as released",
              "release-all with the stale-world reward for NDP and PPO-multi, as the release ran "
              "both; our first-held ratio (each sub-step's own sample)",
              (("ndp", "ndp-rall"), ("ppo-multi", "ppo-multi-rall-stale"), ("ppo", "ppo-rall")),
              True),
    Condition("release-all as released, release ratio",
              "release-all as released with the release's first-held PPO ratio "
              "pi_j,new(a_0) / pi_0,old(a_0) for NDP and PPO-multi",
              (("ndp", "ndp-rall-rr"), ("ppo-multi", "ppo-multi-rall-rr"), ("ppo", "ppo-rall")),
              True),
    Condition("push: release goal, all executed",
              "push only: v1 rewards, the release's one goal for every method",
              (("ndp", "ndp-v1-rel"), ("ppo-multi", "ppo-multi-v1-rel"),
               ("ppo-repeat", "ppo-repeat-v1-rel"))),
    Condition("push: release goal, first held",
              "push only: v1 rewards, the release's one goal; NDP / PPO-multi execute only their "
              "first sub-action, held k = 5 steps; PPO-repeat holds its one action",
              (("ndp", "ndp-v1-rel-fh"), ("ppo-multi", "ppo-multi-v1-rel-fh"),
               ("ppo-repeat", "ppo-repeat-v1-rel"))),
    Condition("throw: release basket, all executed",
              "Throw only: the basket at the release's one place for every method",
              (("ndp", "ndp-rel"), ("ppo-multi", "ppo-multi-rel"), ("ppo", "ppo-rel"),
               ("ppo-repeat", "ppo-repeat-rel"))),
    Condition("throw: release basket, first held",
              "Throw only: the release's basket; NDP / PPO-multi execute only their first "
              "sub-action, held k = 5 steps",
              (("ndp", "ndp-rel-fh"), ("ppo-multi", "ppo-multi-rel-fh"), ("ppo", "ppo-rel"),
               ("ppo-repeat", "ppo-repeat-rel"))),
)  # fmt: skip
"""The conditions of release-explained (release-all is UNEQUAL on push and soccer: PPO draws
random goals there, as in the release)."""


REGIME_TASKS = ("push-v3", "throw")
"""Tasks of ndp-regimes (a Meta-World task and a Jaco task; never used to tune NDP)."""
REGIME_KS = (5, 10, 20)
"""Decision lengths of the chunk-size arms (NDP's basis count stays at the task's preset, so a
larger k compresses more env steps into the same parameters)."""
PARAM_NOISE_LOG_STD = "0.0"
"""init_log_std of the calibrated parameter-noise arms: the value at which the executed
(clipped) sub-actions of a fresh NDP policy vary as much as under the white arm's std 1
(benchmarks/param_noise_calibration.py,
docs/results/param_noise_calibration/param_noise_calibration.json: 0.01 to 0.05 on push-v3,
-0.12 to -0.09 on Throw, for k = 5, 10, 20)."""
PARAM_NOISE_DISPLACEMENT = {5: "-1.5", 10: "-2.0", 20: "-2.3"}
"""init_log_std at which parameter noise moves a decision's summed displacement as much as the
white arm (the same benchmark: push-v3 -1.57 / -1.98 / -2.35, Throw -1.46 / -1.84 / -2.19):
the smaller calibration, by the other reading of "as much noise"."""
AR1_CORR = "0.8"
"""Correlation of consecutive env steps' AR(1) noise in the correlated-noise arms."""


MECHANISM_TASKS = ("push-v3", "throw", "reach-v3")
"""Tasks of ndp-mechanism: the conditioning set on push-v3 and Throw, the basis set on push-v3,
the rewards pilot on reach-v3 and push-v3 (each arm on its tasks)."""
MECHANISM_BASES = ("dmp", "dct", "bspline")
"""The fixed chunk bases of the basis set run by default ('pca' needs a file fitted on the free
PPO-multi arm's runs first: its arm runs only when named, with ``--chunk-basis-file``)."""
LIVE = ("--no-stale-world",)
"""The env's own reward at every sub-step (docs/rl-release.md part 3: the fair-live rule)."""


def _mechanism_arms() -> tuple[ArmSpec, ...]:
    """The arms of ndp-mechanism (docs/rl-mechanism.md, readings committed before the runs)."""
    both, push = ("push-v3", "throw"), ("push-v3",)
    arms = [
        ArmSpec("ndp-linear", "ndp", ("--param-map", "linear", *LIVE),
                "NDP, k = 5, live reward, goal and weights linear in the outputs (no tanh)",
                tasks=both),
        ArmSpec("ndp-whitened", "ndp", ("--param-map", "whitened", *LIVE),
                "NDP, k = 5, live reward, outputs whitened through the action map at rest",
                tasks=both),
    ]  # fmt: skip
    for k in (10, 20):
        ka = (*_k_args(k), *LIVE)
        arms += [
            ArmSpec(f"ppo-multi-live-k{k}", "ppo-multi", ka, f"PPO-multi, k = {k}, live reward",
                    tasks=push),
            ArmSpec(f"ndp-live-k{k}", "ndp", ka, f"NDP, k = {k}, live reward", tasks=push),
            *[ArmSpec(f"ppo-multi-{b}-k{k}", "ppo-multi", (*ka, "--chunk-basis", b),
                      f"PPO-multi, k = {k}, live reward, chunk in the {b} basis (1 + N per DoF)",
                      tasks=push) for b in MECHANISM_BASES],
            ArmSpec(f"ppo-multi-pca-k{k}", "ppo-multi", (*ka, "--chunk-basis", "pca"),
                    f"PPO-multi, k = {k}, live reward, chunk in a PCA basis of the free arm's "
                    "chunks (give --chunk-basis-file)", in_default=False, tasks=push),
        ]  # fmt: skip
    rewards = ("reach-v3", "push-v3")
    for variant in ("sparse", "smooth"):
        rv = ("--reward", variant)
        arms += [
            ArmSpec(f"ndp-{variant}", "ndp", (*rv, *LIVE), f"NDP, k = 5, {variant} reward",
                    requires="--reward", tasks=rewards),
            ArmSpec(f"ppo-multi-{variant}", "ppo-multi", (*rv, *LIVE),
                    f"PPO-multi, k = 5, {variant} reward", requires="--reward", tasks=rewards),
            ArmSpec(f"ppo-{variant}", "ppo", rv, f"PPO, {variant} reward", requires="--reward",
                    tasks=rewards),
        ]  # fmt: skip
    return tuple(arms)


def _mechanism_conditions() -> tuple[Condition, ...]:
    """ndp-mechanism's tables; the fair-live arms (ndp-nostale, ppo-multi-nostale, ppo) are
    ndp-regimes' runs (read with both run directories)."""
    conds = [
        Condition("conditioning, k = 5", "NDP's head with tanh (default), linear and whitened "
                  "maps beside PPO-multi and PPO, every method on the live reward",
                  (("ndp", "ndp-nostale"), ("ndp (linear)", "ndp-linear"),
                   ("ndp (whitened)", "ndp-whitened"), ("ppo-multi", "ppo-multi-nostale"),
                   ("ppo", "ppo"))),
    ]  # fmt: skip
    for k in (10, 20):
        conds.append(
            Condition(f"basis, k = {k}", f"PPO-multi free and restricted to a fixed basis of "
                      f"1 + N functions per DoF, and NDP, at k = {k}, live reward (push-v3)",
                      (("ppo-multi", f"ppo-multi-live-k{k}"),
                       *[(f"ppo-multi ({b})", f"ppo-multi-{b}-k{k}")
                         for b in (*MECHANISM_BASES, "pca")],
                       ("ndp", f"ndp-live-k{k}")))
        )  # fmt: skip
    for variant in ("sparse", "smooth"):
        conds.append(
            Condition(f"{variant} reward", f"every method on the {variant} reward variant "
                      "(--reward), k = 5 for the chunked methods, live world",
                      (("ndp", f"ndp-{variant}"), ("ppo-multi", f"ppo-multi-{variant}"),
                       ("ppo", f"ppo-{variant}")))
        )  # fmt: skip
    return tuple(conds)


def _k_args(k: int) -> tuple[str, ...]:
    """Options of a k-step arm: k, and the mini-batch count that keeps about 13 decisions per
    mini-batch at 2,048 env steps per update (32 at k = 5, 16 at k = 10, 8 at k = 20)."""
    if k == 5:
        return ()
    return ("--k", str(k), "--minibatches", str(32 * 5 // k))


def _regime_arms() -> tuple[ArmSpec, ...]:
    """The arms of ndp-regimes (docs/rl-regimes.md): priority order (the sweep runs them in the
    order --arms names them)."""
    arms = [ArmSpec("ppo", "ppo", (), "PPO, k = 1, white noise")]
    for k in REGIME_KS:
        arms += [
            ArmSpec(f"ndp-k{k}", "ndp", _k_args(k), f"NDP, k = {k}, white noise"),
            ArmSpec(f"ppo-multi-k{k}", "ppo-multi", _k_args(k), f"PPO-multi, k = {k}, white"),
            ArmSpec(f"ndp-param-k{k}", "ndp",
                    (*_k_args(k), "--param-noise", "--init-log-std", PARAM_NOISE_LOG_STD),
                    f"NDP, k = {k}, parameter noise calibrated per sub-action"),
        ]  # fmt: skip
    ar1 = ("--noise", "ar1", "--noise-corr", AR1_CORR)
    arms += [
        ArmSpec("ndp-ar1-k5", "ndp", ar1, "NDP, k = 5, AR(1) noise"),
        ArmSpec("ppo-multi-ar1-k5", "ppo-multi", ar1, "PPO-multi, k = 5, AR(1) noise"),
        ArmSpec("ppo-ar1", "ppo", ar1, "PPO, AR(1) noise"),
        ArmSpec("ndp-nostale", "ndp", ("--no-stale-world",), "NDP, k = 5, live reward"),
        ArmSpec("ppo-multi-nostale", "ppo-multi", ("--no-stale-world",),
                "PPO-multi, k = 5, live reward"),
    ]  # fmt: skip
    # the correlated noise at the best k (chosen by the pre-registered rule after the k arms),
    # and parameter noise at the displacement calibration: only when named
    for k in REGIME_KS[1:]:
        arms += [
            ArmSpec(f"ndp-ar1-k{k}", "ndp", (*_k_args(k), *ar1), f"NDP, k = {k}, AR(1) noise",
                    in_default=False),
            ArmSpec(f"ppo-multi-ar1-k{k}", "ppo-multi", (*_k_args(k), *ar1),
                    f"PPO-multi, k = {k}, AR(1) noise", in_default=False),
        ]  # fmt: skip
    for k in REGIME_KS:
        arms.append(
            ArmSpec(
                f"ndp-paramd-k{k}",
                "ndp",
                (*_k_args(k), "--param-noise", "--init-log-std", PARAM_NOISE_DISPLACEMENT[k]),
                f"NDP, k = {k}, parameter noise calibrated per decision displacement",
                in_default=False,
            )
        )
    # NDP with ndp-settings' winner (docs/results/ndp_settings/ndp_settings.md: N 10; lr, a_z
    # and the init std stay at their defaults), added after that study, before any of these runs
    arms.append(ArmSpec("ndp-tuned", "ndp", ("--n-basis", "10"),
                        "NDP, k = 5, white noise, the ndp-settings winner (N 10)",
                        in_default=False))  # fmt: skip
    return tuple(arms)


NDP_SETTINGS_AXES = (
    ("lr", ("1e-4", "1e-3")),
    ("n-basis", ("3", "10")),
    ("a-z", ("5", "25")),
    ("init-log-std", ("-1.0", "-0.5")),
)
"""NDP's own settings, one axis at a time from the defaults (lr 3e-4, reach-v3's preset N 6 and
a_z 15, init_log_std 0): the pre-registered sweep of ndp-settings (docs/rl-regimes.md)."""


REGIME_1M_ARMS = ("ndp-k5", "ppo-multi-k5", "ndp-k10", "ppo-multi-k10", "ndp-k20", "ppo-multi-k20",
                  "ppo")  # fmt: skip
"""The arms of ndp-regimes-1m, in priority order: the chunk-size arms (white noise) and PPO."""


def _regime_1m_arms() -> tuple[ArmSpec, ...]:
    """ndp-regimes' chunk-size arms and PPO, unchanged, for the 1M-step run on push-v3."""
    by_label = {a.label: a for a in _regime_arms()}
    return tuple(by_label[lb] for lb in REGIME_1M_ARMS)


def _regime_conditions(ks: Sequence[int], extra: bool) -> tuple[Condition, ...]:
    """ndp-regimes' arms as conditions (NDP, PPO-multi, PPO under one setting each): the white
    noise at each k of ``ks`` and, with ``extra``, the exploration, stale-rule and tuned arms
    (PPO-multi and PPO keep white noise where they have no arm of that setting)."""
    conds = [
        Condition(f"white, k = {k}", f"white Gaussian noise per sub-action, k = {k} (PPO k = 1)",
                  (("ndp", f"ndp-k{k}"), ("ppo-multi", f"ppo-multi-k{k}"), ("ppo", "ppo")))
        for k in ks
    ]  # fmt: skip
    if not extra:
        return tuple(conds)
    conds += [
        Condition(f"NDP parameter noise, k = {k}",
                  f"NDP explores in its DMP parameters (calibrated), k = {k}; PPO-multi and PPO "
                  "white", (("ndp", f"ndp-param-k{k}"), ("ppo-multi", f"ppo-multi-k{k}"),
                            ("ppo", "ppo")))
        for k in ks
    ]  # fmt: skip
    conds += [
        Condition("AR(1), k = 5", "AR(1) (Ornstein-Uhlenbeck) noise, rho 0.8, for every method",
                  (("ndp", "ndp-ar1-k5"), ("ppo-multi", "ppo-multi-ar1-k5"), ("ppo", "ppo-ar1"))),
        Condition("live reward, k = 5", "--no-stale-world for NDP and PPO-multi (PPO: k = 1, no "
                  "sub-steps)", (("ndp", "ndp-nostale"), ("ppo-multi", "ppo-multi-nostale"),
                                 ("ppo", "ppo"))),
        Condition("NDP tuned (N 10), k = 5", "NDP with ndp-settings' winner; PPO-multi and PPO "
                  "white", (("ndp", "ndp-tuned"), ("ppo-multi", "ppo-multi-k5"), ("ppo", "ppo"))),
    ]  # fmt: skip
    return tuple(conds)


def _regimes_readings(
    cells: Sequence[Any], seeds: Sequence[int]
) -> tuple[list[str], list[dict[str, Any]]]:
    """ndp-regimes' readings 1-7 (:func:`ndp.experiments.report.regimes.regimes_readings`)."""
    from ndp.experiments.report.regimes import regimes_readings

    return regimes_readings(cells, seeds)


def _mt50_attribution_readings(
    cells: Sequence[Any], seeds: Sequence[int]
) -> tuple[list[str], list[dict[str, Any]]]:
    """mt50-attribution's reading (``regimes.mt50_attribution_readings``)."""
    from ndp.experiments.report.regimes import mt50_attribution_readings

    return mt50_attribution_readings(cells, seeds)


def _regimes_1m_readings(
    cells: Sequence[Any], seeds: Sequence[int]
) -> tuple[list[str], list[dict[str, Any]]]:
    """ndp-regimes-1m's reading 8 (:func:`ndp.experiments.report.regimes.regimes_1m_readings`)."""
    from ndp.experiments.report.regimes import regimes_1m_readings

    return regimes_1m_readings(cells, seeds)


def _off_policy_readings(
    cells: Sequence[Any], seeds: Sequence[int]
) -> tuple[list[str], list[dict[str, Any]]]:
    """off-policy's readings A-D (:func:`ndp.experiments.report.offpolicy.off_policy_readings`)."""
    from ndp.experiments.report.offpolicy import off_policy_readings

    return off_policy_readings(cells, seeds)


def _settings_arms() -> tuple[ArmSpec, ...]:
    arms = [ArmSpec("ndp", "ndp", (), "NDP defaults (lr 3e-4, N 6, a_z 15, log std 0)")]
    for opt, values in NDP_SETTINGS_AXES:
        for v in values:
            label = f"ndp-{opt}{v}".replace(".", "p")
            arms.append(ArmSpec(label, "ndp", (f"--{opt}", v), f"NDP, --{opt} {v}"))
    return tuple(arms)


BC_TASKS = ("throw", "pick", "push-v3", "soccer-v3", "faucet-open-v3")
"""Tasks of the behaviour-cloning study (the paper's five robot tasks, each with a scripted
expert: ndp.bc.experts)."""
BC_DEMOS = (25, 100, 400)
"""Demonstration counts of the behaviour-cloning study (the first n of one recording per task)."""


def _bc_arms() -> tuple[ArmSpec, ...]:
    """NDP and the plain network (the PPO-multi actor) at each demonstration count; the PPO
    actor (one action per step) and NDP starting from the commanded velocity only by name."""
    models = (
        ("ndp", "bc-ndp", (), "NDP: (g, w) -> DMP -> inverse controller -> k actions", True),
        ("nn", "bc-nn", (), "NN: k raw actions per decision (the PPO-multi actor)", True),
        ("nn-step", "bc-nn-step", (), "NN: one action per env step (the PPO actor)", False),
        ("ndp-vstate", "bc-ndp", ("--dmp-velocity", "state"),
         "NDP whose DMP starts from the commanded velocity", False),
    )  # fmt: skip
    return tuple(
        ArmSpec(
            f"{label}-n{n}",
            algo,
            (*args, "--episodes", str(n)),
            f"{note}; {n} demos",
            in_default=default,
        )
        for n in BC_DEMOS
        for label, algo, args, note, default in models
    )


DIGITS_TASKS = ("pendigits", "synthetic-300", "synthetic-1000", "synthetic-3000", "synthetic")


def _digits_arms() -> tuple[ArmSpec, ...]:
    return (
        ArmSpec("ndp", "il-ndp", (), "NDP: CNN -> (g, w) -> DMP layer"),
        ArmSpec("cnn", "il-cnn", (), "CNN: 301 x 2 points directly"),
        ArmSpec("cnn-dmp", "il-cnn-dmp", (), "CNN-DMP: regress fitted DMP parameters"),
    )


CONVERGED_LRS = ("3e-4", "1e-3", "3e-3")
"""The learning-rate grid of the converged digit study (the same for every model)."""
CONVERGED_ARGS = ("--val-fraction", "0.1", "--patience", "20", "--eval-every", "0")
"""Every converged run: 10% of the training split for validation, stop after 20 epochs without
a lower validation MSE, the test split scored once at the end (on the best weights)."""
CONVERGED_MODELS = (("ndp", "il-ndp"), ("cnn", "il-cnn"), ("cnn-dmp", "il-cnn-dmp"))


def _converged_arms() -> tuple[ArmSpec, ...]:
    return tuple(
        ArmSpec(
            f"{m}-lr{lr}",
            algo,
            ("--lr", lr, *CONVERGED_ARGS),
            f"{m}, Adam lr {lr}, early stopping on validation",
        )
        for m, algo in CONVERGED_MODELS
        for lr in CONVERGED_LRS
    )


MT50_ATTRIBUTION_TASKS = (
    "button-press-v3",
    "door-unlock-v3",
    "faucet-close-v3",
    "plate-slide-v3",
    "sweep-into-v3",
    "window-close-v3",
    "window-open-v3",
)
"""The Meta-World tasks where NDP's and PPO's final success differed by more than 0.1 at seed 0
in docs/results/mt50_100k/mt50_100k.csv (100k env steps), fixed before any run of
mt50-attribution."""


def _mt50_attribution_arms() -> tuple[ArmSpec, ...]:
    return (
        ArmSpec("ndp", "ndp", (), "NDP (default head)"),
        ArmSpec("ppo-multi", "ppo-multi", (), "PPO-multi"),
        ArmSpec("ppo", "ppo", (), "PPO"),
    )


HEAD_LRS = ("1e-3", "3e-3", "1e-2")
"""The learning-rate grid of digits-head (NDP's best converged lr sat at the top of the old
grid, 3e-3, on several sizes)."""
HEADS = (("lin", ()), ("paper", ("--network", "paper")))
"""digits-head's head axis: the linear head and the release's 100-200-128-64 MLP."""


def _head_arms() -> tuple[ArmSpec, ...]:
    return tuple(
        ArmSpec(
            f"{m}-{h}-lr{lr}",
            algo,
            ("--lr", lr, *args, *CONVERGED_ARGS),
            f"{m}, {'the release head 100-200-128-64' if args else 'linear head'}, Adam lr {lr}",
        )
        for m, algo in CONVERGED_MODELS
        for h, args in HEADS
        for lr in HEAD_LRS
    )


def _head_selection() -> tuple[tuple[str, tuple[str, ...]], ...]:
    """Per model: the best of both heads and every lr; and each head alone (equal capacity)."""
    out = []
    for m, _ in CONVERGED_MODELS:
        out.append((m, tuple(f"{m}-{h}-lr{lr}" for h, _ in HEADS for lr in HEAD_LRS)))
    for h, _ in HEADS:
        for m, _ in CONVERGED_MODELS:
            out.append((f"{m} ({h} head)", tuple(f"{m}-{h}-lr{lr}" for lr in HEAD_LRS)))
    return tuple(out)


STUDIES: dict[str, Study] = {
    s.name: s
    for s in (
        Study(
            name="paper-five",
            title="The paper's five tasks: NDP vs PPO, PPO-multi, VICES and Dyn-E",
            doc=(
                "Throw, Pick (Jaco), Push, Soccer, Faucet-open (Meta-World v3) x NDP, PPO, "
                "PPO-multi, VICES and Dyn-E (vices-pos and vices-low-freq when named with "
                "--arms); same budget, seeds and evaluation for every method, same PPO settings "
                "for the PPO-trained ones. Success = charts/success_any of the training episodes "
                "(stochastic policy)."
            ),
            tasks=lambda: PAPER_FIVE_TASKS,
            arms=_paper_five_arms,
            steps=300_000,
        ),
        Study(
            name="mt50",
            title="All 50 Meta-World tasks: NDP vs PPO",
            doc=(
                "The 50 Meta-World v3 tasks (metaworld's order) x NDP and PPO. The report adds "
                "the paper's summary: the mean success over tasks per method and on how many "
                "tasks NDP >= PPO (final success; higher, equal, of those both at 0, lower)."
            ),
            tasks=_mt50_tasks,
            arms=_mt50_arms,
            steps=300_000,
            summary=("over-tasks",),
        ),
        Study(
            name="ablations",
            title="NDP ablations on Throw",
            doc=(
                "Throw x the NDP head with one setting changed from the task's preset (the "
                "reference arm 'ndp': gaussian RBF, N 5, a_z 5, k 5, 35 integration steps per "
                "decision): RBF kind (every other kind of ndp.dmp.basis.RBF_FUNCTIONS), N in "
                "{2, 6, 10, 15, 20}, integration steps in {15, 25, 35, 45}, k in "
                "{3, 5, 7, 10, 15}, a learned a_z (--learn-az: per sample, clamped to [0.5, 30], "
                "b_z = a_z / 4), a goal-only NDP (--only-g), and VICES in end-effector space "
                "(vices-pos) and at NDP's decision rate (vices-low-freq). Values equal to the "
                "reference are the 'ndp' arm."
            ),
            tasks=lambda: ("throw",),
            arms=_ablation_arms,
            steps=300_000,
        ),
        Study(
            name="release-conditions",
            title="The 2021 release's conditions, one at a time: NDP vs PPO-multi vs PPO",
            doc=(
                "push-v3, soccer-v3, faucet-open-v3 x NDP, PPO-multi, PPO under five conditions "
                "that share runs (12 distinct runs per task and seed): fair (v2 rewards, random "
                "goals, our defaults); v1 (the v1 shaped rewards the release trained on); "
                "release-goals (v1, fixed goals for NDP and PPO-multi, random goals for PPO: the "
                "release's UNEQUAL condition, reproduced on purpose and labelled so); fixed-all "
                "(v1, fixed goals for every method); release-optimiser (v1, entropy 0.01 and the "
                "clipped value loss for every method). Success is the v2 evaluation under every "
                "reward. Report with --conditions: per condition and task the mean and 95% "
                "bootstrap CI over seeds, success at any step and at the final step; over tasks "
                "the IQM with stratified-bootstrap CIs and P(NDP > baseline)."
            ),
            tasks=lambda: RELEASE_TASKS,
            arms=_release_arms,
            steps=300_000,
            conditions=RELEASE_CONDITIONS,
        ),
        Study(
            name="ndp-head-ablation",
            title="NDP head ablation: each fix of the first release's head off alone",
            doc=(
                "push-v3 and the toy point-mass x the default NDP head, PPO, PPO-multi and the "
                "NDP head with one fix off at a time from the commanded frame at rest (mean "
                "clip, goal-proportional forcing, goal bound, gripper DMP, start velocity, "
                "parameter noise) and with every fix off (ndp-v0); ndp-measured only with "
                "--arms. The tables of docs/results/ndp_ablation_*/ were made with "
                "benchmarks/ndp_ablation.py, which runs these arms."
            ),
            tasks=lambda: ("push-v3", "point-mass"),
            arms=_head_ablation_arms,
            steps=300_000,
        ),
        Study(
            name="ppo-vs-sb3",
            title="Our PPO vs Stable-Baselines3's PPO on five Meta-World tasks",
            doc=(
                "reach-v3, push-v3, window-close-v3, drawer-open-v3, button-press-v3 x this "
                "package's PPO (k = 1) and SB3's PPO with the same hyperparameters "
                "(ndp.sb3.runs). docs/results/ppo_vs_sb3/ppo_vs_sb3.md was made with "
                "benchmarks/ppo_vs_sb3.py, which runs these arms."
            ),
            tasks=lambda: PPO_VS_SB3_TASKS,
            arms=_ppo_vs_sb3_arms,
            steps=150_000,
        ),
        Study(
            name="sac-vs-sb3",
            title="Our SAC vs Stable-Baselines3's SAC on push-v3",
            doc=(
                "push-v3 x this package's SAC (ndp.rl.sac) and SB3's SAC with the same settings "
                "(buffer 1M, batch 256, lr 3e-4, tau 0.005, 5,000 random env steps, automatic "
                "temperature, 256-256 ReLU, one gradient step per env step; "
                "ndp.sb3.runs), 3 seeds: the check that ours is level with the "
                "reference within noise (training-episode success; deterministic at the end)."
            ),
            tasks=lambda: ("push-v3",),
            arms=_sac_vs_sb3_arms,
            steps=100_000,
        ),
        Study(
            name="td3-vs-sb3",
            title="Our TD3 vs Stable-Baselines3's TD3 on push-v3",
            doc=(
                "push-v3 x this package's TD3 (ndp.rl.td3) and SB3's TD3 with the same settings "
                "(buffer 1M, batch 256, lr 1e-3, tau 0.005, policy delay 2, target noise 0.2 "
                "clipped at 0.5, exploration noise 0.1, 5,000 random env steps, 400-300 ReLU, "
                "one gradient step per env step; ndp.sb3.runs), 3 seeds, 100k env steps (the "
                "second budget: --steps 300000): the check that ours is level with the "
                "reference within noise (training-episode success; deterministic at the end)."
            ),
            tasks=lambda: ("push-v3",),
            arms=_td3_vs_sb3_arms,
            steps=100_000,
        ),
        Study(
            name="off-policy",
            title="Off-policy learners: SAC, chunked SAC and NDP-SAC",
            doc=(
                "push-v3 and Throw x SAC, chunked SAC (k = 5) and NDP-SAC (k = 5), 300k env "
                "steps, 3 seeds, deterministic evaluation every 15,000 env steps; read beside "
                "ndp-regimes' fair on-policy arms (ndp-k5, ppo-multi-k5, ppo) on the same "
                "tasks, budget, seeds and evaluation (ndp report RUNS/off_policy "
                "RUNS/ndp_regimes). docs/offpolicy.md."
            ),
            tasks=lambda: OFF_POLICY_TASKS,
            arms=_off_policy_arms,
            steps=300_000,
            conditions=OFF_POLICY_CONDITIONS,
            readings=_off_policy_readings,
        ),
        Study(
            name="sac-critic",
            title="NDP-SAC's critic runaway on push-v3: plain against LayerNorm critics",
            doc=(
                "push-v3 x NDP-SAC (k = 5, critic of the DMP parameters) with SAC's plain "
                "critics and with LayerNorm after each hidden layer of both critics "
                "(--sac-critic-layer-norm), 40k env steps (both plain seeds of off-policy ran "
                "away by 20k), 3 seeds. A post-hoc diagnostic of off-policy's critic runaway "
                "(added 2026-12-05; its reading written before its runs): the critic-health "
                "table and whether LayerNorm stops the runaway. docs/offpolicy.md."
            ),
            tasks=lambda: ("push-v3",),
            arms=_sac_critic_arms,
            steps=40_000,
            readings=_sac_critic_readings,
        ),
        Study(
            name="sb3-ndp",
            title="Stable-Baselines3 PPO: NDPPolicy vs MlpPolicy",
            doc=(
                "The toy point-mass x SB3's PPO with ndp.sb3.NDPPolicy and with SB3's "
                "MlpPolicy, on the same chunked env (k = 5), hyperparameters, seeds and budget "
                "(ndp.sb3.runs); each run ends with 20 deterministic episodes "
                "(report with --eval-episodes 20). It shows the NDP layer training inside "
                "another library's PPO; other tasks with --tasks."
            ),
            tasks=lambda: ("point-mass",),
            arms=_sb3_ndp_arms,
            steps=100_000,
        ),
        Study(
            name="release-goals-1m",
            title="The release's goal condition at 1M env steps: NDP vs PPO-multi vs PPO",
            doc=(
                "push-v3 and throw x NDP, PPO-multi, PPO at 1M env steps (3.3x the screen), "
                "under two conditions: fair (v2 rewards, random goals for every method) and "
                "release-goals, the release's goal rule per task (one fixed goal per run for "
                "NDP and PPO-multi, random goals for PPO on push-v3: UNEQUAL, reproduced on "
                "purpose and labelled so; fixed for every method on Throw, arm ppo-fixed; v2 "
                "rewards, since Throw has no v1 reward). It asks "
                "whether the 300k screen's reading (only unequal goals put NDP ahead of PPO) "
                "holds with a larger budget. Report with --conditions."
            ),
            tasks=lambda: RELEASE_1M_TASKS,
            arms=_release_1m_arms,
            steps=1_000_000,
            conditions=RELEASE_1M_CONDITIONS,
        ),
        Study(
            name="release-explained",
            title="The 2021 release explained: its goals per task, its execution, its "
            "observation, and all its conditions at once",
            doc=(
                "push-v3, soccer-v3, faucet-open-v3 and throw x NDP, PPO-multi, PPO (and "
                "PPO-repeat: PPO with its action held k = 5 env steps) under the release's "
                "conditions as the release ran them: release-all (v1 rewards, the release's "
                "goals per task with PPO on random goals on push / soccer, only the first "
                "sub-action executed and held k steps, the 9-D observation, entropy 0.01, the "
                "clipped value loss, 500 env steps per update; Meta-World tasks; UNEQUAL); the "
                "first-held execution against all-executed and PPO-repeat on push (v1, the "
                "release's one goal) and Throw (its one basket place); the 9-D observation "
                "alone on push and soccer; fair reference arms. Each arm runs only on its "
                "tasks. 300k env steps, 3 seeds; report with --study release-explained."
            ),
            tasks=lambda: EXPLAINED_TASKS,
            arms=_explained_arms,
            steps=300_000,
            conditions=EXPLAINED_CONDITIONS,
        ),
        Study(
            name="ndp-regimes",
            title="Where NDP's structure can win: deterministic evaluation, exploration, chunk "
            "size",
            doc=(
                "push-v3 and throw x NDP and PPO-multi at k = 5 / 10 / 20 with white noise, NDP "
                "with calibrated parameter noise at each k, NDP / PPO-multi / PPO with AR(1) "
                "(Ornstein-Uhlenbeck) noise at k = 5, NDP / PPO-multi with the live reward "
                "(--no-stale-world), PPO at k = 1; 2,048 env steps per update at every k, the "
                "mini-batch count scaled to keep ~13 decisions per mini-batch. Every run "
                "evaluates its deterministic policy 10 episodes every 15,000 env steps; the "
                "report's headline is that curve (docs/rl-regimes.md: the pre-registered "
                "readings). The AR(1) arms at the best k and parameter noise calibrated on a "
                "decision's displacement run only when named (--arms)."
            ),
            tasks=lambda: REGIME_TASKS,
            arms=_regime_arms,
            steps=300_000,
            conditions=_regime_conditions(REGIME_KS, extra=True),
            readings=_regimes_readings,
        ),
        Study(
            name="ndp-mechanism",
            title="Why NDP loses: the action map's conditioning, the chunk basis, and rewards "
            "that favour trajectories",
            doc=(
                "docs/rl-mechanism.md (readings committed before the runs). Conditioning: NDP "
                "with --param-map linear / whitened on push-v3 and Throw (k = 5, live reward), "
                "read beside ndp-regimes' ndp-nostale, ppo-multi-nostale and ppo (ndp report "
                "RUNS/ndp_mechanism RUNS/fair10). Basis: PPO-multi free and restricted to the "
                "dmp / dct / bspline (/ pca) chunk basis, and NDP, at k = 10 and 20 on push-v3. "
                "Rewards pilot: NDP, PPO-multi, PPO under --reward sparse / smooth on reach-v3 "
                "and push-v3. 300k env steps, seeds 0-2 (the conditioning arms 0-9)."
            ),
            tasks=lambda: MECHANISM_TASKS,
            arms=_mechanism_arms,
            steps=300_000,
            conditions=_mechanism_conditions(),
        ),
        Study(
            name="ndp-regimes-1m",
            title="Chunk size at 1M env steps: NDP and PPO-multi at k = 5 / 10 / 20, PPO",
            doc=(
                "push-v3 x ndp-regimes' chunk-size arms (NDP and PPO-multi at k = 5 / 10 / 20, "
                "white noise, 2,048 env steps per update) and PPO at k = 1, at 1M env steps "
                "(3.3x ndp-regimes): does a larger k pay off with a larger budget? "
                "Deterministic evaluation every 15,000 env steps; the reading is "
                "pre-registered in docs/rl-regimes.md."
            ),
            tasks=lambda: ("push-v3",),
            arms=_regime_1m_arms,
            steps=1_000_000,
            conditions=_regime_conditions(REGIME_KS, extra=False),
            readings=_regimes_1m_readings,
        ),
        Study(
            name="ndp-settings",
            title="NDP's own settings on reach-v3 (a tuning task never reported)",
            doc=(
                "reach-v3 x NDP with one setting changed at a time from the defaults: learning "
                "rate 1e-4 / 1e-3, basis count 3 / 10, a_z 5 / 25, initial log std -1 / -0.5; "
                "150k env steps, 3 seeds, deterministic evaluation. The pre-registered rule "
                "(docs/rl-regimes.md) picks one value per axis; the combination is the "
                "ndp-tuned arm used on push-v3 and Throw."
            ),
            tasks=lambda: ("reach-v3",),
            arms=_settings_arms,
            steps=150_000,
        ),
        Study(
            name="il-robot",
            title="Behaviour cloning on the robot tasks: NDP vs NN",
            doc=(
                "The five robot tasks x NDP and the plain network (the PPO-multi actor) cloned "
                "from the first 25 / 100 / 400 successful episodes of one scripted-expert "
                "recording per task (reset seeds from 0), 100 epochs, 3 seeds; each cloned "
                "policy evaluated closed loop over 50 episodes with seeds disjoint from the "
                "demonstrations'. The report gives success, the cloning's validation loss and "
                "the smoothness (jerk, SPARC) of the executed arm path. nn-step-nN (the PPO "
                "actor) and ndp-vstate-nN (NDP starting from the commanded velocity) run only "
                "when named with --arms."
            ),
            tasks=lambda: BC_TASKS,
            arms=_bc_arms,
            steps=100,
            kind="bc",
        ),
        Study(
            name="digits-data",
            title="Digit writing: NDP vs CNN vs CNN-DMP, by training-set size",
            doc=(
                "ndp il train runs (budget in epochs, the paper's 71): Pendigits with the "
                "writer-disjoint split, and the synthetic set (paper split) at 300, 1000, 3000 "
                "and all (10,000) training digits; 3 seeds. The synthetic test set is 2,000 "
                "digits drawn with the training digits from the first n_train + 2,000 samples "
                "(the paper split), so it differs between sizes (same distribution). The "
                "report gives the test MSE (px^2) per data set and model."
            ),
            tasks=lambda: DIGITS_TASKS,
            arms=_digits_arms,
            steps=71,
            kind="il",
        ),
        Study(
            name="mt50-attribution",
            title="MT50 at 100k: NDP vs PPO-multi vs PPO where seed 0 told them apart",
            doc=(
                "The 7 Meta-World tasks where NDP's and PPO's final success differed by more "
                "than 0.1 at seed 0 of mt50 (docs/results/mt50_100k/mt50_100k.csv) x NDP, "
                "PPO-multi, PPO, "
                "100k env steps, seeds 0-2, deterministic evaluation: whether the MT50 "
                "direction (NDP slightly ahead of PPO) holds with spread and against PPO-multi. "
                "Report with the per-task intervals and the over-tasks IQM (--study "
                "mt50-attribution)."
            ),
            tasks=lambda: MT50_ATTRIBUTION_TASKS,
            arms=_mt50_attribution_arms,
            steps=100_000,
            conditions=(
                Condition(
                    "fair",
                    "v2 rewards, random goals, 100k env steps",
                    (("ndp", "ndp"), ("ppo-multi", "ppo-multi"), ("ppo", "ppo")),
                ),
            ),
            readings=_mt50_attribution_readings,
        ),
        Study(
            name="digits-head",
            title="Digit writing: the head as an axis every model shares (linear vs the "
            "release's 100-200-128-64 MLP)",
            doc=(
                "synthetic-300, synthetic-1000 and Pendigits' writers x NDP, CNN, CNN-DMP x "
                "{linear head, the 2021 release's head (--network paper)} x Adam lr 1e-3 / "
                "3e-3 / 1e-2, the converged protocol of digits-converged (validation split, "
                "patience 20, at most 500 epochs, best-validation weights, test scored once); "
                "3 seeds. The report selects per data set each model's head and lr on "
                "validation alone (rows 'ndp', 'cnn', 'cnn-dmp'), and each model's lr within "
                "one head (rows 'ndp (lin head)', ... 'cnn-dmp (paper head)'): the comparison "
                "at equal capacity."
            ),
            tasks=lambda: ("synthetic-300", "synthetic-1000", "pendigits"),
            arms=_head_arms,
            steps=500,
            kind="il",
            selection=_head_selection(),
        ),
        Study(
            name="digits-converged",
            title="Digit writing at convergence: NDP vs CNN vs CNN-DMP, selected on validation",
            doc=(
                "The digits-data sets (300 / 1,000 / 3,000 / 10,000 synthetic training digits "
                "and Pendigits' writers) x NDP, CNN, CNN-DMP x Adam lr 3e-4 / 1e-3 / 3e-3, each "
                "run stopped on a validation split (10% of its training split, the same for "
                "every model; patience 20 epochs, at most 500) and its best-validation weights "
                "kept; 3 seeds. The report picks each model's learning rate per data set on the "
                "validation MSE alone and gives that arm's test MSE (scored once, at the end) "
                "with its 95% bootstrap interval, epochs to best and wall time, and the DMP's "
                "floor (least-squares DMP fits to every test trajectory, N 10 / 20 / 30)."
            ),
            tasks=lambda: (
                "synthetic-300",
                "synthetic-1000",
                "synthetic-3000",
                "synthetic",
                "pendigits",
            ),
            arms=_converged_arms,
            steps=500,
            kind="il",
            selection=tuple(
                (m, tuple(f"{m}-lr{lr}" for lr in CONVERGED_LRS)) for m, _ in CONVERGED_MODELS
            ),
        ),
    )
}
"""Name -> :class:`Study`."""


def get_study(name: str) -> Study:
    """The named study (unknown: ValueError naming it and the close names)."""
    if name in STUDIES:
        return STUDIES[name]
    close = difflib.get_close_matches(name, list(STUDIES), n=3, cutoff=0.4)
    hint = f"; close names: {', '.join(close)}" if close else ""
    raise ValueError(f"study: unknown study {name!r}{hint} (known: {', '.join(STUDIES)})")
