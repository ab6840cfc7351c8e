"""The checkpoint of the off-policy learners (SAC family, TD3, Dyn-E), in one place.

Layout (the run session adds ``rng``, ``config``, ``kind`` and ``schema_version``)::

    model, obs_norm, obs_dim, update, global_step       the policy keys of every RL run
    <section>:                                           'sac', 'td3' or 'dyne'
        <part>: state dict                               the learner's networks and optimisers
        replay, rng, grad_steps, update_debt             the collection loop's state
        <extra>                                          the learner's own values

A learner names its section, its parts and its extras; :class:`OffPolicyState` writes the
checkpoint, validates it on load (:func:`ndp.runs.checkpoint.check_state`: one line naming the
file, the key and what was expected) and restores it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import nn

from ndp.rl.normalize import ObsNormalizer
from ndp.rl.replay import RingReplay
from ndp.runs.checkpoint import (
    INT,
    REAL,
    Holds,
    OptimizerState,
    Spec,
    StateDict,
    check_state,
    policy_schema,
)

if TYPE_CHECKING:
    from ndp.policies import ActorCritic
    from ndp.runs.layout import RunDir

Part = nn.Module | torch.optim.Optimizer
"""What a learner saves as a state dict under its section: a network or an optimiser."""


class OffPolicyState:
    """The checkpoint of an off-policy learner (see the module docstring).

    A subclass sets :attr:`section` and implements :meth:`parts`; it may add its own values
    (:meth:`extra_state`, :meth:`extra_schema`, :meth:`load_extra_state`).
    """

    section: str
    """The checkpoint key of the learner's own state ('sac', 'td3', 'dyne')."""
    model: ActorCritic
    obs_norm: ObsNormalizer
    obs_dim: int
    update: int
    global_step: int
    replay: RingReplay
    rng: np.random.Generator
    grad_steps: int
    update_debt: float
    run: RunDir

    def parts(self) -> dict[str, Part]:
        """The networks and optimisers saved under :attr:`section`, by key."""
        raise NotImplementedError

    def extra_state(self) -> dict[str, object]:
        """The learner's own values under :attr:`section` (none by default)."""
        return {}

    def extra_schema(self) -> dict[str, Spec]:
        """What :meth:`extra_state`'s values must be on load."""
        return {}

    def load_extra_state(self, s: dict[str, Any]) -> None:
        """Restore :meth:`extra_state`'s values from the section ``s`` (validated)."""

    # ----------------------------------------------------------------------- the loop's state
    def loop_state(self) -> dict[str, Any]:
        """The loop's part of the checkpoint: replay, generator, gradient steps, update debt."""
        return {
            "replay": self.replay.state_dict(),
            "rng": self.rng.bit_generator.state,
            "grad_steps": self.grad_steps,
            "update_debt": self.update_debt,
        }

    def load_loop_state(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`loop_state`'s output."""
        self.replay.load_state_dict(state["replay"])
        self.rng.bit_generator.state = state["rng"]
        self.grad_steps, self.update_debt = int(state["grad_steps"]), float(state["update_debt"])

    # ----------------------------------------------------------------------- the checkpoint
    def checkpoint_schema(self) -> dict[str, Spec]:
        """What a checkpoint of this learner must hold, shaped like its networks now."""
        own: dict[str, Spec] = {
            name: StateDict(p.state_dict()) if isinstance(p, nn.Module) else OptimizerState(p)
            for name, p in self.parts().items()
        }
        loop: dict[str, Spec] = {
            "replay": Holds(self.replay.problem, "a replay buffer"),
            "rng": dict,
            "grad_steps": INT,
            "update_debt": REAL,
        }
        return {
            **policy_schema(self.model.state_dict(), self.obs_dim),
            self.section: {**own, **loop, **self.extra_schema()},
        }

    def state_dict(self) -> dict[str, Any]:
        """The policy checkpoint keys (``ndp.rl.methods.POLICY_CHECKPOINT_KEYS``) plus
        :attr:`section`: the parts' state dicts, the loop's state and the learner's own."""
        own = {name: part.state_dict() for name, part in self.parts().items()}
        return {
            "model": self.model.state_dict(),
            "obs_norm": self.obs_norm.state_dict(),
            "obs_dim": self.obs_dim,
            "update": self.update,
            "global_step": self.global_step,
            self.section: {**own, **self.loop_state(), **self.extra_state()},
        }

    def load_state_dict(self, ckpt: dict[str, Any]) -> None:
        """Continue from :meth:`state_dict`'s output (the session restores the global RNGs).

        Raises:
            ValueError: the checkpoint does not match :meth:`checkpoint_schema` (one line
                naming the file and the key).
        """
        check_state(ckpt, self.checkpoint_schema(), self.run.checkpoint)
        self.model.load_state_dict(ckpt["model"])
        self.obs_norm.load_state_dict(ckpt["obs_norm"])
        self.update, self.global_step = int(ckpt["update"]), int(ckpt["global_step"])
        s = ckpt[self.section]
        for name, part in self.parts().items():
            part.load_state_dict(s[name])
        self.load_loop_state(s)
        self.load_extra_state(s)
