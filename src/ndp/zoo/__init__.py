"""The trained policies shipped with the package: ``ndp.load_policy("zoo:push-v3-ndp")``.

The exports live in this package's data (``ndp/zoo/policies/<name>/``: ``policy.json``,
``policy.safetensors`` and a model card ``README.md``; ``zoo.json`` indexes them, ``README.md``
is their table; ``benchmarks/zoo.py`` makes them), so they are there after a plain
``pip install``, found with :mod:`importlib.resources`. In a source checkout ``zoo/`` points at
the same folder.

- :func:`list`: the names; :func:`info`: a policy's row of the index (task, method, seed,
  success over the published episodes, ...); :func:`card`: its model card;
- :func:`path`: its directory (what ``ndp.load_policy("zoo:<name>")`` loads).

Unknown names raise a one-line ``ValueError`` with the close names.
"""

from __future__ import annotations

import builtins
import difflib
import json
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # importlib.resources.abc from Python 3.11
    from importlib.abc import Traversable

PREFIX = "zoo:"
"""``ndp.load_policy`` reads a path that starts with this as a zoo name."""


def root() -> Traversable:
    """The folder of the shipped policies (a ``pathlib.Path`` for an ordinary install)."""
    return resources.files(__name__) / "policies"


def index() -> dict[str, Any]:
    """The zoo's index, ``zoo.json``: the command and commit that made it, the evaluation
    protocol (``episodes``, ``select_episodes``) and one row per policy (``"policies"``)."""
    data: dict[str, Any] = json.loads((root() / "zoo.json").read_text())
    return data


def list() -> builtins.list[str]:
    """The names of the shipped policies, in the index's order (``"push-v3-ndp"``, ...)."""
    return [str(row["policy"]) for row in index()["policies"]]


def _check(name: str) -> str:
    names = list()
    if isinstance(name, str) and name.startswith(PREFIX):
        name = name[len(PREFIX) :]
    if isinstance(name, str) and name in names:
        return name
    close = difflib.get_close_matches(str(name), names, n=4, cutoff=0.4)
    hint = f"close names: {', '.join(close)}" if close else "none close"
    raise ValueError(f"zoo: no policy {name!r} ({hint}; ndp.zoo.list() gives all {len(names)})")


def info(name: str) -> dict[str, Any]:
    """A policy's row of the index (``task``, ``method``, ``seed``, ``steps``, ``success``,
    ``success_final``, ``episode_return``, ``source_run``, ``trained_at``, ...)."""
    name = _check(name)
    row: dict[str, Any] = next(r for r in index()["policies"] if r["policy"] == name)
    return row


def card(name: str) -> str:
    """A policy's model card (its ``README.md``: YAML front matter, then text)."""
    return (root() / _check(name) / "README.md").read_text()


def path(name: str) -> Path:
    """The directory of a shipped policy, on the file system.

    Args:
        name: ``"push-v3-ndp"`` or ``"zoo:push-v3-ndp"``.

    Raises:
        ValueError: an unknown name (one line, with the close names).
    """
    name = _check(name)
    found = root() / name
    if isinstance(found, Path):
        return found
    # an install that is not on a file system (a zip): the files are copied out once
    import tempfile

    out = Path(tempfile.mkdtemp(prefix=f"ndp-zoo-{name}-"))
    for f in found.iterdir():
        (out / f.name).write_bytes(f.read_bytes())
    return out
