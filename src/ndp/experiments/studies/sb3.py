"""Checks against Stable-Baselines3: its PPO and SAC beside ours, and NDPPolicy inside its PPO."""

from __future__ import annotations

from ndp.experiments.studies.base import ArmSpec, Study

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


STUDIES: tuple[Study, ...] = (
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
)
"""This module's studies, in ``ndp sweep --list`` order."""
