"""What the off-policy learners share: the collection loop (:mod:`ndp.rl.offpolicy.loop`)."""
