"""Run checkpoints: atomic ``torch.save`` (via :mod:`ndp.io`) and a loader with clear errors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch

from ndp.io import atomic_torch_save

__all__ = ["CHECKPOINT_NAME", "load_checkpoint", "save_checkpoint"]

CHECKPOINT_NAME = "checkpoint.pt"
"""File name of the latest good checkpoint inside a run directory."""


def save_checkpoint(path: Path, state: dict[str, Any]) -> None:
    """``torch.save(state)`` to ``path`` atomically (a crash leaves the previous file intact)."""
    atomic_torch_save(state, path)


def load_checkpoint(path: Path) -> dict[str, Any]:
    """Load a checkpoint written by :func:`save_checkpoint`.

    Raises:
        FileNotFoundError: no checkpoint at ``path``.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint: no such file {path}")
    return torch.load(path, map_location="cpu", weights_only=False)
