"""An ONNX export loads and acts through ``ndp.load_policy`` in a process where torch cannot be
imported (issue "a user's first day, part 3"); ``OnnxPolicy.spec`` says what the task is."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import ndp
from policy_fixtures import fixture_policy

pytest.importorskip("onnxruntime")

BLOCK = """
import sys
class _Block:
    def find_spec(self, name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ModuleNotFoundError(f"No module named {name!r} (blocked by the test)")
sys.meta_path.insert(0, _Block())
import numpy as np
import ndp
pol = ndp.load_policy(sys.argv[1])
obs = np.zeros(pol.spec.obs_dim, np.float32)
y0 = np.zeros(pol.spec.dmp_dofs, np.float32)
a = pol.act(obs, ndp.RobotState(y0=y0, dy0=np.zeros_like(y0)))
assert "torch" not in sys.modules
print(type(pol).__name__, a.shape, pol.spec.task, pol.spec.k, len(pol.spec.dof_names))
"""


def test_load_policy_of_an_onnx_folder_needs_no_torch(tmp_path):
    out = ndp.load_policy(fixture_policy("push-v3-ndp")).export(tmp_path / "onnx", format="onnx")
    res = subprocess.run([sys.executable, "-c", BLOCK, str(out)], capture_output=True, text=True,
                         timeout=120)  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["OnnxPolicy", "(5,", "4)", "push-v3", "5", "4"], res.stdout


def test_onnx_policy_spec_agrees_with_the_torch_policy(tmp_path):
    src = ndp.load_policy(fixture_policy("push-v3-ndp"))
    pol = ndp.load_policy(src.export(tmp_path / "onnx", format="onnx"))
    assert pol.spec.obs_dim == src.spec.obs_dim and pol.spec.dmp_dofs == src.spec.dmp_dofs
    assert pol.spec.dof_names == tuple(src.spec.dof_names) and pol.spec.k == 5
    np.testing.assert_allclose(pol.spec.action_low, np.asarray(src.spec.action_low))
    assert pol.spec.control_dt == pytest.approx(float(src.spec.control_dt))
