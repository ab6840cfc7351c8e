"""The low-level controllers of the task table (trajectory points -> env actions).

They live in :mod:`ndp.dmp.controllers` (torch only), so that a trained policy acts without
the simulators; this module keeps the name the task table and older code import.
"""

from ndp.dmp.controllers import CONTROLLERS, DeltaController

__all__ = ["CONTROLLERS", "DeltaController"]
