"""Neural Dynamic Policies (Bahl, Mukadam, Gupta, Pathak, NeurIPS 2020).

A policy network predicts the goal ``g`` and forcing-term weights ``w`` of a Dynamic Movement
Primitive (DMP); a differentiable integrator (:mod:`ndp.dmp`) turns them into a trajectory, and
the robot follows it for ``k`` sub-steps per decision.

Packages, in the order the data flows:

- :mod:`ndp.dmp`          DMP maths: basis functions, integrators, layer, fit, sensitivities
- :mod:`ndp.nets`         MLP and CNN encoders
- :mod:`ndp.policies`     action heads (step, multi, ndp), k-head critic
- :mod:`ndp.envs`         task table, Meta-World and Jaco tasks, chunked stale-world wrapper
- :mod:`ndp.rl`           rollout buffer, GAE, PPO trainer
- :mod:`ndp.il`           digit-writing data, models, trainer, metrics
- :mod:`ndp.experiments`  presets, sweeps, result tables and plots
- :mod:`ndp.cli`          the ``ndp`` command
"""

__version__ = "0.1.0"
