"""Moved to :mod:`ndp.envs.presets` (the presets are fields of the task table now)."""

from ndp.envs.presets import DEFAULT, NDP_PRESETS, NDPPreset
from ndp.envs.spec import ndp_preset

__all__ = ["DEFAULT", "NDP_PRESETS", "NDPPreset", "ndp_preset"]
