"""DMP integrators: a readable reference Euler loop and a fast linear-map path.

Both follow the released integration order (ndp-method.md section 2), per degree of freedom and
batched over samples. For every step t = 1..T:

    x_t  = x_{t-1} - a_x * x_{t-1} / tau * dt
    f_t  = (sum_i psi_i(x_t) w_i / sum_j psi_j(x_t)) * x_t * (g - y0)   [(g - y0): scale_by_goal]
    dz   = (a_z * (b_z * (g - y_{t-1}) - z_{t-1}) + f_t) / tau        (released form)
    dz   = a_z * (b_z * (g - y_{t-1}) - z_{t-1} + f_t) / tau          (supplement form)
    y_t  = y_{t-1} + z_{t-1} / tau * dt
    z_t  = z_{t-1} + dz * dt

with z_0 = tau * dy0. Velocities are dy_t = z_t / tau and accelerations ddy_t = dz / tau of the
step that produced z_t (ddy_0 = 0).

For a fixed a_z the rollout is linear in u = (w * (g - y0), g, y0, dy0): the fast path
precomputes that linear map once (in float64, by running the same recursion on unit inputs) and
applies it with one matrix product.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator
from typing import NamedTuple, TypeVar

import numpy as np
import torch

from ndp.dmp.basis import basis_centres, forcing_features, rbf
from ndp.dmp.config import DMPConfig


class DMPTrajectory(NamedTuple):
    """A batch of DMP rollouts; each field is [B, n_out, D] with n_out = steps // subsample + 1."""

    pos: torch.Tensor
    """Positions y_t; ``pos[:, 0] == y0``."""
    vel: torch.Tensor
    """Velocities dy_t = z_t / tau; ``vel[:, 0] == dy0``."""
    acc: torch.Tensor
    """Accelerations ddy_t = dz / tau of the step ending at t; ``acc[:, 0] == 0``."""


# --------------------------------------------------------------------------------------------
# Input checks
# --------------------------------------------------------------------------------------------
Num = TypeVar("Num", torch.Tensor, np.ndarray)


def euler_step(
    y: Num,
    z: Num,
    goal: Num | float,
    f: Num,
    a_z: Num | float,
    b_z: Num | float,
    tau: float,
    dt: float,
    forcing: str,
) -> tuple[Num, Num, Num]:
    """One explicit Euler step of the transformation system (the one place it is written).

    Used by the reference loop, the linear-map builder (on unit inputs) and the analytic
    sensitivities (on derivative states: dy/dw follows the same step with goal 0, dy/dg with
    goal 1). Works on tensors and arrays of any broadcastable shapes.

    Args:
        y, z: position and scaled velocity z = tau * dy before the step.
        goal: g.
        f: forcing term of this step.
        a_z, b_z: spring constants (numbers or broadcastable tensors).
        tau, dt: temporal scale and step size.
        forcing: 'released' (f added outside the a_z bracket) or 'supplement' (inside it).

    Returns:
        (y_next, z_next, dz): the new state and the derivative dz used (ddy = dz / tau).
    """
    if forcing == "released":
        dz = (a_z * (b_z * (goal - y) - z) + f) / tau
    else:
        dz = a_z * (b_z * (goal - y) - z + f) / tau
    return y + z / tau * dt, z + dz * dt, dz


def _check_tensor(name: str, t: object, ndim: int, shape_doc: str) -> torch.Tensor:
    if not isinstance(t, torch.Tensor):
        raise ValueError(f"{name}: expected a torch.Tensor of shape {shape_doc}, got {type(t)}")
    if t.ndim != ndim:
        raise ValueError(f"{name}: expected shape {shape_doc}, got {tuple(t.shape)}")
    if not t.is_floating_point():
        raise ValueError(f"{name}: expected a floating-point tensor, got dtype {t.dtype}")
    return t


class DMPInputs(NamedTuple):
    """A rollout's inputs after :func:`validate_inputs` (one value through the integrators)."""

    goal: torch.Tensor
    """g [B, D]."""
    weights: torch.Tensor
    """w [B, D, N] (zeros where omitted with ``only_g``)."""
    y0: torch.Tensor
    """Start position [B, D]."""
    dy0: torch.Tensor
    """Start velocity [B, D] (zeros where omitted)."""
    a_z: torch.Tensor | None
    """Per-sample spring constants [B, D], or None (the config's)."""


def validate_inputs(
    cfg: DMPConfig,
    goal: torch.Tensor,
    weights: torch.Tensor | None,
    y0: torch.Tensor,
    dy0: torch.Tensor | None,
    a_z: torch.Tensor | None = None,
) -> DMPInputs:
    """Check shapes, dtypes and devices; fill defaults.

    Args:
        goal: [B, D].
        weights: [B, D, N], or ``None`` only when ``cfg.only_g``.
        y0: [B, D].
        dy0: [B, D] or ``None`` (zeros).
        a_z: ``None``, or per-sample spring constants [B], [B, 1] or [B, D].

    Returns:
        :class:`DMPInputs` (goal, weights, y0, dy0, a_z) with weights zero-filled if omitted
        and a_z as [B, D].

    Raises:
        ValueError: naming the offending argument and the expected shape.
    """
    goal = _check_tensor("goal", goal, 2, "[B, D]")
    b, d = goal.shape
    y0 = _check_tensor("y0", y0, 2, "[B, D]")
    if y0.shape != goal.shape:
        raise ValueError(f"y0: expected shape {(b, d)} like goal, got {tuple(y0.shape)}")
    if dy0 is None:
        dy0 = torch.zeros_like(y0)
    dy0 = _check_tensor("dy0", dy0, 2, "[B, D]")
    if dy0.shape != goal.shape:
        raise ValueError(f"dy0: expected shape {(b, d)} like goal, got {tuple(dy0.shape)}")
    n = cfg.n_basis
    if weights is None:
        if not cfg.only_g:
            raise ValueError("weights: expected a tensor [B, D, N] (None only with only_g=True)")
        weights = goal.new_zeros(b, d, n)
    weights = _check_tensor("weights", weights, 3, "[B, D, N]")
    if weights.shape != (b, d, n):
        raise ValueError(
            f"weights: expected shape {(b, d, n)} (B, D, n_basis), got {tuple(weights.shape)}"
        )
    for name, t in (("y0", y0), ("dy0", dy0), ("weights", weights)):
        if t.dtype != goal.dtype or t.device != goal.device:
            raise ValueError(
                f"{name}: expected dtype {goal.dtype} on {goal.device} like goal, "
                f"got {t.dtype} on {t.device}"
            )
    if a_z is not None:
        if not isinstance(a_z, torch.Tensor) or not a_z.is_floating_point():
            raise ValueError("a_z: expected a floating-point tensor [B], [B, 1] or [B, D]")
        if a_z.ndim == 1:
            a_z = a_z.unsqueeze(-1)
        if a_z.ndim != 2 or a_z.shape[0] != b or a_z.shape[1] not in (1, d):
            raise ValueError(f"a_z: expected shape [B], [B, 1] or [B, D], got {tuple(a_z.shape)}")
        a_z = a_z.to(goal.dtype).expand(b, d)
    return DMPInputs(goal, weights, y0, dy0, a_z)


def spring_constants(
    cfg: DMPConfig, a_z: torch.Tensor | None
) -> tuple[torch.Tensor | float, torch.Tensor | float]:
    """(a_z, b_z) of a rollout: the config's, or a per-sample a_z [B, D] with b_z = a_z / 4."""
    if a_z is None:
        return cfg.a_z, cfg.bz
    return a_z, a_z / 4.0


def recording() -> bool:
    """True while ``torch.export``, ``torch.compile`` or ``torch.jit.trace`` records the
    computation rather than running it.

    A recorded graph cannot raise a Python exception on a value it has not seen yet, so the
    finite checks (one ``bool`` of a reduction: a data-dependent branch) are left out of it, and
    the linear map enters it as a constant rather than through the process-wide cache (under
    ``torch.export`` every tensor made while tracing is a fake tensor that must not be cached).
    """
    is_compiling = getattr(torch.compiler, "is_compiling", None)  # torch >= 2.3
    tracing = torch.jit.is_tracing()  # type: ignore[attr-defined, no-untyped-call]
    return bool(tracing or (is_compiling is not None and is_compiling()))


def check_finite(**tensors: torch.Tensor | None) -> None:
    """Raise ``FloatingPointError`` naming the first tensor that holds NaN or Inf.

    Trainers call this on DMP parameters before integrating (the layer does it by default).
    """
    for name, t in tensors.items():
        if t is not None and not bool(torch.isfinite(t).all()):
            raise FloatingPointError(f"{name}: expected finite values, found NaN or Inf")


def canonical_phases(cfg: DMPConfig) -> Iterator[float]:
    """The canonical system's phase x after each of the ``cfg.steps`` Euler steps (x_0 = 1)."""
    tau, dt, a_x = cfg.tau, cfg.step_dt, cfg.a_x
    x = 1.0
    for _ in range(cfg.steps):
        x = x - a_x * x / tau * dt
        yield x


def phase_basis(
    cfg: DMPConfig,
    like: torch.Tensor,
    basis: Callable[[torch.Tensor, torch.Tensor, torch.Tensor, str], torch.Tensor] = rbf,
) -> Iterator[tuple[float, torch.Tensor]]:
    """The step loops' phase and basis values: ``(x_t, basis(x_t) [N])`` for t = 1..T, in the
    dtype and on the device of ``like`` (``basis``: :func:`ndp.dmp.basis.rbf` or
    :func:`ndp.dmp.basis.normalised_rbf`; centres and widths computed once)."""
    dtype, device = like.dtype, like.device
    c, h = basis_centres(cfg.n_basis, cfg.a_x, dtype)
    c, h = c.to(device), h.to(device)
    for x in canonical_phases(cfg):
        yield x, basis(torch.tensor(x, dtype=dtype, device=device), c, h, cfg.rbf)


def reported(cfg: DMPConfig, *series: list[torch.Tensor]) -> tuple[torch.Tensor, ...]:
    """Each per-step list (step 0..T) stacked at the reported steps (every ``subsample``-th)
    along dim 1: [B, n_out, ...]."""
    sl = slice(None, None, cfg.subsample)
    return tuple(torch.stack(s[sl], dim=1) for s in series)


# --------------------------------------------------------------------------------------------
# Reference loop
# --------------------------------------------------------------------------------------------
def dmp_rollout_reference(
    goal: torch.Tensor,
    weights: torch.Tensor | None,
    y0: torch.Tensor,
    dy0: torch.Tensor | None = None,
    cfg: DMPConfig | None = None,
    a_z: torch.Tensor | None = None,
) -> DMPTrajectory:
    """Integrate the DMP with the explicit Euler loop, step by step, as written in the paper.

    Args:
        goal: g [B, D].
        weights: w [B, D, N] (``None`` allowed with ``only_g``).
        y0: start position [B, D].
        dy0: start velocity [B, D] (``None``: zeros).
        cfg: integrator settings (default :class:`DMPConfig`).
        a_z: optional per-sample spring constant [B], [B, 1] or [B, D] (used as given; the
            layer clamps learned values); b_z is then a_z / 4.

    Returns:
        :class:`DMPTrajectory` with fields [B, steps // subsample + 1, D].
    """
    cfg = cfg or DMPConfig()
    return _reference(cfg, validate_inputs(cfg, goal, weights, y0, dy0, a_z))


def _reference(cfg: DMPConfig, inputs: DMPInputs) -> DMPTrajectory:
    goal, weights, y0, dy0, a_z_t = inputs
    az, bz = spring_constants(cfg, a_z_t)
    tau, dt = cfg.tau, cfg.step_dt
    y = y0
    z = tau * dy0
    pos, vel, acc = [y0], [dy0], [torch.zeros_like(y0)]
    for x, psi in phase_basis(cfg, goal):  # psi [N]
        if cfg.only_g:
            f = torch.zeros_like(y0)
        else:
            f = (weights @ psi) / psi.sum() * x  # [B, D]
            if cfg.scale_by_goal:
                f = f * (goal - y0)
        y, z, dz = euler_step(y, z, goal, f, az, bz, tau, dt, cfg.forcing)
        pos.append(y)
        vel.append(z / tau)
        acc.append(dz / tau)
    return DMPTrajectory(*reported(cfg, pos, vel, acc))


# --------------------------------------------------------------------------------------------
# Fast linear-map path
# --------------------------------------------------------------------------------------------
def linear_map_f64(cfg: DMPConfig, a_z: float | None = None) -> np.ndarray:
    """The rollout as a linear map of u = (v_1..v_N, g, y0, dy0), v = w * (g - y0) (or w).

    Built by running the Euler recursion on the N + 3 unit inputs at once (float64), so that
    position, velocity and acceleration at every reported step are ``u @ M``.

    Args:
        cfg: integrator settings.
        a_z: spring constant to build the map for (default ``cfg.a_z``; b_z follows cfg or a_z/4).

    Returns:
        M: [N + 3, 3 * n_out] float64, columns ordered (pos_0..pos_T, vel_0.., acc_0..).
    """
    m: np.ndarray = _linear_map_f64(cfg, None if a_z is None else float(a_z)).copy()
    return m


@functools.lru_cache(maxsize=64)
def _linear_map_f64(cfg: DMPConfig, a_z: float | None) -> np.ndarray:
    n = cfg.n_basis
    az = cfg.a_z if a_z is None else a_z
    bz = cfg.bz if a_z is None else a_z / 4.0
    tau, dt = cfg.tau, cfg.step_dt
    feats = forcing_features(cfg).numpy()  # [T, N]
    if cfg.only_g:
        feats = np.zeros_like(feats)
    # Coefficient rows of y and z on the inputs (v_1..v_N, g, y0, dy0).
    y = np.zeros(n + 3)
    z = np.zeros(n + 3)
    y[n + 1] = 1.0
    z[n + 2] = tau
    unit_g = np.zeros(n + 3)
    unit_g[n] = 1.0
    f = np.zeros(n + 3)
    pos, vel, acc = [y.copy()], [z / tau], [np.zeros(n + 3)]
    for t in range(cfg.steps):
        f[:n] = feats[t]
        y, z, dz = euler_step(y, z, unit_g, f, az, bz, tau, dt, cfg.forcing)
        pos.append(y)
        vel.append(z / tau)
        acc.append(dz / tau)
    sl = slice(None, None, cfg.subsample)
    m = np.concatenate([np.stack(pos[sl], 1), np.stack(vel[sl], 1), np.stack(acc[sl], 1)], 1)
    m.setflags(write=False)
    return m


@functools.lru_cache(maxsize=64)
def _linear_map(
    cfg: DMPConfig, a_z: float | None, device: torch.device, dtype: torch.dtype
) -> torch.Tensor:
    """The linear map as a tensor, cached per (config, device, dtype): read-only, never
    written in place (callers slice it and multiply by it)."""
    return torch.as_tensor(_linear_map_f64(cfg, a_z).copy(), dtype=dtype, device=device)


def dmp_rollout_fast(
    goal: torch.Tensor,
    weights: torch.Tensor | None,
    y0: torch.Tensor,
    dy0: torch.Tensor | None = None,
    cfg: DMPConfig | None = None,
) -> DMPTrajectory:
    """Integrate the DMP by one matrix product with the precomputed linear map.

    Same arguments and result as :func:`dmp_rollout_reference` for a fixed a_z. The returned
    fields are views of one [3, B, n_out, D]-strided buffer (call ``.contiguous()`` if needed).
    """
    cfg = cfg or DMPConfig()
    return DMPTrajectory(*_fast(cfg, validate_inputs(cfg, goal, weights, y0, dy0)))


def _map_tensor(
    cfg: DMPConfig, like: torch.Tensor, map_f64: np.ndarray | None = None
) -> torch.Tensor:
    """The linear map [N + 3, 3 * n_out] on ``like``'s device and dtype: from the cache when
    running, a graph constant when recorded (:func:`recording`; ``map_f64``: the caller's
    precomputed map, so that nothing is built from fake tensors while tracing)."""
    if recording():
        src = map_f64 if map_f64 is not None else _linear_map_f64(cfg, None)
        return torch.as_tensor(src.copy(), dtype=like.dtype, device=like.device)
    return _linear_map(cfg, None, like.device, like.dtype)


def _fast_packed(
    cfg: DMPConfig, inputs: DMPInputs, check: bool, map_f64: np.ndarray | None = None
) -> tuple[torch.Tensor, torch.Tensor, bool]:
    """(u [B * D, N + 3] packed inputs, m [N + 3, 3 * n_out] map, whether the outputs still
    need their own finite check) of the linear-map path.

    The check (``check=True``) is one reduction over the packed inputs, ``max |u|``: it is NaN
    or Inf exactly when an input (or the product w * (g - y0)) is, and it bounds every output,
    ``|(u @ m)_j| <= max |u| * max_j sum_k |m_kj|``. Below half the dtype's largest number the
    outputs are finite by construction and are not reduced again (the common case: one small
    reduction and one host sync per call); above it the outputs are checked after the product.
    While a call is recorded (:func:`recording`) the callers pass ``check=False``.
    """
    goal, weights, y0, dy0, _ = inputs
    m = _map_tensor(cfg, goal, map_f64)
    b, d = goal.shape
    n = cfg.n_basis
    if cfg.only_g:
        u = torch.stack((goal, y0, dy0), dim=-1)  # [B, D, 3]
        m = m[n:]
    else:
        v = weights * (goal - y0).unsqueeze(-1) if cfg.scale_by_goal else weights  # [B, D, N]
        u = torch.cat((v, goal.unsqueeze(-1), y0.unsqueeze(-1), dy0.unsqueeze(-1)), dim=-1)
    check_out = False
    if check and u.numel():
        peak = float(u.detach().abs().amax())
        if not math.isfinite(peak):
            # name the culprit only when something is wrong
            check_finite(goal=goal, weights=weights, y0=y0, dy0=dy0)
            raise FloatingPointError(
                f"inputs: the forcing amplitudes w * (g - y0) overflow {u.dtype} (finite goal, "
                "weights and y0 whose product is not)"
            )
        check_out = peak * _map_gain(cfg) >= 0.5 * torch.finfo(u.dtype).max
    # explicit width: B = 0 or D = 0 give empty results
    return u.reshape(b * d, u.shape[-1]), m, check_out


@functools.lru_cache(maxsize=64)
def _map_gain(cfg: DMPConfig) -> float:
    """``max_j sum_k |M_kj|`` of the whole linear map, a bound for any of its row or column
    slices: ``|(u @ M)_j| <= max |u| * gain``."""
    return float(np.abs(_linear_map_f64(cfg, None)).sum(axis=0).max())


def _fast(
    cfg: DMPConfig,
    inputs: DMPInputs,
    check: bool = False,
    map_f64: np.ndarray | None = None,
    parts: int = 3,
) -> tuple[torch.Tensor, ...]:
    """The linear-map path's first ``parts`` outputs (3: positions, velocities and
    accelerations; 1: positions only, one third of the map), each [B, n_out, D]."""
    u, m, check_out = _fast_packed(cfg, inputs, check, map_f64)
    b, d = inputs.goal.shape
    n = cfg.n_out
    out = (u @ m[:, : parts * n]).view(b, d, parts, n).permute(2, 0, 3, 1)
    if check_out:
        _check_outputs(out)
    return tuple(out.unbind(0))


def _check_outputs(out: torch.Tensor) -> None:
    """Finite inputs can still overflow (huge weights in float32): one reduction over the
    outputs, a one-line error when it is not finite."""
    if not bool(torch.isfinite(out).all()):
        raise FloatingPointError(
            "outputs: the rollout is not finite although its inputs are (goal / weights too "
            f"large for {out.dtype}); scale the inputs down or use float64"
        )


def dmp_rollout(
    goal: torch.Tensor,
    weights: torch.Tensor | None,
    y0: torch.Tensor,
    dy0: torch.Tensor | None = None,
    cfg: DMPConfig | None = None,
    a_z: torch.Tensor | None = None,
    method: str = "auto",
    check: bool = False,
    *,
    linear_map: np.ndarray | None = None,
) -> DMPTrajectory:
    """Integrate a batch of DMPs (pure function).

    Args:
        goal: g [B, D].
        weights: w [B, D, N] (``None`` allowed with ``cfg.only_g``).
        y0: start position [B, D].
        dy0: start velocity [B, D] (``None``: zeros).
        cfg: integrator settings (default :class:`DMPConfig`).
        a_z: optional per-sample spring constant [B], [B, 1] or [B, D]; requires
            ``cfg.learn_az`` and is clamped to ``cfg.az_range``.
        method: 'auto' (fast path unless a_z is per-sample), 'fast' or 'loop'.
        check: raise ``FloatingPointError`` if any input holds NaN or Inf (not while the call
            is recorded by ``torch.export`` / ``torch.jit.trace``: :func:`recording`, nor on
            the meta device, whose tensors hold no values: there the call infers shapes).
        linear_map: ``linear_map_f64(cfg)``, precomputed by the caller (``DMPLayer`` holds
            its own, so that ``torch.export`` never has to build it while tracing); None: the
            process-wide cache.

    Returns:
        :class:`DMPTrajectory`, each field [B, steps // subsample + 1, D].
    """
    cfg = cfg or DMPConfig()
    if method not in ("auto", "fast", "loop"):
        raise ValueError(f"method: expected 'auto', 'fast' or 'loop', got {method!r}")
    if cfg.learn_az and a_z is None:
        raise ValueError("a_z: expected a per-sample tensor because cfg.learn_az is True")
    if not cfg.learn_az and a_z is not None:
        raise ValueError("a_z: per-sample a_z given but cfg.learn_az is False")
    inputs = validate_inputs(cfg, goal, weights, y0, dy0, a_z)
    check = check and not recording() and not inputs.goal.is_meta
    loop = cfg.learn_az or method == "loop"
    if check and loop:
        check_finite(**inputs._asdict())
    if not loop:
        return DMPTrajectory(*_fast(cfg, inputs, check, linear_map))
    if method == "fast":
        raise ValueError("method: 'fast' needs a fixed a_z; use 'loop' or 'auto' with learn_az")
    if inputs.a_z is not None:  # learn_az: clamped to its range
        inputs = inputs._replace(a_z=inputs.a_z.clamp(*cfg.az_range))
    traj = _reference(cfg, inputs)
    if check:
        _check_outputs(traj.pos)
    return traj


def dmp_positions(
    goal: torch.Tensor,
    weights: torch.Tensor | None,
    y0: torch.Tensor,
    dy0: torch.Tensor | None = None,
    cfg: DMPConfig | None = None,
    check: bool = False,
    *,
    linear_map: np.ndarray | None = None,
) -> torch.Tensor:
    """Positions only, [B, steps // subsample + 1, D], of a fixed-a_z DMP (one third of the
    linear map: for callers that need no velocities or accelerations, e.g. the RL head);
    ``check`` and ``linear_map`` as for :func:`dmp_rollout`."""
    cfg = cfg or DMPConfig()
    if cfg.learn_az:
        raise ValueError("cfg: dmp_positions needs a fixed a_z (learn_az False)")
    inputs = validate_inputs(cfg, goal, weights, y0, dy0)
    check = check and not recording() and not inputs.goal.is_meta
    return _fast(cfg, inputs, check, linear_map, parts=1)[0]
