r"""Differentiable Dynamic Movement Primitives (DMPs), batched over samples and DoFs.

Notation (written once; every function in this package uses it):

- B batch size, D degrees of freedom, N basis functions, T integration steps, l the reporting
  stride (``subsample``), n_out = T / l + 1 reported points (start included).
- Canonical system: x_0 = 1, x_t = x_{t-1} - a_x x_{t-1} / tau * dt.
- Basis: c_i = exp(-a_x * linspace(0, 1, N)), h_i = N^1.5 / (c_i a_x), e_i = (x - c_i)^2,
  psi_i(x) in {exp(-h e), sqrt(1 + h e), 1 / (1 + h e), 1 / sqrt(1 + h e), h e},
  phi_i = psi_i / sum_j psi_j.
- Forcing term: f(x) = sum_i phi_i(x) w_i * x * (g - y0).
- Transformation system, z = tau dy, b_z = a_z / 4 by default:
  released form   dz = (a_z (b_z (g - y) - z) + f) / tau,
  supplement form dz = a_z (b_z (g - y) - z + f) / tau,
  dy = z / tau; explicit Euler in the order x, then psi(x_t), then y, then z.

Public API: :class:`DMPConfig`, :class:`DMPLayer`, :func:`dmp_rollout` (auto),
:func:`dmp_rollout_reference` (loop), :func:`dmp_rollout_fast` (linear map),
:func:`linear_map_f64`, :func:`dmp_sensitivities`, :func:`fit_dmp`, :func:`check_finite`.
"""

from ndp.dmp.basis import (
    RBF_FUNCTIONS,
    RBF_KINDS,
    basis_centres,
    canonical_phase,
    forcing_features,
    normalised_rbf,
    rbf,
)
from ndp.dmp.config import FORCING_FORMS, DMPConfig
from ndp.dmp.fit import fit_dmp
from ndp.dmp.integrate import (
    DMPTrajectory,
    check_finite,
    dmp_positions,
    dmp_rollout,
    dmp_rollout_fast,
    dmp_rollout_reference,
    euler_step,
    linear_map_f64,
    validate_inputs,
)
from ndp.dmp.layer import DMPLayer
from ndp.dmp.sensitivity import dmp_sensitivities

__all__ = [
    "FORCING_FORMS",
    "RBF_FUNCTIONS",
    "RBF_KINDS",
    "DMPConfig",
    "DMPLayer",
    "DMPTrajectory",
    "basis_centres",
    "canonical_phase",
    "check_finite",
    "dmp_positions",
    "dmp_rollout",
    "dmp_rollout_fast",
    "dmp_rollout_reference",
    "dmp_sensitivities",
    "euler_step",
    "fit_dmp",
    "forcing_features",
    "linear_map_f64",
    "normalised_rbf",
    "rbf",
    "validate_inputs",
]
