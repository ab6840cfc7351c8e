"""``ndp rl push``: a run, an export folder or ``zoo:NAME`` to the Hugging Face Hub (the export
made first, with its card; the upload is :func:`ndp.hub.push_folder`)."""

from __future__ import annotations

import tempfile
from pathlib import Path

from ndp.hub import push_folder

__all__ = ["push_policy"]


def push_policy(
    source: str | Path,
    repo_id: str,
    private: bool = False,
    message: str | None = None,
    api: object = None,
) -> dict[str, object]:
    """Upload a policy to the Hub as model repository ``repo_id``.

    Args:
        source: a training run (exported first, with its card: ``Policy.export``), an export
            folder (uploaded as it is), or ``zoo:NAME``.
        repo_id: ``ORG/NAME``; created if missing.
        private, message, api: as :func:`ndp.hub.push_folder`.

    Raises:
        ValueError: a source that is no policy, or what :func:`ndp.hub.push_folder` refuses.
    """
    src = str(source)
    msg = message or f"ndp rl push {src}"
    if not src.startswith("zoo:"):
        here = Path(src)
        if (here / "policy.json").is_file() or (here / "policy.onnx").is_file():
            return push_folder(here, repo_id, private, msg, api)
        if not here.is_dir():
            raise ValueError(f"source: no such run or export folder {src}")
    from ndp.rl.policy import load_policy  # a run or zoo:NAME (an export was uploaded above)

    with tempfile.TemporaryDirectory(prefix="ndp-push-") as tmp:
        out = load_policy(src).export(Path(tmp) / "export")
        return push_folder(out, repo_id, private, msg, api)
