"""The NDP head diagnostic shows the handicaps it is meant to catch (real push-v3 rollouts)."""

from __future__ import annotations

import numpy as np
import pytest

from ndp.experiments.diagnose import diagnose


@pytest.mark.filterwarnings("ignore:Constant")
def test_diagnostic_flags_the_gripper_noise_leak_and_the_mean_clip():
    new = diagnose("push-v3", decisions=80, seed=0)
    old = diagnose(
        "push-v3",
        decisions=80,
        seed=0,
        absolute_mode="dmp",
        mean_clip=True,
        dmp_state="measured",
        dmp_velocity="state",
    )
    assert len(new["intended_disp"]) == 5 and len(new["executed_disp"]) == 5
    # the first version's gripper: the previous decision's noise steers the command
    assert old["grip_noise_corr"][0] > 0.9 and old["grip_mean_std"][0] > 0.3
    # the default: it does not
    assert abs(new["grip_noise_corr"][0]) < 0.5 and new["grip_mean_std"][0] < 0.05
    assert np.all(np.isfinite(new["executed_disp"]))
