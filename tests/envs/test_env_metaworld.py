"""Meta-World through the chunked wrapper: experts, the stale-world rule and its side effects."""

from __future__ import annotations

import numpy as np
import pytest
from metaworld.policies import ENV_POLICY_MAP

from ndp.envs import ChunkedEnv, make_env
from ndp.envs.metaworld_env import METAWORLD_POS_SCALE, V1_REWARD_BROKEN, metaworld_env_names

# Tasks whose expert is run in the default suite (the full 50 run under -m slow).
EXPERT_TASKS = ["reach-v3", "push-v3", "faucet-open-v3", "drawer-close-v3", "button-press-v3"]
# metaworld experts are feedback controllers. Measured with seed 0, horizon 500 (docs/envs.md):
# with k = 1 all succeed but these two (imperfect experts); run open loop on the decision's
# observation for k = 5 sub-steps, these eleven miss as well (the object moves under the stale
# observation and the expert never re-plans inside the chunk).
K1_EXPERT_MISSES = {"soccer-v3", "stick-pull-v3"}
K5_EXPERT_MISSES = K1_EXPERT_MISSES | {
    "door-close-v3",
    "door-open-v3",
    "handle-pull-v3",
    "plate-slide-v3",
    "plate-slide-back-v3",
    "peg-insert-side-v3",
    "stick-push-v3",
    "push-back-v3",
    "sweep-v3",
}


def run_expert(name: str, k: int, seed: int = 0, horizon: int = 500) -> bool:
    """Run metaworld's scripted expert through ChunkedEnv; return success-any.

    The expert sees the observation once per decision (the world is stale); inside the decision
    its own hand position is advanced by the commanded displacement before it plans the next
    sub-action, so the k sub-actions form one open-loop chunk.
    """
    policy = ENV_POLICY_MAP[name]()
    env = ChunkedEnv(make_env(name, horizon=horizon), k=k)
    obs, _ = env.reset(seed=seed)
    while True:
        o = obs.copy()
        chunk = []
        for _ in range(k):
            a = np.clip(policy.get_action(o), -1.0, 1.0)
            chunk.append(a)
            o = o.copy()
            o[:3] += a[:3] * METAWORLD_POS_SCALE
        obs, _, term, trunc, info = env.step(np.stack(chunk))
        if term or trunc:
            env.close()
            return bool(info["success_any"])


@pytest.mark.filterwarnings("ignore:Constant")
@pytest.mark.parametrize("name", EXPERT_TASKS)
def test_expert_succeeds_through_wrapper_k5(name):
    assert run_expert(name, k=5)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:Constant")
@pytest.mark.parametrize("name", metaworld_env_names())
def test_expert_all_tasks(name):
    if name not in K1_EXPERT_MISSES:
        assert run_expert(name, k=1)
    if name not in K5_EXPERT_MISSES:
        assert run_expert(name, k=5)


@pytest.mark.filterwarnings("ignore:Constant")
def test_stale_rule_does_not_change_the_dynamics_and_uses_the_stale_world():
    on = ChunkedEnv(make_env("push-v3"), k=5, stale_world=True)
    off = ChunkedEnv(make_env("push-v3"), k=5, stale_world=False)
    policy = ENV_POLICY_MAP["push-v3"]()
    obs_on, _ = on.reset(seed=4)
    obs_off, _ = off.reset(seed=4)
    differed = False
    for _ in range(30):
        chunk = np.stack([np.clip(policy.get_action(obs_on), -1, 1)] * 5)
        obs_on, _, _, _, i_on = on.step(chunk)
        obs_off, _, _, _, i_off = off.step(chunk)
        np.testing.assert_array_equal(obs_on, obs_off)
        np.testing.assert_array_equal(i_on["sub_rewards_live"], i_off["sub_rewards"])
        np.testing.assert_array_equal(i_on["robot_pos"], i_off["robot_pos"])
        assert i_on["sub_rewards"][0] == i_off["sub_rewards"][0]
        differed |= not np.allclose(i_on["sub_rewards"][1:], i_off["sub_rewards"][1:])
    assert differed  # the puck moved within some decision, and the stale reward saw that


def _state(env) -> dict:
    """Everything a reward function could change: MjData arrays and the env's attributes."""
    d = env.data
    out = {
        f: getattr(d, f).copy()
        for f in (
            "qpos",
            "qvel",
            "act",
            "ctrl",
            "mocap_pos",
            "mocap_quat",
            "qacc_warmstart",
            "xpos",
            "site_xpos",
        )
    }
    for key, val in vars(env.mw).items():
        if isinstance(val, (bool, int, float, str, type(None))):
            out["mw." + key] = val
        elif isinstance(val, np.ndarray):
            out["mw." + key] = val.copy()
    return out


def _assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key in a:
        if isinstance(a[key], np.ndarray):
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        else:
            assert a[key] == b[key], key


def check_reward_has_no_side_effects(name: str, reward_version: str = "v2") -> None:
    """stale_reward leaves the env untouched, and a twin env that never called it agrees."""
    env = make_env(name, reward_version=reward_version)
    twin = make_env(name, reward_version=reward_version)
    env.reset(seed=2)
    twin.reset(seed=2)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(12, 4))
    snapshot = None
    for t, a in enumerate(actions):
        o1, r1, *_ = env.step(a)
        o2, r2, *_ = twin.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2
        if t == 1:
            snapshot = env.world_snapshot()
            # Same world as now: the recomputed reward is the live one.
            assert env.stale_reward(snapshot, a) == pytest.approx(r1, abs=1e-6)
        if t >= 2:
            before = _state(env)
            env.stale_reward(snapshot, a)
            env.stale_reward(snapshot, a)
            _assert_same(before, _state(env))


@pytest.mark.parametrize("name", metaworld_env_names())
@pytest.mark.parametrize("version", ["v2", "v1"])
def test_reward_function_has_no_side_effects_all_tasks(name, version):
    # All 50 x both reward versions in the default suite (about 50 s): the stale-world rule
    # relies on it (v1 rewards read site positions and attributes set at reset, such as push's
    # maxPushDist). assembly-v3's v1 reward does not run in metaworld 3.1.1: refused at
    # construction (test_v1_reward_refused_where_metaworld_cannot_run_it).
    if version == "v1" and name in V1_REWARD_BROKEN:
        pytest.skip("v1 reward refused")
    check_reward_has_no_side_effects(name, version)


def test_command_state_is_the_mocap_target_that_leads_the_hand():
    """The DMP's commanded coordinates: the mocap target moves exactly 0.01 m per unit action
    and per step (until its bounds), while the measured hand lags it."""
    env = ChunkedEnv(make_env("reach-v3", seed=0), k=5)
    _, info = env.reset(seed=0)
    np.testing.assert_allclose(info["cmd_dy0"], 0.0)
    start = info["cmd_y0"].copy()
    act = np.zeros((5, 4))
    act[:, 1] = 0.5  # +y at half speed, inside the mocap bounds from the reset pose
    act[:, 3] = -1.0
    _, _, _, _, info = env.step(act)
    np.testing.assert_allclose(info["cmd_y0"][1] - start[1], 5 * 0.5 * 0.01, atol=1e-9)
    np.testing.assert_allclose(info["cmd_dy0"][1], 0.5 * 0.01 / 0.0125, atol=1e-9)
    assert info["cmd_y0"][3] == -1.0
    lead = info["cmd_y0"][1] - info["dmp_y0"][1]
    assert lead > 0.005  # the hand trails its target
    env.close()


def _reward_forms(
    name: str, decisions: int = 30, k: int = 5, reward_version: str = "v2"
) -> tuple[float, int]:
    """(max |full - observation-only| stale reward, states where the world had moved) on a
    noisy-expert episode (world snapshot after each decision's first sub-step)."""
    from ndp.envs.metaworld_env import WORLD_OBS

    env = make_env(name, horizon=150, reward_version=reward_version)
    mw = env.unwrapped
    policy = ENV_POLICY_MAP[name]()
    rng = np.random.default_rng(0)
    obs, _ = env.reset(seed=0)
    diff, moved = 0.0, 0
    for _ in range(decisions):
        for j in range(k):
            a = np.clip(policy.get_action(obs) + rng.normal(0.0, 0.3, 4), -1.0, 1.0)
            obs, *_ = env.step(a)
            if j == 0:
                snap = mw.world_snapshot()
                continue
            full = mw.stale_reward(snap, a, from_obs=False)
            diff = max(diff, abs(full - mw.stale_reward(snap, a, from_obs=True)))
            moved += int(np.abs(obs[WORLD_OBS] - snap[2][WORLD_OBS]).max() > 1e-6)
    env.close()
    return diff, moved


@pytest.mark.filterwarnings("ignore:Constant")
@pytest.mark.parametrize("name", metaworld_env_names())
@pytest.mark.parametrize("version", ["v2", "v1"])
def test_reward_from_obs_flag_is_measured(name, version):
    """The reward_from_obs flag of each reward version (the task table's for v2): both
    stale-reward forms agree exactly on recorded states where it is set (while the world
    moved), and differ where it is not."""
    from ndp.envs import TASKS
    from ndp.envs.metaworld_env import reward_from_obs

    if version == "v1" and name in V1_REWARD_BROKEN:
        pytest.skip("v1 reward refused")
    diff, moved = _reward_forms(name, reward_version=version)
    if version == "v2":
        assert TASKS[name].reward_from_obs == reward_from_obs(name, "v2")
    if reward_from_obs(name, version):
        assert moved > 0 and diff == 0.0
    else:
        assert diff > 1e-6


def _live_rewards_with_and_without_stale_calls(name: str, reward_version: str) -> tuple:
    """A noisy expert's episode twice: through ChunkedEnv with the stale rule (stale rewards
    recomputed at every inner sub-step) and on a plain env; (live rewards, simulator qpos after
    each decision) of each."""
    policy = ENV_POLICY_MAP[name]()
    rng = np.random.default_rng(1)
    chunked = ChunkedEnv(make_env(name, reward_version=reward_version), k=5, stale_world=True)
    plain = make_env(name, reward_version=reward_version)
    obs, _ = chunked.reset(seed=3)
    plain.reset(seed=3)
    live_c, live_p, obs_c, obs_p = [], [], [], []
    for _ in range(30):
        chunk = np.clip(policy.get_action(obs) + rng.normal(0.0, 0.2, (5, 4)), -1.0, 1.0)
        obs, _, _, _, info = chunked.step(chunk)
        live_c += list(info["sub_rewards_live"])
        obs_c.append(chunked.unwrapped.data.qpos.copy())
        for a in chunk:
            _, r, *_ = plain.step(a)
            live_p.append(r)
        obs_p.append(plain.unwrapped.data.qpos.copy())
    chunked.close()
    plain.close()
    return (live_c, live_p), (obs_c, obs_p)


@pytest.mark.filterwarnings("ignore:Constant")
@pytest.mark.parametrize("name", sorted(set(metaworld_env_names()) - V1_REWARD_BROKEN))
def test_v1_stale_rewards_never_change_a_live_reward(name):
    """The v1 rewards of several tasks write flags (pickCompleted, placeCompleted, ...) from the
    state they are computed on. Each is set before it is read within one reward call, so a stale
    recomputation never reaches a later live reward: on a noisy expert's episode (which picks
    and places, unlike random actions), the live rewards and simulator states with the stale
    rule equal a plain env's bit for bit."""
    (live_c, live_p), (obs_c, obs_p) = _live_rewards_with_and_without_stale_calls(name, "v1")
    assert live_c == live_p
    np.testing.assert_array_equal(np.array(obs_c), np.array(obs_p))
