"""Trained policies the tests use as fixtures (tests/fixtures/policies): copies of the zoo's
exports as they were when the tests' reference actions, numbers and cards were recorded.

The zoo (ndp/zoo/policies) is regenerated with new weights and may hold other policies; a test
that depends on specific weights (reference actions, a condition number, a card's content) or on
a method or task the zoo need not hold (VICES, Dyn-E, reach-v3, ...) loads the fixture by path:
``ndp.load_policy(fixture_policy("throw-vices"))``. Tests of the zoo mechanism itself (``zoo:``
names, ``ndp.zoo.list()``, the wheel) use the zoo.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "policies"


def fixture_names() -> list[str]:
    """Every fixture policy, sorted."""
    return sorted(p.name for p in FIXTURES.iterdir() if (p / "policy.json").is_file())


def fixture_policy(name: str) -> Path:
    """The folder of the fixture policy ``name`` (e.g. ``"push-v3-ndp"``)."""
    path = FIXTURES / name
    if not (path / "policy.json").is_file():
        raise FileNotFoundError(f"no fixture policy {name!r} in {FIXTURES}: {fixture_names()}")
    return path


def fixture_index() -> dict[str, Any]:
    """The zoo's index (zoo.json, copied with them) as it was when the fixtures were copied:
    their published success, steps, seeds and the evaluation's command."""
    return json.loads((FIXTURES / "zoo.json").read_text())


def fixture_row(name: str) -> dict[str, Any]:
    """The fixture policy ``name``'s row of :func:`fixture_index`."""
    return next(r for r in fixture_index()["policies"] if r["policy"] == name)
