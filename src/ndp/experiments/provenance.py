"""Provenance of generated results (moved to :mod:`ndp.provenance`; kept for the benchmarks)."""

from ndp.provenance import git_commit

__all__ = ["git_commit"]
