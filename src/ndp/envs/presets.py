"""Per-task NDP presets: N basis functions, a_z, integration steps, goal bound, DMP frame.

Each task's preset is a field of its row in the task table (``TaskSpec.ndp``, filled from
:data:`NDP_PRESETS` here); nothing else holds per-task DMP settings. docs/rl.md's preset table
is checked against it by a test.

The supplement tried N in {4, 5, 6, 7, 10}, a_z in {10, 15, 25} and 35 integration steps per NDP
rollout with k = 5 (7 per sub-step). The authors' release chose: throw N 5, a_z 5; push N 6,
a_z 10; soccer N 6, a_z 15; faucet N 6, a_z 5. Tasks not in the table use ``DEFAULT``.

The DMP's frame (where each decision's DMP starts) is measured per robot (docs/rl.md, "NDP
head ablation"): on the Meta-World tasks the measured hand with its measured velocity learns
best (push-v3, faucet-open, soccer, 300k env steps, 3 seeds); on the Jaco tasks, whose joint
targets lead the joints, the commanded targets at rest (Throw: deterministic success 0.88 and
0.80 on seeds 0 and 1 against 0.33 and 0.00 from the measured joints).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypedDict


@dataclass(frozen=True)
class NDPPreset:
    """DMP settings of one task."""

    n_basis: int
    """N radial basis functions per DMP DoF."""
    a_z: float
    """Spring constant alpha_z (b_z = a_z / 4)."""
    steps_per_substep: int = 7
    """Euler integration steps per sub-step (35 per decision for k = 5)."""
    goal_scale: float = 2.0
    """Goal bound, in units of the largest displacement of one decision (see PolicyConfig): 2
    puts the goal beyond the k-step reach, so the bell-shaped DMP velocity profile can command
    full speed at every sub-step (1, the first release's bound, saturates the middle ones)."""
    dmp_state: str = "measured"
    """Where each decision's DMP starts: the 'measured' robot (hand / joints) or the
    'commanded' state (Meta-World mocap target, Jaco joint targets); PolicyConfig.dmp_state."""
    dmp_velocity: str = "state"
    """The DMP's initial velocity: the state's ('state') or at rest ('zero');
    PolicyConfig.dmp_velocity."""


class _DMPFrame(TypedDict):
    """A row's DMP frame fields (``NDPPreset.dmp_state`` / ``dmp_velocity``)."""

    dmp_state: str
    dmp_velocity: str


_JACO: _DMPFrame = {"dmp_state": "commanded", "dmp_velocity": "zero"}
"""Jaco rows: the joint targets lead the joints (position servos), so the DMP plans from the
targets, at rest."""


DEFAULT = NDPPreset(n_basis=6, a_z=15.0)
"""Used for every task without its own row."""

NDP_PRESETS: dict[str, NDPPreset] = {
    "throw": NDPPreset(n_basis=5, a_z=5.0, **_JACO),
    "pick": NDPPreset(n_basis=6, a_z=10.0, **_JACO),
    "push-v3": NDPPreset(n_basis=6, a_z=10.0),
    "soccer-v3": NDPPreset(n_basis=6, a_z=15.0),
    "faucet-open-v3": NDPPreset(n_basis=6, a_z=5.0),
    "reach-v3": NDPPreset(n_basis=6, a_z=15.0),
    # the toy task keeps the frame it was measured with (commanded = measured there: no lag)
    "point-mass": NDPPreset(n_basis=6, a_z=5.0, dmp_state="commanded", dmp_velocity="zero"),
    "point-mass-3d": NDPPreset(n_basis=6, a_z=5.0, dmp_state="commanded", dmp_velocity="zero"),
}
"""Task name (canonical, as in ``ndp.envs.TASKS``) -> preset."""


def preset_of(spec: object) -> NDPPreset:
    """The preset of a task spec: its ``ndp`` field, else its name's row (or ``DEFAULT``), for
    spec-like objects without one."""
    pre = getattr(spec, "ndp", None)
    if isinstance(pre, NDPPreset):
        return pre
    return NDP_PRESETS.get(str(getattr(spec, "name", "")), DEFAULT)
