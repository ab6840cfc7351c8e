"""Provenance of generated results: which commit produced them."""

from __future__ import annotations

import subprocess
from pathlib import Path


def git_commit(short: bool = True, cwd: str | Path | None = None) -> str:
    """The current git commit (short hash by default), or ``"unknown"`` outside a checkout."""
    cmd = ["git", "rev-parse", *(["--short"] if short else []), "HEAD"]
    try:
        out = subprocess.run(
            cmd, capture_output=True, text=True, check=True, cwd=cwd or Path(__file__).parent
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return out or "unknown"
