"""Meta-World tasks on which the EnvPool backend differs from metaworld (generated).

Written by ``python -m ndp.envs.envpool_equivalence --write`` from its 50-task check
(docs/results/envpool_equivalence/); ``ndp.envs.envpool_backend.check_backend`` refuses these
tasks under ``--backend envpool``. tests/envs/test_envpool_backend.py checks that this list is
the committed table's.
"""

ENVPOOL_DIFFERING: frozenset[str] = frozenset(
    {
        "box-close-v3",
        "button-press-topdown-wall-v3",
        "disassemble-v3",
        "door-close-v3",
        "door-lock-v3",
        "door-unlock-v3",
        "drawer-close-v3",
        "hand-insert-v3",
        "handle-press-v3",
        "handle-pull-v3",
        "lever-pull-v3",
        "peg-insert-side-v3",
        "peg-unplug-side-v3",
        "pick-place-v3",
        "pick-place-wall-v3",
        "push-back-v3",
        "push-v3",
        "push-wall-v3",
        "reach-v3",
        "reach-wall-v3",
        "soccer-v3",
        "sweep-into-v3",
        "sweep-v3",
        "window-close-v3",
    }
)
"""Tasks whose observations, rewards or success differ beyond the stated tolerances."""
