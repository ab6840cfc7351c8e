"""The SAC family, one package: SAC (k = 1), chunked SAC (k actions per decision, a critic of
the whole chunk trained on the k-step return: the Q-chunking recipe) and NDP-SAC (the actor
emits the DMP's goal and forcing weights; the NDP head turns them into the k-step actions).

- :mod:`ndp.rl.sac.config`: :class:`ndp.rl.sac.config.SACConfig`, every setting typed and
  documented;
- :mod:`ndp.rl.sac.losses`: the pure functions (chunk return, target, the three losses), with
  stated tensor shapes;
- :mod:`ndp.rl.sac.replay`: the decision replay buffer (saved with the checkpoint);
- :mod:`ndp.rl.sac.learner`: :class:`ndp.rl.sac.learner.SACLearner`, an
  :class:`ndp.rl.run.RLLearner` that the run driver opens, seeds, drives and checkpoints.

The methods are registered in :mod:`ndp.rl.methods` (``sac``, ``sac-chunk``, ``ndp-sac``) with
the heads of :mod:`ndp.policies.squashed`; docs/offpolicy.md has the maths and the defaults.
"""
