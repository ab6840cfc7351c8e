"""The observation layout (ndp.envs.observations.LAYOUTS) against the environments and
docs/observations.md."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from ndp.envs import make_env
from ndp.envs.observations import LAYOUTS, layout_markdown

DOC = Path(__file__).resolve().parents[2] / "docs" / "observations.md"


def _block(family: str, start: int) -> slice:
    a, b, _ = next(r for r in LAYOUTS[family] if r[0] == start)
    return slice(a, b)


def test_blocks_tile_each_observation():
    for family, rows in LAYOUTS.items():
        assert rows[0][0] == 0
        for (_, b, _), (a2, _, _) in itertools.pairwise(rows):
            assert b == a2, family


def test_metaworld_layout_matches_the_env():
    env = make_env("push-v3", fixed_goal="release")
    obs, _ = env.reset(seed=0)
    u = env.unwrapped
    assert obs.shape == (LAYOUTS["metaworld"][-1][1],)
    np.testing.assert_allclose(obs[_block("metaworld", 0)], u.robot_state()[0][:3])
    np.testing.assert_allclose(obs[_block("metaworld", 36)], u.mw._target_pos)
    np.testing.assert_allclose(obs[_block("metaworld", 4)][:2], (0.0, 0.6), atol=1e-3)  # puck
    np.testing.assert_allclose(obs[_block("metaworld", 11)], 0.0)  # push has one object
    obs2, _, _, _, _ = env.step(np.array([1.0, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(obs2[18:36], obs[0:18])  # the previous frame
    env.close()
    r9 = make_env("push-v3", observation="release9")
    o9, _ = r9.reset(seed=0)
    full = make_env("push-v3")
    of, _ = full.reset(seed=0)
    np.testing.assert_allclose(o9, np.concatenate([of[0:3], of[4:7], of[36:39]]))
    r9.close()
    full.close()


def test_jaco_layout_matches_the_env():
    for task in ("throw", "pick"):
        env = make_env(task)
        obs, _ = env.reset(seed=1)
        u = env.unwrapped
        d = u.data
        assert obs.shape == (LAYOUTS["jaco"][-1][1],)
        np.testing.assert_allclose(obs[_block("jaco", 0)], d.qpos[u._arm_q])
        np.testing.assert_allclose(obs[_block("jaco", 6)], d.qpos[u._fin_q])
        np.testing.assert_allclose(obs[_block("jaco", 18)], d.qpos[u._cube_q : u._cube_q + 3])
        np.testing.assert_allclose(obs[_block("jaco", 28)], d.site_xpos[u._grip])
        np.testing.assert_allclose(obs[_block("jaco", 31)], u._goal)
        env.close()


def test_toy_layout_matches_the_env():
    env = make_env("point-mass")
    obs, _ = env.reset(seed=2)
    u = env.unwrapped
    np.testing.assert_allclose(obs[_block("toy", 0)], u._pos)
    np.testing.assert_allclose(obs[_block("toy", 2)], u._vel)
    np.testing.assert_allclose(obs[_block("toy", 4)], u._goal)


def test_the_doc_states_the_layout():
    assert layout_markdown() in DOC.read_text()
