"""An NDP policy for Stable-Baselines3's PPO on this package's chunked envs (docs/sb3.md).

SB3 sees one decision as one env step: ``ndp.make_env(task, k)`` takes actions [k, A] (SB3's
Gaussian is over the k * A flattened numbers) and returns the sum of the k sub-step rewards.
:class:`NDPPolicy` acts through the DMP: its network predicts the DMP goal and forcing weights
of the decision, the DMP is integrated from the robot state and the task's inverse controller
turns the trajectory into the k sub-actions (the :class:`ndp.policies.NDPHead` of this package's
own trainer, with the task's presets).

The DMP starts from the robot state, which an SB3 policy does not see (it gets the observation
only): :func:`with_robot_state` turns the chunked env's observation into a dict
``{"obs": obs [O], "y0": [D], "dy0": [D]}`` whose ``y0`` / ``dy0`` are the info keys of the
task's DMP frame (``cmd_y0`` / ``cmd_dy0`` for the commanded state, ``dmp_y0`` / ``dmp_dy0``
for the measured one; ``ndp.envs.presets``), in physical units. The policy's network reads
``obs`` only; the DMP reads ``y0`` and ``dy0``. With ``VecNormalize``, normalise the ``obs``
key only (``norm_obs_keys=["obs"]``): a normalised y0 is not where the robot is.

Exploration: a diagonal Gaussian around each of the k sub-actions the DMP gives, with one
learned, state-independent log std per action dimension shared by the k sub-actions (this
package's ``SubActionGaussian``); SB3 sums its log-probability over the k * A numbers (one
ratio per decision). Its deterministic action is the DMP's sub-actions themselves.

Example::

    import ndp.sb3
    from stable_baselines3 import PPO

    env = ndp.sb3.make_env("point-mass", k=5)          # = with_robot_state(ndp.make_env(...))
    model = PPO(ndp.sb3.NDPPolicy, env, gamma=0.99**5)  # gamma per decision of 5 env steps
    model.learn(20_000)                                 # decisions (5 env steps each)
    obs, info = env.reset(seed=0)
    actions, _ = model.predict(obs, deterministic=True)  # [5, A]
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, SupportsFloat

import numpy as np
import torch
from torch import nn

from ndp.act_inputs import check_act_inputs
from ndp.checks import install_hint

try:
    import gymnasium as gym
    from gymnasium import spaces
    from stable_baselines3.common.distributions import DiagGaussianDistribution
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
    from stable_baselines3.common.type_aliases import Schedule
except ModuleNotFoundError as _exc:  # name the extra that installs what is missing
    if (_exc.name or "").split(".")[0] not in ("stable_baselines3", "gymnasium"):
        raise
    raise ModuleNotFoundError(
        f"{_exc}: ndp.sb3 needs the [sb3] extra ({install_hint('sb3')})",
        name=_exc.name,
    ) from _exc

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.policies import BasePolicy
    from stable_baselines3.common.vec_env import VecNormalize

    from ndp.rl.policy import Policy

import ndp
from ndp.chunk_info import DMP_START_KEYS
from ndp.policies import PolicyConfig, build_actor_critic, build_head
from ndp.rl.normalize import ObsNormalizer

__all__ = [
    "NDPPolicy",
    "ObservationOnly",
    "RobotStateSpace",
    "make_env",
    "to_policy",
    "with_robot_state",
]

STATE_KEYS = DMP_START_KEYS
"""DMP frame -> the chunked env's info keys of the DMP start (:mod:`ndp.chunk_info`)."""


class RobotStateSpace(spaces.Dict):
    """The observation space of :func:`with_robot_state`: ``obs``, ``y0``, ``dy0``, and the task
    and DMP frame they belong to (so that ``PPO(NDPPolicy, env)`` needs no other argument)."""

    def __init__(self, obs: spaces.Box, dofs: int, task: str, dmp_state: str) -> None:
        state = spaces.Box(-np.inf, np.inf, shape=(int(dofs),), dtype=np.float64)
        super().__init__({"obs": obs, "y0": state, "dy0": state})
        self.task = str(task)
        self.dmp_state = str(dmp_state)

    @property
    def state_keys(self) -> tuple[str, str]:
        """The info keys ``y0`` and ``dy0`` are read from."""
        return STATE_KEYS[self.dmp_state]


class _RobotState(gym.Wrapper):
    def __init__(self, env: gym.Env, task: str, dmp_state: str) -> None:
        super().__init__(env)
        act = env.action_space
        if not isinstance(act, spaces.Box) or len(act.shape) != 2:
            raise ValueError(
                f"env: expected a chunked env (ndp.make_env(task, k=...)) whose actions are "
                f"[k, A], got action space {act}"
            )
        obs = env.observation_space
        if not isinstance(obs, spaces.Box):
            raise ValueError(f"env: expected a Box observation space, got {obs}")
        from ndp.envs import get_task_spec

        self._spec = get_task_spec(task)
        if act.shape[1] != self._spec.action_dim:
            raise ValueError(
                f"env: actions [k, {act.shape[1]}], but task {self._spec.name!r} has "
                f"{self._spec.action_dim} action dimensions"
            )
        self.observation_space = RobotStateSpace(
            obs, self._spec.dmp_dofs, self._spec.name, dmp_state
        )
        self._keys = STATE_KEYS[dmp_state]

    def _dict(self, obs: object, info: Mapping[str, object]) -> dict[str, np.ndarray]:
        ky, kdy = self._keys
        if ky not in info or kdy not in info:
            raise ValueError(
                f"info: expected the chunked env's {ky!r} and {kdy!r}, got keys {sorted(info)[:8]}"
            )
        return {
            "obs": np.asarray(obs),
            "y0": np.asarray(info[ky], dtype=np.float64).copy(),
            "dy0": np.asarray(info[kdy], dtype=np.float64).copy(),
        }

    def reset(self, **kwargs: Any) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        return self._dict(obs, info), info

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], SupportsFloat, bool, bool, dict[str, object]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._dict(obs, info), reward, terminated, truncated, info


def with_robot_state(env: gym.Env, task: str, dmp_state: str | None = None) -> gym.Env:
    """The chunked env ``env`` with the DMP start in its observation (see the module).

    Args:
        env: ``ndp.make_env(task, k=...)`` (actions [k, A]; info with the robot state).
        task: its task name (sets the DMP frame's default and the NDP head of the policy).
        dmp_state: 'commanded' or 'measured'; None: the task's preset.
    """
    from ndp.envs import get_task_spec
    from ndp.envs.presets import preset_of

    spec = get_task_spec(task)
    frame = preset_of(spec).dmp_state if dmp_state is None else dmp_state
    if frame not in STATE_KEYS:
        raise ValueError(f"dmp_state: expected one of {', '.join(STATE_KEYS)}, got {frame!r}")
    return _RobotState(env, spec.name, frame)


def make_env(task: str, k: int = 5, dmp_state: str | None = None, **kwargs: Any) -> gym.Env:
    """``with_robot_state(ndp.make_env(task, k, **kwargs), task, dmp_state)``."""
    return with_robot_state(ndp.make_env(task, k=k, **kwargs), task, dmp_state)


class ObservationOnly(BaseFeaturesExtractor):
    """Features of :class:`RobotStateSpace` observations: the ``obs`` entry, flattened (the
    robot state is for the DMP, not the network)."""

    def __init__(self, observation_space: spaces.Dict) -> None:
        shape = observation_space["obs"].shape
        assert shape is not None  # a Box (RobotStateSpace)
        super().__init__(observation_space, int(np.prod(shape)))

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        return observations["obs"].flatten(1)


class NDPPolicy(ActorCriticPolicy):
    """SB3 actor-critic whose actions come from a DMP (see the module).

    The features are the ``obs`` entry (:class:`ObservationOnly`); the actor and critic are
    SB3's ``MlpExtractor`` (``net_arch``, ``activation_fn``: SB3's defaults, as for its
    ``MlpPolicy``); the actor's last layer gives the raw DMP parameters of the decision
    (goal and N weights per DoF) and :class:`ndp.policies.NDPHead` maps them, from ``y0`` /
    ``dy0``, to the k sub-action means.

    Args:
        observation_space: a :class:`RobotStateSpace` (:func:`with_robot_state`).
        action_space: Box [k, A].
        lr_schedule: SB3's learning-rate schedule.
        task: the task (None: the observation space's).
        ndp: NDP head settings, any field of :class:`ndp.policies.PolicyConfig` (``n_basis``,
            ``a_z``, ``goal_scale``, ``forcing``, ``dmp_velocity``, ...); None fields take the
            task's presets. ``param_noise`` is not supported (SB3's Gaussian is over actions).
        log_std_init: initial log std of the sub-action Gaussian.
        **kwargs: the remaining ``ActorCriticPolicy`` arguments (``net_arch``,
            ``activation_fn``, ``ortho_init``, ``optimizer_class``, ...).
    """

    def __init__(
        self,
        observation_space: spaces.Space[Any],
        action_space: spaces.Space[Any],
        lr_schedule: Schedule,
        task: str | None = None,
        ndp: dict[str, Any] | None = None,
        log_std_init: float = 0.0,
        use_sde: bool = False,
        **kwargs: Any,
    ) -> None:
        if use_sde:
            raise ValueError("NDPPolicy: gSDE (use_sde=True) is not supported")
        if task is None:
            task = getattr(observation_space, "task", None)
        if not isinstance(observation_space, spaces.Dict) or task is None:
            raise ValueError(
                "NDPPolicy: expected the observations of ndp.sb3.with_robot_state(env, task) "
                f"(a dict with obs, y0, dy0), got {observation_space}"
            )
        if not isinstance(action_space, spaces.Box) or len(action_space.shape) != 2:
            raise ValueError(f"NDPPolicy: expected actions [k, A] (a Box), got {action_space}")
        ndp = dict(ndp or {})
        if ndp.get("param_noise"):
            raise ValueError("NDPPolicy: param_noise is not supported (SB3 explores in actions)")
        frame = getattr(observation_space, "dmp_state", None)
        if frame is not None and ndp.setdefault("dmp_state", frame) != frame:
            raise ValueError(
                f"NDPPolicy: ndp dmp_state {ndp['dmp_state']!r}, but the observations carry the "
                f"{frame!r} state"
            )
        self.task = str(task)
        self.ndp = ndp
        kwargs.pop("features_extractor_class", None)  # the obs entry only
        super().__init__(
            observation_space,
            action_space,
            lr_schedule,
            log_std_init=log_std_init,
            features_extractor_class=ObservationOnly,
            **kwargs,
        )

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        for key in ("use_sde", "squash_output", "full_std", "use_expln"):
            data.pop(key, None)  # gSDE: refused
        data.pop("features_extractor_class", None)  # always ObservationOnly
        data.update(task=self.task, ndp=self.ndp)
        return data

    def _build(self, lr_schedule: Schedule) -> None:
        """The MLP extractor, the raw-parameter layer, the NDP head, the value layer, SB3's
        orthogonal initialisation and the optimiser."""
        from ndp.rl.config import TrainConfig, resolve_config

        shape = self.action_space.shape
        assert shape is not None  # a [k, A] Box (checked in __init__)
        k, a = (int(n) for n in shape)
        cfg = resolve_config(
            TrainConfig(
                task=self.task,
                algo="ndp",
                policy=PolicyConfig.from_dict(
                    {"k": k, "init_log_std": self.log_std_init, **self.ndp}
                ),
            )
        )
        from ndp.rl.envs import resolve_task

        spec = resolve_task(cfg.task).spec
        if spec.action_dim != a:
            raise ValueError(
                f"NDPPolicy: actions [k, {a}], but task {spec.name!r} has {spec.action_dim}"
            )
        self.k = k
        self.ndp_config = cfg.policy
        self._build_mlp_extractor()
        self.ndp_head = build_head(cfg.policy, spec)
        self.action_net = nn.Linear(self.mlp_extractor.latent_dim_pi, self.ndp_head.n_params)
        self.value_net = nn.Linear(self.mlp_extractor.latent_dim_vf, 1)
        if self.ortho_init:  # SB3's gains: sqrt(2) hidden, 0.01 policy output, 1 value output
            gains = {self.mlp_extractor: np.sqrt(2), self.action_net: 0.01, self.value_net: 1.0}
            for module, gain in gains.items():
                module.apply(functools.partial(self.init_weights, gain=gain))
        self.optimizer = self.optimizer_class(
            self.parameters(),
            lr=lr_schedule(1),
            **self.optimizer_kwargs,  # type: ignore[call-arg]
        )

    @property
    def log_std(self) -> nn.Parameter:
        """The sub-action log std [A] (SB3 logs ``exp(log_std).mean()`` as train/std); it is the
        NDP head's parameter, so it cannot be replaced."""
        log_std: nn.Parameter = self.ndp_head.log_std
        return log_std

    @log_std.setter
    def log_std(self, value: nn.Parameter) -> None:
        raise AttributeError("log_std: NDPPolicy's log std is the NDP head's parameter (read-only)")

    def dmp_actions(self, latent_pi: torch.Tensor, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        """The k sub-action means [B, k, A] of the DMP (goal and weights from ``latent_pi``,
        started at the observation's ``y0`` / ``dy0``)."""
        raw = self.action_net(latent_pi)
        y0 = obs["y0"].to(raw.dtype).reshape(raw.shape[0], -1)
        dy0 = obs["dy0"].to(raw.dtype).reshape(raw.shape[0], -1)
        means: torch.Tensor = self.ndp_head.decode(raw, y0, dy0)[0]
        return means

    def _distribution(
        self, latent_pi: torch.Tensor, obs: dict[str, torch.Tensor]
    ) -> DiagGaussianDistribution:
        mean = self.dmp_actions(latent_pi, obs).flatten(1)  # [B, k * A], sub-step major
        log_std = self.ndp_head.log_std.repeat(self.k)  # one std per action dim, k times
        dist = self.action_dist
        assert isinstance(dist, DiagGaussianDistribution)
        return dist.proba_distribution(mean, log_std)

    def _latents(self, obs: dict[str, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        features = self.extract_features(obs)
        if self.share_features_extractor:
            return self.mlp_extractor(features)  # type: ignore[no-any-return]
        pi, vf = features
        return self.mlp_extractor.forward_actor(pi), self.mlp_extractor.forward_critic(vf)

    def forward(
        self, obs: Any, deterministic: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        latent_pi, latent_vf = self._latents(obs)
        dist = self._distribution(latent_pi, obs)
        actions = dist.get_actions(deterministic=deterministic)
        log_prob = dist.log_prob(actions)
        return actions.reshape((-1, *self.action_space.shape)), self.value_net(latent_vf), log_prob  # type: ignore[misc]

    def evaluate_actions(
        self, obs: Any, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
        latent_pi, latent_vf = self._latents(obs)
        dist = self._distribution(latent_pi, obs)
        flat = actions.reshape(actions.shape[0], -1)
        return self.value_net(latent_vf), dist.log_prob(flat), dist.entropy()

    def predict(
        self,
        observation: np.ndarray | dict[str, np.ndarray],
        state: tuple[np.ndarray, ...] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...] | None]:
        """SB3's ``predict``, its inputs checked first as every policy runtime checks them
        (:func:`ndp.act_inputs.check_act_inputs`: shapes, finite values, float32's range; one
        line naming ``obs`` or the state key, the index and what was expected)."""
        if not isinstance(observation, dict) or not {"obs", "y0", "dy0"} <= set(observation):
            got = sorted(observation) if isinstance(observation, dict) else type(observation)
            raise ValueError(
                "observation: expected the dict of ndp.sb3.with_robot_state (obs, y0, dy0), "
                f"got {got}"
            )
        obs_space = self.observation_space
        assert isinstance(obs_space, spaces.Dict)
        check_act_inputs(
            observation["obs"],
            {"y0": observation["y0"], "dy0": observation["dy0"]},
            obs_dim=int(np.prod(obs_space["obs"].shape)),  # type: ignore[arg-type]
            dofs=int(np.prod(obs_space["y0"].shape)),  # type: ignore[arg-type]
            state_keys=("y0", "dy0"),
            needs_state=True,
            starts_at_rest=False,
            what="this NDPPolicy",
            state_name="observation",
        )
        return super().predict(observation, state, episode_start, deterministic)

    def get_distribution(self, obs: Any) -> DiagGaussianDistribution:
        features = super(ActorCriticPolicy, self).extract_features(obs, self.pi_features_extractor)
        return self._distribution(self.mlp_extractor.forward_actor(features), obs)


def to_policy(
    model: BaseAlgorithm | BasePolicy, vec_normalize: VecNormalize | None = None
) -> Policy:
    """An SB3 model with :class:`NDPPolicy` as the package's :class:`ndp.rl.policy.Policy`,
    so that it exports (``.export(DIR)``: safetensors + JSON + card; ``format="onnx"``),
    evaluates and renders like a policy trained by ``ndp rl train``.

    The weights are copied, not retrained: SB3's policy MLP and action layer become the actor,
    the NDP head is the same module, and SB3's value network becomes the critic (its one value
    repeated for the k sub-step value heads the package's critic has; the critic does not act).
    ``vec_normalize``: the ``VecNormalize`` the model was trained with (its frozen ``obs``
    statistics and clip become the policy's observation normaliser); None: no normalisation.

    Raises:
        ValueError: a model whose policy is not an NDPPolicy, different policy and value
            widths (``net_arch``), an activation the package has no name for, or a VecNormalize
            that normalises more than ``obs`` (one line naming the argument).
    """
    from ndp.rl.config import RunConfig, TrainConfig, resolve_config
    from ndp.rl.envs import resolve_task
    from ndp.rl.policy import Policy

    pol = getattr(model, "policy", model)
    if not isinstance(pol, NDPPolicy):
        raise ValueError(f"model: expected an SB3 model with ndp.sb3.NDPPolicy, got {type(pol)}")
    pi, vf = _widths(pol.mlp_extractor.policy_net), _widths(pol.mlp_extractor.value_net)
    if pi != vf:
        raise ValueError(
            f"model: the package's actor-critic has one hidden width list; this NDPPolicy has "
            f"net_arch pi={list(pi)}, vf={list(vf)}"
        )
    activation = _ACTIVATIONS.get(pol.activation_fn)
    if activation is None:
        raise ValueError(
            f"model: activation_fn {pol.activation_fn.__name__} has no name in the package "
            f"({', '.join(c.__name__ for c in _ACTIVATIONS)})"
        )
    obs_space = pol.observation_space
    assert isinstance(obs_space, spaces.Dict)
    obs_dim = int(np.prod(obs_space["obs"].shape))  # type: ignore[arg-type]
    norm = _normaliser(vec_normalize, obs_dim)
    policy_cfg = PolicyConfig.from_dict(
        {**pol.ndp_config.to_dict(), "hidden": list(pi), "activation": activation}
    )
    cfg = resolve_config(
        TrainConfig(
            task=pol.task,
            algo="ndp",
            policy=policy_cfg,
            norm_obs=norm is not None,
            clip_obs=norm[2] if norm else RunConfig.clip_obs,
        )
    )
    spec = resolve_task(cfg.task).spec

    net = build_actor_critic(obs_dim, spec, cfg.policy)
    state = _state_from_sb3(pol, net.k)
    net.load_state_dict(state)
    net.eval()
    obs_norm = ObsNormalizer(obs_dim, cfg.clip_obs, cfg.norm_obs)
    if norm is not None:
        obs_norm.load_state_dict({"mean": norm[0], "var": norm[1], "count": 1.0})
    return Policy(
        cfg,
        spec,
        net,
        obs_norm,
        training={"commands": ["Stable-Baselines3 PPO with ndp.sb3.NDPPolicy"], "commits": []},
    )


_ACTIVATIONS = {nn.Tanh: "tanh", nn.ReLU: "relu", nn.ELU: "elu", nn.GELU: "gelu"}
"""SB3's ``activation_fn`` classes -> the package's activation names."""


def _widths(seq: nn.Module) -> tuple[int, ...]:
    return tuple(m.out_features for m in seq.modules() if isinstance(m, nn.Linear))


def _normaliser(
    vec_normalize: VecNormalize | None, obs_dim: int
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """(mean [O], var [O], clip) of a VecNormalize's ``obs`` statistics; None without one."""
    if vec_normalize is None or not getattr(vec_normalize, "norm_obs", False):
        return None
    keys = getattr(vec_normalize, "norm_obs_keys", None)
    if keys is not None and list(keys) != ["obs"]:
        raise ValueError(
            f"vec_normalize: expected norm_obs_keys=['obs'] (a normalised robot state is not "
            f"where the robot is), got {keys}"
        )
    stats = vec_normalize.obs_rms
    rms = stats["obs"] if isinstance(stats, dict) else stats
    mean, var = np.asarray(rms.mean, dtype=np.float64), np.asarray(rms.var, dtype=np.float64)
    if mean.shape != (obs_dim,) or var.shape != (obs_dim,):
        raise ValueError(
            f"vec_normalize: expected obs statistics of {obs_dim} values, got {list(mean.shape)}"
        )
    return mean, var, float(vec_normalize.clip_obs)


def _state_from_sb3(pol: NDPPolicy, k: int) -> dict[str, torch.Tensor]:
    """The package ActorCritic's state dict from an NDPPolicy's modules (names mapped; the
    value layer's row repeated for the k value heads)."""
    out: dict[str, torch.Tensor] = {}
    lin = [m for m in pol.mlp_extractor.policy_net if isinstance(m, nn.Linear)]
    assert isinstance(pol.action_net, nn.Linear)  # NDPPolicy._build makes it one
    for i, m in enumerate([*lin, pol.action_net]):
        out[f"actor.net.{2 * i}.weight"] = m.weight.detach().clone()
        out[f"actor.net.{2 * i}.bias"] = m.bias.detach().clone()
    lin = [m for m in pol.mlp_extractor.value_net if isinstance(m, nn.Linear)]
    for i, m in enumerate(lin):
        out[f"critic.net.{2 * i}.weight"] = m.weight.detach().clone()
        out[f"critic.net.{2 * i}.bias"] = m.bias.detach().clone()
    n = 2 * len(lin)
    out[f"critic.net.{n}.weight"] = pol.value_net.weight.detach().repeat(k, 1)
    out[f"critic.net.{n}.bias"] = pol.value_net.bias.detach().repeat(k)
    for name, t in pol.ndp_head.state_dict().items():
        out[f"head.{name}"] = t.detach().clone()
    return out
