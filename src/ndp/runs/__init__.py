"""One run infrastructure for every trainer (RL and imitation alike).

A run directory holds::

    config.json       the resolved, typed config of the run (written at start)
    provenance.json   one entry per session (start / resume): time, command line, commit,
                      dirty flag, host, versions, CPU model (the environment fingerprint)
    checkpoint.pt     the latest good checkpoint (atomic; ``kind`` names the trainer)
    metrics.csv       one row per update / epoch, stable column names (docs/metrics.md)
    tb/               the same scalars as TensorBoard events

:class:`RunDir` creates, refuses and resumes run directories; :class:`MetricsLogger` writes the
CSV and TensorBoard together and truncates both consistently on resume; :func:`save_checkpoint`
/ :func:`load_checkpoint` are the one checkpoint format and loader.
"""

from ndp.runs.checkpoint import load_checkpoint, save_checkpoint
from ndp.runs.layout import (
    CHECKPOINT_NAME,
    CONFIG_NAME,
    LEGACY_METRICS_NAMES,
    METRICS_NAME,
    PROVENANCE_NAME,
    TB_DIR,
    RunDir,
    run_commits,
    run_fingerprints,
)
from ndp.runs.metrics import MetricsLogger, metrics_path, read_metrics

__all__ = [
    "CHECKPOINT_NAME",
    "CONFIG_NAME",
    "LEGACY_METRICS_NAMES",
    "METRICS_NAME",
    "PROVENANCE_NAME",
    "TB_DIR",
    "MetricsLogger",
    "RunDir",
    "load_checkpoint",
    "metrics_path",
    "read_metrics",
    "run_commits",
    "run_fingerprints",
    "save_checkpoint",
]
