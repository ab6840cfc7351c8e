"""Policies on the Hugging Face Hub (ndp.hub): load offline from a pre-populated cache, push
through a stand-in of HfApi (no network in tests), one-line errors."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("huggingface_hub")

from ndp.cli import main
from ndp.hub import download, parse_hub_ref
from ndp.rl.hub import push_policy as push
from policy_fixtures import fixture_policy

COMMIT = "0123456789abcdef0123456789abcdef01234567"


def _cache(tmp_path: Path, repo: str = "me/throw") -> Path:
    """A Hub cache holding ``repo`` at ``main``: the Throw fixture policy exported into it."""
    import ndp

    export = ndp.load_policy(fixture_policy("throw-ndp")).export(tmp_path / "export")
    cache = tmp_path / "hf-cache"
    org, name = repo.split("/")
    snap = cache / f"models--{org}--{name}" / "snapshots" / COMMIT
    shutil.copytree(export, snap)
    (snap.parents[1] / "refs").mkdir()
    (snap.parents[1] / "refs" / "main").write_text(COMMIT)
    return cache


def test_hub_addresses_are_parsed_or_refused():
    assert parse_hub_ref("hf://me/throw").repo_id == "me/throw"
    ref = parse_hub_ref("hf://me/throw@v1")
    assert (ref.repo_id, ref.revision) == ("me/throw", "v1")
    for bad in ("hf://throw", "hf://me/", "hf://me/throw@", "hf://a/b/c", "hf://me/thr ow"):
        with pytest.raises(ValueError, match=r"^path: expected a Hub address 'hf://ORG/NAME'"):
            parse_hub_ref(bad)


def test_load_policy_from_the_hub_offline_acts_as_the_original(tmp_path):
    """HF_HUB_OFFLINE=1 with a pre-populated cache: ndp.load_policy('hf://me/throw') is the
    exported policy (same actions); a repository that is not cached is one line."""
    cache = _cache(tmp_path)
    code = (
        "import json, numpy as np, ndp\n"
        "hub = ndp.load_policy('hf://me/throw')\n"
        f"src = ndp.load_policy({str(fixture_policy('throw-ndp'))!r})\n"
        "env = src.make_env(); obs, info = env.reset(seed=2); env.close()\n"
        "same = bool(np.allclose(hub.act(obs, info), src.act(obs, info), atol=1e-6))\n"
        "try:\n"
        "    ndp.load_policy('hf://me/absent'); err = ''\n"
        "except ValueError as e:\n"
        "    err = str(e)\n"
        "print(json.dumps({'task': hub.cfg.task, 'same': same, 'err': err}))\n"
    )
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "HF_HUB_CACHE": str(cache), "OMP_NUM_THREADS": "1"}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=300)  # fmt: skip
    assert res.returncode == 0, res.stderr[-2000:]
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["task"] == "throw" and out["same"]
    assert out["err"].startswith("path: cannot get hf://me/absent from the Hugging Face Hub")
    assert "\n" not in out["err"]


def test_a_repository_without_an_export_is_refused(tmp_path, monkeypatch):
    empty = tmp_path / "snapshot"
    empty.mkdir()
    (empty / "notes.txt").write_text("not a policy\n")
    import huggingface_hub

    monkeypatch.setattr(huggingface_hub, "snapshot_download", lambda *a, **k: str(empty))
    with pytest.raises(ValueError, match=r"^path: hf://me/notes holds no policy export"):
        download("hf://me/notes")


class FakeApi:
    """Records what push asks of the Hub (create_repo, upload_folder) and what it uploads."""

    def __init__(self, fail: bool = False) -> None:
        self.calls: list[tuple[str, Any]] = []
        self.uploaded: dict[str, bytes] = {}
        self.fail = fail

    def create_repo(self, repo_id: str, **kw: Any) -> str:
        self.calls.append(("create_repo", (repo_id, kw)))
        return f"https://huggingface.co/{repo_id}"

    def upload_folder(self, **kw: Any) -> str:
        self.calls.append(("upload_folder", kw))
        if self.fail:
            raise RuntimeError("401 Client Error: Unauthorized")
        root = Path(kw["folder_path"])
        self.uploaded = {
            p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()
        }
        return "commit abc"


def test_push_exports_a_policy_with_its_card_and_uploads_it(tmp_path):
    api = FakeApi()
    res = push("zoo:throw-ndp", "me/throw", private=True, api=api)
    assert res["repo_id"] == "me/throw" and res["commit"] == "commit abc"
    assert {"policy.safetensors", "policy.json", "README.md"} <= set(res["files"])
    assert api.calls[0] == ("create_repo", ("me/throw", {"private": True, "exist_ok": True}))
    up = api.calls[1][1]
    assert up["repo_id"] == "me/throw" and "policy.json" in up["allow_patterns"]
    assert json.loads(api.uploaded["policy.json"])["config"]["task"] == "throw"
    # an export folder is uploaded as it is
    import ndp

    folder = ndp.load_policy("zoo:throw-ndp").export(tmp_path / "exp")
    api2 = FakeApi()
    push(folder, "me/throw2", api=api2)
    assert api2.calls[1][1]["folder_path"] == str(folder)
    with pytest.raises(ValueError, match=r"^repo_id: the Hub refused the upload to me/x \("):
        push(folder, "me/x", api=FakeApi(fail=True))
    with pytest.raises(ValueError, match=r"^repo_id: expected 'ORG/NAME'"):
        push(folder, "no-slash", api=FakeApi())
    with pytest.raises(ValueError, match=r"^source: no such run or export folder"):
        push(tmp_path / "absent", "me/x", api=FakeApi())


def test_cli_push_uses_the_hub_api(monkeypatch, capsys):
    import huggingface_hub

    api = FakeApi()
    monkeypatch.setattr(huggingface_hub, "HfApi", lambda: api)
    assert main(["rl", "push", "zoo:throw-ndp", "me/throw", "--message", "first"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["repo_id"] == "me/throw" and "policy.safetensors" in out["files"]
    assert api.calls[1][1]["commit_message"] == "first"


def test_commands_with_a_default_output_write_a_clean_folder_for_a_hub_address():
    from ndp.rl.evaluate import check_save_target, default_output_dir

    assert default_output_dir("hf://me/throw@v2") == Path("throw")
    with pytest.raises(ValueError, match=r"^run_dir: --save writes into a run directory; hf://"):
        check_save_target("hf://me/throw")
