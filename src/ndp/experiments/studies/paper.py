"""The paper's studies: its five tasks, MT50, the Throw ablations, the NDP head ablation and
MT50's attribution re-run."""

from __future__ import annotations

from ndp.experiments.studies.base import ArmSpec, Condition, Study

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


STUDIES: tuple[Study, ...] = (
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
        readings="ndp.experiments.report.regimes:mt50_attribution_readings",
    ),
)
"""This module's studies, in ``ndp sweep --list`` order."""
