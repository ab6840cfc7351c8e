"""The 2021 release's task configurations and its per-task goal rule, in one place.

The release hard-coded ONE task configuration per task for every run and seed
(``../shared/docs/ndp-method.md`` section 7; docs/rl-release.md):

- push: object (0, 0.6, 0.02), goal (0.1, 0.8, 0.02);
- soccer: object (0, 0.6, 0.03), goal (0, 0.9, 0.03);
- faucet-open: faucet (0, 0.8, 0.05), goal (0.1, 0.8, 0.115);
- Throw's basket and Pick's cube at one place (here: the nominal place, jitter 0).

Meta-World v3 draws the same quantities as its "random reset vector", so the release's
configuration is that vector fixed (:data:`RELEASE_CONFIGS`). Where v3's geometry differs from
the release's vendored pre-v1 copy, the heights are v3's (soccer's goal sits at z = 0, the
faucet base at z = 0) and faucet-open's goal follows from v3's handle: (0.175, 0.8, 0.125).

Which methods got it (:func:`release_goals`): on push and soccer NDP and PPO-multi trained on
the fixed configuration while PPO drew random goals (its ``params`` dict was set before its
worker processes forked, NDP's and PPO-multi's after); on faucet-open, Throw and Pick every
method trained on the fixed one.
"""

from __future__ import annotations

import numpy as np

RELEASE_CONFIGS: dict[str, tuple[float, ...]] = {
    "push-v3": (0.0, 0.6, 0.02, 0.1, 0.8, 0.02),
    "soccer-v3": (0.0, 0.6, 0.03, 0.0, 0.9, 0.0),
    "faucet-open-v3": (0.0, 0.8, 0.0),
    "throw": (0.0, 0.0),
    "pick": (0.0, 0.0),
}
"""Task -> the release's configuration as the env's own random draw: Meta-World's reset vector
(push / soccer: object xyz, goal xyz; faucet-open: faucet base xyz) and the Jaco tasks' xy jitter
of the basket (Throw) or cube (Pick), 0: the nominal place."""
RELEASE_GOAL_TASKS = tuple(RELEASE_CONFIGS)
"""Tasks with a release configuration (``fixed_goal="release"``, ``--goals release``)."""
RELEASE_PPO_RANDOM = ("push-v3", "soccer-v3")
"""Tasks on which the release gave PPO random goals (and NDP / PPO-multi the fixed one)."""
FIXED_FOR_ALL_METHODS = ("ndp", "ppo-multi")
"""Methods that always got the release's fixed configuration."""


def release_config(task: str) -> np.ndarray | None:
    """The release's configuration of ``task`` (:data:`RELEASE_CONFIGS`), None where it had
    none."""
    cfg = RELEASE_CONFIGS.get(task)
    return None if cfg is None else np.array(cfg, dtype=np.float64)


def release_goals(task: str, method: str) -> str:
    """The ``--goals`` value under which ``method`` trained on ``task`` in the release: 'random'
    for PPO (and its variants) on push and soccer, 'release' otherwise.

    Raises:
        ValueError: a task the release did not run (no configuration to fix).
    """
    if task not in RELEASE_CONFIGS:
        raise ValueError(
            f"task: the release's goal rule covers {', '.join(RELEASE_GOAL_TASKS)}, got {task!r}"
        )
    if task in RELEASE_PPO_RANDOM and method not in FIXED_FOR_ALL_METHODS:
        return "random"
    return "release"
