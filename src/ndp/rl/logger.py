"""The RL trainer's metric names: the columns of ``metrics.csv`` (one row per PPO update).

They are documented in docs/metrics.md; :class:`ndp.runs.MetricsLogger` writes them to the CSV
and TensorBoard (x axis ``global_step``).
"""

from __future__ import annotations

METRICS: tuple[str, ...] = (
    "update",
    "global_step",
    "charts/episodes",
    "charts/success_any",
    "charts/success_final",
    "charts/episode_return",
    "charts/episode_return_live",
    "charts/episode_length",
    "charts/env_steps_per_s",
    "charts/learning_rate",
    "losses/policy",
    "losses/value",
    "losses/entropy",
    "losses/approx_kl",
    "losses/clipfrac",
    "losses/grad_norm",
    "losses/explained_variance",
    "policy/std",
    "dmp/goal_norm",
    "dmp/weight_norm",
    "ctrl/gains_clipped",
    "ctrl/torque_saturated",
    "ctrl/nonfinite",
    "time/rollout_s",
    "time/update_s",
    # the periodic deterministic evaluation (ndp.rl.periodic_eval.EVAL_METRICS)
    "eval/success_any",
    "eval/success_final",
    "eval/return",
    "eval/episodes",
    "time/eval_s",
)
"""CSV columns, in order. Values that do not apply (e.g. dmp/* for PPO) are left empty."""

TIME_METRICS = ("charts/env_steps_per_s", "time/rollout_s", "time/update_s", "time/eval_s")
"""Columns that depend on wall-clock time (excluded from determinism checks)."""
