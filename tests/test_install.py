"""The install layout: the core (torch, numpy, safetensors) gives a working DMP layer and
trained policies that act; the rest are extras.

``pip install neural-dynamic-policies`` installs torch, numpy and safetensors only; ``ndp.dmp``
(and ``ndp.nets``, ``ndp.policies``) must import and run with nothing else, and a shipped policy
(``ndp.load_policy("zoo:...")``) must load and act. The first test runs a Python in which every
package of an extra is unimportable; the others read pyproject.toml, constraints.txt and the
Makefile.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import textwrap
from importlib import metadata
from pathlib import Path

import pytest

import ndp

ROOT = Path(__file__).resolve().parents[1]
SRC = Path(ndp.__file__).resolve().parents[1]  # the ndp under test (editable install or PYTHONPATH)
EXTRAS = ("envs", "rl", "il", "ray", "onnx", "sb3", "stats", "dev")
CORE = {"torch", "numpy", "safetensors"}
# Packages only an extra installs (import names); the core must run with all of them absent.
BLOCKED = (
    "gymnasium mujoco metaworld dm_control scipy matplotlib tensorboard tqdm tyro imageio "
    "imageio_ffmpeg PIL sklearn stable_baselines3 ray yaml onnx onnxruntime rliable arch"
).split()

BARE_SCRIPT = r"""
import importlib.abc
import sys

BLOCKED = set(BLOCKED_NAMES)


class BlockExtras(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {name!r} (blocked by the test)", name=name)
        return None


preloaded = sorted(m for m in sys.modules if m.partition(".")[0] in BLOCKED)
assert not preloaded, f"imported before the test could block them: {preloaded}"
sys.meta_path.insert(0, BlockExtras())
sys.path.insert(0, SRC)

import ndp

assert ndp.__file__.startswith(SRC), ndp.__file__
import ndp.dmp
import ndp.nets
import ndp.policies
import torch
from ndp.dmp import dmp_rollout_reference, fit_dmp

# a rollout through the layer, forward and backward
torch.manual_seed(0)
B, D, N, T = 3, 2, 10, 50
cfg = ndp.DMPConfig(n_basis=N, steps=T)
layer = ndp.DMPLayer(cfg)
goal = torch.randn(B, D, dtype=torch.float64, requires_grad=True)
weights = (10 * torch.randn(B, D, N, dtype=torch.float64)).requires_grad_(True)
y0 = torch.randn(B, D, dtype=torch.float64)
traj = layer(goal, weights, y0, None)
for name in ("pos", "vel", "acc"):
    t = getattr(traj, name)
    assert t.shape == (B, T + 1, D), (name, t.shape)
    assert torch.isfinite(t).all(), name
assert torch.equal(traj.pos[:, 0], y0)
assert (traj.pos[:, -1] - goal).abs().max() < 0.1  # the spring has pulled it to the goal
(traj.pos**2).mean().backward()
for g in (goal.grad, weights.grad):
    assert g is not None and torch.isfinite(g).all() and g.abs().sum() > 0
ref = dmp_rollout_reference(goal.detach(), weights.detach(), y0, None, cfg)
assert torch.allclose(traj.pos, ref.pos, atol=1e-8), (traj.pos - ref.pos).abs().max()

# a least-squares fit of that rollout reproduces it
g_fit, w_fit = fit_dmp(traj.pos.detach(), cfg)
refit = layer(g_fit, w_fit, y0)
assert (refit.pos - traj.pos).abs().max() < 1e-4

# a shipped policy loads and acts (the robot state given directly: no env)
policy = ndp.load_policy("zoo:push-v3-ndp")
actions = policy.act(torch.zeros(39).numpy(), ndp.RobotState(torch.zeros(4).numpy(),
                                                             torch.zeros(4).numpy()))
# (any weights the zoo ships: the shape is the policy's own)
assert actions.shape == (policy.exec_k, policy.spec.action_dim), actions.shape
assert abs(actions).max() <= 1.0, actions
assert policy.simulator_free

# the public API names the extra a missing package belongs to
try:
    ndp.make_env("point-mass")
except ModuleNotFoundError as exc:
    assert "[envs]" in str(exc), exc
else:
    raise AssertionError("make_env ran without gymnasium")

# an optional module imported without its extra names the pip line
try:
    import ndp.sb3
except ModuleNotFoundError as exc:
    assert "pip install -c constraints.txt '.[sb3]' in a clone" in str(exc), exc
else:
    raise AssertionError("ndp.sb3 imported without stable_baselines3")

# the `ndp` command still starts; a command whose extra is missing says which one
from ndp.cli import build_parser, main

assert "il" in build_parser().format_help()
assert main(["il", "train"]) == 2

print("BARE OK", sorted(m for m in sys.modules if m.partition(".")[0] in BLOCKED))
"""


def test_core_runs_without_any_extra():
    script = BARE_SCRIPT.replace("BLOCKED_NAMES", repr(BLOCKED)).replace("SRC", repr(str(SRC)))
    r = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"OMP_NUM_THREADS": "1"},
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "BARE OK []" in r.stdout, r.stdout + r.stderr
    assert "needs the [il] extra" in r.stderr


def _tomllib():
    return pytest.importorskip("tomllib")  # Python >= 3.11


def _canon(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _req_name(req: str) -> tuple[str, set[str]]:
    """A requirement's canonical name and the extras it asks for."""
    m = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)\s*(?:\[([^\]]*)\])?", req)
    assert m, req
    extras = {e.strip() for e in (m.group(2) or "").split(",") if e.strip()}
    return _canon(m.group(1)), extras


def _project() -> dict:
    return _tomllib().loads((ROOT / "pyproject.toml").read_text())["project"]


def _expand(project: dict, extra: str) -> set[str]:
    """The canonical names an extra installs (self-references ``pkg[a,b]`` expanded)."""
    out = set()
    for req in project["optional-dependencies"][extra]:
        name, sub = _req_name(req)
        if name == _canon(project["name"]):
            for e in sub:
                out |= _expand(project, e)
        else:
            out.add(name)
    return out


def _constraints() -> dict[str, str]:
    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        m = re.fullmatch(r"([A-Za-z0-9][A-Za-z0-9._-]*)==([0-9][A-Za-z0-9.+!-]*)", line)
        assert m, f"constraints.txt: not an exact pin: {line!r}"
        pins[_canon(m.group(1))] = m.group(2)
    return pins


def test_pyproject_core_is_torch_numpy_safetensors_and_dev_has_every_extra():
    project = _project()
    assert {_req_name(r)[0] for r in project["dependencies"]} == CORE
    for req in project["dependencies"]:
        assert "==" not in req, f"core dependencies take ranges (pins: constraints.txt): {req}"
    extras = project["optional-dependencies"]
    assert set(EXTRAS) <= set(extras), sorted(extras)
    assert _expand(project, "envs") <= _expand(project, "rl")
    dev = _expand(project, "dev")
    for e in extras:
        assert _expand(project, e) <= dev, f"[dev] lacks [{e}]: {_expand(project, e) - dev}"
    assert {"gymnasium", "mujoco", "metaworld", "dm-control"} <= _expand(project, "envs")
    assert {"scipy", "tensorboard"} <= _expand(project, "il")


def test_constraints_pin_only_what_pyproject_names():
    project = _project()
    named = {_req_name(r)[0] for r in project["dependencies"]}
    for e in project["optional-dependencies"]:
        named |= _expand(project, e)
    pins = _constraints()
    assert set(pins) <= named, f"pinned but not in pyproject.toml: {sorted(set(pins) - named)}"
    must = {"torch", "numpy", "gymnasium", "mujoco", "metaworld", "dm-control"}
    must |= {"stable-baselines3", "tyro", "ruff"}
    assert must <= set(pins), sorted(must - set(pins))
    # the Makefile installs with the pins and names torch in the same command (the CPU build)
    makefile = (ROOT / "Makefile").read_text()
    assert re.search(r"pip install -c constraints\.txt torch -e \"\.\[dev\]\"", makefile)


def _third_party_imports(path: Path, top_level_only: bool) -> set[str]:
    tree = ast.parse(path.read_text())
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    found = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            found |= {a.name.partition(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module.partition(".")[0])
    return {m for m in found if m not in sys.stdlib_module_names and m not in ("ndp", "__future__")}


TYPE_ONLY = ("_typeshed", "typing_extensions")
"""Modules the type checker brings (typeshed's stub-only ``_typeshed``; ``typing_extensions``,
which mypy requires), allowed only inside ``if TYPE_CHECKING:`` (never imported at run time)."""


def _only_when_type_checking(path: Path, mod: str) -> bool:
    """Whether every import of ``mod`` in ``path`` sits inside an ``if TYPE_CHECKING:`` block."""
    tree = ast.parse(path.read_text())
    guarded = {
        id(n)
        for node in ast.walk(tree)
        if isinstance(node, ast.If)
        and ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING")
        for stmt in node.body
        for n in ast.walk(stmt)
    }
    imports = [
        n
        for n in ast.walk(tree)
        if (isinstance(n, ast.ImportFrom) and (n.module or "").partition(".")[0] == mod)
        or (isinstance(n, ast.Import) and any(a.name.partition(".")[0] == mod for a in n.names))
    ]
    return bool(imports) and all(id(n) in guarded for n in imports)


def test_every_third_party_import_is_declared():
    project = _project()
    named = {_req_name(r)[0] for r in project["dependencies"]}
    for e in project["optional-dependencies"]:
        named |= _expand(project, e)
    dists = metadata.packages_distributions()
    undeclared = {}
    for f in sorted((SRC / "ndp").rglob("*.py")):
        for mod in _third_party_imports(f, top_level_only=False):
            if mod in TYPE_ONLY and _only_when_type_checking(f, mod):
                continue
            names = {_canon(d) for d in dists.get(mod, [mod])}
            if not names & named:
                undeclared[str(f.relative_to(SRC))] = mod
    assert not undeclared, f"imports of packages pyproject.toml does not name: {undeclared}"


@pytest.mark.parametrize("pkg", ["dmp", "nets", "policies", "zoo"])
def test_core_packages_import_only_the_core_at_module_level(pkg):
    bad = {}
    for f in sorted((SRC / "ndp" / pkg).rglob("*.py")):
        extra = _third_party_imports(f, top_level_only=True) - CORE
        if extra:
            bad[str(f.relative_to(SRC))] = sorted(extra)
    assert not bad, f"module-level imports outside the core install: {bad}"


def test_the_project_links_are_https_and_name_the_paper_and_the_release():
    urls = _project()["urls"]
    assert all(u.startswith("https://") for u in urls.values()), urls
    assert "https://arxiv.org/abs/2012.02788" in urls.values()
    assert any("github.com/shikharbahl/neural-dynamic-policies" in u for u in urls.values())
