"""The decision replay buffer of the SAC family: one row per decision (k env steps), float32,
a ring of fixed capacity, saved whole with the checkpoint (so a resumed run continues with the
same data, and its first batches are the ones the uninterrupted run would draw)."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

FIELDS = ("obs", "y0", "dy0", "u", "critic_in", "ret", "discount", "next_obs", "next_y0",
          "next_dy0")  # fmt: skip
"""Columns: the state (observation O, robot state D, D), the raw parameters drawn (P), what the
critic scores with the state (C), the chunk's discounted return and bootstrap weight (scalars),
and the next state (O, D, D)."""


class DecisionReplay:
    """A ring buffer of decisions.

    Args:
        capacity: decisions kept.
        dims: width of each column of :data:`FIELDS` (``ret`` and ``discount``: 1).
    """

    def __init__(self, capacity: int, dims: dict[str, int]) -> None:
        self.capacity = int(capacity)
        self.data = {
            name: np.zeros((self.capacity, int(dims.get(name, 1))), dtype=np.float32)
            for name in FIELDS
        }
        self.ptr = 0
        self.size = 0

    def add(self, **batch: np.ndarray) -> None:
        """Append E decisions: each column [E, width] (or [E] for the scalars)."""
        n = len(batch["obs"])
        idx = (self.ptr + np.arange(n)) % self.capacity
        for name in FIELDS:
            self.data[name][idx] = np.asarray(batch[name], dtype=np.float32).reshape(n, -1)
        self.ptr = int((self.ptr + n) % self.capacity)
        self.size = int(min(self.size + n, self.capacity))

    def sample(self, n: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        """``n`` decisions drawn uniformly with replacement: column -> tensor [n, width]."""
        idx = rng.integers(0, self.size, size=n)
        return {name: torch.from_numpy(col[idx]) for name, col in self.data.items()}

    def state_dict(self) -> dict[str, Any]:
        """The filled rows (in ring order as stored), the write position and the size."""
        return {
            "data": {name: col[: self.size].copy() for name, col in self.data.items()},
            "ptr": self.ptr,
            "size": self.size,
        }

    def load_state_dict(self, d: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`'s output (same capacity and widths).

        Raises:
            ValueError: the saved buffer does not fit (another capacity or column width)."""
        size = int(d["size"])
        if size > self.capacity:
            raise ValueError(
                f"replay: the checkpoint holds {size} decisions, capacity {self.capacity}"
            )
        for name in FIELDS:
            col = np.asarray(d["data"][name], dtype=np.float32)
            if col.shape[1:] != self.data[name].shape[1:]:
                raise ValueError(
                    f"replay: column {name} has width {col.shape[1:]} in the checkpoint, "
                    f"{self.data[name].shape[1:]} now"
                )
            self.data[name][:size] = col
        self.ptr, self.size = int(d["ptr"]), size
