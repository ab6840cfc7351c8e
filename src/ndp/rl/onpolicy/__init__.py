"""On-policy learning, one package: PPO with GAE over sub-steps for every method whose head the
shared actor-critic runs (PPO, PPO-multi, PPO-repeat, NDP, VICES and its ablations).

- :mod:`ndp.rl.onpolicy.trainer`: :class:`ndp.rl.onpolicy.trainer.Trainer`, the learner (an
  :class:`ndp.rl.run.RLLearner`: collect T decisions per env, then the PPO epochs);
- :mod:`ndp.rl.onpolicy.losses`: the clipped policy loss (per sub-step or per decision), the
  value loss, advantage normalisation, entropy;
- :mod:`ndp.rl.onpolicy.gae`: GAE over the sub-step sequence, truncation bootstrapping.

A method differs from another only in its action head (``ndp.policies.heads``) and its
registration (``ndp.rl.methods``).
"""
