"""``ndp.load_policy``: one entry for every kind of saved policy. An ONNX export loads as an
:class:`ndp.rl.onnx_policy.OnnxPolicy` without importing torch; a run, a safetensors export or
``zoo:NAME`` through :func:`ndp.rl.policy.load_any_policy` (torch); ``hf://ORG/NAME`` from the
Hugging Face Hub (:mod:`ndp.hub`) as the export it holds."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from ndp.hub import download, is_hub_ref
from ndp.rl.onnx_policy import OnnxPolicy, is_onnx_export

if TYPE_CHECKING:
    from ndp.rl.policy import Policy


def load_any(path: str | Path) -> Policy | OnnxPolicy:
    """``ndp.load_policy``: an ONNX export as an :class:`OnnxPolicy` without importing torch;
    anything else (a run, a safetensors export, ``zoo:NAME``) through
    :func:`ndp.rl.policy.load_any_policy`."""
    if is_hub_ref(path):  # hf://ORG/NAME: the export's files from the Hub (or its cache)
        path = download(str(path))
    if isinstance(path, (str, Path)) and not str(path).startswith("zoo:") and is_onnx_export(path):
        return OnnxPolicy(path)
    from ndp.rl.policy import load_any_policy  # torch: only for a torch policy

    return load_any_policy(path)
