"""A stranger adds a robot family in one module: an env on NDPEnv, a TaskSpec row, one
``ndp.envs.register_task`` call and, for demonstrations, one
``ndp.bc.experts.register_expert`` call; then every method trains on it, the chunked env,
gymnasium's ids, evaluation, demonstrations and behaviour cloning work unchanged. (Written as
an outside user would, with the public API.)"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import ndp  # noqa: E402
from ndp.envs import TASKS, TaskSpec, register_task  # noqa: E402
from ndp.envs.base import NDPEnv, defer_seed  # noqa: E402
from ndp.envs.factory import FAMILIES  # noqa: E402

STEP = 0.05  # m per unit action


class SliderEnv(NDPEnv):
    """A block on a 1-D rail pushed towards a random target (obs: x, v, target)."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(self, horizon: int = 40, render_mode: str | None = None) -> None:
        self._setup(horizon, render_mode, action_dim=1)
        self._set_fixed_goal(None)
        self.observation_space = gym.spaces.Box(-2.0, 2.0, shape=(3,), dtype=np.float64)
        self._x = self._v = self._target = 0.0
        self._steps = 0

    def robot_state(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([self._x]), np.array([self._v])

    def world_snapshot(self) -> np.ndarray:
        return np.array([self._target])

    def stale_reward(self, snapshot: np.ndarray, action: Any = None) -> float:
        return -abs(float(snapshot[0]) - self._x)

    def _obs(self) -> np.ndarray:
        return np.array([self._x, self._v, self._target])

    def _info(self) -> dict[str, Any]:
        pos, vel = self.robot_state()
        return {"success": abs(self._target - self._x) < 0.05, "robot_pos": pos, "robot_vel": vel}

    def reset(self, *, seed: int | None = None, options: Any = None) -> tuple[np.ndarray, dict]:
        self._reset_rng(seed)
        rng = self._task_rng()
        self._x, self._v, self._target = 0.0, 0.0, float(rng.uniform(-0.5, 0.5))
        self._steps = 0
        return self._obs(), self._info()

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        a = float(np.clip(np.asarray(action, dtype=np.float64).reshape(1)[0], -1, 1))
        new = self._x + STEP * a
        self._v, self._x = (new - self._x) / 0.05, new
        self._steps += 1
        return (
            self._obs(),
            -abs(self._target - self._x),
            False,
            self._steps >= self.horizon,
            self._info(),
        )


def _make(spec: Any, horizon: int, render_mode: str | None, **kw: Any) -> SliderEnv:
    env = SliderEnv(horizon=horizon, render_mode=render_mode)
    defer_seed(env, kw.get("seed"))
    return env


class SliderExpert:
    """Full speed towards the target (obs: x, v, target)."""

    def reset(self, env: Any, obs: np.ndarray, info: dict[str, Any]) -> None:
        pass

    def act(self, env: Any, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return np.clip(np.array([(obs[2] - obs[0]) / STEP]), -1.0, 1.0)


def _expert(spec: Any) -> SliderExpert:
    return SliderExpert()


SPEC = TaskSpec(name="slider", family="rail", env_id="ndp/Slider-v0", dmp_dofs=1,
                dof_names=("x",), dof_units=("m",), y0_source="the block (m, m/s)",
                action_dim=1, action_low=(-1.0,), action_high=(1.0,), action_scale=(STEP,),
                action_absolute=(False,), horizon=40, control_dt=0.05, sim_dt=0.05,
                obs_dim=3)  # fmt: skip


@pytest.fixture(scope="module")
def slider():
    from ndp.bc.experts import EXPERTS, register_expert

    ids = register_task(SPEC, _make)
    register_expert("rail", _expert)
    yield ids
    EXPERTS.pop("rail")
    # leave the table, the names and gymnasium's registry as they were for the other tests
    from ndp.envs import spec as spec_module

    TASKS.pop("slider")
    FAMILIES.pop("rail")
    spec_module._ALIASES.pop("ndp/Slider-v0")
    for i in ids:
        gym.registry.pop(i)


def test_a_new_family_is_one_registration_and_everything_works_on_it(slider, tmp_path):
    assert slider == ["ndp/Slider-v0", "ndp/slider-k5"]
    env = ndp.make_env("slider", k=5)  # the chunked env with the stale-world rule
    obs, info = env.reset(seed=0)
    assert obs.shape == (3,) and info["dmp_y0"].shape == (1,)
    *_, info = env.step(np.ones((5, 1)))
    assert info["robot_pos"].shape == (6, 1) and info["n_substeps"] == 5
    env.close()
    per_step = gym.make("ndp/Slider-v0")
    assert per_step.spec.max_episode_steps == 40
    per_step.close()
    # every on-policy method trains on it with the shared trainer
    from ndp.rl.config import PPOConfig, TrainConfig
    from ndp.rl.evaluate import evaluate
    from ndp.rl.run import train

    for algo in ("ndp", "ppo", "ppo-multi"):
        run = tmp_path / algo
        cfg = TrainConfig(task="slider", algo=algo, steps=400, seed=0, run_dir=str(run),
                          progress=False, tensorboard=False, vector="sync",
                          ppo=PPOConfig(steps_per_update=200, minibatches=2))  # fmt: skip
        metrics = train(cfg)
        assert metrics["update"] == 2
        out = evaluate(run, episodes=2)
        assert 0.0 <= out["success_any"] <= 1.0


def test_its_expert_demonstrates_and_a_policy_is_cloned_from_it(slider, tmp_path):
    from ndp.bc.demos import collect, save_demos
    from ndp.bc.train import BCConfig, train_bc
    from ndp.rl.evaluate import evaluate

    demos = collect("slider", 6, seed=0)
    assert demos.n_episodes == 6 and demos.episode_success.all()
    path = save_demos(demos, tmp_path / "slider-demos.npz")
    run = tmp_path / "bc"
    out = train_bc(BCConfig(demos=str(path), model="ndp", run_dir=str(run), epochs=2,
                            progress=False, tensorboard=False))  # fmt: skip
    assert out["episodes"] == 6
    assert 0.0 <= evaluate(run, episodes=2)["success_any"] <= 1.0
    from ndp.bc.experts import register_expert

    with pytest.raises(ValueError, match="'rail' already has a scripted expert"):
        register_expert("rail", _expert)


def test_a_taken_name_or_a_family_without_a_factory_is_refused(slider):
    with pytest.raises(ValueError, match="'slider' already names a task"):
        register_task(SPEC, _make)
    other = TaskSpec(**{**SPEC.__dict__, "name": "slider-2", "env_id": "ndp/Slider2-v0",
                        "family": "nowhere", "controller": None, "ndp": None})  # fmt: skip
    with pytest.raises(ValueError, match="family 'nowhere' has no env factory"):
        register_task(other)
    assert "slider-2" not in TASKS


def test_builtin_families_register_through_register_task(monkeypatch):
    """The built-in tables are exactly what ``register_task`` makes of the built-in rows: the
    Meta-World, Jaco and toy families take the path a user's family takes (no table is built
    any other way)."""
    from ndp.envs import factory, spec
    from ndp.gym_ids import shipped

    builtin = {"metaworld", "jaco", "toy"}  # (other tests of this file add a "rail" family)
    tasks = {n: s for n, s in spec.TASKS.items() if s.family in builtin}
    torque = {n: s for n, s in spec.TORQUE_TASKS.items() if s.family in builtin}
    names = {*tasks, *torque}
    aliases = {a: n for a, n in spec._ALIASES.items() if n in names}
    before = (tasks, torque, aliases)
    families = tuple(
        {f: m for f, m in t.items() if f in builtin}
        for t in (factory.FAMILIES, factory.TORQUE_FAMILIES)
    )
    for mod, name in ((spec, "TASKS"), (spec, "TORQUE_TASKS"), (spec, "_ALIASES"),
                      (factory, "FAMILIES"), (factory, "TORQUE_FAMILIES")):  # fmt: skip
        getattr(mod, name)  # exists
        monkeypatch.setattr(mod, name, {})
    monkeypatch.setattr(factory, "TASKS", spec.TASKS)  # the factory's name for the same table
    monkeypatch.setattr(factory, "TORQUE_TASKS", spec.TORQUE_TASKS)
    calls: list[str] = []
    real = factory.register_task

    def counting(row: Any, *a: Any, **kw: Any) -> list[str]:
        calls.append(row.name)
        return real(row, *a, **kw)

    monkeypatch.setattr(factory, "register_task", counting)
    factory.register_builtin_families()
    assert calls == list(before[0])  # one call per position row, in the table's order
    assert (spec.TASKS, spec.TORQUE_TASKS, spec._ALIASES) == before
    assert (factory.FAMILIES, factory.TORQUE_FAMILIES) == families
    assert set(families[0]) == {"metaworld", "jaco", "toy"}
    assert set(families[1]) == {"metaworld", "jaco"}
    # the start-up hook's shipped id table is the one these registrations give
    assert factory.gym_id_table() == {
        "tasks": {n: [s.env_id, s.horizon] for n, s in before[0].items()},
        "chunked_ks": list(factory.CHUNKED_KS),
        "torque": {n: [s.env_id, s.horizon] for n, s in before[1].items()},
    }
    assert {g.id for g in shipped()} <= set(__import__("gymnasium").registry)


def test_a_torque_factory_for_a_family_without_torque_rows_is_refused():
    import dataclasses

    from ndp.envs import factory

    other = dataclasses.replace(SPEC, name="slider-torque", env_id="ndp/slider-torque", aliases=())
    with pytest.raises(ValueError, match="torque: family 'rail' has no torque-actuated rows"):
        register_task(other, _make, torque=_make)
    assert "slider-torque" not in TASKS and "rail" not in factory.TORQUE_FAMILIES


def test_a_clash_in_any_new_row_adds_none_of_them(monkeypatch):
    """register_task adds a task and its torque rows as one: when a torque row's name is taken,
    the position row is not left behind half-registered."""
    import dataclasses

    from ndp.envs import factory, spec
    from ndp.envs.spec import torque_rows

    for name in ("TASKS", "TORQUE_TASKS", "_ALIASES"):
        monkeypatch.setattr(spec, name, dict(getattr(spec, name)))
    monkeypatch.setattr(factory, "TASKS", spec.TASKS)
    monkeypatch.setattr(factory, "TORQUE_TASKS", spec.TORQUE_TASKS)
    new = dataclasses.replace(spec.TASKS["push-v3"], name="zz-push", env_id="ndp/ZzPush-v0",
                              aliases=())  # fmt: skip
    rows = torque_rows(new)
    assert rows, "the metaworld family has torque rows"
    squatter = dataclasses.replace(SPEC, name=rows[0].name, env_id="ndp/Squat-v0", aliases=())
    spec.add_tasks([squatter])
    with pytest.raises(ValueError, match=f"'{rows[0].name}' already names a task"):
        register_task(new)
    assert "zz-push" not in spec.TASKS and "ndp/ZzPush-v0" not in spec._ALIASES
    # two new rows that share a name are refused together as well
    twin = dataclasses.replace(new, name="zz-push-2", env_id="ndp/ZzPush-v0")
    with pytest.raises(ValueError, match="'ndp/ZzPush-v0' names two of the new rows"):
        spec.add_tasks([dataclasses.replace(new, aliases=()), twin])
    assert "zz-push" not in spec.TASKS and "zz-push-2" not in spec.TASKS


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"name": ""}, r"^spec\.name: expected letters"),
        ({"name": "has space"}, r"^spec\.name: expected letters"),
        ({"horizon": -3}, r"^spec\.horizon: expected an integer >= 1, got -3"),
        ({"dmp_dofs": 0}, r"^spec\.dmp_dofs: expected an integer >= 1"),
        ({"env_id": "bad id!"}, r"^spec\.env_id: expected a gymnasium id"),
        ({"action_low": (1.0,)}, r"^spec\.action_low: expected below action_high"),
        ({"action_dim": 2}, r"^spec\.action_low: expected 2 values, got 1"),
        ({"control_dt": float("nan")}, r"^spec\.control_dt: expected finite numbers"),
        ({"sim_dt": 0.1}, r"^spec\.sim_dt: expected at most control_dt"),
        ({"obs_dim": 7}, r"^spec\.obs_dim: the row says 7, but the env's obs has shape \[3\]"),
    ],
)
def test_a_malformed_row_is_refused_naming_its_field_and_leaves_no_trace(change, message):
    """register_task checks every field, and probes the env, before anything is added."""
    import dataclasses

    from ndp.envs import factory

    fields = {"name": "slider-bad", "env_id": "ndp/SliderBad-v0", "aliases": (),
              "family": "rail-bad", **change}  # fmt: skip
    row = dataclasses.replace(SPEC, **fields)
    ids_before = set(gym.registry)
    with pytest.raises(ValueError, match=message):
        register_task(row, _make)
    assert "slider-bad" not in TASKS and "rail-bad" not in factory.FAMILIES
    assert set(gym.registry) == ids_before


def test_a_factory_that_fails_is_named_and_leaves_no_trace():
    import dataclasses

    from ndp.envs import factory

    def broken(spec: Any, horizon: int, render_mode: str | None, **kw: Any) -> Any:
        raise RuntimeError("no simulator here")

    row = dataclasses.replace(SPEC, name="slider-broken", env_id="ndp/SliderBroken-v0",
                              aliases=(), family="rail-broken")  # fmt: skip
    with pytest.raises(ValueError, match=r"^make: building 'slider-broken' failed \(Runtime"):
        register_task(row, broken)
    assert "slider-broken" not in TASKS and "rail-broken" not in factory.FAMILIES
