"""The replay buffer of the off-policy learners (SAC family, Dyn-E's TD3): a ring of decisions.

Every column lives in one contiguous float32 matrix [capacity, total width], so a batch is one
gather of rows (``matrix[idx]``) instead of one per column; the columns are views of it. The
whole filled part is saved with the checkpoint, so a resumed run continues with the same data
and its first batches are the ones the uninterrupted run would draw.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch

from ndp.checks import check_int


class RingReplay:
    """A ring buffer of decisions with named float32 columns.

    Args:
        capacity: decisions kept (the oldest are overwritten).
        shapes: column name -> shape of one row's entry (``()`` for a scalar, ``(w,)`` for a
            vector of width w); the order is the order of the columns.
    """

    def __init__(self, capacity: int, shapes: Mapping[str, tuple[int, ...]]) -> None:
        check_int("capacity", capacity, 1)
        self.capacity = capacity
        self.shapes = {name: tuple(int(d) for d in s) for name, s in shapes.items()}
        self._slices: dict[str, slice] = {}
        off = 0
        for name, shape in self.shapes.items():
            width = math.prod(shape)
            self._slices[name] = slice(off, off + width)
            off += width
        self.matrix = np.zeros((self.capacity, off), dtype=np.float32)
        self.data = {name: self._view(self.matrix, name) for name in self.shapes}
        """Column name -> view [capacity, *shape] of the matrix."""
        self.ptr = 0
        self.size = 0

    def _view(self, rows: np.ndarray, name: str) -> np.ndarray:
        return rows[:, self._slices[name]].reshape(len(rows), *self.shapes[name])

    def add(self, **batch: np.ndarray) -> None:
        """Append n decisions: each column [n, *shape] (any float dtype; a vector column may
        also come as [n] when its width is 1)."""
        n = len(batch[next(iter(self.shapes))])
        idx = (self.ptr + np.arange(n)) % self.capacity
        for name in self.shapes:
            width = self._slices[name].stop - self._slices[name].start
            self.matrix[idx, self._slices[name]] = np.asarray(batch[name]).reshape(n, width)
        self.ptr = int((self.ptr + n) % self.capacity)
        self.size = int(min(self.size + n, self.capacity))

    def sample(self, n: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        """``n`` decisions drawn uniformly with replacement: column -> tensor [n, *shape]."""
        rows = self.matrix[rng.integers(0, self.size, size=n)]
        return {name: torch.from_numpy(self._view(rows, name)) for name in self.shapes}

    def state_dict(self) -> dict[str, Any]:
        """The filled rows of each column (in ring order as stored), the write position, the
        size and the capacity."""
        return {
            "data": {name: col[: self.size].copy() for name, col in self.data.items()},
            "ptr": self.ptr,
            "size": self.size,
            "capacity": self.capacity,
        }

    def problem(self, d: object) -> str | None:
        """What is wrong with a saved buffer (:meth:`state_dict`'s output) for this one, in
        words; None when it loads. Every column present with [size, width] rows of finite
        floats, the size within the capacity (the same capacity where saved) and the write
        position consistent with the size."""
        if not isinstance(d, dict) or not isinstance(d.get("data"), dict):
            return "expected a replay buffer (a dict with data, ptr, size)"
        size, ptr, cap = d.get("size"), d.get("ptr"), d.get("capacity")
        for key, value in (("size", size), ("ptr", ptr)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                return f"{key}: expected an integer, got {value!r}"
        assert isinstance(size, int | np.integer) and isinstance(ptr, int | np.integer)
        if cap is not None and int(cap) != self.capacity:
            return f"the buffer holds {cap} decisions, expected {self.capacity}"
        if not 0 <= size <= self.capacity:
            return f"holds {size} decisions, expected 0 to the capacity {self.capacity}"
        # unwrapped: ptr == size (0 once full); wrapped (size == the saved capacity): any row
        unwrapped = cap is not None and size < int(cap)
        if not 0 <= ptr < self.capacity or ptr > size or (unwrapped and ptr != size):
            return f"write position {ptr} does not fit size {size} (capacity {self.capacity})"
        for name, shape in self.shapes.items():
            if name not in d["data"]:
                return f"column {name} is missing (expected columns {', '.join(self.shapes)})"
            col = np.asarray(d["data"][name])
            width = math.prod(shape)
            if col.ndim < 1 or len(col) != size:
                return f"column {name} has shape {col.shape}, expected {size} rows (the size)"
            if math.prod(col.shape[1:]) != width:
                return f"column {name} has shape {col.shape[1:]} in the checkpoint, {shape} now"
            if col.dtype.kind != "f":
                return f"column {name} has dtype {col.dtype}, expected a float dtype"
            if not np.isfinite(col).all():
                return f"column {name} holds NaN/Inf (expected finite values)"
        return None

    def load_state_dict(self, d: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`'s output (same capacity and column shapes; a checkpoint
        without a capacity must fit in this one), validated first (:meth:`problem`).

        Raises:
            ValueError: the saved buffer does not fit or holds non-finite values, naming the
                mismatch.
        """
        what = self.problem(d)
        if what is not None:
            raise ValueError(f"replay: {what}")
        size = int(d["size"])
        for name, shape in self.shapes.items():
            col = np.asarray(d["data"][name], dtype=np.float32)
            self.matrix[:size, self._slices[name]] = col.reshape(size, math.prod(shape))
        self.ptr = int(d["ptr"])
        self.size = size
