"""A hostile user's catalogue: bad inputs and misuse replayed against the CLI and the Python API,
each outcome classified (docs/reliability.md, "The hostile catalogue").

Outcomes: **clear** (a one-line ``ndp: error:`` or a parser's message naming the option, exit
code 2; or a ``ValueError`` / ``OSError`` from the API with a message naming the argument),
**handled** (the right result, checked), **traceback** (an exception escaped the CLI),
**silent** (exit 0, or no exception, where an error or a notice was due; or a wrong result),
**lost** (a file that was there before the case changed or disappeared).

``make test-hostile`` prints the count per outcome (``pytest -s -m hostile``); the default
suite runs the same cases and fails on any traceback, silent result or lost file.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import shutil
import traceback
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ndp.cli import main as ndp_main

pytestmark = pytest.mark.hostile

RL = ["--task", "point-mass", "--algo", "ndp", "--steps-per-update", "256", "--minibatches", "2",
      "--vector", "sync", "--num-envs", "2", "--no-progress", "--no-tensorboard"]  # fmt: skip
IL = ["--data", "synthetic", "--n-train", "48", "--n-test", "16", "--model", "cnn",
      "--batch-size", "16", "--no-progress", "--no-tensorboard"]  # fmt: skip


@dataclass
class Case:
    name: str
    run: Callable[[Path], Any]
    """CLI: returns (exit code, stderr, stdout); API: returns anything or raises."""
    expect: str
    """'error' (a clear error is due) or 'ok' (a result, checked by ``check``)."""
    check: Callable[[Any], bool] | None = None
    protect: list[str] = field(default_factory=list)
    """Paths (relative to the fixture root) that must be unchanged after the case."""
    api: bool = False


def _cli(argv: list[str]) -> tuple[int, str, str]:
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        rc = ndp_main(argv)
    return rc, err.getvalue(), out.getvalue()


def _val_by_writers(r: Path) -> tuple[int, str, str]:
    """Validation by writers on synthetic digits (no writer ids); a run folder left behind by
    the refusal counts as silent."""
    res = _cli(["il", "train", *IL, "--val-fraction", "0.2", "--val-split", "writers",
                "--epochs", "1", "--out", str(r / "ilw")])  # fmt: skip
    return res if not (r / "ilw").exists() else (0, "", "")


def _clear_cli(res: tuple[int, str, str]) -> bool:
    rc, err, _ = res
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    if rc == 0 or not lines:
        return False
    if "Traceback" in err:
        return False
    last = lines[-1]
    parser_box = any("Error parsing" in ln or "error:" in ln.lower() for ln in lines)
    return last.startswith("ndp: error:") or parser_box


def _digest(root: Path, rel: str) -> str:
    p = root / rel
    if p.is_dir():
        return "|".join(f"{q.relative_to(p)}:{_digest(p, str(q.relative_to(p)))}"
                        for q in sorted(p.rglob("*")) if q.is_file())  # fmt: skip
    return hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "missing"


def classify(case: Case, root: Path) -> tuple[str, str]:
    """(outcome, detail) of one case."""
    before = {p: _digest(root, p) for p in case.protect}
    try:
        res = case.run(root)
    except (ValueError, OSError, FileNotFoundError) as exc:
        if not case.api:
            return "traceback", "".join(traceback.format_exception_only(exc)).strip()
        outcome = "clear" if case.expect == "error" and "\n" not in str(exc) else "silent"
        res = None
        detail = f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # anything else escaping is a traceback for the user
        return "traceback", "".join(traceback.format_exception_only(exc)).strip()
    else:
        if case.api:
            ok = case.expect == "ok" and (case.check is None or case.check(res))
            outcome, detail = ("handled" if ok else "silent"), repr(res)[:200]
        elif case.expect == "error":
            ok = _clear_cli(res) and (case.check is None or case.check(res))
            outcome = "clear" if ok else "silent"
            detail = res[1].strip()[-300:]
            if "Traceback" in res[1]:
                outcome = "traceback"
        else:
            ok = res[0] == 0 and (case.check is None or case.check(res))
            outcome, detail = ("handled" if ok else "silent"), (res[1] + res[2]).strip()[-300:]
    after = {p: _digest(root, p) for p in case.protect}
    if after != before:
        return "lost", f"changed: {[p for p in case.protect if after[p] != before[p]]}"
    return outcome, detail


# ----------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    """A trained RL run (relative name 'rl'), its export, a finished imitation run, BC demos."""
    root = tmp_path_factory.mktemp("hostile")
    assert _cli(["rl", "train", *RL, "--steps", "512", "--run-dir", str(root / "rl")])[0] == 0
    assert _cli(["rl", "export", str(root / "rl"), str(root / "export")])[0] == 0
    assert _cli(["il", "train", *IL, "--epochs", "2", "--out", str(root / "il")])[0] == 0
    assert _cli(["il", "collect", "--task", "point-mass", "--episodes", "1", "--out",
                 str(root / "demos.npz")])[0] == 0  # fmt: skip
    shutil.copytree(root / "rl", root / "rl-locked")
    shutil.copytree(root / "il", root / "il-locked")
    return root


def _export_copy(root: Path, name: str, edit: Callable[[dict], None] | None = None,
                 text: str | None = None) -> Path:  # fmt: skip
    out = root / name
    if not out.exists():
        shutil.copytree(root / "export", out)
        meta = json.loads((out / "policy.json").read_text())
        if edit is not None:
            edit(meta)
        (out / "policy.json").write_text(text if text is not None else json.dumps(meta))
    return out


def _cut_metrics(root: Path) -> Path:
    out = root / "cut"
    if not out.exists():
        shutil.copytree(root / "rl", out)
        rows = (out / "metrics.csv").read_text().splitlines()
        (out / "metrics.csv").write_text("\n".join(rows[:1]) + "\n")
    return out


def _wrong_weights(root: Path) -> Path:
    from safetensors.torch import load_file, save_file

    out = _export_copy(root, "export-shape")
    w = load_file(str(out / "policy.safetensors"))
    k = next(iter(w))
    w[k] = w[k][..., :1].contiguous() if w[k].ndim else w[k]
    save_file(w, str(out / "policy.safetensors"))
    return out


def _one_sample(root: Path) -> Path:
    out = root / "one.npz"
    if not out.exists():
        np.savez(out, images=np.zeros((1, 28, 28), np.float32),
                 trajectories=np.zeros((1, 301, 2), np.float32))  # fmt: skip
    return out


def _policy_act(root: Path, obs: Any, info_batch: bool) -> Any:
    import ndp

    pol = ndp.load_policy(root / "rl")
    env = pol.make_env()
    o, info = env.reset(seed=0)
    env.close()
    if info_batch:
        return pol.act(np.stack([o, o]), {k: v for k, v in info.items()})
    return pol.act(obs if obs is not None else o, info)


def _stochastic_twice(root: Path) -> tuple[str, str]:
    argv = ["rl", "eval", str(root / "rl"), "--episodes", "1", "--mode", "stochastic",
            "--seed", "3"]  # fmt: skip
    return _cli(argv)[2], _cli(argv)[2]


def _sweep_budget(root: Path) -> tuple[int, str, str]:
    runs = root / "sweep"
    if not runs.exists():
        runs.mkdir()
        shutil.copytree(root / "rl", runs / "point-mass-ndp-s0")
    return _cli(["sweep", "--tasks", "point-mass", "--methods", "ndp", "--steps", "1600",
                 "--runs-dir", str(runs), "--jobs", "1", "--vector", "sync"])  # fmt: skip


def _onnx_act(root: Path, what: str) -> Any:
    """OnnxPolicy.act on the point-mass export with one kind of bad (or good) input."""
    from ndp.act_inputs import RobotState
    from ndp.rl.onnx_export import OnnxPolicy

    out = root / "export-onnx"
    if not out.exists():
        assert _cli(["rl", "export", str(root / "rl"), str(out), "--format", "onnx"])[0] == 0
    if what == "corrupt":
        bad = root / "export-onnx-bad"
        bad.mkdir(exist_ok=True)
        (bad / "policy.onnx").write_bytes(b"\x08\x01garbage" * 10)
        return OnnxPolicy(bad)
    pol = OnnxPolicy(out)
    obs, info = np.zeros(6), {k: np.zeros(2) for k in pol.state_keys}
    if what == "nan obs":
        return pol.act(np.full(6, np.nan), info)
    if what == "inf obs":
        return pol.act(np.full(6, np.inf), info)
    if what == "nan state":
        return pol.act(obs, {k: np.full(2, np.nan) for k in pol.state_keys})
    if what == "wrong shape":
        return pol.act(np.zeros(5), info)
    if what == "batch with one env's info":
        return pol.act(np.zeros((2, 6)), info)
    if what == "robot state":
        return pol.act(obs, RobotState(np.zeros(2), np.zeros(2)))
    raise AssertionError(what)


def _locked_train(root: Path, il: bool = False) -> tuple[int, str, str]:
    """`ndp rl train` (or `ndp il train`) into a run another process is training (holds its
    lock)."""
    import subprocess
    import sys

    run = root / ("il-locked" if il else "rl-locked")  # a copy made by the fixture
    code = ("import sys, time; from ndp.runs import lock; lock.acquire(sys.argv[1]); "
            "print('held', flush=True); time.sleep(120)")  # fmt: skip
    proc = subprocess.Popen([sys.executable, "-c", code, str(run)], stdout=subprocess.PIPE)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == b"held"
        if il:
            return _cli(["il", "train", *IL, "--epochs", "2", "--out", str(run), "--overwrite"])
        return _cli(["rl", "train", *RL, "--steps", "512", "--run-dir", str(run), "--overwrite"])
    finally:
        proc.kill()
        proc.wait()


def _bad_archive(root: Path, kind: str) -> tuple[int, str, str]:
    import tarfile

    arc = root / f"bad-{kind.replace('/', '_').replace('.', 'd')}.tar.gz"
    if kind == "not gzip":
        arc.write_bytes(b"this is not an archive")
    else:
        with tarfile.open(arc, "w:gz") as tf:
            data = b"{}"
            info = tarfile.TarInfo(kind)
            info.size = len(data)
            tf.addfile(info, io.BytesIO(data))
    res = _cli(["sweep", "--tasks", "point-mass", "--methods", "ndp", "--runs-dir",
                str(root / "unpacked"), "--unpack", str(arc), "--dry-run"])  # fmt: skip
    stray = list((root / "unpacked").glob(".*")) if (root / "unpacked").exists() else []
    return res if not stray else (0, "", f"left behind: {stray}")


def _binary_metrics(root: Path) -> Path:
    out = root / "binmetrics"
    if not out.exists():
        shutil.copytree(root / "rl", out)
        (out / "metrics.csv").write_bytes(bytes(range(256)) * 4)
    return out


def _clipped_obs(root: Path) -> list[str]:
    import warnings

    import ndp

    pol = ndp.load_policy(root / "rl")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        info = {k: np.zeros(2) for k in pol.state_keys}
        pol.act(np.full(6, 1e30), info)
        pol.act(np.full(6, 1e30), info)  # said once per policy
    return [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]


def _register(root: Path, **change: Any) -> Any:
    """register_task with one field of the toy row changed; a refusal must leave no task."""
    import dataclasses

    from ndp.envs import get_task_spec
    from ndp.envs.factory import register_task
    from ndp.envs.spec import TASKS

    row = dataclasses.replace(get_task_spec("point-mass"), aliases=(), env_id="ndp/Hostile-v0",
                              **{"name": "hostile-pm", **change})  # fmt: skip
    before = set(TASKS)
    try:
        return register_task(row)
    finally:
        if set(TASKS) != before:  # a half-registered task counts as silent
            raise AssertionError(f"register_task left {set(TASKS) - before} behind")


def _other_task_env(root: Path) -> Any:
    import ndp
    from ndp.rl.evaluate import run_episode

    pol = ndp.load_policy(root / "rl")
    env = ndp.make_env("point-mass-3d", k=pol.cfg.k, horizon=5)
    try:
        return run_episode(pol, env, seed=0, deterministic=True)
    finally:
        env.close()


def _spoiled_checkpoint(root: Path, name: str, spoil: Callable[[dict], None]) -> Path:
    """A copy of the trained run whose checkpoint ``spoil`` changed (a key removed, a NaN)."""
    import torch

    out = root / name
    if not out.exists():
        shutil.copytree(root / "rl", out)
        ckpt = torch.load(out / "checkpoint.pt", map_location="cpu", weights_only=False)
        spoil(ckpt)
        torch.save(ckpt, out / "checkpoint.pt")
    return out


def _nan_weight(ckpt: dict) -> None:
    weight = next(v for v in ckpt["model"].values() if v.is_floating_point())
    weight.view(-1)[0] = float("nan")


def _meta_layer(root: Path) -> object:
    from ndp.dmp import DMPLayer

    return DMPLayer(device="meta")


def _cases() -> list[Case]:
    rl = lambda r: str(r / "rl")  # noqa: E731
    protect_rl = ["rl/config.json", "rl/checkpoint.pt", "rl/metrics.csv"]
    protect_il = ["il/config.json", "il/checkpoint.pt", "il/metrics.csv"]
    # fmt: off
    return [
        # budgets and data said, never silently changed
        Case("rl train --steps 400 (rounded up)", lambda r: _cli(["rl", "train", *RL, "--steps",
             "400", "--run-dir", str(r / "s400")]), "ok",
             lambda res: "budget: --steps 400 trains 520 env steps" in res[1]),
        Case("rl resume cutting the budget", lambda r: _cli(["rl", "train", "--resume", rl(r),
             "--steps", "100"]), "error", protect=protect_rl),
        Case("il resume cutting the epochs", lambda r: _cli(["il", "train", "--resume",
             str(r / "il"), "--epochs", "1"]), "error", protect=protect_il),
        Case("il train --epochs 0", lambda r: _cli(["il", "train", *IL, "--epochs", "0",
             "--out", str(r / "il0")]), "error"),
        Case("il train --val-split writers on digits without writers", _val_by_writers,
             "error"),
        Case("il bc with an empty validation split", lambda r: _cli(["il", "bc", "--demos",
             str(r / "demos.npz"), "--val-fraction", "0.5", "--epochs", "1", "--out",
             str(r / "bc"), "--no-progress", "--no-tensorboard"]), "ok",
             lambda res: "val/loss is not measured" in res[1]),
        Case("sweep at another budget over a finished run", _sweep_budget, "error",
             protect=["rl/config.json"]),
        # options the method cannot honour: refused or named, never dropped
        Case("rl train --algo ppo --k 5", lambda r: _cli(["rl", "train", *RL[:2], "--algo",
             "ppo", "--k", "5", "--run-dir", str(r / "ppo-k5")]), "error"),
        Case("rl train --algo sac --k 5", lambda r: _cli(["rl", "train", *RL[:2], "--algo",
             "sac", "--k", "5", "--run-dir", str(r / "sac-k5")]), "error"),
        Case("rl train --algo ppo --n-basis 3 (named)", lambda r: _cli(["rl", "train", *RL[:2],
             "--algo", "ppo", *RL[4:], "--n-basis", "3", "--steps", "256", "--run-dir",
             str(r / "ppo-nb")]), "ok",
             lambda res: "n_basis=3: options of the NDP head" in res[1]),
        Case("rl train --algo ppo --sac-lr 1e-3 (refused)", lambda r: _cli(["rl", "train",
             *RL[:2], "--algo", "ppo", *RL[4:], "--sac-lr", "1e-3", "--steps", "256",
             "--run-dir", str(r / "ppo-saclr")]), "error",
             lambda res: "does not read sac.lr=0.001 (read by --algo sac / sac-chunk" in res[1]),
        # relocation and resume
        Case("resume from the absolute path", lambda r: _cli(["rl", "train", "--resume",
             str((r / "rl").resolve()), "--steps", "512"]), "ok",
             lambda res: "nothing to do" in res[1], protect_rl),
        Case("resume changing the learning rate", lambda r: _cli(["rl", "train", "--resume",
             rl(r), "--lr", "1"]), "error", protect=protect_rl),
        Case("a new run over a finished one", lambda r: _cli(["rl", "train", *RL, "--run-dir",
             rl(r)]), "error", protect=protect_rl),
        # reports
        Case("report of a cut metrics.csv", lambda r: _cli(["report", str(_cut_metrics(r)),
             "--out", str(r / "rep-cut")]), "error"),
        Case("report --budgets -5 nan", lambda r: _cli(["report", rl(r), "--budgets", "-5",
             "nan", "--out", str(r / "rep-b")]), "error"),
        Case("report --out under a file", lambda r: _cli(["report", rl(r), "--out",
             str(r / "rl" / "config.json" / "x")]), "error", protect=protect_rl),
        Case("report of a missing directory", lambda r: _cli(["report", str(r / "nope")]),
             "error"),
        # exports
        Case("export without obs_dim", lambda r: _cli(["rl", "eval", str(_export_copy(
             r, "export-noobs", lambda m: m.pop("obs_dim"))), "--episodes", "1"]),
             "error"),
        Case("export with a truncated policy.json", lambda r: _cli(["rl", "eval", str(
             _export_copy(r, "export-trunc", text='{"format": "ndp-pol')), "--episodes",
             "1"]), "error"),
        Case("export with weights of another shape", lambda r: _cli(["rl", "eval",
             str(_wrong_weights(r)), "--episodes", "1"]), "error"),
        Case("export over an export", lambda r: _cli(["rl", "export", rl(r),
             str(r / "export")]), "error", protect=["export/policy.json"]),
        # bad options
        Case("--device cuda without CUDA", lambda r: _cli(["rl", "train", *RL, "--device",
             "cuda", "--run-dir", str(r / "cuda")]), "error",
             protect=["cuda"]),
        Case("rl eval --seed -1", lambda r: _cli(["rl", "eval", rl(r), "--seed", "-1"]),
             "error"),
        Case("rl eval --episodes 0", lambda r: _cli(["rl", "eval", rl(r), "--episodes", "0"]),
             "error"),
        Case("rl render --width 0", lambda r: _cli(["rl", "render", rl(r), "--out",
             str(r / "w0.mp4"), "--width", "0"]), "error",
             lambda res: "width: expected an integer from 1 to 4096" in res[1]),
        Case("rl render --height 5000", lambda r: _cli(["rl", "render", rl(r), "--out",
             str(r / "h5k.mp4"), "--height", "5000"]), "error",
             lambda res: "height: expected an integer from 1 to 4096" in res[1]),
        Case("--init-log-std nan", lambda r: _cli(["rl", "train", *RL, "--init-log-std", "nan",
             "--run-dir", str(r / "nan")]), "error"),
        Case("--lr inf", lambda r: _cli(["rl", "train", *RL, "--lr", "inf", "--run-dir",
             str(r / "inf")]), "error"),
        Case("--num-envs 0", lambda r: _cli(["rl", "train", *RL, "--num-envs", "0"]), "error"),
        Case("unknown task", lambda r: _cli(["rl", "train", "--task", "pussh-v3"]), "error"),
        Case("v1 rewards on Throw", lambda r: _cli(["rl", "train", "--task", "throw",
             "--reward-version", "v1", "--run-dir", str(r / "v1throw")]), "error"),
        Case("unknown study", lambda r: _cli(["sweep", "paper-fiv"]), "error"),
        Case("il bc into a folder holding a run (no --resume hint)", lambda r: _cli(["il", "bc",
             "--demos", str(r / "demos.npz"), "--out", rl(r)]), "error",
             lambda res: "--resume" not in res[1] and "--overwrite" in res[1],
             protect=protect_rl),
        Case("il train on a one-sample npz", lambda r: _cli(["il", "train", "--data",
             str(_one_sample(r)), "--out", str(r / "il1")]), "error",
             lambda res: "at least one sample on each side" in res[1]),
        Case("il train on a missing file", lambda r: _cli(["il", "train", "--data",
             str(r / "none.npz"), "--out", str(r / "ilx")]), "error"),
        # determinism
        Case("stochastic eval twice, same seed", _stochastic_twice, "ok",
             lambda res: res[0] == res[1], api=True),
        # the Python API
        Case("DMPConfig(n_basis=np.int64(5))", lambda r: __import__("ndp.dmp").dmp.DMPConfig(
             n_basis=np.int64(5)), "ok", lambda c: c.n_basis == 5 and type(c.n_basis) is int,
             api=True),
        Case("DMPConfig(learn_az='no')", lambda r: __import__("ndp.dmp").dmp.DMPConfig(
             learn_az="no"), "error", api=True),
        Case("DMPConfig(only_g=np.True_)", lambda r: __import__("ndp.dmp").dmp.DMPConfig(
             only_g=np.True_), "ok", lambda c: c.only_g is True, api=True),
        Case("PPOConfig(norm_adv='false')", lambda r: __import__("ndp.rl.config").rl.config
             .PPOConfig(norm_adv="false"), "error", api=True),
        Case("policy.act(NaN observation)", lambda r: _policy_act(r, np.full(6, np.nan), False),
             "error", api=True),
        Case("policy.act([2, O] with one env's info)", lambda r: _policy_act(r, None, True),
             "error", api=True),
        Case("make_env(v1 on the point mass)", lambda r: __import__("ndp").make_env(
             "point-mass", reward_version="v1"), "error", api=True),
        # nothing silent, part 3: one run, one writer
        Case("rl train --overwrite of a run another process trains", _locked_train, "error",
             lambda res: "is being trained now (pid" in res[1],
             protect=["rl-locked/checkpoint.pt", "rl-locked/metrics.csv"]),
        Case("il train --overwrite of a run another process trains", lambda r: _locked_train(
             r, il=True), "error", lambda res: "is being trained now (pid" in res[1],
             protect=["il-locked/checkpoint.pt", "il-locked/metrics.csv"]),
        # render sizes the encoder cannot take
        Case("rl render --width 3 --height 3", lambda r: _cli(["rl", "render", rl(r), "--out",
             str(r / "odd.mp4"), "--width", "3", "--height", "3"]), "error",
             lambda res: "expected an even number of px" in res[1]),
        # the ONNX policy checks its inputs as Policy.act does
        Case("OnnxPolicy.act(NaN observation)", lambda r: _onnx_act(r, "nan obs"), "error",
             api=True),
        Case("OnnxPolicy.act(+Inf observation)", lambda r: _onnx_act(r, "inf obs"), "error",
             api=True),
        Case("OnnxPolicy.act(NaN robot state)", lambda r: _onnx_act(r, "nan state"), "error",
             api=True),
        Case("OnnxPolicy.act(observation of the wrong size)", lambda r: _onnx_act(
             r, "wrong shape"), "error", api=True),
        Case("OnnxPolicy.act([2, O] with one env's info)", lambda r: _onnx_act(
             r, "batch with one env's info"), "error", api=True),
        Case("OnnxPolicy.act(obs, RobotState)", lambda r: _onnx_act(r, "robot state"), "ok",
             lambda a: np.shape(a) == (5, 2), api=True),
        Case("OnnxPolicy of a corrupt policy.onnx", lambda r: _onnx_act(r, "corrupt"), "error",
             api=True),
        # archives
        Case("sweep --unpack of a file that is not an archive", lambda r: _bad_archive(
             r, "not gzip"), "error"),
        Case("sweep --unpack of a member ./x", lambda r: _bad_archive(r, "./x"), "error"),
        Case("sweep --unpack of a member ../x", lambda r: _bad_archive(r, "../x"), "error"),
        # a run of the wrong kind
        Case("rl export of an imitation run", lambda r: _cli(["rl", "export", str(r / "il"),
             str(r / "il-export")]), "error",
             lambda res: "is an imitation run" in res[1] and "ndp il eval" in res[1],
             protect=protect_il),
        Case("rl eval of an imitation run", lambda r: _cli(["rl", "eval", str(r / "il")]),
             "error", lambda res: "is an imitation run" in res[1]),
        Case("rl train --resume of an imitation run", lambda r: _cli(["rl", "train", "--resume",
             str(r / "il")]), "error", lambda res: "is an imitation run" in res[1],
             protect=protect_il),
        Case("load_policy(an imitation run)", lambda r: __import__("ndp").load_policy(
             r / "il"), "error", api=True),
        Case("il eval of an RL run", lambda r: _cli(["il", "eval", rl(r)]), "error",
             lambda res: "ndp rl eval" in res[1], protect=protect_rl),
        # paths that are files
        Case("sweep --runs-dir a file --dry-run", lambda r: _cli(["sweep", "--tasks",
             "point-mass", "--methods", "ndp", "--runs-dir", str(r / "rl" / "config.json"),
             "--dry-run"]), "error", lambda res: "is a file, not a folder" in res[1],
             protect=protect_rl),
        Case("rl export OUT under a file", lambda r: _cli(["rl", "export", rl(r),
             str(r / "rl" / "config.json" / "exp")]), "error",
             lambda res: "out_dir: cannot write" in res[1] and "is a file" in res[1],
             protect=protect_rl),
        Case("rl export --format onnx OUT under a file", lambda r: _cli(["rl", "export", rl(r),
             str(r / "rl" / "config.json" / "exp"), "--format", "onnx"]), "error",
             lambda res: "out_dir: cannot write" in res[1], protect=protect_rl),
        Case("il collect --out under a file", lambda r: _cli(["il", "collect", "--task",
             "point-mass", "--episodes", "1", "--out", str(r / "rl" / "config.json" / "d.npz")]),
             "error", lambda res: "a part of that path" in res[1], protect=protect_rl),
        # messages that name the file and field at fault
        Case("report of a binary metrics.csv", lambda r: _cli(["report", str(_binary_metrics(r)),
             "--out", str(r / "rep-bin")]), "error",
             lambda res: "binmetrics/metrics.csv is not a metrics CSV" in res[1]),
        Case("export with a cut obs_norm.mean", lambda r: _cli(["rl", "eval", str(_export_copy(
             r, "export-cutnorm", lambda m: m["obs_norm"].update(mean=m["obs_norm"]["mean"][:2]))),
             "--episodes", "1"]), "error",
             lambda res: "policy.json: field 'obs_norm.mean'" in res[1]),
        # inputs clipped silently
        Case("policy.act(observations of 1e30)", _clipped_obs, "ok",
             lambda w: len(w) == 1 and "outside the trained range" in w[0], api=True),
        # the same bad input, every runtime, the same words (ndp.act_inputs)
        Case("export policy.act(obs beyond float32)", lambda r: __import__("ndp").load_policy(
             r / "export").act(np.full(6, 1e39), {k: np.zeros(2) for k in ("cmd_y0", "cmd_dy0",
             "dmp_y0", "dmp_dy0")}), "error", api=True),
        # options that nothing reads
        Case("rl train --noise white --noise-corr 0.5", lambda r: _cli(["rl", "train", *RL,
             "--noise-corr", "0.5", "--steps", "256", "--run-dir", str(r / "noisecorr")]),
             "error", lambda res: "noise_corr: only 'ar1' noise reads it" in res[1]),
        # register_task: every field checked, the env probed, nothing left on refusal
        Case("register_task(empty name)", lambda r: _register(r, name=""), "error", api=True),
        Case("register_task(obs_dim the env does not have)", lambda r: _register(r, obs_dim=99),
             "error", api=True),
        Case("register_task(negative horizon)", lambda r: _register(r, horizon=-1), "error",
             api=True),
        # checkpoints checked against their schema on load (file and key named)
        Case("rl resume from a checkpoint without its optimiser state", lambda r: _cli(["rl",
             "train", "--resume", str(_spoiled_checkpoint(r, "ckpt-noopt",
             lambda c: c.pop("optimizer")))]), "error",
             lambda res: "checkpoint.pt: optimizer: missing" in res[1]),
        Case("rl resume from a checkpoint with NaN in a weight", lambda r: _cli(["rl", "train",
             "--resume", str(_spoiled_checkpoint(r, "ckpt-nan", _nan_weight))]), "error",
             lambda res: "holds NaN/Inf" in res[1] and "checkpoint.pt: model." in res[1]),
        Case("rl resume from a checkpoint of a newer schema", lambda r: _cli(["rl", "train",
             "--resume", str(_spoiled_checkpoint(r, "ckpt-v99",
             lambda c: c.update(schema_version=99)))]), "error",
             lambda res: "is newer than" in res[1]),
        # a layer asked for a device it does not hold parameters on
        Case("DMPLayer(device='meta')", _meta_layer, "error", api=True),
        # a policy in another task's env
        Case("run_episode(a point-mass policy in the 3-D point mass)", _other_task_env, "error",
             api=True),
    ]
    # fmt: on


CASES = _cases()


@pytest.fixture(scope="module")
def outcomes(root) -> list[tuple[str, str, str]]:
    rows = [(c.name, *classify(c, root)) for c in CASES]
    counts = Counter(o for _, o, _ in rows)
    print("\nhostile catalogue: " + ", ".join(
        f"{k} {counts.get(k, 0)}" for k in ("clear", "handled", "traceback", "silent", "lost")
    ) + f" (of {len(rows)} cases)")  # fmt: skip
    for name, o, d in rows:
        if o in ("traceback", "silent", "lost"):
            print(f"  {o:9s} {name}: {d}")
    with (root / "catalogue.csv").open("w", newline="") as fh:
        csv.writer(fh).writerows([("case", "outcome", "detail"), *rows])
    return rows


def test_no_traceback_silent_result_or_lost_file(outcomes):
    bad = [(n, o, d) for n, o, d in outcomes if o in ("traceback", "silent", "lost")]
    assert not bad, "\n".join(f"{o}: {n}: {d}" for n, o, d in bad)


def test_every_case_has_its_expected_kind_of_outcome(outcomes):
    want = {c.name: ("clear",) if c.expect == "error" else ("handled",) for c in CASES}
    assert all(o in want[n] for n, o, _ in outcomes), [
        (n, o) for n, o, _ in outcomes if o not in want[n]
    ]
