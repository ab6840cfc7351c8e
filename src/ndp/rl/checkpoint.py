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
        ValueError: the file is empty, truncated or not a checkpoint (one line naming it).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint: no such file {path}")
    try:
        state = torch.load(path, map_location="cpu", weights_only=False)
    except (EOFError, RuntimeError, OSError, ValueError, ImportError, AttributeError) as exc:
        raise ValueError(
            f"checkpoint: cannot read {path} ({type(exc).__name__}: {str(exc)[:120]}); the file "
            "is empty, truncated or not a checkpoint of this package"
        ) from None
    except Exception as exc:  # unpickling garbage raises many kinds
        raise ValueError(
            f"checkpoint: cannot read {path} ({type(exc).__name__}); the file is not a "
            "checkpoint of this package"
        ) from None
    if not isinstance(state, dict):
        raise ValueError(f"checkpoint: {path} is not a checkpoint of this package (not a dict)")
    return state
