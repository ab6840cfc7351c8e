"""The per-task spec table and the inverse controllers."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from ndp.envs import TASKS, TaskSpec, get_task_spec
from ndp.envs.metaworld_env import metaworld_env_names


def test_table_covers_all_tasks():
    names = metaworld_env_names()
    assert len(names) == 50
    assert set(TASKS) == {*names, "throw", "pick", "point-mass", "point-mass-3d"}
    for n in ("push-v3", "reach-v3", "soccer-v3", "faucet-open-v3"):
        s = TASKS[n]
        assert s.family == "metaworld" and s.dmp_dofs == 4 and s.action_dim == 4
        assert s.horizon == 150 and s.obs_dim == 39
    for n in ("throw", "pick"):
        s = TASKS[n]
        assert s.family == "jaco" and s.dmp_dofs == 7 and s.action_dim == 7
    for s in TASKS.values():
        assert len(s.dof_names) == len(s.dof_units) == len(s.action_scale) == s.dmp_dofs
        assert len(s.action_low) == len(s.action_high) == s.action_dim
        assert s.control_dt > 0 and s.sim_dt > 0


def test_spec_is_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        TASKS["push-v3"].horizon = 3  # type: ignore[misc]
    assert isinstance(get_task_spec("push-v3"), TaskSpec)


def test_lookup_aliases_and_unknown_names():
    assert get_task_spec("jaco-throw").name == "throw"
    assert get_task_spec("ndp/JacoPick-v0").name == "pick"
    assert get_task_spec("ndp/push-v3").name == "push-v3"
    with pytest.raises(ValueError, match="push-v3"):
        get_task_spec("psuh-v3")
    with pytest.raises(ValueError, match="name"):
        get_task_spec(3)  # type: ignore[arg-type]


def test_metaworld_inverse_controller_by_hand():
    spec = TASKS["push-v3"]
    traj = torch.tensor(
        [[0.0, 0.6, 0.2, -1.0], [0.005, 0.6, 0.19, 0.5], [0.025, 0.59, 0.19, 3.0]]
    )  # [k+1 = 3, 4]
    act = spec.inverse_controller(traj)
    expected = torch.tensor([[0.5, 0.0, -1.0, 0.5], [1.0, -1.0, 0.0, 1.0]])
    torch.testing.assert_close(act, expected, atol=1e-5, rtol=0)
    # Batched, and robot_pos replaces the first point.
    batch = traj.expand(5, 3, 4)
    start = torch.tensor([0.004, 0.6, 0.2, -1.0]).expand(5, 4)
    out = spec.inverse_controller(batch, robot_pos=start)
    assert out.shape == (5, 2, 4)
    torch.testing.assert_close(out[:, 0, 0], torch.full((5,), 0.1), atol=1e-4, rtol=0)


def test_jaco_inverse_controller_by_hand():
    spec = TASKS["throw"]
    traj = torch.zeros(2, 6, 7, dtype=torch.float64)  # [B = 2, k+1 = 6, D = 7]
    traj[:, 1:, 0] = 0.05  # one step of +0.05 rad on joint 1, then hold
    traj[:, 1:, 6] = torch.tensor([0.02, 0.04, 0.06, 0.08, 0.5])  # fingers
    act = spec.inverse_controller(traj)
    assert act.shape == (2, 5, 7) and act.dtype == torch.float64
    torch.testing.assert_close(act[0, :, 0], torch.tensor([0.5, 0, 0, 0, 0], dtype=torch.float64))
    torch.testing.assert_close(
        act[0, :, 6], torch.tensor([0.2, 0.2, 0.2, 0.2, 1.0], dtype=torch.float64)
    )


def test_inverse_controller_bad_shapes():
    with pytest.raises(ValueError, match="traj"):
        TASKS["push-v3"].inverse_controller(torch.zeros(1, 4))
    with pytest.raises(ValueError, match="traj"):
        TASKS["push-v3"].inverse_controller(torch.zeros(3, 7))


def test_controller_is_data_of_the_task_row():
    """The controller is a field of the task (a registry of kinds), not a TaskSpec method; a
    non-linear controller makes the NDP head use the composed DMP + controller path."""
    import dataclasses

    from ndp.envs.controllers import CONTROLLERS, DeltaController
    from ndp.policies import PolicyConfig, build_actor_critic

    spec = TASKS["push-v3"]
    assert isinstance(spec.controller, DeltaController) and CONTROLLERS["delta"] is DeltaController
    assert spec.controller.absolute == (False, False, False, True)
    with pytest.raises(ValueError, match="equal length"):
        DeltaController(scale=(1.0,), absolute=(False, True), low=(0.0,), high=(1.0,))
    with pytest.raises(ValueError, match="scale"):
        DeltaController(scale=(0.0,), absolute=(False,), low=(-1.0,), high=(1.0,))

    @dataclasses.dataclass(frozen=True)
    class Doubled:  # a non-linear stand-in for another actuation
        kind = "doubled"

        def __call__(self, traj, robot_pos=None, clip=True):
            return 2.0 * spec.controller(traj, robot_pos, clip)

    other = dataclasses.replace(spec, controller=Doubled())
    cfg = PolicyConfig.from_dict(
        {"n_basis": 6, "a_z": 10.0, "dmp_steps": 35, "goal_scale": 2.0, "weight_scale": 25.0}
    )
    fused = build_actor_critic(39, spec, cfg).head
    composed = build_actor_critic(39, other, cfg).head
    assert fused._fused and not composed._fused
    raw = torch.randn(3, fused.n_params, generator=torch.Generator().manual_seed(0))
    y0 = torch.tensor([[0.0, 0.6, 0.2, -1.0]]).expand(3, 4)
    a1 = fused.decode(raw, y0, torch.zeros(3, 4))[0]
    a2 = composed.decode(raw, y0, torch.zeros(3, 4))[0]
    # float32 positions of ~0.6 m differenced and divided by 0.01 m: ~1e-5 of rounding
    torch.testing.assert_close(a2, 2.0 * a1, rtol=1e-4, atol=1e-4)
