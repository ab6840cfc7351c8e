"""Start-up hook of neural-dynamic-policies: registers the ``ndp/...`` gymnasium ids when
``gymnasium`` is imported, so ``import gymnasium; gymnasium.make("ndp/push-v3")`` works without
``import ndp``.

gymnasium 1.x loads no plugin entry points, so the package ships ``_ndp_gymnasium.pth``, which
imports this module when Python starts. It only puts one finder on ``sys.meta_path``; nothing
else runs until ``gymnasium`` itself is imported. Then, right after gymnasium's own
``__init__`` has run, it registers the shipped id table (:func:`ndp.gym_ids.register_shipped`:
strings only, no simulator is imported) and takes itself off ``sys.meta_path``. A failure there
is a warning, never a failed ``import gymnasium``. Set ``NDP_NO_GYMNASIUM_HOOK=1`` to skip it.
"""

from __future__ import annotations

import os
import sys

# Python runs this at every start-up: import nothing beyond os and sys (importlib.abc and typing
# cost tens of milliseconds); the finder and loader are duck-typed.
TYPE_CHECKING = False
if TYPE_CHECKING:
    from typing import Any


class _Loader:
    """gymnasium's own loader, plus the registration once the module has executed."""

    def __init__(self, loader: Any) -> None:
        self._loader = loader

    def create_module(self, spec: object) -> object:
        return self._loader.create_module(spec)

    def exec_module(self, module: object) -> None:
        self._loader.exec_module(module)
        try:
            from ndp.gym_ids import register_shipped

            register_shipped()
        except Exception as e:  # never break `import gymnasium`
            import warnings

            warnings.warn(
                f"neural-dynamic-policies could not register its gymnasium ids ({e!r}); "
                "`import ndp.envs` registers them",
                RuntimeWarning,
                stacklevel=2,
            )

    def __getattr__(self, name: str) -> object:  # get_data, get_resource_reader, is_package, ...
        return getattr(self._loader, name)


class _GymnasiumFinder:
    """Finds nothing itself: wraps the loader of ``gymnasium`` the other finders find."""

    def find_spec(self, fullname: str, path: object = None, target: object = None) -> object:
        if fullname != "gymnasium":
            return None
        remove()
        for finder in sys.meta_path:
            find = getattr(finder, "find_spec", None)
            spec = find(fullname, path, target) if find is not None else None
            if spec is not None:
                if spec.loader is not None and hasattr(spec.loader, "exec_module"):
                    spec.loader = _Loader(spec.loader)
                return spec
        return None


def remove() -> None:
    """Take the finder off ``sys.meta_path`` (idempotent)."""
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _GymnasiumFinder)]


def install() -> None:
    """Put the finder first on ``sys.meta_path`` unless gymnasium is loaded or the hook is off."""
    if os.environ.get("NDP_NO_GYMNASIUM_HOOK") or "gymnasium" in sys.modules:
        return
    remove()
    sys.meta_path.insert(0, _GymnasiumFinder())  # type: ignore[arg-type]  # duck-typed


install()
