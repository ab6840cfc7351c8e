"""Import circles inside the package: none new, and the known ones shrink only.

The graph counts every ``import`` of an ndp module, function-local ones included (a circle held
open by a lazy import is still a circle a reader has to untangle), but not imports under
``if TYPE_CHECKING:`` (annotations only). Strongly connected components of more than one
module are the circles.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import ndp

SRC = Path(ndp.__file__).resolve().parent

KNOWN: set[frozenset[str]] = set()
"""Circles left to break: none (issue "one skeleton" broke the last three: the task-table lookups
moved into ``ndp.envs.spec``, the method registry names Dyn-E's learner by entry point and holds
VICES' registrations, ``exec_k_table`` moved into ``ndp.rl.evaluate``)."""


def _modules() -> dict[str, Path]:
    out = {}
    for f in SRC.rglob("*.py"):
        parts = f.relative_to(SRC.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = f
    return out


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                skip |= {id(n) for n in ast.walk(child)}
    return skip


def import_graph() -> dict[str, set[str]]:
    mods = _modules()

    def resolve(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {m: set() for m in mods}
    for m, f in mods.items():
        tree = ast.parse(f.read_text())
        skip = _type_checking_nodes(tree)
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
            for t in targets:
                if t.split(".")[0] != "ndp":
                    continue
                r = resolve(t)
                # a module's own package (__init__) is not an edge of a circle through it
                if r and r != m and not m.startswith(r + "."):
                    graph[m].add(r)
    return graph


def circles(graph: dict[str, set[str]]) -> set[frozenset[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: set[frozenset[str]] = set()
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = set()
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.add(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    out.add(frozenset(comp))
    return out


def test_the_circle_finder_finds_a_circle_and_ignores_a_chain():
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert circles(g) == {frozenset("abc")}
    assert circles({"a": {"b"}, "b": set()}) == set()


def test_no_new_import_circle_and_the_known_ones_are_still_there():
    found = circles(import_graph())
    new = found - KNOWN
    assert not new, f"new import circles: {[sorted(c) for c in new]}"
    gone = KNOWN - found
    assert not gone, f"circles broken (remove them from KNOWN): {[sorted(c) for c in gone]}"


LAYERS = {
    # foundations: files, checks, provenance, protocols, data tables
    "io": 0,
    "checks": 0,
    "provenance": 0,
    "chunk_info": 0,
    "act_inputs": 0,
    "gym_ids": 0,
    "zoo": 0,
    "hub": 1,
    # numerical core and run infrastructure
    "dmp": 1,
    "nets": 1,
    "runs": 1,
    # the one task schema (what a task is for a DMP, a policy and an export)
    "schema": 2,
    # the data flow: environments -> policies -> learners -> studies -> command line
    "envs": 3,
    "policies": 4,
    "rl": 5,
    "il": 5,
    "bc": 6,
    "sb3": 6,
    "experiments": 7,
    "cli": 8,
    "": 8,  # the package facade (ndp/__init__.py)
}
"""Each top-level part of ``src/ndp`` and its layer (docs/design: data flow first); a part may
import only parts of a lower layer."""


def _part(module: str) -> str:
    return module.split(".")[1] if "." in module else ""


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """``"a -> b"`` for each import of a part of the same or a higher layer."""
    return sorted(
        f"{m} -> {t}"
        for m, targets in graph.items()
        for t in targets
        if _part(m) != _part(t) and LAYERS[_part(t)] >= LAYERS[_part(m)]
    )


def test_every_import_between_parts_goes_down_a_layer():
    graph = import_graph()
    missing = {_part(m) for m in graph} - set(LAYERS)
    assert not missing, f"parts of src/ndp without a layer (add them to LAYERS): {missing}"
    upward = upward_imports(graph)
    assert not upward, f"imports that do not go down a layer: {upward}"


def test_the_layer_check_sees_an_upward_and_a_sideways_import():
    graph = {
        "ndp.dmp.layer": {"ndp.rl.onpolicy.trainer", "ndp.io"},
        "ndp.rl.onpolicy.trainer": {"ndp.il.train"},
        "ndp.il.train": set(),
        "ndp.io": set(),
    }
    assert upward_imports(graph) == [
        "ndp.dmp.layer -> ndp.rl.onpolicy.trainer",
        "ndp.rl.onpolicy.trainer -> ndp.il.train",
    ]


# ----------------------------------------------------------------------------- lazy imports

LAZY_DEBT: set[str] = set()
"""Modules that still import ndp modules inside functions for no reason the rule below accepts
(the list only shrinks)."""


def _help_path() -> set[str]:
    """The ndp modules that ``ndp --help`` imports."""
    code = (
        "import runpy, sys\n"
        "sys.argv = ['ndp', '--help']\n"
        "try:\n"
        "    runpy.run_module('ndp.cli', run_name='__main__')\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(' '.join(m for m in sys.modules if m.startswith('ndp')), file=sys.stderr)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return {*out.stderr.strip().splitlines()[-1].split(), "ndp.cli"}


def _imports(tree: ast.AST, skip: set[int]) -> Iterator[tuple[ast.AST, list[str], bool]]:
    """(node, imported names, inside a function) for every import outside TYPE_CHECKING."""
    local: set[int] = set()
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            local |= {id(n) for n in ast.walk(fn)}
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            yield node, [a.name for a in node.names], id(node) in local
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node, [node.module], id(node) in local


def needless_lazy_imports() -> dict[str, list[str]]:
    """Per module off the ``ndp --help`` path: its function-local imports of ndp modules that
    would load no third-party package the module does not load already (moving them to the top
    costs nothing and shows the dependency)."""
    mods = _modules()

    def resolve(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    def with_parents(m: str) -> set[str]:
        out = {m}
        while "." in m:
            m = m.rpartition(".")[0]
            out.add(m)
        return out

    trees = {m: ast.parse(f.read_text()) for m, f in mods.items()}
    top: dict[str, set[str]] = {}
    third: dict[str, set[str]] = {}
    for m, tree in trees.items():
        top[m], third[m] = set(), set()
        for _, names, local in _imports(tree, _type_checking_nodes(tree)):
            if local:
                continue
            for n in names:
                root = n.split(".")[0]
                if root == "ndp":
                    r = resolve(n)
                    top[m] |= with_parents(r) - {m} if r else set()
                elif root not in sys.stdlib_module_names and root != "__future__":
                    third[m].add(root)
    memo: dict[str, set[str]] = {}

    def loads(m: str, stack: tuple[str, ...] = ()) -> set[str]:
        """Third-party packages loaded by importing ``m``."""
        if m in memo:
            return memo[m]
        if m in stack:
            return set()
        out = set(third[m])
        for d in top[m]:
            out |= loads(d, (*stack, m))
        memo[m] = out
        return out

    help_path = _help_path()
    found: dict[str, list[str]] = {}
    for m, tree in trees.items():
        if m in help_path:
            continue
        for node, names, local in _imports(tree, _type_checking_nodes(tree)):
            if not local or not all(n.split(".")[0] == "ndp" for n in names):
                continue
            targets = {p for n in names if (r := resolve(n)) for p in with_parents(r)}
            if not set().union(*(loads(t) for t in targets)) - loads(m):
                found.setdefault(m, []).append(f"line {node.lineno}: {ast.unparse(node)}")
    return found


def test_function_local_imports_only_where_they_keep_a_dependency_away():
    found = needless_lazy_imports()
    new = {m: v for m, v in found.items() if m not in LAZY_DEBT}
    assert not new, f"import these at the top (nothing heavier loads): {new}"
    fixed = LAZY_DEBT - set(found)
    assert not fixed, f"take these off LAZY_DEBT: {sorted(fixed)}"
