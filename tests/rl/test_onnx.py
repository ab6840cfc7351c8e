"""`ndp rl export --format onnx`: the deterministic decision as one ONNX graph, run in
onnxruntime on observations recorded from the env and compared with ``Policy.act``."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch

import ndp
from ndp.policies import MultiHead, PolicyConfig, build_actor_critic
from ndp.rl.config import TrainConfig, resolve_config
from ndp.rl.envs import resolve_task
from ndp.rl.normalize import ObsNormalizer
from ndp.rl.onnx_export import DecisionModule, OnnxPolicy, onnx_metadata, probe_inputs
from ndp.rl.policy import Policy
from policy_fixtures import FIXTURES

onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")

# every method of the trained fixtures (tests/fixtures/policies: the zoo's exports as they were
# when these tests were written): NDP from the measured (Meta-World) and the commanded (Jaco)
# state, PPO, PPO-multi, VICES (impedance actions), Dyn-E (decoded action sequences)
TRAINED = [
    "push-v3-ndp",
    "push-v3-ppo",
    "push-v3-ppo-multi",
    "throw-ndp",
    "throw-vices",
    "throw-dyne",
]
ATOL = 1e-5


def _record(policy: Policy, steps: int = 3, seed: int = 0) -> list[tuple[np.ndarray, dict]]:
    """(obs, info's state keys) of the first ``steps`` decisions of an episode."""
    env = policy.make_env()
    obs, info = env.reset(seed=seed)
    out = []
    for _ in range(steps):
        out.append((np.array(obs), {k: np.array(info[k]) for k in policy.state_keys}))
        obs, _, term, trunc, info = env.step(policy.act(obs, info))
        if term or trunc:
            break
    env.close()
    return out


def _run(session, policy: Policy, obs: np.ndarray, info: dict) -> np.ndarray:
    ky, kdy = policy.state_keys
    feed = {"obs": obs, "y0": np.asarray(info[ky]), "dy0": np.asarray(info[kdy])}
    feed = {k: np.asarray(v, dtype=np.float32) for k, v in feed.items()}  # the graph's inputs
    return session.run(["actions"], feed)[0]


def _check_graph(path: Path, policy: Policy) -> None:
    model = onnx.load(str(path))
    onnx.checker.check_model(model, full_check=True)
    assert [i.name for i in model.graph.input] == ["obs", "y0", "dy0"]
    assert [o.name for o in model.graph.output] == ["actions"]
    for value in (*model.graph.input, *model.graph.output):
        assert value.type.tensor_type.shape.dim[0].dim_param == "E", value.name  # dynamic batch
    meta = onnx_metadata(path.parent)
    assert meta["state_keys"] == list(policy.state_keys)
    assert meta["dmp_state"] == policy.cfg.policy.dmp_state
    assert (meta["algo"], meta["task"], meta["k"]) == (
        policy.cfg.algo,
        policy.cfg.task,
        policy.model.k,
    )
    assert meta["uses_robot_state"] == policy.model.head.needs_robot_state


@pytest.mark.parametrize("name", TRAINED)
def test_trained_policy_runs_as_one_onnx_graph(name, tmp_path):
    policy = ndp.load_policy(FIXTURES / name)
    out = policy.export(tmp_path / "onnx", format="onnx")
    path = out / "policy.onnx"
    _check_graph(path, policy)
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    low, high = np.asarray(policy.spec.action_low), np.asarray(policy.spec.action_high)
    recorded = _record(policy)
    for obs, info in recorded:
        want = policy.act(obs, info, deterministic=True)
        got = _run(session, policy, obs[None], {k: v[None] for k, v in info.items()})[0]
        assert got.dtype == np.float32 and got.shape == want.shape == (policy.model.k, len(low))
        np.testing.assert_allclose(got, want, rtol=0.0, atol=ATOL)
        assert np.all(got >= low - 1e-7) and np.all(got <= high + 1e-7)
    # the recorded decisions as one batch (E = 3 here, 2 when traced)
    obs_b = np.stack([o for o, _ in recorded])
    info_b = {k: np.stack([i[k] for _, i in recorded]) for k in policy.state_keys}
    np.testing.assert_allclose(
        _run(session, policy, obs_b, info_b), policy.act(obs_b, info_b), rtol=0.0, atol=ATOL
    )
    # OnnxPolicy: the same calling convention as Policy.act, from the file alone
    np.testing.assert_allclose(
        OnnxPolicy(out).act(*recorded[0]), policy.act(*recorded[0]), rtol=0.0, atol=ATOL
    )


def _fresh(task: str, algo: str, seed: int = 0, **policy_kw) -> Policy:
    """An untrained policy with random actor weights (far from the near-zero init) and
    normaliser statistics: heads and options the trained fixtures do not hold."""
    cfg = resolve_config(
        TrainConfig(task=task, algo=algo, policy=PolicyConfig.from_dict(policy_kw))
    )
    spec = resolve_task(cfg.task).spec
    torch.manual_seed(seed)
    model = build_actor_critic(spec.obs_dim, spec, cfg.policy).eval()
    with torch.no_grad():
        for p in model.actor.parameters():
            p.normal_(0.0, 0.5)
    norm = ObsNormalizer(spec.obs_dim, cfg.clip_obs, cfg.norm_obs)
    rng = np.random.default_rng(seed)
    norm.rms.mean = rng.normal(0.0, 0.5, spec.obs_dim)
    norm.rms.var = rng.uniform(0.05, 2.0, spec.obs_dim)
    return Policy(cfg, spec, model, norm)


FRESH = {
    "ndp-param-noise": ("point-mass", "ndp", {"param_noise": True}),
    "ndp-learn-az": ("point-mass", "ndp", {"learn_az": True}),  # the reference DMP loop
    "ndp-mean-clip-goal-forcing": ("point-mass", "ndp", {"mean_clip": True, "forcing": "goal"}),
    "ndp-gripper-dmp-commanded": (
        "push-v3",
        "ndp",
        {"absolute_mode": "dmp", "dmp_state": "commanded", "dmp_velocity": "state"},
    ),
    "vices-low-freq": ("push-v3", "vices-low-freq", {}),  # the hold head
    # PPO-multi with a chunk basis (k 10 >= 1 + N = 7); 'dmp' on push-v3 reads the measured
    # state (its offset in dy0), so y0 / dy0 enter the graph (the 'pca' basis:
    # tests/rl/test_chunk_basis_train.py)
    "ppo-multi-dct": ("point-mass", "ppo-multi", {"k": 10, "chunk_basis": "dct"}),
    "ppo-multi-bspline": ("point-mass", "ppo-multi", {"k": 10, "chunk_basis": "bspline"}),
    "ppo-multi-dmp": ("push-v3", "ppo-multi", {"k": 10, "chunk_basis": "dmp"}),
    "ndp-linear": ("point-mass", "ndp", {"param_map": "linear"}),  # no tanh: actions clipped
    # W (a float64 buffer) in the graph; parameter noise over the whitened raw outputs
    "ndp-whitened-param-noise": (
        "point-mass",
        "ndp",
        {"param_map": "whitened", "param_noise": True},
    ),
}


@pytest.mark.parametrize("name", list(FRESH))
def test_heads_not_in_the_fixtures_export_too(name, tmp_path):
    task, algo, kw = FRESH[name]
    policy = _fresh(task, algo, **kw)
    out = policy.export(tmp_path / "onnx", format="onnx")
    _check_graph(out / "policy.onnx", policy)
    session = ort.InferenceSession(str(out / "policy.onnx"), providers=["CPUExecutionProvider"])
    if task == "point-mass":  # cheap env: recorded observations
        cases = _record(policy, steps=4)
        obs = np.stack([o for o, _ in cases])
        info = {k: np.stack([i[k] for _, i in cases]) for k in policy.state_keys}
    else:  # inputs around the normaliser's statistics
        o, y0, dy0 = (t.numpy() for t in probe_inputs(policy, 4, seed=7))
        obs, info = o, dict(zip(policy.state_keys, (y0, dy0), strict=True))
    want = policy.act(obs, info, deterministic=True)
    assert np.ptp(want) > 0.1  # the random weights make the decisions differ
    np.testing.assert_allclose(_run(session, policy, obs, info), want, rtol=0.0, atol=ATOL)


def test_cli_writes_onnx_and_keeps_an_existing_file(tmp_path, capsys):
    from ndp.cli import main as ndp_main

    out = tmp_path / "cli"
    argv = ["rl", "export", str(FIXTURES / "push-v3-ppo-multi"), str(out), "--format", "onnx"]
    assert ndp_main(argv) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert json.loads(line) == {"export": str(out), "format": "onnx"}
    assert (out / "policy.onnx").is_file() and not (out / "policy.json").exists()
    before = (out / "policy.onnx").read_bytes()
    assert ndp_main(argv) == 2
    assert "already holds policy.onnx" in capsys.readouterr().err
    assert (out / "policy.onnx").read_bytes() == before


def test_a_graph_that_does_not_reproduce_the_policy_is_refused_naming_the_method(tmp_path):
    policy = _fresh("point-mass", "ppo-multi")

    class NumpyHead(MultiHead):
        """Goes through numpy: a tracer records the example's values as constants."""

        def distribution(self, raw, y0=None, dy0=None):
            return super().distribution(torch.as_tensor(np.tanh(raw.detach().numpy())), y0, dy0)

    policy.model.head = NumpyHead(policy.model.k, policy.model.head.action_dim)
    with pytest.raises(ValueError, match=r"method 'ppo-multi' \(head NumpyHead\): the ONNX") as exc:
        policy.export(tmp_path / "x", format="onnx")
    assert "\n" not in str(exc.value) and "does not reproduce the policy" in str(exc.value)
    assert not (tmp_path / "x" / "policy.onnx").exists()

    class ScalarHead(MultiHead):
        """A Python float of the data: the tracer bakes the example's value into the graph."""

        def distribution(self, raw, y0=None, dy0=None):
            return super().distribution(raw * float(raw.abs().mean()), y0, dy0)

    policy.model.head = ScalarHead(policy.model.k, policy.model.head.action_dim)
    with pytest.raises(ValueError, match=r"\(head ScalarHead\): .* max difference"):
        policy.export(tmp_path / "x", format="onnx")
    with pytest.raises(ValueError, match="exec-k evaluation copy"):
        dataclasses.replace(_fresh("point-mass", "ndp"), substeps=2).export(
            tmp_path / "y", format="onnx"
        )
    with pytest.raises(ValueError, match="format: expected one of safetensors, onnx"):
        ndp.export_policy(FIXTURES / "push-v3-ppo", tmp_path / "z", format="tflite")


def test_decision_module_passes_torch_export():
    """The first stage of torch's dynamo-based ONNX exporter (torch.export) records the whole
    decision of an NDP policy with a dynamic batch."""
    policy = ndp.load_policy(FIXTURES / "push-v3-ndp")
    module = DecisionModule(policy).eval()
    batch = torch.export.Dim("E")
    args = probe_inputs(policy, 3)
    program = torch.export.export(module, args, dynamic_shapes=tuple({0: batch} for _ in args))
    for e in (1, 6):
        new = probe_inputs(policy, e, seed=e)
        with torch.no_grad():
            torch.testing.assert_close(program.module()(*new), module(*new), rtol=0.0, atol=1e-6)


def test_load_policy_loads_an_onnx_export_with_the_same_calling_convention(tmp_path):
    """ndp.load_policy of an ONNX export (its folder or the file) gives an OnnxPolicy whose
    act(obs, robot_state) matches the torch policy's deterministic decision; sampling is refused
    in one line; what needs the torch policy says what the path is."""
    import ndp
    from ndp.act_inputs import RobotState
    from ndp.rl.evaluate import evaluate
    from ndp.rl.onnx_export import OnnxPolicy

    torch_pol = ndp.load_policy(FIXTURES / "throw-ndp")
    out = torch_pol.export(tmp_path / "onnx", format="onnx")
    for where in (out, out / "policy.onnx"):
        pol = ndp.load_policy(where)
        assert isinstance(pol, OnnxPolicy)
        env = torch_pol.make_env()
        obs, info = env.reset(seed=3)
        env.close()
        np.testing.assert_allclose(pol.act(obs, info), torch_pol.act(obs, info), atol=1e-5)
        ky, kdy = pol.state_keys
        state = RobotState(info[ky], info[kdy])
        np.testing.assert_allclose(pol.act(obs, state), torch_pol.act(obs, state), atol=1e-5)
        with pytest.raises(ValueError, match="deterministic: an ONNX export holds"):
            pol.act(obs, info, deterministic=False)
        with pytest.raises(ValueError, match="deterministic: expected True or False, got 'no'"):
            pol.act(obs, info, deterministic="no")  # truthy: it would have acted as True
    with pytest.raises(ValueError, match="is an ONNX export"):
        evaluate(out, episodes=1)


def test_load_policy_of_a_missing_path_names_the_zoo(tmp_path, monkeypatch):
    import ndp

    monkeypatch.chdir(tmp_path)  # outside the checkout: zoo/ is not there
    with pytest.raises(FileNotFoundError, match=r"ndp.load_policy\('zoo:push-v3-ndp'\)"):
        ndp.load_policy("zoo/push-v3-ndp")
    with pytest.raises(FileNotFoundError, match="close zoo names: zoo:push-v3-ndp"):
        ndp.load_policy("runs/push-v3-ndpp")
    with pytest.raises(FileNotFoundError, match="load as 'zoo:NAME'"):
        ndp.load_policy("nothing/like/it")


def test_the_graph_takes_float32_inputs(tmp_path):
    """Deployment runtimes feed float32: the graph's three inputs are float32 (the normaliser
    computes in float64 inside), and the wrapper accepts any real dtype."""
    import ndp

    pol = ndp.load_policy(FIXTURES / "push-v3-ppo-multi")
    out = pol.export(tmp_path / "o", format="onnx")
    model = onnx.load(str(out / "policy.onnx"))
    assert [i.type.tensor_type.elem_type for i in model.graph.input] == [onnx.TensorProto.FLOAT] * 3
    assert onnx_metadata(out)["input_dtype"] == "float32"
    onnx_pol = ndp.load_policy(out)
    obs = np.zeros(39, dtype=np.float32)
    state = {k: np.zeros(4, dtype=np.float16) for k in onnx_pol.state_keys}
    np.testing.assert_allclose(onnx_pol.act(obs, state), pol.act(obs.astype(np.float64), state),
                               atol=1e-5)  # fmt: skip


def test_torch_and_onnx_refuse_and_warn_on_bad_observations_with_the_same_words(tmp_path):
    """One input check for every runtime (ndp.act_inputs): a NaN, a value beyond float32 and a
    value outside the trained range get the same one-line error / the same single warning,
    naming ``obs``, the index and what was expected, from the torch policy and its ONNX
    export."""
    import warnings

    import ndp

    torch_pol = ndp.load_policy(FIXTURES / "throw-ndp")
    onnx_pol = ndp.load_policy(torch_pol.export(tmp_path / "onnx", format="onnx"))
    env = torch_pol.make_env()
    obs, info = env.reset(seed=1)
    env.close()
    for bad, message in ((np.nan, r"^obs: expected finite values, got nan at \[0, 3\]$"),
                         (1e39, r"^obs: expected values within float32's range")):  # fmt: skip
        o = obs.astype(np.float64).copy()
        o[3] = bad
        for pol in (torch_pol, onnx_pol):
            with pytest.raises(ValueError, match=message):
                pol.act(o, info)
    far = obs.astype(np.float64).copy()
    far[2] = 1e30
    said = []
    for pol in (torch_pol, onnx_pol):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            out = pol.act(far, info)
            pol.act(far, info)  # once per policy
        assert np.isfinite(out).all()
        said.append([str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)])
    assert len(said[0]) == 1 and said[0] == said[1]
    assert said[0][0].startswith("obs: entry [2] is 1e+30, outside the trained range [")
