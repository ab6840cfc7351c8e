"""Typed configuration of the actor-critic and its action head."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated, Any

from ndp.checks import check_int, plain_numbers
from ndp.runs.cli import HIDDEN

if TYPE_CHECKING:
    from ndp.dmp.config import DMPConfig

HEADS = ("step", "multi", "ndp", "dyne")
"""Built-in action heads: one raw action per step, k raw actions per decision, DMP parameters,
a Dyn-E latent decoded into k actions (more register with ``ndp.policies.heads.register_head``)."""
DMP_HEADS = ("ndp", "ndp-squashed")
"""Heads that run a DMP and read the NDP head's settings (``PolicyConfig.ndp``): NDP's, and
NDP-SAC's squashed form of it."""
FORCING = ("amplitude", "goal")
"""NDP forcing-weight forms: bounded amplitude per DoF, or the paper's f proportional to g - y0."""
ABSOLUTE_MODES = ("direct", "dmp")
"""NDP absolute-command DoF (gripper): the goal emitted as the command, or a DMP from y0."""
DMP_VELOCITIES = ("zero", "state")
"""NDP DMP start velocity: at rest, or the state's velocity (commanded or measured)."""
PARAM_MAPS = ("tanh", "linear", "whitened")
"""NDP raw outputs -> goal and weights: bounded by tanh, linear (unbounded), or linear after a
fixed whitening transform W (``ndp.policies.heads.NDPHead``, docs/rl.md)."""
DMP_STATES = ("commanded", "measured")
"""Where the NDP DMP starts: the commanded target (mocap, joint targets) or the measured robot."""


CHUNK_BASES = ("none", "dmp", "dct", "bspline", "pca")
"""Values of ``PolicyConfig.chunk_basis`` (``ndp.policies.chunk_basis``): PPO-multi's free chunk,
or a fixed basis of 1 + n_basis columns per DoF."""
FILE_BASES = ("pca",)
"""Chunk bases read from ``PolicyConfig.chunk_basis_file``."""
BASIS_HEADS = ("multi",)
"""Heads that read ``PolicyConfig.chunk_basis`` (PPO-multi's); the others have it cleared."""

AR1_HEADS = ("step", "multi", "ndp")
"""Heads whose exploration is a Gaussian around each sub-action (``noise="ar1"`` applies)."""
PRESET_FIELDS = ("n_basis", "a_z", "dmp_steps", "goal_scale", "weight_scale")
"""The NDP head's fields whose ``None`` means "the task's preset" (``ndp.rl.methods.resolve_ndp``
fills them; a head without a DMP has them cleared)."""

DEFAULT_K = 5
"""Env steps per decision of the chunked methods when ``k`` is not given (the paper's)."""
DEFAULT_HIDDEN = (100, 100)
"""Hidden widths of the PPO family's actor and critic when ``hidden`` is not given."""
DEFAULT_ACTIVATION = "tanh"
"""Hidden non-linearity of the PPO family's networks when ``activation`` is not given."""


@dataclass(frozen=True)
class NDPHeadConfig:
    """The NDP head's settings (``PolicyConfig.ndp``; only the 'ndp' head reads them).

    ``None`` fields are filled from the per-task preset table when a run's config is resolved
    (``ndp.rl.methods.resolve_ndp``). The DMP of a decision is :meth:`dmp_config`: the one place
    where these fields become a :class:`ndp.dmp.DMPConfig` (``n_basis``, ``a_z``, ``rbf``,
    ``only_g``, ``learn_az`` as they are; ``steps`` = ``dmp_steps``; ``subsample`` =
    ``dmp_steps / k``; ``scale_by_goal`` from ``forcing``). The other fields are the head's
    own: how the network's outputs are bounded and explored.
    """

    n_basis: int | None = None
    """Radial basis functions per DMP DoF (N, ``DMPConfig.n_basis``); None: per-task preset."""
    a_z: float | None = None
    """DMP spring constant alpha_z (``DMPConfig.a_z``); None: per-task preset."""
    dmp_steps: int | None = None
    """Euler integration steps per decision (``DMPConfig.steps``, a multiple of k); None:
    per-task preset."""
    goal_scale: float | None = None
    """Goal bound g = y0 + s * tanh(raw), s = goal_scale * (k * action_scale) per delta DoF
    (absolute-command DoF always span their action range); None: per-task preset."""
    weight_scale: float | None = None
    """Weight bound, w = weight_scale * tanh(raw) ('goal' forcing) or w = weight_scale * reach
    * tanh(raw) per DoF ('amplitude'); None: a_z^2 / 4 (the spring stiffness)."""
    rbf: str = "gaussian"
    """Radial basis kind of the forcing term (``DMPConfig.rbf``)."""
    absolute_goal: bool = True
    """DoF whose action is the trajectory value (gripper) get a goal in the action range
    independent of y0 and start at dy0 = 0; False: relative to y0 like every other DoF."""
    param_noise: bool = False
    """Explore with a Gaussian over the DMP parameters (one log-prob per decision)."""
    only_g: bool = False
    """Ablation 'only-g': no forcing term; the network outputs the goals only (a critically
    damped spring to g per decision; ``DMPConfig.only_g``)."""
    learn_az: bool = False
    """Ablation: a learned spring constant, one more network output per decision mapped into
    [0.5, 30] (b_z = a_z / 4; the preset a_z at a zero output); the DMP then runs the reference
    integration loop instead of the folded map (slower; ``DMPConfig.learn_az``)."""
    mean_clip: bool = False
    """Clip the sub-action means to the action bounds before the noise (the first release's
    handicap); False: only the executed sample is clipped, as for PPO."""
    forcing: str = "amplitude"
    """'amplitude' (forcing term f = sum psi w x with |w| <= weight_scale * reach: a gradient
    from the first update; ``DMPConfig.scale_by_goal`` False) or 'goal' (the paper's f
    proportional to (g - y0), whose weights get almost no gradient while g is near y0)."""
    absolute_mode: str = "direct"
    """Absolute-command DoF (Meta-World gripper): 'direct' emits the decision's goal as the
    command of all k sub-steps (no dependence on the previous decision's noise); 'dmp'
    integrates a DMP from the last sampled command (the first release's form)."""
    param_map: str = "tanh"
    """How the raw outputs become goal and weights: 'tanh' (bounded, g - y0 = s tanh(raw)),
    'linear' (the same scale without tanh; only the executed actions are clipped) or 'whitened'
    (linear after a fixed transform W making the map's Jacobian at raw = 0 isotropic on the
    chunk's reachable directions; 'amplitude' forcing, fixed a_z). NDP (PPO) head only."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        if self.n_basis is not None:
            check_int("n_basis", self.n_basis, 1)
        if self.a_z is not None and not self.a_z > 0:
            raise ValueError(f"a_z: expected a number > 0, got {self.a_z!r}")
        if self.dmp_steps is not None:
            check_int("dmp_steps", self.dmp_steps, 1)
        for name in ("goal_scale", "weight_scale"):
            v = getattr(self, name)
            if v is not None and not v > 0:
                raise ValueError(f"{name}: expected a number > 0, got {v!r}")
        for name, allowed in (
            ("forcing", FORCING),
            ("absolute_mode", ABSOLUTE_MODES),
            ("param_map", PARAM_MAPS),
        ):
            if getattr(self, name) not in allowed:
                raise ValueError(
                    f"{name}: expected one of {', '.join(allowed)}, got {getattr(self, name)!r}"
                )
        if self.param_map == "whitened" and (self.forcing != "amplitude" or self.learn_az):
            raise ValueError(
                "param_map: 'whitened' needs forcing='amplitude' and a fixed a_z (a map linear in "
                f"the raw outputs), got forcing={self.forcing!r}, learn_az={self.learn_az}"
            )

    @property
    def resolved(self) -> bool:
        """Whether every preset field is set (no ``None`` left)."""
        return all(getattr(self, name) is not None for name in PRESET_FIELDS)

    def dmp_config(self, k: int) -> DMPConfig:
        """The DMP of one decision of ``k`` sub-steps (a resolved config only).

        Raises:
            ValueError: a preset field is still None, or ``dmp_steps`` is not a multiple of k.
        """
        from ndp.dmp.config import DMPConfig

        if not self.resolved:
            raise ValueError(
                "policy config: NDP fields must be resolved (see ndp.rl.methods.resolve_ndp)"
            )
        assert self.n_basis is not None and self.a_z is not None and self.dmp_steps is not None
        if self.dmp_steps % k:
            raise ValueError(f"dmp_steps: expected a multiple of k={k}, got {self.dmp_steps}")
        return DMPConfig(
            n_basis=int(self.n_basis),
            a_z=float(self.a_z),
            steps=int(self.dmp_steps),
            subsample=int(self.dmp_steps) // k,
            rbf=self.rbf,
            scale_by_goal=self.forcing == "goal",
            only_g=self.only_g,
            learn_az=self.learn_az,
        )


NDP_FIELDS = tuple(f.name for f in dataclasses.fields(NDPHeadConfig))
"""The NDP head's fields; a config written before :class:`NDPHeadConfig` holds them flat in
its ``policy`` (:meth:`PolicyConfig.from_dict` reads both forms)."""


NOISE_CORR = 0.8
"""The default ``noise_corr`` (the only value accepted with noise other than 'ar1')."""


@dataclass(frozen=True)
class PolicyConfig:
    """Actor-critic settings: the ones every method reads, and the NDP head's (``ndp``).

    The NDP goal bound is per DoF: ``ndp.goal_scale`` times the largest displacement the actions
    can make in one decision (``k * action_scale`` for delta-controlled DoF, the action range
    ``high - low`` for DoF whose action is the trajectory value itself).

    The three clocks: one env step (sub-step) lasts ``spec.control_dt`` seconds; one policy
    decision runs ``k`` sub-steps; the DMP of a decision spans its whole duration
    ``k * control_dt`` seconds with ``ndp.dmp_steps`` Euler steps (``dmp_steps / k`` per
    sub-step) over DMP time ``tau = 1``.

    On the command line the nested fields are flat options (``--n-basis``, ``--forcing``, ...;
    ``ndp.runs.cli``).
    """

    head: Annotated[str, HIDDEN] = "ndp"
    """Action head: 'step' (PPO), 'multi' (PPO-multi), 'ndp' or 'dyne' (follows the method: not an
    option of ``ndp rl train``)."""
    k: int | None = None
    """Sub-steps (env steps) per policy decision; None: the method's (5 for the chunked methods,
    1 for the one-action ones, the controller's period for VICES). A k the method cannot run
    (``--algo ppo --k 5``) is refused when the config is resolved, not dropped."""
    hidden: tuple[int, ...] | None = None
    """Hidden widths of the actor and critic MLPs; None: the method's (100-100 for the PPO
    family, 256-256 for the SAC family, 400-300 for Dyn-E)."""
    activation: str | None = None
    """Hidden non-linearity of both MLPs; None: the method's (tanh for the PPO family, relu
    for the SAC family and Dyn-E)."""
    init_log_std: float = 0.0
    """Initial value of the learned, state-independent log std (0: std 1), every method."""
    noise: str = "white"
    """Exploration noise around the sub-actions: 'white' (independent per env step) or 'ar1'
    (temporally correlated: an AR(1) / discretised Ornstein-Uhlenbeck process over env steps,
    continued across decisions, restarted at each episode; exact conditional log-probs,
    ndp.policies.distributions.AR1SubActionGaussian). PPO, PPO-multi and NDP (not with
    param_noise or the hold head). Acting with a loaded policy samples the white marginal."""
    noise_corr: float = NOISE_CORR
    """'ar1' noise: correlation of consecutive env steps' noise, in [0, 1) (0.8: a correlation
    time of about one k = 5 decision). Another value with any other noise is refused (it would
    be read by nothing); the default itself cannot be told apart from a value given."""
    hidden_gain: float | None = None
    """Orthogonal-init gain of the hidden layers; None: the activation's (5/3 for tanh)."""
    ndp: NDPHeadConfig = field(default_factory=NDPHeadConfig)
    """The NDP head's settings (:class:`NDPHeadConfig`)."""
    dmp_state: str | None = None
    """Where the DMP starts, and the frame of the robot state the trainer records for every
    method: the commanded state (Meta-World mocap target and its commanded velocity; Jaco joint
    targets), which is what the actions move, or the 'measured' robot (hand / joints), which
    lags the command; None: the task's preset (measured on Meta-World, commanded on Jaco and
    the toy task; ndp.envs.presets)."""
    dmp_velocity: str | None = None
    """The DMP starts at rest ('zero') or with the state's velocity ('state': the commanded
    velocity is the previous decision's last *sampled* sub-action, i.e. its exploration noise;
    the measured one double-counts the momentum stored in the target's lead); None: the task's
    preset ('state' on Meta-World, 'zero' on Jaco and the toy task)."""
    chunk_basis: str = "none"
    """PPO-multi only: restrict each DoF's k sub-action means to a fixed basis of 1 + n_basis
    columns (n_basis: the task's NDP preset unless given): 'none' (k free means, PPO-multi as
    it is), 'dmp' (the NDP head's affine span from the robot state, tanh bounds removed), 'dct',
    'bspline' (cubic) or 'pca' (--chunk-basis-file); refused where 1 + n_basis > k
    (docs/policies.md, 'Chunk bases')."""
    chunk_basis_file: str | None = None
    """The 'pca' basis' file, written by ndp rl fit-basis; its task, k and DoF count must be the
    run's."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        from ndp.policies.heads import HEAD_BUILDERS, SINGLE_STEP_HEADS

        if self.head not in HEAD_BUILDERS:
            raise ValueError(f"head: expected one of {', '.join(HEAD_BUILDERS)}, got {self.head!r}")
        k = self.k
        if k is not None:
            check_int("k", k, 1)
        if self.head in SINGLE_STEP_HEADS and k not in (None, 1):
            raise ValueError(f"k: the {self.head!r} head runs one action per decision, got k={k}")
        if self.hidden is not None and (not self.hidden or any(int(h) < 1 for h in self.hidden)):
            raise ValueError(f"hidden: expected positive widths, got {self.hidden!r}")
        if not isinstance(self.ndp, NDPHeadConfig):
            raise ValueError(f"ndp: expected an NDPHeadConfig, got {type(self.ndp).__name__}")
        if self.ndp.dmp_steps is not None and k is not None and self.ndp.dmp_steps % k:
            raise ValueError(
                f"dmp_steps: expected a positive multiple of k={self.k}, got {self.ndp.dmp_steps!r}"
            )
        for name, allowed in (("dmp_state", DMP_STATES), ("dmp_velocity", DMP_VELOCITIES)):
            v = getattr(self, name)
            if v is not None and v not in allowed:  # None: the task's preset (resolve_config)
                raise ValueError(f"{name}: expected one of {', '.join(allowed)}, got {v!r}")
        if self.chunk_basis not in CHUNK_BASES:
            raise ValueError(
                f"chunk_basis: expected one of {', '.join(CHUNK_BASES)}, got {self.chunk_basis!r}"
            )
        has_file = self.chunk_basis_file is not None
        if has_file != (self.chunk_basis in FILE_BASES):
            raise ValueError(
                f"chunk_basis_file: expected a file for chunk_basis in {', '.join(FILE_BASES)} "
                f"only (ndp rl fit-basis writes one), got chunk_basis={self.chunk_basis!r} and "
                f"chunk_basis_file={self.chunk_basis_file!r}"
            )
        if self.hidden_gain is not None and not self.hidden_gain > 0:
            raise ValueError(f"hidden_gain: expected a number > 0, got {self.hidden_gain!r}")
        if self.ndp.param_noise and self.head != "ndp":
            raise ValueError("param_noise: parameter-space exploration needs the 'ndp' head")
        if self.ndp.param_map != "tanh" and self.head in DMP_HEADS and self.head != "ndp":
            raise ValueError(
                f"param_map: {self.ndp.param_map!r} needs the 'ndp' head; the {self.head!r} head "
                "bounds its DMP parameters by tanh in its density (use 'tanh')"
            )
        from ndp.policies.distributions import NOISES

        if self.noise not in NOISES:
            raise ValueError(f"noise: expected one of {', '.join(NOISES)}, got {self.noise!r}")
        if not (isinstance(self.noise_corr, (int, float)) and 0.0 <= self.noise_corr < 1.0):
            raise ValueError(f"noise_corr: expected a number in [0, 1), got {self.noise_corr!r}")
        if self.noise != "ar1" and self.noise_corr != NOISE_CORR:
            raise ValueError(
                f"noise_corr: only 'ar1' noise reads it, got noise_corr={self.noise_corr!r} with "
                f"noise={self.noise!r} (add --noise ar1, or leave noise_corr at {NOISE_CORR})"
            )
        if self.noise == "ar1" and (self.head not in AR1_HEADS or self.ndp.param_noise):
            raise ValueError(
                "noise: 'ar1' needs a Gaussian around each sub-action (ppo, ppo-multi, ndp "
                f"without --param-noise), got head {self.head!r}"
                + (" with param_noise" if self.ndp.param_noise else "")
            )

    def with_defaults(self) -> PolicyConfig:
        """A copy with the method-dependent fields left at None filled with the PPO family's
        values (k: 1 for a one-action head, else :data:`DEFAULT_K`; :data:`DEFAULT_HIDDEN`;
        :data:`DEFAULT_ACTIVATION`). ``ndp.rl.config.resolve_config`` fills them from the
        method first; this is what building a head or an actor-critic from an unresolved
        config uses."""
        from ndp.policies.heads import SINGLE_STEP_HEADS

        k = self.k if self.k is not None else (1 if self.head in SINGLE_STEP_HEADS else DEFAULT_K)
        hidden = self.hidden if self.hidden is not None else DEFAULT_HIDDEN
        activation = self.activation if self.activation is not None else DEFAULT_ACTIVATION
        if (k, hidden, activation) == (self.k, self.hidden, self.activation):
            return self
        return dataclasses.replace(self, k=k, hidden=hidden, activation=activation)

    @property
    def resolved(self) -> bool:
        """Whether every field the head needs is set (no ``None`` left for NDP)."""
        return self.head != "ndp" or self.ndp.resolved

    def updated(self, **changes: Any) -> PolicyConfig:
        """A copy with ``changes`` applied, the NDP head's fields (:data:`NDP_FIELDS`) given
        flat like the others (``updated(k=3, n_basis=6)``; ``ndp=`` replaces the whole head).

        Raises:
            ValueError: a name that is no field, or a bad value (the field's message).
        """
        head = {n: changes.pop(n) for n in NDP_FIELDS if n in changes}
        known = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise ValueError(
                f"policy: no field {', '.join(unknown)} (expected one of "
                f"{', '.join(sorted(known | set(NDP_FIELDS)))})"
            )
        ndp = changes.pop("ndp", self.ndp)
        if head:
            ndp = dataclasses.replace(ndp, **head)
        return dataclasses.replace(self, ndp=ndp, **changes)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (``ndp`` nested)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PolicyConfig:
        """Inverse of :meth:`to_dict`; also reads the flat form written before
        :class:`NDPHeadConfig` (the NDP fields beside the others) and flat keyword sets such
        as ``ndp.sb3.NDPPolicy``'s ``ndp=`` dict.

        Raises:
            ValueError: unknown keys, a field given both flat and nested, or bad values.
        """
        d = dict(d)
        nested = d.pop("ndp", None)
        nested = dict(nested) if isinstance(nested, dict) else ({} if nested is None else nested)
        if not isinstance(nested, dict):
            raise ValueError(f"ndp: expected a dict of NDP head fields, got {nested!r}")
        flat = {name: d.pop(name) for name in NDP_FIELDS if name in d}
        both = sorted(set(flat) & set(nested))
        if both:
            raise ValueError(f"policy: {', '.join(both)} given both flat and under 'ndp'")
        if d.get("hidden") is not None:
            d["hidden"] = tuple(d["hidden"])
        try:
            return cls(ndp=NDPHeadConfig(**flat, **nested), **d)
        except TypeError as exc:
            raise ValueError(f"policy: {exc}") from None
