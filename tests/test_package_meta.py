"""The package's face: version (``ndp --version``, ``ndp.version()``), the public API listed by
``__all__`` and ``dir(ndp)`` while ``import ndp`` stays light, and LICENSE / CITATION.cff /
CHANGELOG.md agreeing with pyproject.toml."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

import ndp

ROOT = Path(__file__).resolve().parents[1]
SRC = Path(ndp.__file__).resolve().parents[1]
PUBLIC = {"DMPConfig", "DMPLayer", "load_policy", "make_env", "export_policy", "Policy"}


def _pyproject_version() -> str:
    tomllib = pytest.importorskip("tomllib")
    return str(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"])


def test_version_everywhere_is_pyprojects():
    v = _pyproject_version()
    assert ndp.__version__ == v
    cff = pytest.importorskip("yaml").safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["version"] == v and cff["license"] == "MIT"
    changelog = (ROOT / "CHANGELOG.md").read_text()
    # an [Unreleased] section (Keep a Changelog) may come first; the newest release is the version
    first = re.search(r"^## \[((?!Unreleased)[^\]]+)\]", changelog, re.MULTILINE)
    assert first and first.group(1) == v, "CHANGELOG.md's newest entry is not pyproject's version"


def test_license_is_mit_as_pyproject_says():
    tomllib = pytest.importorskip("tomllib")
    assert tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["license"] == "MIT"
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License")
    assert "neural-dynamic-policies developers" in text.splitlines()[2]
    assert "WITHOUT WARRANTY OF ANY KIND" in text


def test_citation_names_the_software_and_the_paper():
    cff = pytest.importorskip("yaml").safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software"
    paper = cff["preferred-citation"]
    assert paper["title"] == "Neural Dynamic Policies for End-to-End Sensorimotor Learning"
    assert [a["family-names"] for a in paper["authors"]] == ["Bahl", "Mukadam", "Gupta", "Pathak"]
    assert paper["year"] == 2020 and "NeurIPS" in paper["collection-title"]


def test_ndp_version_prints_the_installed_version_without_loading_the_commands():
    script = (
        f"import sys; sys.path.insert(0, {str(SRC)!r}); from ndp.cli import main; "
        "rc = main(['--version']); import json; "
        "print(json.dumps([rc, sorted(m for m in sys.modules if m.startswith('ndp.'))]))"
    )
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    out = r.stdout.splitlines()
    assert out[0] == f"ndp {ndp.version()}"
    rc, loaded = json.loads(out[1])
    assert rc == 0 and "ndp.rl.cli" not in loaded and "ndp.il.cli" not in loaded


def test_version_falls_back_to_the_pyproject_version(monkeypatch):
    try:
        installed = metadata.version("neural-dynamic-policies")
    except metadata.PackageNotFoundError:
        installed = None
    assert ndp.version() == (installed or _pyproject_version())

    def missing(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "version", missing)
    assert ndp.version() == _pyproject_version()


def test_all_names_the_public_api_and_dir_shows_it():
    assert set(ndp.__all__) >= PUBLIC
    assert set(ndp.__all__) <= set(dir(ndp))
    assert not {"Any", "annotations"} & set(dir(ndp))  # the file's own typing imports
    for name in ndp.__all__:
        assert getattr(ndp, name) is not None, name
    assert ndp.zoo.list()  # the lazily imported sub-package
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = ndp.nope


def test_import_ndp_and_dir_stay_light():
    script = (
        f"import sys; sys.path.insert(0, {str(SRC)!r}); import ndp; names = dir(ndp); "
        "heavy = sorted(m for m in sys.modules if m.partition('.')[0] in "
        "('torch', 'numpy', 'gymnasium', 'mujoco', 'safetensors')); "
        "print(heavy, 'load_policy' in names)"
    )
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[] True", r.stdout + r.stderr
