"""Policies on the Hugging Face Hub: ``ndp.load_policy("hf://ORG/NAME")`` and ``ndp rl push``.

A policy on the Hub is an export folder (``ndp rl export``: ``policy.safetensors`` +
``policy.json`` + ``README.md``, or ``policy.onnx`` + its card) as a model repository, the way
rl-zoo's ``load_from_hub`` and LeRobot's ``from_pretrained`` keep theirs. Loading downloads the
export's files into the Hub's cache (``huggingface_hub.snapshot_download``; offline with
``HF_HUB_OFFLINE=1``, from the cache alone) and loads that folder; pushing uploads an export
folder (``HfApi.create_repo`` + ``upload_folder``; ``ndp.rl.hub.push_policy`` exports a run
first). A foundation module: it imports nothing of the package but ``ndp.checks``.

Addresses: ``hf://ORG/NAME`` or ``hf://ORG/NAME@REVISION`` (a branch, tag or commit).
Needs the [hub] extra (``huggingface_hub``); nothing else of the package imports it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ndp.checks import install_hint

__all__ = [
    "EXPORT_PATTERNS",
    "HUB_PREFIX",
    "HubRef",
    "download",
    "is_hub_ref",
    "parse_hub_ref",
    "push_folder",
]

HUB_PREFIX = "hf://"
"""The prefix of a policy address on the Hub."""

EXPORT_PATTERNS = (
    "policy.safetensors",
    "policy.json",
    "policy.onnx",
    "README.md",
    "*.gif",
    ".eval_results/*.yaml",
)
"""The files of an export folder: what is downloaded (nothing else of a repository) and
uploaded."""

_REPO = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*/[A-Za-z0-9][A-Za-z0-9._-]*$")


@dataclass(frozen=True)
class HubRef:
    """A parsed ``hf://ORG/NAME[@REVISION]``."""

    repo_id: str
    """``ORG/NAME``."""
    revision: str | None = None
    """A branch, tag or commit; None: the repository's default branch."""


def is_hub_ref(path: object) -> bool:
    """Whether ``path`` is a Hub address (a string starting with ``hf://``)."""
    return isinstance(path, str) and path.startswith(HUB_PREFIX)


def parse_hub_ref(address: str) -> HubRef:
    """``"hf://ORG/NAME@rev"`` -> :class:`HubRef`.

    Raises:
        ValueError: naming ``path`` and the expected form.
    """
    body = address[len(HUB_PREFIX) :] if address.startswith(HUB_PREFIX) else address
    repo, sep, rev = body.partition("@")
    if not _REPO.match(repo) or (sep and not rev):
        raise ValueError(
            f"path: expected a Hub address 'hf://ORG/NAME' or 'hf://ORG/NAME@REVISION', got "
            f"{address!r}"
        )
    return HubRef(repo, rev or None)


def _hub() -> Any:
    try:
        import huggingface_hub
    except ImportError:
        raise ValueError(
            "path: a Hub address needs huggingface_hub; " + install_hint("hub")
        ) from None
    return huggingface_hub


def download(address: str, cache_dir: str | Path | None = None) -> Path:
    """The local folder of the export at ``address`` (downloaded into the Hub's cache, or found
    there when ``HF_HUB_OFFLINE=1``).

    Raises:
        ValueError: a malformed address, huggingface_hub missing, or the repository / revision
            not found (online) or not cached (offline), in one line naming the address.
    """
    ref = parse_hub_ref(address)
    hub = _hub()
    try:
        folder = hub.snapshot_download(
            ref.repo_id,
            revision=ref.revision,
            cache_dir=cache_dir,
            allow_patterns=list(EXPORT_PATTERNS),
            library_name="neural-dynamic-policies",
        )
    except Exception as exc:  # the Hub's own error kinds (offline, not found, auth)
        first = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else ""
        raise ValueError(
            f"path: cannot get {address} from the Hugging Face Hub ({type(exc).__name__}: {first})"
        ) from None
    out = Path(str(folder))
    if not ((out / "policy.json").is_file() or (out / "policy.onnx").is_file()):
        raise ValueError(
            f"path: {address} holds no policy export (policy.json + policy.safetensors, or "
            "policy.onnx; ndp rl push uploads one)"
        )
    return out


def push_folder(
    folder: str | Path,
    repo_id: str,
    private: bool = False,
    message: str | None = None,
    api: Any = None,
) -> dict[str, Any]:
    """Upload an export folder to the Hub as model repository ``repo_id`` (created if
    missing); only the export's files (:data:`EXPORT_PATTERNS`). ``ndp.rl.hub.push_policy``
    exports a run or ``zoo:NAME`` first and calls this.

    Args:
        folder: an export folder (``policy.json`` + weights, or ``policy.onnx``).
        repo_id: ``ORG/NAME``.
        private: create the repository private.
        message: the commit message (default names the folder).
        api: a ``huggingface_hub.HfApi`` (tests pass a stand-in); None: a new one (the token of
            ``huggingface-cli login`` or ``HF_TOKEN``).

    Returns:
        ``{"repo_id", "files", "commit"}``: the files uploaded and the Hub's commit info.

    Raises:
        ValueError: a malformed ``repo_id``, a folder that holds no export, or the Hub refusing
            (one line).
    """
    if not _REPO.match(str(repo_id)):
        raise ValueError(f"repo_id: expected 'ORG/NAME', got {repo_id!r}")
    folder = Path(folder)
    if not ((folder / "policy.json").is_file() or (folder / "policy.onnx").is_file()):
        raise ValueError(f"source: {folder} is not an export folder (ndp rl export writes one)")
    if api is None:
        api = _hub().HfApi()
    files = sorted(
        rel
        for p in folder.rglob("*")
        if p.is_file() and _is_export_file(rel := p.relative_to(folder).as_posix())
    )
    try:
        api.create_repo(repo_id, private=private, exist_ok=True)
        info = api.upload_folder(
            repo_id=repo_id,
            folder_path=str(folder),
            commit_message=message or f"ndp rl push {folder}",
            allow_patterns=list(EXPORT_PATTERNS),
        )
    except Exception as exc:  # the Hub's own error kinds
        first = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else ""
        raise ValueError(
            f"repo_id: the Hub refused the upload to {repo_id} ({type(exc).__name__}: {first})"
        ) from None
    return {"repo_id": repo_id, "files": files, "commit": str(info)}


def _is_export_file(name: str) -> bool:
    import fnmatch

    return any(fnmatch.fnmatch(name, pat) for pat in EXPORT_PATTERNS)
