"""Behaviour cloning on the robot tasks: demonstrations from scripted experts, NDP vs a plain
network cloned from them, and runs that the RL tools load.

Data flow::

    expert (ndp.bc.experts) --ndp il collect--> demonstrations file (ndp.bc.demos, .npz)
    --ndp il bc--> run directory (ndp.bc.train): an RL config + policy checkpoint, so that
    ``ndp rl eval / render / export`` and ``ndp.load_policy`` work on it unchanged

The cloned policy is the RL actor of the chosen method (``ndp``: DMP head through the task's
inverse controller; ``nn``: the PPO-multi head, k raw actions; ``nn-step``: the PPO head, one),
trained on the demonstrated actions of the k steps that follow each state, and executed closed
loop at one decision per k env steps with the stale-world rule, as in RL.
"""
