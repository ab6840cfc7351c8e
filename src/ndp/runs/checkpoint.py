"""The one checkpoint format: an atomic ``torch.save`` of a dict naming its trainer's ``kind``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ndp.io import atomic_torch_save
from ndp.runs.layout import CHECKPOINT_NAME
from ndp.runs.signals import deferred_stops

__all__ = ["load_checkpoint", "save_checkpoint"]


def save_checkpoint(path: str | Path, state: dict[str, Any], kind: str) -> None:
    """``torch.save({**state, 'kind': kind})`` to ``path`` atomically.

    A crash (even SIGKILL) mid-write leaves the previous checkpoint intact; a SIGTERM or Ctrl-C
    under ``stop_on_sigterm`` is held until the write is complete (``deferred_stops``).

    Args:
        path: file to write (``<run_dir>/checkpoint.pt``).
        state: the trainer's state (tensors, numbers, plain containers).
        kind: the trainer, 'rl' or 'il'; :func:`load_checkpoint` checks it.
    """
    with deferred_stops():
        atomic_torch_save({**state, "kind": kind}, Path(path))


def _legacy_kind(state: dict[str, Any]) -> str | None:
    """The trainer of a checkpoint written before ``kind`` was stored."""
    cfg = state.get("config")
    if isinstance(cfg, dict) and "algo" in cfg:
        return "rl"
    if isinstance(cfg, dict) and "model" in state and "data" in cfg:
        return "il"
    if "actor_critic" in state or "policy" in state:
        return "rl"
    return None


def load_checkpoint(path: str | Path, kind: str | None = None) -> dict[str, Any]:
    """Load a checkpoint written by :func:`save_checkpoint` (a run directory or the file).

    Args:
        path: the checkpoint file, or a run directory holding ``checkpoint.pt``.
        kind: expected trainer ('rl', 'il'); None accepts any.

    Raises:
        FileNotFoundError: no checkpoint at ``path``.
        ValueError: the file is empty, truncated, not a checkpoint of this package, or of
            another trainer than ``kind`` (one line naming the file).
    """
    import torch

    path = Path(path)
    if path.is_dir():
        path = path / CHECKPOINT_NAME
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
    found = state.get("kind") or _legacy_kind(state)
    if kind is not None and found != kind:
        from ndp.runs.layout import RUN_KINDS

        names = {"rl": "an RL", "il": "an imitation"}
        what = names.get(str(found), "not a known")
        readers = RUN_KINDS.get(str(found), ("", ""))[1].replace("RUN", str(path.parent))
        hint = f"; read it with {readers}" if readers else ""
        raise ValueError(
            f"checkpoint: {path} is {what} checkpoint; expected {names.get(kind, kind)} one{hint}"
        )
    return state
