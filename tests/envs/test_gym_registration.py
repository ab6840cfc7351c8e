"""gymnasium ids: every task registered with its horizon, usable without importing ndp first."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import ndp  # noqa: E402
from ndp.envs import TASKS, TORQUE_TASKS, register_envs, register_torque_envs  # noqa: E402
from ndp.envs.factory import CHUNKED_KS, gym_id_table  # noqa: E402
from ndp.gym_ids import LEGACY_IDS  # noqa: E402

SRC = Path(ndp.__file__).resolve().parents[1]


OLD_IDS = sum(s.env_id in LEGACY_IDS for s in TASKS.values())
"""Task rows whose older id (ndp/JacoThrow-v0, ndp/PointMass2D-v0, ...) stays registered as a
deprecated alias of ndp/<name>."""


def test_every_id_has_the_task_horizon_as_max_episode_steps():
    ids = set(register_envs()) | set(register_torque_envs())
    assert len(ids) == len(TASKS) * (1 + len(CHUNKED_KS)) + len(TORQUE_TASKS) + OLD_IDS
    assert OLD_IDS == 4  # JacoThrow-v0, JacoPick-v0, PointMass2D-v0, PointMass3D-v0
    for name in TASKS:  # one scheme: ndp/<task> and ndp/<task>-k<k> for every task
        assert f"ndp/{name}" in ids and f"ndp/{name}-k5" in ids
    for name, spec in TASKS.items():
        assert (
            gym.spec(spec.env_id).max_episode_steps
            == spec.horizon
            == 150 - 100 * (spec.family == "toy")
        ), name
        for k in CHUNKED_KS:
            chunked = gym.spec(f"ndp/{name}-k{k}")
            assert chunked.max_episode_steps == -(-spec.horizon // k), name  # ceil: 30 at k 5
            assert chunked.kwargs == {"name": name, "k": k}
    for name, spec in TORQUE_TASKS.items():
        assert gym.spec(spec.env_id).max_episode_steps == spec.horizon, name
    # string entry points: registering imports no env class
    assert gym.spec("ndp/push-v3").entry_point == "ndp.envs.factory:_make_registered"


def test_gymnasium_has_no_plugin_entry_points():
    # gymnasium 1.0 removed the `gymnasium.envs` entry-point plugins (0.26-0.29 loaded them on
    # `import gymnasium`), which is why ndp ships a start-up hook (_ndp_gymnasium.pth) instead.
    # Should a later gymnasium load plugins again, this fails: declare the entry point then.
    from gymnasium.envs import registration

    assert not hasattr(registration, "load_plugin_envs")
    assert not hasattr(registration, "load_env_plugins")


def test_the_shipped_id_table_is_the_one_the_task_tables_give():
    from ndp import gym_ids

    shipped = json.loads(gym_ids.TABLE.read_text())
    assert shipped == gym_id_table(), "rewrite it: ndp.envs.factory.write_gym_id_table()"
    # and the ids it expands to are exactly what `import ndp.envs` registered
    by_id = {g.id: g for g in gym_ids.shipped()}
    assert set(by_id) == set(register_envs()) | set(register_torque_envs())
    for i, g in by_id.items():
        spec = gym.spec(i)
        assert (spec.entry_point, spec.kwargs, spec.max_episode_steps) == (
            g.entry_point,
            g.kwargs,
            g.max_episode_steps,
        ), i
        assert spec.disable_env_checker == g.disable_env_checker, i


HOOK_SCRIPT = r"""
import json
import sys
import time

t = time.perf_counter()
import numpy as np
import gymnasium
import_s = time.perf_counter() - t
heavy = sorted(m for m in sys.modules if m.split(".")[0] in ("torch", "mujoco", "metaworld")
               or m.startswith("ndp.envs"))
ids = [i for i in gymnasium.registry if i.startswith("ndp/")]
env = gymnasium.make("ndp/reach-v3")  # imports ndp.envs now, through the string entry point
env.reset(seed=0)
steps, done = 0, False
while not done:
    _, _, term, trunc, _ = env.step(env.action_space.sample() * 0)
    steps += 1
    done = term or trunc
print("RESULT " + json.dumps({"heavy": heavy, "n_ids": len(ids), "steps": steps,
                              "max_steps": env.spec.max_episode_steps,
                              "ndp": sys.modules["ndp"].__file__, "import_s": import_s}))
"""


def test_import_gymnasium_alone_registers_the_ids_through_the_startup_hook(tmp_path):
    """The installed package (the test venv is an editable install, like `make install`) ships
    _ndp_gymnasium.pth: `import gymnasium` registers every id without importing a simulator."""
    pytest.importorskip("metaworld")
    import site
    import sysconfig

    dirs = {sysconfig.get_paths()["purelib"], *site.getsitepackages()}
    assert any((Path(d) / "_ndp_gymnasium.pth").is_file() for d in dirs), (
        f"_ndp_gymnasium.pth is not in {sorted(dirs)}: reinstall the package (make install)"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NDP_NO_GYMNASIUM_HOOK")}
    r = subprocess.run(
        [sys.executable, "-c", HOOK_SCRIPT],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        cwd=tmp_path,  # not the repository root: only the installed package can be found
        env=env | {"OMP_NUM_THREADS": "1"},
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    out = json.loads(next(x for x in r.stdout.splitlines() if x.startswith("RESULT "))[7:])
    assert out["heavy"] == []  # registering imported no simulator, torch or env module
    assert out["n_ids"] == len(TASKS) * (1 + len(CHUNKED_KS)) + len(TORQUE_TASKS) + OLD_IDS
    assert out["steps"] == out["max_steps"] == 150
    # and the switch turns it off
    r = subprocess.run(
        [
            sys.executable,
            "-c",
            "import gymnasium; print(sum(i.startswith('ndp/') for i in gymnasium.registry))",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
        cwd=tmp_path,
        env=env | {"NDP_NO_GYMNASIUM_HOOK": "1"},
    )
    assert r.stdout.strip() == "0"


def test_a_failing_registration_warns_and_never_breaks_import_gymnasium(tmp_path):
    import _ndp_gymnasium

    # a gym_ids that raises: gymnasium still imports, with one warning naming the way out
    fake = tmp_path / "ndp"
    fake.mkdir()
    (fake / "__init__.py").write_text("")
    (fake / "gym_ids.py").write_text("def register_shipped():\n    raise OSError('table gone')\n")
    code = (
        f"import sys, warnings; sys.path.insert(0, {str(tmp_path)!r})\n"
        "import _ndp_gymnasium; _ndp_gymnasium.install()\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    import gymnasium\n"
        "print('OK', gymnasium.__version__, [str(x.message) for x in w if 'ndp' in str(x.message)])"
    )
    r = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        | {"NDP_NO_GYMNASIUM_HOOK": ""},
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.startswith("OK "), r.stdout
    assert "table gone" in r.stdout and "import ndp.envs" in r.stdout
    assert _ndp_gymnasium.__file__  # the hook module itself is importable in the test venv


def test_a_built_wheel_ships_the_hook_and_the_table(tmp_path):
    pytest.importorskip("setuptools")
    pytest.importorskip("wheel")
    import shutil
    import zipfile

    root = Path(__file__).resolve().parents[2]
    proj = tmp_path / "proj"
    proj.mkdir()
    for f in ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md", "LICENSE"):
        shutil.copy(root / f, proj / f)
    shutil.copytree(
        root / "src", proj / "src", ignore=shutil.ignore_patterns("*.egg-info", "__pycache__")
    )
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "-w",
            str(tmp_path / "dist"),
            str(proj),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    (whl,) = (tmp_path / "dist").glob("*.whl")
    names = set(zipfile.ZipFile(whl).namelist())
    assert {
        "_ndp_gymnasium.pth",
        "_ndp_gymnasium.py",
        "ndp/gym_ids.py",
        "ndp/gym_ids.json",
    } <= names
    assert (
        zipfile.ZipFile(whl).read("_ndp_gymnasium.pth")
        == (root / "src" / "_ndp_gymnasium.pth").read_bytes()
    )


SCRIPT = r"""
import json
import sys

sys.path.insert(0, SRC)
import gymnasium

assert "ndp" not in sys.modules
env = gymnasium.make("ndp.envs:ndp/reach-v3")  # the module prefix: gymnasium imports it
assert sys.modules["ndp"].__file__.startswith(SRC)
obs, info = env.reset(seed=0)
steps, truncated = 0, False
while not truncated:
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample() * 0)
    steps += 1
chunked = gymnasium.make("ndp/reach-v3-k5")  # registered now
chunked.reset(seed=0)
decisions, done = 0, False
while not done:
    _, _, term, trunc, info = chunked.step(chunked.action_space.sample() * 0)
    decisions += 1
    done = term or trunc
print("RESULT " + json.dumps({"max_steps": env.spec.max_episode_steps, "steps": steps,
                              "chunked_max": chunked.spec.max_episode_steps,
                              "decisions": decisions}))
"""


def test_make_by_module_prefix_without_importing_ndp_and_episodes_end_at_the_horizon():
    pytest.importorskip("metaworld")
    r = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(SCRIPT.replace("SRC", repr(str(SRC))))],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        # the module prefix alone, without the start-up hook (which would import ndp.gym_ids)
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        | {"OMP_NUM_THREADS": "1", "NDP_NO_GYMNASIUM_HOOK": "1"},
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    out = json.loads(next(x for x in r.stdout.splitlines() if x.startswith("RESULT "))[7:])
    # the env's own horizon and gymnasium's TimeLimit end the episode at the same step
    assert out == {"max_steps": 150, "steps": 150, "chunked_max": 30, "decisions": 30}


def test_old_ids_are_deprecated_aliases_of_the_one_scheme():
    import warnings

    register_envs()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = gym.make("ndp/JacoThrow-v0")
    assert any("use gymnasium.make('ndp/throw')" in str(w.message) for w in caught)
    new = gym.make("ndp/throw")
    o1, _ = old.reset(seed=3)
    o2, _ = new.reset(seed=3)
    np.testing.assert_array_equal(o1, o2)
    assert gym.spec("ndp/point-mass").max_episode_steps == 50
    old.close()
    new.close()


@pytest.mark.parametrize(
    "env_id,steps,env_steps",
    [("ndp/point-mass", 37, 37), ("ndp/push-v3", 300, 300), ("ndp/push-v3-k5", 40, 200)],
)
def test_max_episode_steps_is_honoured_at_both_ends(env_id, steps, env_steps):
    """gymnasium.make(..., max_episode_steps=N) runs N steps (N decisions of k env steps for a
    chunked id), longer and shorter than the task's own horizon, and the default stays it."""
    import gymnasium

    import ndp.envs  # noqa: F401  # registers the ids

    def length(env) -> tuple[int, int]:
        env.reset(seed=0)
        n = 0
        while True:
            _, _, term, trunc, info = env.step(env.action_space.sample() * 0)
            n += 1
            if term or trunc:
                return n, int(info.get("n_substeps", 1))

    env = gymnasium.make(env_id, max_episode_steps=steps)
    try:
        n, _ = length(env)
        assert n == steps
        n, sub = length(env)  # every episode, not only the first
        assert n == steps and sub == env_steps // steps
    finally:
        env.close()
    default = gymnasium.make(env_id)  # the registered horizon
    try:
        n, _ = length(default)
        assert n == default.spec.max_episode_steps
    finally:
        default.close()
