"""Off-policy learners (SAC, chunked SAC, NDP-SAC) and NDP-SAC's critic (docs/offpolicy.md)."""

from __future__ import annotations

from ndp.experiments.studies.base import ArmSpec, Condition, Study

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


STUDIES: tuple[Study, ...] = (
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
        readings="ndp.experiments.report.offpolicy:off_policy_readings",
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
        readings="ndp.experiments.report.offpolicy:critic_study_readings",
    ),
)
"""This module's studies, in ``ndp sweep --list`` order."""
