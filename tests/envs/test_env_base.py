"""The boilerplate every env family shares (``ndp.envs.base``): argument checks, deferred
seeding and the unstable-simulator truncation, checked on each family."""

from __future__ import annotations

import numpy as np
import pytest

from ndp.envs import TASKS, make_env
from ndp.envs.base import NDPEnv, check_horizon, check_render_mode, sim_unstable, warning_count
from ndp.envs.factory import FAMILIES
from ndp.envs.jaco import JacoEnv
from ndp.envs.metaworld_env import MetaWorldEnv
from ndp.envs.point_mass import PointMassEnv, make_point_mass_env

# one task per family (the Jaco family twice: Throw and Pick reset differently)
NAMES = ["reach-v3", "throw", "pick", "point-mass"]
CLASSES = {
    "metaworld": lambda **kw: MetaWorldEnv("reach-v3", **kw),
    "jaco": lambda **kw: JacoEnv("throw", **kw),
    "toy": lambda **kw: PointMassEnv(**kw),
}
MUJOCO_NAMES = ["push-v3", "throw", "pick"]


def test_every_family_is_an_ndp_env():
    families = {spec.family: name for name, spec in TASKS.items()}
    assert set(families) == set(FAMILIES) == set(CLASSES)
    for name in families.values():
        env = make_env(name)
        assert isinstance(env.unwrapped, NDPEnv), name
        env.close()


@pytest.mark.parametrize("family", list(CLASSES))
@pytest.mark.parametrize("mode", ["human", "rgb", "depth_array"])
def test_bad_render_mode_names_the_argument(family, mode):
    with pytest.raises(
        ValueError, match=rf"^render_mode: expected None or 'rgb_array', got '{mode}'$"
    ):
        CLASSES[family](render_mode=mode)


@pytest.mark.parametrize("family", list(CLASSES))
@pytest.mark.parametrize("horizon", [0, -3, None, "many"])
def test_bad_horizon_names_the_argument(family, horizon):
    with pytest.raises(ValueError, match=r"^horizon: expected a positive int, got "):
        CLASSES[family](horizon=horizon)


@pytest.mark.parametrize("family", list(CLASSES))
@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("width", 0),
        ("height", -5),
        ("width", 4097),
        ("height", 64.0),
        ("width", "64"),
        ("width", True),
    ],
)
def test_bad_render_size_names_the_argument(family, name, value):
    with pytest.raises(
        ValueError, match=rf"^{name}: expected an integer from 1 to 4096 \(px\), got "
    ):
        CLASSES[family](render_mode="rgb_array", **{name: value})


@pytest.mark.parametrize("family", list(CLASSES))
@pytest.mark.parametrize(("width", "height"), [(40, 30), (800, 600)])
def test_every_family_renders_at_the_size_asked(family, width, height):
    # 800 x 600 is larger than the Jaco scene's 640 x 480 offscreen framebuffer, which the env
    # grows to fit
    env = CLASSES[family](render_mode="rgb_array", width=width, height=height)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame.shape == (height, width, 3) and frame.dtype == np.uint8
    assert frame.min() < frame.max()  # something drawn, not a blank buffer


def test_point_mass_view_scales_with_the_frame():
    small = PointMassEnv(render_mode="rgb_array")
    big = PointMassEnv(render_mode="rgb_array", width=192, height=96)
    small.reset(seed=3), big.reset(seed=3)
    a, b = small.render(), big.render()
    assert a.shape == (96, 96, 3) and b.shape == (96, 192, 3)
    # the goal marker (green) sits at the same relative place, in x stretched twice as far
    ga = np.argwhere((a == (0, 160, 0)).all(-1)).mean(0)
    gb = np.argwhere((b == (0, 160, 0)).all(-1)).mean(0)
    assert abs(ga[0] - gb[0]) <= 1 and abs(2 * ga[1] - gb[1]) <= 3


@pytest.mark.parametrize("family", list(CLASSES))
def test_good_arguments_are_stored(family):
    env = CLASSES[family](horizon=7, render_mode="rgb_array")
    assert env.horizon == 7 and env.render_mode == "rgb_array"
    assert env.action_space.dtype == np.float32
    assert np.all(env.action_space.low == -1.0) and np.all(env.action_space.high == 1.0)
    env.close()


def test_check_helpers():
    assert check_horizon(3) == 3 and check_horizon(np.int64(150)) == 150
    check_render_mode(None, ["rgb_array"])
    check_render_mode("human", ["human", "rgb_array"])
    with pytest.raises(ValueError, match="render_mode: expected None or 'human' or 'rgb_array'"):
        check_render_mode("ansi", ["human", "rgb_array"])


@pytest.mark.parametrize("name", NAMES)
def test_seed_is_deferred_to_the_first_unseeded_reset(name):
    first = make_env(name, seed=5).reset()[0]
    np.testing.assert_array_equal(first, make_env(name).reset(seed=5)[0])
    assert not np.array_equal(first, make_env(name, seed=6).reset()[0])
    # an explicit seed leaves the deferred one for the next unseeded reset ...
    env = make_env(name, seed=5)
    other = env.reset(seed=6)[0]
    assert not np.array_equal(other, first)
    np.testing.assert_array_equal(env.reset()[0], first)
    # ... which uses it up: the following reset draws a new configuration
    assert not np.array_equal(env.reset()[0], first)
    # the factories seed the action space's sampler too
    np.testing.assert_array_equal(
        make_env(name, seed=5).action_space.sample(), make_env(name, seed=5).action_space.sample()
    )


@pytest.mark.parametrize("family", list(CLASSES))
def test_seed_next_reset_on_the_class(family):
    a, b = CLASSES[family](), CLASSES[family]()
    a.seed_next_reset(11)
    np.testing.assert_array_equal(a.reset()[0], b.reset(seed=11)[0])
    a.close()
    b.close()


def test_point_mass_factory_defers_its_seed():
    np.testing.assert_array_equal(
        make_point_mass_env(seed=4).reset()[0], make_env("point-mass").reset(seed=4)[0]
    )


@pytest.mark.parametrize("name", MUJOCO_NAMES)
def test_unstable_simulator_truncates_with_flag(name):
    env = make_env(name, seed=0)
    env.reset()
    zero = np.zeros(env.action_space.shape)
    obs_before, *_, info = env.step(zero)
    assert info["sim_unstable"] is False
    env.unwrapped.data.qvel[:] = 1e30  # provoke MuJoCo's bad-qvel / bad-qacc warning
    if TASKS[name].family == "jaco":  # Jaco observes the state the step started from
        obs_before = env.unwrapped._obs()
    obs, reward, terminated, truncated, info = env.step(zero)
    assert truncated and not terminated and reward == 0.0
    assert info["sim_unstable"] is True and info["success"] is False
    np.testing.assert_array_equal(obs, obs_before)  # the last good observation
    assert np.all(np.isfinite(info["robot_pos"])) and np.all(np.isfinite(info["robot_vel"]))
    with pytest.raises(RuntimeError, match="episode is over: call reset"):
        env.step(zero)
    _, info = env.reset()
    assert info["sim_unstable"] is False
    *_, truncated, info = env.step(zero)
    assert not truncated and info["sim_unstable"] is False
    env.close()


@pytest.mark.parametrize("name", ["reach-v3", "throw"])
def test_sim_unstable_reads_warnings_and_non_finite_state(name):
    data = make_env(name, seed=0).unwrapped.data
    n = warning_count(data)
    assert not sim_unstable(data, n)
    data.qvel[0] = np.nan  # no warning counted yet: the finiteness check alone catches it
    assert warning_count(data) == n and sim_unstable(data, n)
    data.qvel[0] = 0.0
    data.qpos[-1] = np.inf
    assert sim_unstable(data, n)
    data.qpos[-1] = 0.0
    assert not sim_unstable(data, n) and sim_unstable(data, n - 1)  # one more warning


class _Toy(NDPEnv):
    """The smallest NDPEnv: checks the shared step helpers without a simulator."""

    metadata = {"render_modes": ["rgb_array"]}  # noqa: RUF012

    def __init__(self, horizon=3, render_mode=None):
        self._setup(horizon, render_mode, action_dim=2)
        self.steps = 0

    def reset(self, *, seed=None, options=None):
        self._reset_rng(seed)
        self._unstable = False
        self.steps = 0
        return self.np_random.uniform(size=2), {}

    def step(self, action):
        a = self._check_action(action)
        self._check_running(self.steps)
        self.steps += 1
        if a[0] > 0.5:  # "the simulator blew up"
            return self._unstable_step(np.zeros(2), np.full(2, np.nan), np.full(2, np.inf))
        return a, 1.0, False, self.steps >= self.horizon, self._state_info(True, a, a)


def test_shared_step_helpers():
    env = _Toy()
    env.seed_next_reset(3)
    np.testing.assert_array_equal(env.reset()[0], _Toy().reset(seed=3)[0])
    with pytest.raises(ValueError, match=r"action: expected shape \(2,\), got \(3,\)"):
        env.step(np.zeros(3))
    with pytest.raises(ValueError, match="action: expected finite values"):
        env.step(np.array([0.0, np.nan]))
    _, r, _, trunc, info = env.step(np.zeros(2))
    assert (
        r == 1.0
        and not trunc
        and list(info)
        == [
            "success",
            "robot_pos",
            "robot_vel",
            "sim_unstable",
        ]
    )
    _, r, term, trunc, info = env.step(np.array([1.0, 0.0]))
    assert (r, term, trunc, info["sim_unstable"], info["success"]) == (
        0.0,
        False,
        True,
        True,
        False,
    )
    np.testing.assert_array_equal(info["robot_pos"], [0.0, 0.0])
    assert np.all(np.isfinite(info["robot_vel"]))
    with pytest.raises(RuntimeError, match="episode is over"):
        env.step(np.zeros(2))
    env.reset()
    for _ in range(3):
        *_, trunc, _ = env.step(np.zeros(2))
    assert trunc
    with pytest.raises(RuntimeError, match="episode is over"):  # the horizon ends it too
        env.step(np.zeros(2))
