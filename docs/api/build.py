"""Build the API reference of ``ndp`` from its docstrings, with pdoc (``make api``).

    python docs/api/build.py                 # -> build/api/index.html (open it in a browser)
    python docs/api/build.py --out DIR       # elsewhere
    python docs/api/build.py --module NAME   # other modules (repeatable; tests use it)

It documents the public packages (:data:`MODULES`) and, for those without ``__all__``
(``ndp.rl``, ``ndp.il``, ``ndp.experiments``), their sub-modules; a package with ``__all__``
gets one page with the names it exports. Docstrings are read as Google style with the
reStructuredText roles this package uses (pdoc's ``google`` format).

The build is strict; any of these is an error (exit status 1, every problem listed):

- a Python warning while the modules are imported or the pages rendered (pdoc reports its
  problems as warnings: a name in ``__all__`` that does not resolve, an annotation it cannot
  parse, a module it cannot import, ...);
- a cross-reference role in a docstring (``:class:`X```, ``:func:`x``` ...) that names neither a
  documented object nor an importable one, or that pdoc would print literally (Sphinx's ``~``
  prefix, a role pdoc does not know such as ``:ref:``).

Imports are the only side effect on the modules: the lazy public names of ``ndp`` and
``ndp.policies`` (a module ``__getattr__``, which pdoc does not follow) are resolved into their
modules' namespaces in this process, so that they are documented where users find them. The
output folder is replaced as a whole; a folder that is not empty and was not written by this
script is refused.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import re
import shutil
import sys
import time
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any, cast

MODULES = (
    "ndp",
    "ndp.dmp",
    "ndp.nets",
    "ndp.policies",
    "ndp.envs",
    "ndp.rl",
    "ndp.il",
    "ndp.runs",
    "ndp.experiments",
    "ndp.sb3",
    "ndp.zoo",
)
"""The public packages the reference documents (with the sub-modules pdoc walks)."""

DEFAULT_OUT = Path(__file__).resolve().parents[2] / "build" / "api"
MARKER = ".ndp-api-reference"
"""A file in the output folder that marks it as this script's (so that it may be replaced)."""

# the roles pdoc's reStructuredText conversion turns into code references (pdoc.docstrings.rst),
# and any role-like markup
_PDOC_ROLES = {"mod", "func", "data", "const", "class", "meth", "attr", "exc", "obj"}
_ROLE = re.compile(r"(?<![\w`]):(?:py:)?([a-z]+):`([^`]*)`")


class ReferenceBuildError(RuntimeError):
    """The reference did not build cleanly; ``problems`` lists why, one line each."""

    def __init__(self, problems: Sequence[str]) -> None:
        self.problems = list(problems)
        super().__init__(
            f"API reference: {len(self.problems)} problem(s):\n"
            + "\n".join(f"  {p}" for p in self.problems)
        )


def _resolve_lazy_names(module: ModuleType) -> None:
    """Put the names of ``module.__all__`` that its ``__getattr__`` provides into its namespace."""
    for name in getattr(module, "__all__", ()):
        if name not in vars(module):
            setattr(module, name, getattr(module, name))


def _module_names(specs: Sequence[str]) -> list[str]:
    """The modules pdoc documents for ``specs``, each once, imported outside pdoc's import
    sandbox (which replaces ``subprocess.Popen``: MuJoCo's GLFW probe breaks under it)."""
    import pdoc.extract

    names: list[str] = []
    for spec in specs:
        _resolve_lazy_names(importlib.import_module(spec))
        for name in pdoc.extract.walk_specs([spec]):
            if name not in names:
                _resolve_lazy_names(importlib.import_module(name))
                names.append(name)
    return names


def _walk(doc: Any) -> Iterator[Any]:
    """``doc`` and the members pdoc renders under it (public ones, defined in their module)."""
    import pdoc.doc

    yield doc
    if isinstance(doc, pdoc.doc.Module | pdoc.doc.Class):
        for member in doc.own_members:
            if isinstance(member, pdoc.doc.Module):
                continue  # a sub-module has its own page
            if member.name.startswith("_") and member.name != "__init__":
                continue  # pdoc does not render private members
            yield from _walk(member)


def _own_docstring(doc: Any, packages: set[str]) -> str:
    """The docstring if the source of the documented ``packages`` holds it ('' for one pdoc
    takes from a base class elsewhere, e.g. gymnasium's, or generates, e.g. a dataclass's
    signature)."""
    import inspect

    text = str(doc.docstring)
    module = sys.modules.get(doc.taken_from[0])
    if not text.strip() or module is None or doc.taken_from[0].split(".")[0] not in packages:
        return ""
    try:
        source = inspect.getsource(module)
    except (OSError, TypeError):
        return ""
    first = next(line.strip() for line in text.splitlines() if line.strip())
    return text if first in source else ""


def _importable(path: str) -> bool:
    """``path`` (dotted) names a module or an attribute of an (already importable) module."""
    parts = path.split(".")
    for i in range(len(parts), 0, -1):
        name = ".".join(parts[:i])
        try:
            module = sys.modules.get(name) or importlib.import_module(name)
        except ImportError:
            continue
        obj: Any = module
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def check_references(all_modules: dict[str, Any]) -> list[str]:
    """Roles in the documented docstrings that name nothing, or that pdoc prints literally."""
    import pdoc.doc
    from pdoc.render_helpers import linkify

    packages = {name.split(".")[0] for name in all_modules}
    problems: dict[tuple[str, str], str] = {}
    for module in all_modules.values():
        # linkify's context: the module the docstring is rendered in and every documented one
        context = {"module": module, "all_modules": all_modules, "is_public": lambda d: "yes"}
        for doc in _walk(module):
            text = _own_docstring(doc, packages)
            where = f"{doc.taken_from[0]}:{doc.taken_from[1] or '(module)'}"
            # the scope names resolve in: a class's own, else the enclosing class (or module)
            ns = (
                doc.qualname if isinstance(doc, pdoc.doc.Class) else doc.qualname.rpartition(".")[0]
            )
            for m in _ROLE.finditer(text):
                role, target = m.group(1), m.group(2)
                if role == "math":
                    continue
                key = (where, m.group(0))
                if role not in _PDOC_ROLES:
                    problems[key] = f"{where}: {m.group(0)}: pdoc does not render :{role}:"
                    continue
                if target.startswith("~"):
                    problems[key] = f"{where}: {m.group(0)}: pdoc prints the '~' (drop it)"
                    continue
                name = target.removesuffix("()")
                if "<a " in linkify(cast(Any, context), f"<code>{name}</code>", ns):
                    continue  # a documented object: pdoc links it
                owner = doc.taken_from[0]
                scope = ns.split(".") if ns else []
                candidates = [name] + [
                    ".".join([owner, *scope[:i], name]) for i in range(len(scope), -1, -1)
                ]
                if not any(_importable(c) for c in candidates):
                    problems.setdefault(key, f"{where}: {m.group(0)} does not resolve")
    return sorted(set(problems.values()))


def build(out: Path = DEFAULT_OUT, modules: Sequence[str] = MODULES) -> list[str]:
    """Write the reference of ``modules`` to ``out`` (``out/index.html``); return the modules
    documented. Raises :class:`ReferenceBuildError` on any warning or bad reference (then
    nothing is written: the pages are rendered in memory first)."""
    import pdoc.doc
    import pdoc.render

    out = Path(out)
    if out.exists() and any(out.iterdir()) and not (out / MARKER).exists():
        raise ReferenceBuildError([f"{out} is not empty and not an API reference of this script"])
    # every warning is collected (not raised at once: pdoc catches exceptions in places, and
    # one build should list every problem); any of them fails the build
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        names = _module_names(modules)
        import ndp

        pdoc.render.configure(
            docformat="google",
            footer_text=f"neural-dynamic-policies {ndp.version()}",
            show_source=True,
        )
        all_modules = {name: pdoc.doc.Module.from_name(name) for name in names}
        pages = {
            name: pdoc.render.html_module(mod, all_modules) for name, mod in all_modules.items()
        }
        index = pdoc.render.html_index(all_modules)
        search = pdoc.render.search_index(all_modules)
        problems = check_references(all_modules)
    problems = [
        f"warning ({w.category.__name__}, {Path(w.filename).name}:{w.lineno}): {w.message}"
        for w in caught
    ] + problems
    if problems:
        raise ReferenceBuildError(problems)

    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    (out / MARKER).write_text("written by docs/api/build.py; replaced by the next build\n")
    for name, html in pages.items():
        page = out / f"{name.replace('.', '/')}.html"
        page.parent.mkdir(parents=True, exist_ok=True)
        page.write_text(html, encoding="utf-8")
    if index:
        (out / "index.html").write_text(index, encoding="utf-8")
    if search:
        (out / "search.js").write_text(search, encoding="utf-8")
    return names


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder")
    parser.add_argument(
        "--module", action="append", help="a module to document (default: the public packages)"
    )
    args = parser.parse_args(argv)
    start = time.perf_counter()
    try:
        names = build(args.out, args.module or MODULES)
    except ReferenceBuildError as exc:
        print(exc, file=sys.stderr)
        return 1
    seconds = time.perf_counter() - start
    index = args.out / "index.html"
    print(f"API reference: {len(names)} modules in {seconds:.1f} s -> {index}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
