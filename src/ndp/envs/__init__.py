"""Tasks of the paper behind one interface.

- :data:`TASKS` / :func:`get_task_spec`: per-task spec table (DMP coordinates, units, action
  bounds and scale, inverse controller, horizon, clocks).
- :func:`make_env`: plain per-step env for the 50 Meta-World v3 tasks and Jaco Throw / Pick,
  and their torque-actuated variants (:data:`TORQUE_TASKS`, the VICES baseline).
- :class:`ChunkedEnv`: k sub-steps per decision with the stale-world reward rule.
- :func:`write_mp4`: save rendered frames.

All tasks are registered with gymnasium as ``ndp/<name>`` (``ndp/push-v3``,
``ndp/JacoThrow-v0``, ``ndp/JacoPick-v0``) when this package is imported.
"""

from ndp.envs.chunked import ChunkedEnv
from ndp.envs.factory import (
    fixed_goal_seed,
    make_env,
    register_builtin_families,
    register_envs,
    register_task,
    register_torque_envs,
    task_options,
)
from ndp.envs.jaco import JacoEnv
from ndp.envs.metaworld_env import MetaWorldEnv
from ndp.envs.render import write_mp4
from ndp.envs.spec import (
    TASKS,
    TORQUE_TASKS,
    TaskSpec,
    finer_spec,
    get_task_spec,
    substep_factors,
    torque_variant,
)

# the built-in tasks are registered (tables and gymnasium ids) by ndp.envs.factory's import:
# register_builtin_families, through the register_task a user calls

__all__ = [
    "TASKS",
    "TORQUE_TASKS",
    "ChunkedEnv",
    "JacoEnv",
    "MetaWorldEnv",
    "TaskSpec",
    "finer_spec",
    "fixed_goal_seed",
    "get_task_spec",
    "make_env",
    "register_builtin_families",
    "register_envs",
    "register_task",
    "register_torque_envs",
    "substep_factors",
    "task_options",
    "torque_variant",
    "write_mp4",
]
