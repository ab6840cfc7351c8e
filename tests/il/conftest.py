"""Shared fixtures of the imitation-learning tests."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

PENDIGITS = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "pendigits"
PENDIGITS_TRAIN = PENDIGITS / "pendigits-train"


@pytest.fixture(autouse=True)
def _few_threads() -> None:
    torch.set_num_threads(1)


@pytest.fixture(scope="session")
def pendigits_path() -> Path:
    if not PENDIGITS_TRAIN.exists():
        pytest.skip(f"Pendigits not found at {PENDIGITS_TRAIN}")
    return PENDIGITS_TRAIN


@pytest.fixture(scope="session")
def pendigits(pendigits_path: Path):
    from ndp.il.data import load_pendigits

    return load_pendigits(pendigits_path)
