"""Action heads: the ONE place where PPO, PPO-multi and NDP differ.

A head turns the actor's last-layer output ``raw`` [B, P] (and, for NDP, the robot's physical
state) into an exploration distribution over the k sub-actions of a decision [B, k, A]:

- :class:`StepHead` (PPO): P = A, k = 1, the raw output is the action mean.
- :class:`MultiHead` (PPO-multi): P = k * A, the raw output is k action means.
- :class:`ChunkBasisHead` (PPO-multi with ``--chunk-basis``): P = A (1 + N), each action
  dimension's k means restricted to a fixed basis (``ndp.policies.chunk_basis``).
- :class:`NDPHead`: P = D (1 + N) DMP parameters per decision. Goal and weights are bounded,

      g = y0 + goal_scale * tanh(raw_g)                     (delta DoF, e.g. the hand's xyz)
      g = centre + half_range * tanh(raw_g)                 (absolute DoF, e.g. the gripper)
      w = weight_scale * tanh(raw_w)                        (per DoF, see ``forcing``)

  (``param_map='tanh'``, the default; ``'linear'`` drops the tanh, ``'whitened'`` also applies
  a fixed transform W to the raw outputs first: :class:`NDPHead`, docs/rl.md),

  the DMP is integrated from the robot state (y0, dy0; the commanded target by default, see
  ``PolicyConfig.dmp_state``) over one decision, the trajectory [B, k + 1, D] is cut at the k
  sub-step boundaries and the task's inverse controller maps it to the k sub-action means
  [B, k, A]. The means are NOT clipped (``mean_clip`` restores the first release's clip): only
  the executed sample is, as for PPO. Absolute-command DoF with ``absolute_mode='direct'`` take
  the goal itself as the command of all k sub-steps (their y0 is the previous decision's
  *sampled* command, which the actor does not observe).

Clocks (named once): an env step (sub-step) lasts ``control_dt`` s; a decision runs k sub-steps,
i.e. ``decision_dt = k * control_dt`` s; the DMP rollout spans DMP time tau = 1 with
``dmp_steps`` Euler steps, reported every ``dmp_steps / k`` steps (one point per sub-step). A
physical velocity v (units/s) is therefore ``v * decision_dt / tau`` in DMP time units.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import torch
from numpy.typing import ArrayLike
from torch import nn

from ndp.dmp import DMPConfig, DMPLayer
from ndp.dmp.controllers import DeltaController
from ndp.dmp.integrate import _linear_map_f64, check_finite, recording
from ndp.policies import chunk_basis
from ndp.policies.base import HEAD_BUILDERS as HEAD_BUILDERS  # the registry, re-exported:
from ndp.policies.base import SINGLE_STEP_HEADS as SINGLE_STEP_HEADS  # importing this module
from ndp.policies.base import (  # registers every built-in head first
    ActionHead,
    HeadOutput,
    decision_k,
)
from ndp.policies.base import register_head as register_head
from ndp.policies.conditioning import raw_jacobian, whitening_transform
from ndp.policies.distributions import ParamGaussian, SubActionGaussian, scalar_like
from ndp.policies.dyne import DyneHead  # Dyn-E: latent -> frozen decoder -> k actions
from ndp.policies.squashed import SquashedActionHead as SquashedActionHead  # the SAC family's
from ndp.policies.squashed import SquashedNDPHead as SquashedNDPHead  # heads, registered there

if TYPE_CHECKING:
    from ndp.policies.config import PolicyConfig
    from ndp.schema import TaskSchema


class _RawActionHead(ActionHead):
    """A head whose actor outputs raw actions: k sub-steps, ``n_params`` outputs, and a learned,
    state-independent log std [A] shared by the sub-steps."""

    def __init__(self, k: int, action_dim: int, n_params: int, init_log_std: float) -> None:
        super().__init__()
        self.k = int(k)
        self.action_dim = int(action_dim)
        self.n_params = int(n_params)
        self.log_std = nn.Parameter(torch.full((self.action_dim,), float(init_log_std)))


class StepHead(_RawActionHead):
    """PPO: one raw action per decision (k = 1), Gaussian with learned log std [A]."""

    def __init__(self, action_dim: int, init_log_std: float = 0.0) -> None:
        super().__init__(1, action_dim, action_dim, init_log_std)

    def distribution(
        self, raw: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> HeadOutput:
        return SubActionGaussian(raw.view(raw.shape[0], 1, self.action_dim), self.log_std), {}


class MultiHead(_RawActionHead):
    """PPO-multi: k raw actions per decision, each a Gaussian with the shared log std [A]."""

    def __init__(self, k: int, action_dim: int, init_log_std: float = 0.0) -> None:
        super().__init__(k, action_dim, int(k) * int(action_dim), init_log_std)

    def distribution(
        self, raw: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> HeadOutput:
        mean = raw.view(raw.shape[0], self.k, self.action_dim)
        return SubActionGaussian(mean, self.log_std), {}


class ChunkBasisHead(_RawActionHead):
    """PPO-multi with each action dimension's chunk restricted to a fixed basis.

    For action dimension a the actor outputs c_a [P] (``raw`` [B, A * P], c_a contiguous) and
    the k sub-action means are

        m[:, a] = basis[a] @ c_a + offset[:, a] (+ offset_y0[:, a] y0_a + offset_dy0[:, a] dy0_a)

    the state-dependent terms for the ``dmp`` basis only (:attr:`needs_robot_state`). The
    exploration is :class:`MultiHead`'s: a Gaussian around each sub-action with the shared
    learned log std [A]. The basis and offsets are persistent buffers (saved in checkpoints and
    exports, restored by ``load_policy``); a basis of NaN (a ``pca`` head built without its
    file) must be loaded from a state dict before the head acts.

    Args:
        k: sub-steps per decision.
        action_dim: A.
        kind: the basis' name (``ndp.policies.config.CHUNK_BASES``, not 'none').
        basis: [A, k, P].
        offset, offset_y0, offset_dy0: [k, A] (zeros where None).
        init_log_std: initial log std.
    """

    basis: torch.Tensor
    offset: torch.Tensor
    offset_y0: torch.Tensor
    offset_dy0: torch.Tensor

    def __init__(
        self,
        k: int,
        action_dim: int,
        kind: str,
        basis: torch.Tensor,
        offset: torch.Tensor | None = None,
        offset_y0: torch.Tensor | None = None,
        offset_dy0: torch.Tensor | None = None,
        init_log_std: float = 0.0,
    ) -> None:
        b = torch.as_tensor(basis, dtype=torch.float32)
        if b.ndim != 3 or tuple(b.shape[:2]) != (int(action_dim), int(k)):
            raise ValueError(f"basis: expected [A={action_dim}, k={k}, P], got {list(b.shape)}")
        super().__init__(k, action_dim, int(action_dim) * int(b.shape[2]), init_log_std)
        self.kind = str(kind)
        self.columns = int(b.shape[2])
        self.needs_robot_state = self.kind == "dmp"
        self.register_buffer("basis", b.clone())
        for name, value in (("offset", offset), ("offset_y0", offset_y0),
                            ("offset_dy0", offset_dy0)):  # fmt: skip
            t = torch.zeros(self.k, self.action_dim) if value is None else torch.as_tensor(value)
            if tuple(t.shape) != (self.k, self.action_dim):
                raise ValueError(
                    f"{name}: expected [k={self.k}, A={self.action_dim}], got {list(t.shape)}"
                )
            self.register_buffer(name, t.to(torch.float32).clone())
        self._has_basis = bool(torch.isfinite(self.basis).all())

    def _load_from_state_dict(
        self, state_dict: dict[str, object], prefix: str, *args: object, **kwargs: object
    ) -> None:
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)
        self._has_basis = bool(torch.isfinite(self.basis).all())

    def means(
        self, raw: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> torch.Tensor:
        """The k sub-action means [B, k, A] of raw outputs [B, A * P] (and the robot state
        y0, dy0 [B, A], physical, for the ``dmp`` basis)."""
        if not self._has_basis:
            raise ValueError(
                f"chunk_basis: the {self.kind!r} head holds no basis (its file was not read "
                "and no checkpoint set it); load the run's state or give chunk_basis_file"
            )
        c = raw.reshape(raw.shape[0], self.action_dim, self.columns).transpose(0, 1)  # [A, B, P]
        mean = torch.bmm(c, self.basis.transpose(1, 2)).permute(1, 2, 0) + self.offset
        if self.needs_robot_state:
            if y0 is None or dy0 is None:
                raise ValueError("ChunkBasisHead: the 'dmp' basis needs the robot state y0, dy0")
            mean = mean + y0.unsqueeze(1) * self.offset_y0 + dy0.unsqueeze(1) * self.offset_dy0
        return mean

    def distribution(
        self, raw: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> HeadOutput:
        return SubActionGaussian(self.means(raw, y0, dy0), self.log_std), {}

    def extra_repr(self) -> str:
        return f"kind={self.kind!r}, k={self.k}, A={self.action_dim}, P={self.columns}"


PARAM_MAPS = ("tanh", "linear", "whitened")
"""How the NDP head maps its raw outputs to the goal and forcing weights (the same tuple as
``ndp.policies.config.PARAM_MAPS``, which the config validates against without torch)."""


DERIVED_BUFFERS = (
    "goal_scale",
    "absolute_goal",
    "goal_center",
    "weight_scale",
    "direct",
    "action_map",
    "action_low",
    "action_high",
)
"""NDPHead buffers computed from the config and the task: not saved, ignored when loading
(checkpoints of earlier versions saved some of them)."""


def _check_head_args(k: int, dmp: DMPConfig, param_map: str) -> None:
    """Refuse an unknown ``param_map``, a whitened map on a nonlinear DMP or a DMP config
    whose reported grid does not give ``k`` points."""
    if param_map not in PARAM_MAPS:
        raise ValueError(f"param_map: expected one of {', '.join(PARAM_MAPS)}, got {param_map!r}")
    if param_map == "whitened" and (dmp.learn_az or dmp.scale_by_goal):
        raise ValueError(
            "param_map: 'whitened' needs a fixed a_z and 'amplitude' forcing (the map must be "
            f"linear in the raw outputs), got learn_az={dmp.learn_az}, "
            f"forcing={'goal' if dmp.scale_by_goal else 'amplitude'}"
        )
    if dmp.steps // dmp.subsample != k or dmp.steps % dmp.subsample:
        raise ValueError(
            f"dmp: steps/subsample must give k={k} points, got steps={dmp.steps}, "
            f"subsample={dmp.subsample}"
        )


class NDPHead(ActionHead):
    """NDP: DMP parameters -> DMP layer from the robot state -> inverse controller -> k actions.

    Args:
        k: sub-steps per decision.
        dmp_dofs: D, DoF driven by the DMP.
        action_dim: A, env action size.
        dmp: integrator settings; ``dmp.steps // dmp.subsample`` must equal k.
        goal_scale: goal bound per DoF [D] or scalar (physical units).
        weight_scale: forcing-weight bound per DoF [D] or scalar.
        inverse_controller: trajectory [B, k + 1, D] (physical) -> actions [B, k, A].
        decision_dt: seconds per decision (k * control_dt), to convert dy0 to DMP time.
        param_noise: explore in parameter space (one log-prob per decision).
        init_log_std: initial log std (of the sub-actions, or of the raw parameters).
        goal_center: [D] fixed goal centre per DoF (absolute-command DoF: goal = centre +
            goal_scale * tanh(raw), dy0 = 0), NaN (or None for all) where the goal is relative
            to y0.
        mean_clip: clip the sub-action means to the action bounds (the first release's form).
        direct: [D] bool, DoF whose command is the goal itself for all k sub-steps (no DMP).
        start_at_rest: integrate every DoF from dy0 = 0 (the given dy0 is ignored).
        linear_controller: ``(scale [D], absolute [D], low [D], high [D])`` when
            ``inverse_controller`` is the standard linear one (action = delta / scale, or the
            value itself; A = D): the DMP, the inverse controller and ``direct`` then fold into
            one precomputed map per DoF (:meth:`decode` uses it; :meth:`decode_reference` is
            the composed form, equal in value and gradient, tested).
        param_map: how the raw outputs become the goal and weights (``u``: the first
            ``D + D N`` raw outputs; a learned a_z's output is mapped as always):

            - ``'tanh'`` (default): ``g - y0 = goal_scale * tanh(u_g)`` (absolute DoF: ``g -
              centre``), ``w = weight_scale * tanh(u_w)``: bounded parameters;
            - ``'linear'``: the same without the tanh, ``g - y0 = goal_scale * u_g``, ``w =
              weight_scale * u_w`` (the same Jacobian at raw = 0); only the executed sample is
              clipped to the action bounds (and the means with ``mean_clip``), as PPO-multi's;
            - ``'whitened'``: ``'linear'`` after a fixed transform, ``u = W raw``, with ``W``
              [D + D N, D + D N] (:func:`ndp.policies.conditioning.whitening_transform`) of the
              ``'linear'`` map's Jacobian of the k sub-action means at raw = 0, y0 = dy0 = 0 (the
              map is affine in (raw, y0, dy0) with 'amplitude' forcing, so the Jacobian and W
              are the same at every start): unit noise in raw space is unit noise over the
              chunk's reachable directions. W is a buffer (``whitening``, float64) saved in
              checkpoints and exports, computed once here and then loaded, never recomputed.
              Needs 'amplitude' forcing (``dmp.scale_by_goal`` False; with 'goal' forcing the
              weights' columns vanish at raw = 0) and a fixed a_z. Composed with the linear map,
              not with tanh: an elementwise bound after W would make the map's slopes depend on
              the raw outputs again, so the whitening would hold at raw = 0 only; without it J
              is ``J_map W`` at every raw output and state.
    """

    needs_robot_state = True

    # buffers registered in __init__ (the action_* three only with a linear controller)
    goal_scale: torch.Tensor
    absolute_goal: torch.Tensor
    goal_center: torch.Tensor
    weight_scale: torch.Tensor
    direct: torch.Tensor
    action_map: torch.Tensor
    action_low: torch.Tensor
    action_high: torch.Tensor
    whitening: torch.Tensor  # param_map 'whitened' only

    def __init__(
        self,
        k: int,
        dmp_dofs: int,
        action_dim: int,
        dmp: DMPConfig,
        goal_scale: float | torch.Tensor,
        weight_scale: float | torch.Tensor,
        inverse_controller: Callable[..., torch.Tensor],
        decision_dt: float,
        param_noise: bool = False,
        init_log_std: float = 0.0,
        goal_center: torch.Tensor | None = None,
        mean_clip: bool = False,
        direct: torch.Tensor | None = None,
        start_at_rest: bool = False,
        linear_controller: tuple[torch.Tensor, ...] | None = None,
        param_map: str = "tanh",
    ) -> None:
        super().__init__()
        _check_head_args(k, dmp, param_map)
        self.k = int(k)
        self.dmp_dofs = int(dmp_dofs)
        self.action_dim = int(action_dim)
        self.n_basis = dmp.n_basis
        # only-g (the supplement's ablation): no forcing term, the network outputs goals only;
        # a learned a_z: one more output per decision, a_z in dmp.az_range (b_z = a_z / 4)
        self.only_g = bool(dmp.only_g)
        self.learn_az = bool(dmp.learn_az)
        n_w = 0 if self.only_g else self.dmp_dofs * self.n_basis
        self.n_params = self.dmp_dofs + n_w + (1 if self.learn_az else 0)
        self.dmp = DMPLayer(dmp)
        if self.learn_az:
            lo, hi = dmp.az_range
            frac = min(max((dmp.a_z - lo) / (hi - lo), 1e-3), 1 - 1e-3)
            self._az_offset = math.log(frac / (1.0 - frac))  # raw 0 gives the preset a_z
        self._register_scales(goal_scale, weight_scale, goal_center, direct)
        self.mean_clip = bool(mean_clip)
        self.start_at_rest = bool(start_at_rest)
        self.inverse_controller = inverse_controller
        self.decision_dt = float(decision_dt)
        self.param_noise = bool(param_noise)
        n_std = self.n_params if self.param_noise else self.action_dim
        self.log_std = nn.Parameter(torch.full((n_std,), float(init_log_std)))
        self._fused = (
            linear_controller is not None
            and self.action_dim == self.dmp_dofs
            and not self.learn_az  # the folded map is built for one a_z
        )
        if self._fused:
            assert linear_controller is not None
            scale, absolute, low, high = (torch.as_tensor(x) for x in linear_controller)
            self.register_buffer(
                "action_map", self._action_map(scale, absolute.bool()), persistent=False
            )
            self.register_buffer("action_low", low.to(torch.float32).clone(), persistent=False)
            self.register_buffer("action_high", high.to(torch.float32).clone(), persistent=False)
        self.param_map = "linear" if param_map == "whitened" else param_map
        # decode's no-autograd form (_decode_no_grad): the fused map, bounds of goal and weights
        self._fast_ok = self._fused and not self.only_g and param_map != "whitened"
        self._no_grad_cache: tuple[tuple[object, ...], tuple[torch.Tensor, ...]] | None = None
        self.n_mapped = self.dmp_dofs + n_w  # the raw outputs that become g and w (D + D N)
        self.whitening_rank = 0
        if param_map == "whitened":  # computed once on the linear map, then a saved buffer
            w, self.whitening_rank = whitening_transform(self._map_jacobian_at_rest())
            self.register_buffer("whitening", w)
            self.param_map = "whitened"

    def _register_scales(
        self,
        goal_scale: float | torch.Tensor,
        weight_scale: float | torch.Tensor,
        goal_center: torch.Tensor | None,
        direct: torch.Tensor | None,
    ) -> None:
        """Register the per-DoF buffers goal_scale, absolute_goal, goal_center, weight_scale
        and direct (non-persistent: derived from the arguments)."""
        gs = torch.as_tensor(goal_scale, dtype=torch.float32).expand(self.dmp_dofs).clone()
        self.register_buffer("goal_scale", gs, persistent=False)
        # DoF with a fixed goal centre (absolute commands) ignore y0 and dy0 for the goal.
        centre = (
            torch.full((self.dmp_dofs,), float("nan"))
            if goal_center is None
            else (torch.as_tensor(goal_center, dtype=torch.float32).clone())
        )
        # NaN centre: a goal relative to y0
        self.register_buffer("absolute_goal", ~torch.isnan(centre), persistent=False)
        self.register_buffer("goal_center", centre.nan_to_num(), persistent=False)
        ws = torch.as_tensor(weight_scale, dtype=torch.float32).expand(self.dmp_dofs).clone()
        self.register_buffer("weight_scale", ws, persistent=False)
        direct_t = (
            torch.zeros(self.dmp_dofs, dtype=torch.bool)
            if direct is None
            else (torch.as_tensor(direct, dtype=torch.bool).clone())
        )
        self.register_buffer("direct", direct_t, persistent=False)
        self._any_direct = bool(direct_t.any())
        self._any_absolute = bool(self.absolute_goal.any())

    def _load_from_state_dict(
        self, state_dict: dict[str, object], prefix: str, *args: object, **kwargs: object
    ) -> None:
        for name in DERIVED_BUFFERS:  # derived, not state: older checkpoints held some of them
            state_dict.pop(prefix + name, None)
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)

    def _action_map(self, scale: torch.Tensor, absolute: torch.Tensor) -> torch.Tensor:
        """Per DoF, the map [D, N + 3, k] from (w, g, y0, dy0) to the k sub-action means."""
        cfg = self.dmp.config
        n, k = cfg.n_basis, self.k
        pos = torch.as_tensor(_linear_map_f64(cfg, None)[:, : cfg.n_out].copy())  # [N+3, k+1]
        maps = []
        for d in range(self.dmp_dofs):
            if bool(self.direct[d]):
                m = torch.zeros(n + 3, k, dtype=torch.float64)
                m[n] = 1.0  # the goal, at every sub-step
            elif bool(absolute[d]):
                m = pos[:, 1:]  # the trajectory value itself
            else:
                m = (pos[:, 1:] - pos[:, :-1]) / float(scale[d])  # consecutive differences
            maps.append(m)
        return torch.stack(maps).to(torch.float32)

    def _map_jacobian_at_rest(self) -> torch.Tensor:
        """The linear map's Jacobian [k A, D + D N] of the sub-action means w.r.t. the bounded
        raw outputs at raw = 0, y0 = dy0 = 0, in float64 (a float64 copy of this head)."""
        twin = copy.deepcopy(self).double()
        zero = torch.zeros(1, self.n_params, dtype=torch.float64, device=self.goal_scale.device)
        state = torch.zeros(1, self.dmp_dofs, dtype=torch.float64, device=zero.device)
        jac = raw_jacobian(lambda r: twin.decode(r, state, state)[0], zero)[0]
        return jac[:, : self.n_mapped]

    def _bound(self, x: torch.Tensor) -> torch.Tensor:
        """The elementwise bound of the goal / weight outputs: tanh, or none."""
        return torch.tanh(x) if self.param_map == "tanh" else x

    def _whiten(self, raw: torch.Tensor) -> torch.Tensor:
        """``'whitened'``: the raw outputs [B, P] with ``W`` applied to the first
        ``D + D N``; the others as they are."""
        n = self.n_mapped
        u = raw[:, :n] @ self.whitening.to(raw.dtype).T
        return torch.cat((u, raw[:, n:]), dim=-1) if raw.shape[1] > n else u

    def unit_params(self, raw: torch.Tensor) -> torch.Tensor:
        """The raw outputs [B, P] as the ``'linear'`` map would take them to give the same
        goal and weights: ``tanh(raw)`` in the first ``D + D N`` for ``'tanh'``, ``W raw`` for
        ``'whitened'``, ``raw`` for ``'linear'`` (a learned a_z's output unchanged)."""
        if self.param_map == "whitened":
            return self._whiten(raw)
        n = self.n_mapped
        return torch.cat((self._bound(raw[:, :n]), raw[:, n:]), dim=-1)

    def raw_jacobians(
        self, raw: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The Jacobians of the k sub-action means of each decision, in float64 (on a copy).

        Args:
            raw: [B, P] raw outputs; y0, dy0: [B, D] the robot state (physical units).

        Returns:
            ``(J, J_map)``, each [B, k A, P] (rows sub-step major: ``j * A + a``): ``J = d
            means / d raw``, and ``J_map`` the same map's Jacobian w.r.t. :meth:`unit_params`
            (the ``'linear'`` map at ``unit_params(raw)``: the tanh slopes replaced by 1, W
            left out), so that ``J = J_map diag(1 - tanh(raw)^2)`` ('tanh', on the first ``D +
            D N`` columns), ``J_map W`` ('whitened') or ``J_map`` ('linear').
        """
        twin = copy.deepcopy(self).double()
        dev = twin.goal_scale.device
        r, s0, s1 = (t.detach().to(dev, torch.float64) for t in (raw, y0, dy0))
        jac = raw_jacobian(lambda x: twin.decode(x, s0, s1)[0], r)
        unit = twin.unit_params(r).detach()
        twin.param_map = "linear"
        map_jac = raw_jacobian(lambda x: twin.decode(x, s0, s1)[0], unit)
        return jac, map_jac

    def _goal_weights_dy0(
        self, raw: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor, bounded: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        b, d = raw.shape[0], self.dmp_dofs
        if self.param_map == "whitened":
            raw = self._whiten(raw)
        squash = self._bound if bounded else _identity
        step = self.goal_scale * squash(raw[:, :d])
        goal = torch.where(self.absolute_goal, self.goal_center + step, y0 + step)
        if self.only_g:
            weights = raw.new_zeros(b, d, self.n_basis)
        else:
            weights = self.weight_scale.unsqueeze(-1) * squash(
                raw[:, d : d + d * self.n_basis].reshape(b, d, self.n_basis)
            )
        if self.start_at_rest:
            dy0_dmp = torch.zeros_like(y0)
        else:
            dy0_dmp = torch.where(
                self.absolute_goal, 0.0, dy0 * (self.decision_dt / self.dmp.config.tau)
            )
        return goal, weights, dy0_dmp

    def a_z_of(self, raw: torch.Tensor) -> torch.Tensor:
        """The learned spring constant [B] of each decision (``learn_az``): the last raw output
        through a sigmoid onto ``az_range`` (0 gives the configured a_z)."""
        lo, hi = self.dmp.config.az_range
        return lo + (hi - lo) * torch.sigmoid(raw[:, -1] + self._az_offset)

    def decode(
        self, raw: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor, bounded: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Raw parameters [B, P] and robot state (physical, [B, D]) -> (actions [B, k, A],
        goal [B, D], weights [B, D, N]).

        ``bounded=False`` removes the tanh bounds: ``raw`` takes the place of ``tanh(raw)``
        (g = y0 + goal_scale * raw_g, w = weight_scale * raw_w, ...), which makes the actions
        an affine function of ``raw`` for a fixed robot state (:meth:`affine_parts`; the
        ``dmp`` chunk basis of PPO-multi)."""
        if not self._fused:
            return self.decode_reference(raw, y0, dy0, bounded)
        if self._fast_ok and not torch.is_grad_enabled() and not recording():
            return self._decode_no_grad(raw, y0, dy0, bounded)
        goal, weights, dy0_dmp = self._goal_weights_dy0(raw, y0, dy0, bounded)
        cfg = self.dmp.config
        v = weights * (goal - y0).unsqueeze(-1) if cfg.scale_by_goal else weights
        u = torch.cat((v, torch.stack((goal, y0, dy0_dmp), dim=-1)), dim=-1)  # [B, D, N + 3]
        if self.dmp.check_finite and not recording() and not bool(torch.isfinite(u.sum())):
            check_finite(goal=goal, weights=weights, y0=y0, dy0=dy0_dmp)
            raise FloatingPointError("inputs: expected finite values, their sum overflows")
        actions = torch.bmm(u.transpose(0, 1), self.action_map).permute(1, 2, 0)  # [B, k, D]
        if self.mean_clip:
            actions = torch.maximum(torch.minimum(actions, self.action_high), self.action_low)
        return actions, goal, weights

    def _decode_no_grad(
        self, raw: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor, bounded: bool
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """:meth:`decode`'s fused map without autograd (rollouts): the same elementwise
        operations on the same values, fewer of them (one bound and one scale for goal and
        weights, the absolute goals' centre chosen before the one addition); equal bits."""
        d, n = self.dmp_dofs, self.n_basis
        scale, absolute, centre, action_map = self._no_grad_constants()
        p = raw[:, : d + d * n]
        gw = (torch.tanh(p) if bounded and self.param_map == "tanh" else p) * scale
        base = torch.where(absolute, centre, y0) if self._any_absolute else y0
        goal = base + gw[:, :d]
        weights = gw[:, d:].view(raw.shape[0], d, n)
        if self.start_at_rest:
            dy0_dmp = torch.zeros_like(y0)
        else:
            dy0_dmp = dy0 * scalar_like(self.decision_dt / self.dmp.config.tau, dy0)
            if self._any_absolute:
                dy0_dmp = dy0_dmp.masked_fill_(absolute, 0.0)
        v = weights * (goal - y0).unsqueeze(-1) if self.dmp.config.scale_by_goal else weights
        state = (goal.unsqueeze(-1), y0.unsqueeze(-1), dy0_dmp.unsqueeze(-1))
        u = torch.cat((v, *state), dim=-1)  # [B, D, N + 3]
        if self.dmp.check_finite and not math.isfinite(float(u.sum())):
            check_finite(goal=goal, weights=weights, y0=y0, dy0=dy0_dmp)
            raise FloatingPointError("inputs: expected finite values, their sum overflows")
        actions = torch.bmm(u.transpose(0, 1), action_map).permute(1, 2, 0)  # [B, k, D]
        if self.mean_clip:
            actions = torch.maximum(torch.minimum(actions, self.action_high), self.action_low)
        return actions, goal, weights

    def _no_grad_constants(self) -> tuple[torch.Tensor, ...]:
        """``(scale [D + D N]`` (goal_scale, then each DoF's weight_scale N times),
        ``absolute_goal, goal_center, action_map)``, rebuilt when a buffer is replaced
        (``.to``, ``.double``)."""
        bufs = self._buffers
        names = ("goal_scale", "weight_scale", "absolute_goal", "goal_center", "action_map")
        key = tuple(bufs[name] for name in names)
        cached = self._no_grad_cache
        if cached is None or any(a is not b for a, b in zip(cached[0], key, strict=True)):
            scale = torch.cat((self.goal_scale, self.weight_scale.repeat_interleave(self.n_basis)))
            consts = (scale, self.absolute_goal, self.goal_center, self.action_map)
            cached = self._no_grad_cache = (key, consts)
        return cached[1]

    def decode_reference(
        self, raw: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor, bounded: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """:meth:`decode` composed step by step: DMP layer, then the inverse controller."""
        goal, weights, dy0_dmp = self._goal_weights_dy0(raw, y0, dy0, bounded)
        if self.learn_az:
            traj = self.dmp(goal, weights, y0, dy0_dmp, a_z=self.a_z_of(raw)).pos
        else:
            traj = self.dmp.positions(goal, weights, y0, dy0_dmp)  # [B, k + 1, D]; [:, 0] = y0
        if self._any_direct:  # the goal is the command of every sub-step
            traj = torch.where(self.direct, goal.unsqueeze(1), traj)
        actions = self.inverse_controller(traj, clip=self.mean_clip)  # [B, k, A]
        return actions, goal, weights

    def affine_parts(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """:meth:`decode` without the tanh bounds as an affine map per DoF (the ``dmp`` chunk
        basis of PPO-multi, ``ChunkBasisHead``).

        For a fixed start state the DMP is linear in (g, w) (forcing 'amplitude'), so with the
        bounds removed (``decode(raw, y0, dy0, bounded=False)``) the k sub-action means of DoF d
        are, exactly,

            m[:, d] = basis[d] @ c_d + offset[:, d] + offset_y0[:, d] y0_d + offset_dy0[:, d] dy0_d

        with c_d = (raw goal of d, its N raw weights) [1 + N]. Computed by probing
        :meth:`decode` (``bounded=False``) of a float64 copy of this head: the offset at
        raw = 0 and (y0, dy0) = 0, then one unit input at a time (every raw output, every y0_d,
        every dy0_d); each unit input may move its own DoF's actions only, and a random batch
        must match the assembled map (relative 1e-9), else the head is refused.

        Returns:
            float64 ``(basis [D, k, 1 + N], offset [k, D], offset_y0 [k, D], offset_dy0
            [k, D])``; y0 and dy0 in the physical units the head takes (dy0 per second).

        Raises:
            ValueError: a head that is not affine per DoF: ``learn_az``, ``only_g``,
                ``mean_clip``, forcing 'goal' (w multiplies g - y0), A != D, or a probe that
                moves another DoF or a random batch off the affine map.
        """
        self._refuse_non_affine()
        head = copy.deepcopy(self).to(torch.float64).eval()
        d, n, k = self.dmp_dofs, self.n_basis, self.k
        p = 1 + n
        zeros = torch.zeros(1, d, dtype=torch.float64)

        def run(raw: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor) -> torch.Tensor:
            with torch.no_grad():
                return head.decode(raw, y0, dy0, bounded=False)[0]  # [B, k, A]

        base = run(torch.zeros(1, self.n_params, dtype=torch.float64), zeros, zeros)[0]
        eye_raw, eye_d = (torch.eye(m, dtype=torch.float64) for m in (self.n_params, d))
        no_raw, no_state = torch.zeros_like(eye_raw[:d]), torch.zeros_like(eye_d)
        at_zero = zeros.expand(self.n_params, d)
        j_raw = run(eye_raw, at_zero, at_zero) - base  # [n_params, k, A]
        j_y0 = run(no_raw, eye_d, no_state) - base  # [D, k, A]
        j_dy0 = run(no_raw, no_state, eye_d) - base
        basis = torch.zeros(d, k, p, dtype=torch.float64)
        own = torch.zeros(self.n_params, d, dtype=torch.bool)  # which DoF each raw output moves
        for dof in range(d):
            for col in range(p):
                idx = dof if col == 0 else d + dof * n + col - 1
                basis[dof, :, col] = j_raw[idx, :, dof]
                own[idx, dof] = True
        _check_per_dof(j_raw, j_y0, j_dy0, own)
        offset_y0 = torch.diagonal(j_y0, dim1=0, dim2=2)  # [k, D]
        offset_dy0 = torch.diagonal(j_dy0, dim1=0, dim2=2)
        _check_affine(run, (basis, base, offset_y0, offset_dy0), self.n_params)
        return basis, base, offset_y0, offset_dy0

    def _refuse_non_affine(self) -> None:
        """Refuse (ValueError naming the reasons) a head whose chunk is not affine per DoF."""
        cfg = self.dmp.config
        why = [
            name
            for name, bad in (
                ("learn_az", self.learn_az),
                ("only_g", self.only_g),
                ("mean_clip", self.mean_clip),
                ("forcing='goal'", cfg.scale_by_goal),
                (f"action_dim {self.action_dim} != dmp_dofs {self.dmp_dofs}",
                 self.action_dim != self.dmp_dofs),
            )
            if bad
        ]  # fmt: skip
        if why:
            raise ValueError(
                f"head: the NDP head's chunk is not affine per DoF in (g, w) with {', '.join(why)}"
            )

    def distribution(
        self, raw: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> HeadOutput:
        if y0 is None or dy0 is None:
            raise ValueError("NDPHead: the robot state y0, dy0 [B, D] is required")
        mean_actions, goal, weights = self.decode(raw, y0, dy0)
        aux: dict[str, torch.Tensor] = {}
        if not torch.is_grad_enabled():  # diagnostics of rollouts only (not in the update)
            norm = torch.linalg.vector_norm  # what Tensor.norm(dim=-1) calls
            aux = {
                "goal_norm": norm(goal - y0, dim=-1),
                "weight_norm": norm(weights.flatten(1), dim=-1),
            }
        if self.param_noise:

            def _decode(z: torch.Tensor) -> torch.Tensor:
                return self.decode(z, y0, dy0)[0]

            return ParamGaussian(raw, self.log_std, _decode), aux
        return SubActionGaussian(mean_actions, self.log_std), aux

    def extra_repr(self) -> str:
        return (
            f"k={self.k}, D={self.dmp_dofs}, A={self.action_dim}, N={self.n_basis}, "
            f"decision_dt={self.decision_dt}, param_noise={self.param_noise}, "
            f"mean_clip={self.mean_clip}, direct={self.direct.tolist()}, "
            f"start_at_rest={self.start_at_rest}, only_g={self.only_g}, "
            f"learn_az={self.learn_az}, param_map={self.param_map}"
        )


def _identity(x: torch.Tensor) -> torch.Tensor:
    return x


def build_head(cfg: PolicyConfig, spec: TaskSchema) -> ActionHead:
    """Build the head named by a resolved :class:`ndp.policies.config.PolicyConfig`.

    Args:
        cfg: resolved policy config (no ``None`` NDP fields for the NDP head).
        spec: task spec (``action_dim``, ``dmp_dofs``, ``control_dt``, ``controller``, ...).
    """
    if cfg.head not in HEAD_BUILDERS:
        raise ValueError(f"head: expected one of {', '.join(HEAD_BUILDERS)}, got {cfg.head!r}")
    return HEAD_BUILDERS[cfg.head](cfg.with_defaults(), spec)


@register_head("step", single_step=True)
def _build_step(cfg: PolicyConfig, spec: TaskSchema) -> ActionHead:
    return StepHead(spec.action_dim, cfg.init_log_std)


@register_head("multi")
def _build_multi(cfg: PolicyConfig, spec: TaskSchema) -> ActionHead:
    if cfg.chunk_basis == "none":
        return MultiHead(decision_k(cfg), spec.action_dim, cfg.init_log_std)
    return build_chunk_basis_head(cfg, spec)


def build_chunk_basis_head(cfg: PolicyConfig, spec: TaskSchema) -> ChunkBasisHead:
    """PPO-multi's head restricted to ``cfg.chunk_basis`` (a resolved policy config with
    ``ndp.n_basis`` set; for 'dmp' every NDP field, as the 'ndp' method resolves them).

    - 'dct' / 'bspline': ``chunk_basis.dct_basis`` / ``bspline_basis`` (k, 1 + N), the same for
      every action dimension;
    - 'dmp': :meth:`NDPHead.affine_parts` of the NDP head this config builds (bounds, DMP
      frame and clocks of the task) with the tanh bounds removed, offsets included;
    - 'pca': the file ``cfg.chunk_basis_file`` when it exists and fits the task, k, DoF count
      and columns (``resolve_config`` refuses a run whose file does not), else a NaN basis that
      a checkpoint's state must replace (``load_policy`` of a run or export needs no file).

    Raises:
        ValueError: 1 + N > k, or a 'dmp' head that is not affine per DoF.
    """
    kind, k, a = str(cfg.chunk_basis), decision_k(cfg), int(spec.action_dim)
    if cfg.ndp.n_basis is None:
        raise ValueError("policy config: n_basis must be resolved for a chunk basis")
    columns = 1 + int(cfg.ndp.n_basis)
    chunk_basis.check_columns(kind, columns, k)
    offsets: tuple[torch.Tensor | None, ...] = (None, None, None)
    if kind == "dmp":
        ndp_cfg = cfg.updated(
            head="ndp",
            chunk_basis="none",
            chunk_basis_file=None,
            param_noise=False,
            mean_clip=False,
        )
        ndp = HEAD_BUILDERS["ndp"](ndp_cfg, spec)  # the NDP head as the 'ndp' method builds it
        if not isinstance(ndp, NDPHead):
            raise ValueError(f"head: the registered 'ndp' head is a {type(ndp).__name__}")
        basis_t, *rest = ndp.affine_parts()
        offsets = tuple(rest)
    elif kind in ("dct", "bspline"):
        fn = chunk_basis.dct_basis if kind == "dct" else chunk_basis.bspline_basis
        basis_t = torch.as_tensor(fn(k, columns)).unsqueeze(0).expand(a, k, columns)
    elif kind == "pca":
        basis_t = torch.full((a, k, columns), float("nan"))
        try:
            path = cfg.chunk_basis_file
            assert path is not None  # PolicyConfig requires the file of a file basis
            data = chunk_basis.read_basis_file(path)
            chunk_basis.check_basis_file(
                data, path, task=spec.name, k=k, action_dim=a, columns=columns
            )
            basis_t = torch.as_tensor(data.basis)
        except (OSError, ValueError, TypeError):
            pass  # resolve_config refuses a training run without a fitting file
    else:
        raise ValueError(f"chunk_basis: expected one of dmp, dct, bspline, pca, got {kind!r}")
    offset, offset_y0, offset_dy0 = offsets
    return ChunkBasisHead(
        k, a, kind, basis_t, offset, offset_y0, offset_dy0, init_log_std=cfg.init_log_std
    )


@register_head("ndp")
def _build_ndp(cfg: PolicyConfig, spec: TaskSchema) -> ActionHead:
    head = cfg.ndp  # NDPHeadConfig
    dmp = head.dmp_config(decision_k(cfg))  # refuses an unresolved config
    d = spec.dmp_dofs
    scale = _per_dof(spec.action_scale, d)
    absolute = _per_dof(getattr(spec, "action_absolute", False), d).astype(bool)
    high, low = _per_dof(spec.action_high, d), _per_dof(spec.action_low, d)
    span = high - low
    delta_reach = decision_k(cfg) * scale  # largest move of a delta DoF in one decision
    if head.absolute_goal:
        # absolute commands: goal = centre of the action range + half range * tanh (the goal
        # bound of goal_scale applies to delta DoF only)
        goal_bound = np.where(absolute, span / 2.0, head.goal_scale * delta_reach)
        centre = np.where(absolute, (high + low) / 2.0, np.nan)
        reach = np.where(absolute, span / 2.0, delta_reach)
    else:
        reach = np.where(absolute, span, delta_reach)
        goal_bound = head.goal_scale * reach
        centre = np.full(d, np.nan)
    amplitude = head.forcing == "amplitude"
    # 'amplitude': w is a forcing amplitude; a_z^2 / 4 * reach moves a DoF by about its reach.
    weight_scale = head.weight_scale * reach if amplitude else np.full(d, head.weight_scale)
    direct = absolute & (head.absolute_mode == "direct")
    return NDPHead(
        k=decision_k(cfg),
        dmp_dofs=spec.dmp_dofs,
        action_dim=spec.action_dim,
        dmp=dmp,
        goal_scale=torch.as_tensor(goal_bound, dtype=torch.float32),
        weight_scale=torch.as_tensor(weight_scale, dtype=torch.float32),
        inverse_controller=spec.inverse_controller,
        decision_dt=decision_k(cfg) * float(spec.control_dt),
        param_noise=head.param_noise,
        init_log_std=cfg.init_log_std,
        goal_center=torch.as_tensor(centre, dtype=torch.float32),
        mean_clip=head.mean_clip,
        direct=torch.as_tensor(direct),
        start_at_rest=_dmp_velocity(cfg, spec) == "zero",
        linear_controller=_linear_controller(spec),
        param_map=head.param_map,
    )


def _dmp_velocity(cfg: PolicyConfig, spec: TaskSchema) -> str:
    """The config's DMP start velocity, or the task preset's where the config leaves it None."""
    if cfg.dmp_velocity is not None:
        return str(cfg.dmp_velocity)
    from ndp.envs.presets import preset_of

    return preset_of(spec).dmp_velocity


@register_head("dyne")
def _build_dyne(cfg: PolicyConfig, spec: TaskSchema) -> ActionHead:
    return DyneHead(
        decision_k(cfg), spec.action_dim, _as_tensor(spec.action_low), _as_tensor(spec.action_high)
    )


def _as_tensor(x: ArrayLike) -> torch.Tensor:
    """``x`` as a float32 tensor."""
    return torch.as_tensor(np.asarray(x, dtype=np.float32))


def _linear_controller(spec: TaskSchema) -> tuple[torch.Tensor, ...] | None:
    """(scale, absolute, low, high) [D] of a task whose controller is linear (a
    ``DeltaController``), else None (the composed path is used)."""
    ctrl = getattr(spec, "controller", None)
    if not isinstance(ctrl, DeltaController) or len(ctrl.scale) != spec.dmp_dofs:
        return None
    return ctrl.linear_parts


def _per_dof(value: ArrayLike, d: int) -> np.ndarray:
    """A scalar or a length-D sequence as a float array [D]."""
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.size == 1:
        return np.full(d, float(arr[0]))
    if arr.size != d:
        raise ValueError(f"spec: expected {d} values per DMP DoF, got {arr.size}")
    return arr


class HoldHead(_RawActionHead):
    """One raw action per decision, executed for the k sub-steps (the env holds its target).

    A diagonal Gaussian over the action [A] with a learned, state-independent log std; one
    log-prob per decision (``per_decision``); the k sub-actions [B, k, A] are the sample
    repeated.
    """

    def __init__(self, k: int, action_dim: int, init_log_std: float = 0.0) -> None:
        super().__init__(k, action_dim, action_dim, init_log_std)

    def distribution(
        self, raw: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> HeadOutput:
        k = self.k

        def repeat(z: torch.Tensor) -> torch.Tensor:
            return z.unsqueeze(1).expand(-1, k, -1).contiguous()

        return ParamGaussian(raw, self.log_std, repeat), {}


@register_head("hold")
def _build_hold(cfg: PolicyConfig, spec: TaskSchema) -> ActionHead:
    return HoldHead(decision_k(cfg), spec.action_dim, cfg.init_log_std)


def _check_per_dof(
    j_raw: torch.Tensor, j_y0: torch.Tensor, j_dy0: torch.Tensor, own: torch.Tensor
) -> None:
    """Refuse unit-input responses [inputs, k, D] that move another DoF's actions than their
    own (``own`` [n_params, D] for the raw outputs; the diagonal for y0 and dy0)."""
    d = j_y0.shape[0]
    scale = max(float(j.abs().max()) for j in (j_raw, j_y0, j_dy0, torch.ones(1)))
    cross = max(
        float(j_raw.masked_fill(own.unsqueeze(1), 0.0).abs().max()),
        float(j_y0.masked_fill(torch.eye(d, dtype=torch.bool).unsqueeze(1), 0.0).abs().max()),
        float(j_dy0.masked_fill(torch.eye(d, dtype=torch.bool).unsqueeze(1), 0.0).abs().max()),
    )
    if cross > 1e-12 * scale:
        raise ValueError(
            f"head: the NDP head's chunk couples DoF (a unit input moves another DoF's "
            f"actions by {cross:.3g}); a per-DoF basis cannot represent it"
        )


def _check_affine(
    run: Callable[[torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor],
    parts: tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor],
    n_params: int,
) -> None:
    """Refuse an affine map ``parts`` (:meth:`NDPHead.affine_parts`) that a seeded random batch
    of ``run(raw, y0, dy0)`` does not match to a relative 1e-9."""
    basis, base, offset_y0, offset_dy0 = parts
    d, n = basis.shape[0], basis.shape[2] - 1
    gen = torch.Generator().manual_seed(0)
    raw = torch.randn(8, n_params, generator=gen, dtype=torch.float64)
    y0 = torch.rand(8, d, generator=gen, dtype=torch.float64) * 2 - 1
    dy0 = torch.rand(8, d, generator=gen, dtype=torch.float64) * 2 - 1
    c = torch.cat((raw[:, :d, None], raw[:, d:].reshape(8, d, n)), dim=-1)  # [B, D, P]
    want = run(raw, y0, dy0)
    got = torch.einsum("dkp,bdp->bkd", basis, c) + base
    got = got + y0[:, None, :] * offset_y0 + dy0[:, None, :] * offset_dy0
    err = float((got - want).abs().max())
    if err > 1e-9 * max(float(want.abs().max()), 1.0):
        raise ValueError(
            f"head: the NDP head's chunk is not affine in (g, w) for a fixed start state "
            f"(off by {err:.3g} at random inputs)"
        )
