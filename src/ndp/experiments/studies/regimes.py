"""Where NDP's structure can win: evaluation, exploration, chunk size, and NDP's own settings
(docs/rl-regimes.md)."""

from __future__ import annotations

from collections.abc import Sequence

from ndp.experiments.studies.base import ArmSpec, Condition, Study

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


def _settings_arms() -> tuple[ArmSpec, ...]:
    arms = [ArmSpec("ndp", "ndp", (), "NDP defaults (lr 3e-4, N 6, a_z 15, log std 0)")]
    for opt, values in NDP_SETTINGS_AXES:
        for v in values:
            label = f"ndp-{opt}{v}".replace(".", "p")
            arms.append(ArmSpec(label, "ndp", (f"--{opt}", v), f"NDP, --{opt} {v}"))
    return tuple(arms)


STUDIES: tuple[Study, ...] = (
    Study(
        name="ndp-regimes",
        title="Where NDP's structure can win: deterministic evaluation, exploration, chunk size",
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
        readings="ndp.experiments.report.regimes:regimes_readings",
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
        readings="ndp.experiments.report.regimes:regimes_1m_readings",
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
)
"""This module's studies, in ``ndp sweep --list`` order."""
