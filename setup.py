"""Ships ``src/_ndp_gymnasium.pth`` at the root of site-packages, in wheels and in editable
installs, so ``import gymnasium`` alone registers the ``ndp/...`` ids (src/_ndp_gymnasium.py).
Everything else about the package is declared in pyproject.toml.

setuptools has no option for a top-level .pth file: ``build_py`` copies it into the wheel's root,
and ``editable_wheel`` (``pip install -e``) adds it beside its own ``__editable__`` .pth.
tests/envs/test_gym_registration.py checks both: a built wheel holds the file, and the test venv
(an editable install) makes an id after ``import gymnasium`` alone.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.editable_wheel import editable_wheel

PTH = Path(__file__).resolve().parent / "src" / "_ndp_gymnasium.pth"


class BuildPyWithPth(build_py):
    def run(self) -> None:
        super().run()
        self.copy_file(str(PTH), str(Path(self.build_lib, PTH.name)), preserve_mode=False)

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        return [*super().get_outputs(include_bytecode), str(Path(self.build_lib, PTH.name))]


class EditableWheelWithPth(editable_wheel):
    def _run_build_commands(
        self, dist_name: str, unpacked_wheel: str, *args: Any, **kw: Any
    ) -> Any:
        out = super()._run_build_commands(dist_name, unpacked_wheel, *args, **kw)
        shutil.copyfile(PTH, Path(unpacked_wheel, PTH.name))
        return out


setup(cmdclass={"build_py": BuildPyWithPth, "editable_wheel": EditableWheelWithPth})
