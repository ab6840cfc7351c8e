"""What the off-policy learners (the SAC family, TD3) share: the collection loop
(:mod:`ndp.rl.offpolicy.loop`), the k-step return (:mod:`ndp.rl.offpolicy.returns`), the
decision replay (:mod:`ndp.rl.offpolicy.replay`) and the twin critics
(:mod:`ndp.rl.offpolicy.critics`)."""
