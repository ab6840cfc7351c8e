"""Typed configuration of a Dynamic Movement Primitive (DMP) integrator."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ndp.checks import check_int, check_positive, plain_numbers

FORCING_FORMS = ("released", "supplement")


@dataclass(frozen=True)
class DMPConfig:
    """Settings of one DMP integrator; every field is validated on construction.

    The three clocks: ``steps`` Euler integration steps of length ``dt`` make one DMP rollout of
    duration ``steps * dt`` (``tau`` by default); the rollout is reported every ``subsample``
    integration steps, so a rollout has ``steps // subsample`` output intervals (the k sub-steps
    of one policy decision in RL, 300 pen points in imitation).
    """

    n_basis: int = 30
    """N, the number of radial basis functions of the forcing term per degree of freedom."""
    a_z: float = 25.0
    """Spring constant alpha_z of the transformation system (ignored when a_z is learned)."""
    b_z: float | None = None
    """Damper constant beta_z; ``None`` means a_z / 4 (critical damping)."""
    a_x: float = 1.0
    """Decay rate alpha_x of the canonical system x (x starts at 1)."""
    tau: float = 1.0
    """Temporal scaling tau (z = tau * dy)."""
    steps: int = 300
    """T, the number of explicit Euler integration steps of one rollout."""
    dt: float | None = None
    """Integration step; ``None`` means tau / steps (the rollout lasts tau)."""
    rbf: str = "gaussian"
    """Basis kind: gaussian, multiquadric, inverse_quadric, inverse_multiquadric or linear."""
    forcing: str = "released"
    """Where f enters: 'released' (outside a_z, the default) or 'supplement' (inside a_z)."""
    only_g: bool = False
    """Ablation: forcing term switched off (a critically damped spring to the goal)."""
    scale_by_goal: bool = True
    """Multiply the forcing term by (g - y0) (the paper's form). False: f = sum phi_i w_i x, so
    w is a forcing amplitude in position units and stays bounded when g is close to y0."""
    learn_az: bool = False
    """a_z is predicted per sample and passed to the integrator, clamped to ``az_range``."""
    az_range: tuple[float, float] = field(default=(0.5, 30.0))
    """Clamp applied to a learned a_z (low, high)."""
    subsample: int = 1
    """Report every l-th integration step; ``steps`` must be a multiple of it."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        check_int("n_basis", self.n_basis, 1)
        check_int("steps", self.steps, 1)
        check_int("subsample", self.subsample, 1)
        check_positive("a_z", self.a_z)
        if self.b_z is not None:
            check_positive("b_z", self.b_z)
        check_positive("a_x", self.a_x)
        check_positive("tau", self.tau)
        if self.dt is not None:
            check_positive("dt", self.dt)
        from ndp.dmp.basis import RBF_FUNCTIONS  # the one table of kinds

        if self.rbf not in RBF_FUNCTIONS:
            raise ValueError(f"rbf: expected one of {', '.join(RBF_FUNCTIONS)}, got {self.rbf!r}")
        if self.forcing not in FORCING_FORMS:
            raise ValueError(
                f"forcing: expected one of {', '.join(FORCING_FORMS)}, got {self.forcing!r}"
            )
        lo, hi = self.az_range
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi):
            raise ValueError(f"az_range: expected 0 < low <= high, got {self.az_range!r}")
        if self.a_x * self.step_dt / self.tau >= 1.0:
            raise ValueError(
                f"dt: expected a_x * dt / tau < 1 so the canonical phase decays monotonically, "
                f"got a_x={self.a_x}, dt={self.step_dt}, tau={self.tau}"
            )
        if self.steps % self.subsample:
            raise ValueError(
                f"subsample: expected a divisor of steps={self.steps}, got {self.subsample}"
            )
        a_z_max = max(self.a_z, hi) if self.learn_az else self.a_z
        b_z = self.bz if not self.learn_az else a_z_max / 4.0
        radius = euler_step_radius(a_z_max, b_z, self.tau, self.step_dt)
        if radius >= 1.0:
            raise ValueError(
                f"a_z: explicit Euler with dt={self.step_dt:.4g} diverges for a_z={a_z_max:g} "
                f"(spectral radius {radius:.3g} >= 1 of the step matrix; with b_z = a_z / 4 the "
                f"condition is a_z * dt / tau < 4): use more steps or a smaller a_z"
            )

    @property
    def bz(self) -> float:
        """The resolved damper constant (a_z / 4 unless set)."""
        return self.a_z / 4.0 if self.b_z is None else float(self.b_z)

    @property
    def step_dt(self) -> float:
        """The resolved integration step."""
        return self.tau / self.steps if self.dt is None else float(self.dt)

    @property
    def n_out(self) -> int:
        """Number of reported points per rollout, start included: steps // subsample + 1."""
        return self.steps // self.subsample + 1


def euler_step_radius(a_z: float, b_z: float, tau: float, dt: float) -> float:
    """Spectral radius of one explicit Euler step of the transformation system.

    The homogeneous system ``d(y, z) = (z / tau, a_z (-b_z y - z) / tau)`` stepped with ``dt`` is
    ``x <- M x`` with ``M = I + dt A``; the integration stays bounded iff the radius is < 1. For
    the critically damped ``b_z = a_z / 4`` both eigenvalues are ``1 - a_z dt / (2 tau)``, so the
    condition is ``a_z dt / tau < 4`` (no sign flip between steps below 2).
    """
    import cmath

    t = 2.0 - dt * a_z / tau  # trace of M
    d = 1.0 - dt * a_z / tau + dt * dt * a_z * b_z / (tau * tau)  # determinant of M
    root = cmath.sqrt(t * t / 4.0 - d)
    return max(abs(t / 2.0 + root), abs(t / 2.0 - root))


def __getattr__(name: str) -> object:
    """``RBF_KINDS`` lives in :mod:`ndp.dmp.basis` (next to the functions); kept here too."""
    if name == "RBF_KINDS":
        from ndp.dmp.basis import RBF_KINDS

        return RBF_KINDS
    raise AttributeError(f"module 'ndp.dmp.config' has no attribute {name!r}")
