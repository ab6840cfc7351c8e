"""The decision replay buffer of the off-policy learners (SAC family, TD3): one row per
decision (k env steps), float32, a ring of fixed capacity (:class:`ndp.rl.replay.RingReplay`),
saved whole with the checkpoint (so a resumed run continues with the same data, and its first
batches are the ones the uninterrupted run would draw). TD3 stores its bounded action in both
``u`` and ``critic_in``."""

from __future__ import annotations

from ndp.rl.replay import RingReplay

FIELDS = ("obs", "y0", "dy0", "u", "critic_in", "ret", "discount", "next_obs", "next_y0",
          "next_dy0")  # fmt: skip
"""Columns: the state (observation O, robot state D, D), the raw parameters drawn (P), what the
critic scores with the state (C), the chunk's discounted return and bootstrap weight (width 1),
and the next state (O, D, D)."""


class DecisionReplay(RingReplay):
    """A ring buffer of decisions with the columns of :data:`FIELDS`.

    Args:
        capacity: decisions kept.
        dims: width of each column of :data:`FIELDS` (``ret`` and ``discount``: 1 if absent).
    """

    def __init__(self, capacity: int, dims: dict[str, int]) -> None:
        super().__init__(int(capacity), {name: (int(dims.get(name, 1)),) for name in FIELDS})
