"""Typed configuration of the actor-critic and its action head."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from ndp.checks import plain_numbers
from ndp.runs.cli import HIDDEN

HEADS = ("step", "multi", "ndp", "dyne")
"""Built-in action heads: one raw action per step, k raw actions per decision, DMP parameters,
a Dyn-E latent decoded into k actions (more register with ``ndp.policies.heads.register_head``)."""
FORCING = ("amplitude", "goal")
"""NDP forcing-weight forms: bounded amplitude per DoF, or the paper's f proportional to g - y0."""
ABSOLUTE_MODES = ("direct", "dmp")
"""NDP absolute-command DoF (gripper): the goal emitted as the command, or a DMP from y0."""
DMP_VELOCITIES = ("zero", "state")
"""NDP DMP start velocity: at rest, or the state's velocity (commanded or measured)."""
DMP_STATES = ("commanded", "measured")
"""Where the NDP DMP starts: the commanded target (mocap, joint targets) or the measured robot."""


@dataclass(frozen=True)
class PolicyConfig:
    """Actor-critic settings; ``None`` NDP fields are filled from the per-task preset table.

    The NDP goal bound is per DoF: ``goal_scale`` times the largest displacement the actions can
    make in one decision (``k * action_scale`` for delta-controlled DoF, the action range
    ``high - low`` for DoF whose action is the trajectory value itself).

    The three clocks: one env step (sub-step) lasts ``spec.control_dt`` seconds; one policy
    decision runs ``k`` sub-steps; the DMP of a decision spans its whole duration
    ``k * control_dt`` seconds with ``dmp_steps`` Euler steps (``dmp_steps / k`` per sub-step)
    over DMP time ``tau = 1``.
    """

    head: Annotated[str, HIDDEN] = "ndp"
    """Action head: 'step' (PPO), 'multi' (PPO-multi), 'ndp' or 'dyne' (follows the method: not an
    option of ``ndp rl train``)."""
    k: int = 5
    """Sub-steps (env steps) per policy decision; always 1 for the 'step' head."""
    hidden: tuple[int, ...] = (100, 100)
    """Hidden widths of the actor and critic MLPs."""
    activation: str = "tanh"
    """Hidden non-linearity of both MLPs."""
    init_log_std: float = 0.0
    """Initial value of the learned, state-independent log std (0: std 1), every method."""
    hidden_gain: float | None = None
    """Orthogonal-init gain of the hidden layers; None: the activation's (5/3 for tanh)."""
    n_basis: int | None = None
    """NDP: radial basis functions per DMP DoF (N); None: per-task preset."""
    a_z: float | None = None
    """NDP: DMP spring constant alpha_z; None: per-task preset."""
    dmp_steps: int | None = None
    """NDP: Euler integration steps per decision (a multiple of k); None: per-task preset."""
    goal_scale: float | None = None
    """NDP: goal bound g = y0 + s * tanh(raw), s = goal_scale * (k * action_scale) per delta DoF
    (absolute-command DoF always span their action range); None: per-task preset."""
    weight_scale: float | None = None
    """NDP: weight bound, w = weight_scale * tanh(raw) ('goal' forcing) or w = weight_scale *
    reach * tanh(raw) per DoF ('amplitude'); None: a_z^2 / 4 (the spring stiffness)."""
    rbf: str = "gaussian"
    """NDP: radial basis kind of the forcing term."""
    absolute_goal: bool = True
    """NDP: DoF whose action is the trajectory value (gripper) get a goal in the action range
    independent of y0 and start at dy0 = 0; False: relative to y0 like every other DoF."""
    param_noise: bool = False
    """NDP: explore with a Gaussian over the DMP parameters (one log-prob per decision)."""
    only_g: bool = False
    """NDP ablation 'only-g': no forcing term; the network outputs the goals only (a critically
    damped spring to g per decision)."""
    learn_az: bool = False
    """NDP ablation: a learned spring constant, one more network output per decision mapped
    into [0.5, 30] (b_z = a_z / 4; the preset a_z at a zero output); the DMP then runs the
    reference integration loop instead of the folded map (slower)."""
    mean_clip: bool = False
    """NDP: clip the sub-action means to the action bounds before the noise (the first
    release's handicap); False: only the executed sample is clipped, as for PPO."""
    forcing: str = "amplitude"
    """NDP: 'amplitude' (forcing term f = sum psi w x with |w| <= weight_scale * reach: a
    gradient from the first update) or 'goal' (the paper's f proportional to (g - y0), whose
    weights get almost no gradient while g is near y0)."""
    absolute_mode: str = "direct"
    """NDP, absolute-command DoF (Meta-World gripper): 'direct' emits the decision's goal as the
    command of all k sub-steps (no dependence on the previous decision's noise); 'dmp' integrates
    a DMP from the last sampled command (the first release's form)."""
    dmp_state: str | None = None
    """NDP: the DMP starts from the commanded state (Meta-World mocap target and its commanded
    velocity; Jaco joint targets), which is what the actions move, or from the 'measured' robot
    (hand / joints), which lags the command; None: the task's preset (measured on Meta-World,
    commanded on Jaco and the toy task; ndp.envs.presets)."""
    dmp_velocity: str | None = None
    """NDP: the DMP starts at rest ('zero') or with the state's velocity ('state': the commanded
    velocity is the previous decision's last *sampled* sub-action, i.e. its exploration noise;
    the measured one double-counts the momentum stored in the target's lead); None: the task's
    preset ('state' on Meta-World, 'zero' on Jaco and the toy task)."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        from ndp.policies.heads import HEAD_BUILDERS, SINGLE_STEP_HEADS

        if self.head not in HEAD_BUILDERS:
            raise ValueError(f"head: expected one of {', '.join(HEAD_BUILDERS)}, got {self.head!r}")
        if isinstance(self.k, bool) or not isinstance(self.k, int) or self.k < 1:
            raise ValueError(f"k: expected an integer >= 1, got {self.k!r}")
        if self.head in SINGLE_STEP_HEADS and self.k != 1:
            raise ValueError(
                f"k: the {self.head!r} head runs one action per decision, got k={self.k}"
            )
        if not self.hidden or any(int(h) < 1 for h in self.hidden):
            raise ValueError(f"hidden: expected positive widths, got {self.hidden!r}")
        if self.n_basis is not None and (isinstance(self.n_basis, bool) or self.n_basis < 1):
            raise ValueError(f"n_basis: expected an integer >= 1, got {self.n_basis!r}")
        if self.a_z is not None and not self.a_z > 0:
            raise ValueError(f"a_z: expected a number > 0, got {self.a_z!r}")
        if self.dmp_steps is not None:
            if self.dmp_steps < 1 or self.dmp_steps % self.k:
                raise ValueError(
                    f"dmp_steps: expected a positive multiple of k={self.k}, got {self.dmp_steps!r}"
                )
        for name in ("goal_scale", "weight_scale"):
            v = getattr(self, name)
            if v is not None and not v > 0:
                raise ValueError(f"{name}: expected a number > 0, got {v!r}")
        for name, allowed in (
            ("forcing", FORCING),
            ("absolute_mode", ABSOLUTE_MODES),
            ("dmp_state", DMP_STATES),
            ("dmp_velocity", DMP_VELOCITIES),
        ):
            if name.startswith("dmp_") and getattr(self, name) is None:
                continue  # the task's preset (resolve_config)
            if getattr(self, name) not in allowed:
                raise ValueError(
                    f"{name}: expected one of {', '.join(allowed)}, got {getattr(self, name)!r}"
                )
        if self.hidden_gain is not None and not self.hidden_gain > 0:
            raise ValueError(f"hidden_gain: expected a number > 0, got {self.hidden_gain!r}")
        if self.param_noise and self.head != "ndp":
            raise ValueError("param_noise: parameter-space exploration needs the 'ndp' head")

    @property
    def resolved(self) -> bool:
        """Whether every field the head needs is set (no ``None`` left for NDP)."""
        if self.head != "ndp":
            return True
        return None not in (
            self.n_basis,
            self.a_z,
            self.dmp_steps,
            self.goal_scale,
            self.weight_scale,
        )
