"""Meta-World tasks on which the EnvPool backend differs from metaworld (generated).

Written by ``python -m ndp.envs.envpool_equivalence --write`` from its 50-task check
(docs/results/envpool_equivalence/); ``ndp.envs.envpool_backend.check_backend`` refuses these
tasks under ``--backend envpool``. tests/envs/test_envpool_backend.py checks that this list is
the committed table's.
"""

ENVPOOL_DIFFERING: frozenset[str] = frozenset()
"""Tasks whose observations, rewards or success differ beyond the stated tolerances."""
