"""The package's import graph: no cycle between subpackages, no private names across them.

The graph is built statically from the source (every ``import`` and ``from ... import``,
also those inside functions, relative imports resolved), so an import hidden in a function
to dodge a cycle at run time counts like any other. Nodes are the subpackages
(``flexmor.reduction``, ``flexmor.analysis`` ...), the top-level modules (``flexmor.cli``,
``flexmor.projection`` ...) and the package root ``flexmor`` itself (its ``__init__``).

One exception, :data:`DELEGATING`: the reduced body's methods (``body.frf``, ``.simulate``,
``.expand``, ``.to_control``) hand the body to the modules that own each concern, which sit
above ``body.py`` and import it. Only the module-level imports of ``body.py`` are edges; a test
checks that its function-level imports are those delegations and nothing else.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import flexmor

ROOT = Path(flexmor.__file__).parent

#: Modules whose methods delegate upward, importing at call time: their imports inside functions
#: are not edges of the graph (``test_body_delegates_only_to_its_concerns`` bounds them).
DELEGATING = {"flexmor.body"}


def module_name(path: Path, root: Path = ROOT) -> str:
    """Dotted module name of a source file below ``root`` (a package's ``__init__`` is the package)."""
    parts = [root.name, *path.relative_to(root).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _nodes(tree, in_functions: bool):
    """The AST nodes of ``tree``; without those inside functions unless ``in_functions``."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if in_functions or not isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                todo.append(child)


def imports_of(path: Path, modules: set[str], root: Path = ROOT, *, in_functions: bool = True):
    """``(target, name, line)`` of every import of the package in ``path``.

    ``target`` is the module imported from (relative imports resolved); ``name`` is the
    imported name for ``from target import name`` (None for ``import target``). A name that
    is itself a module (``from . import cache``) becomes the target. ``in_functions=False``
    leaves out the imports inside functions.
    """
    mod = module_name(path, root)
    package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    top = root.name
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    for node in sorted(_nodes(tree, in_functions), key=lambda n: getattr(n, "lineno", 0)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == top or alias.name.startswith(top + "."):
                    yield alias.name, None, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if not (target == top or target.startswith(top + ".")):
                continue
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                yield (sub, None, node.lineno) if sub in modules else (target, alias.name, node.lineno)


def unit(module: str) -> str:
    """The node of ``module``: ``flexmor`` itself, a top-level module or a subpackage."""
    return ".".join(module.split(".")[:2])


def import_graph(root: Path = ROOT) -> dict[str, dict[str, str]]:
    """``{node: {imported node: 'file:line' of the first such import}}`` between distinct nodes."""
    files = sorted(root.rglob("*.py"))
    modules = {module_name(p, root) for p in files}
    graph: dict[str, dict[str, str]] = {}
    for p in files:
        a = unit(module_name(p, root))
        graph.setdefault(a, {})
        inside = module_name(p, root) not in DELEGATING
        for target, _, line in imports_of(p, modules, root, in_functions=inside):
            b = unit(target)
            if b != a:
                graph[a].setdefault(b, f"{p.relative_to(root.parent)}:{line}")
    return graph


def find_cycle(graph: dict[str, dict]) -> list[str] | None:
    """One cycle of the directed ``graph`` as a path ``[a, b, ..., a]``, or None."""
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    path: list[str] = []

    def visit(v):
        state[v] = 1
        path.append(v)
        for w in sorted(graph.get(v, ())):
            if state.get(w) == 1:
                return path[path.index(w):] + [w]
            if w not in state and (found := visit(w)):
                return found
        path.pop()
        state[v] = 2
        return None

    for v in sorted(graph):
        if v not in state and (found := visit(v)):
            return found
    return None


def _describe(graph, cycle) -> str:
    return " -> ".join(cycle) + "\n" + "\n".join(
        f"  {a} -> {b}  ({graph[a][b]})" for a, b in zip(cycle, cycle[1:]))


def test_no_import_cycle_between_subpackages():
    graph = import_graph()
    assert {"flexmor.reduction", "flexmor.analysis", "flexmor.dynamics", "flexmor.cli"} <= set(graph)
    assert "flexmor.linalg" in graph["flexmor.reduction"]  # the graph sees real edges
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle between subpackages:\n" + _describe(graph, cycle)


def test_body_delegates_only_to_its_concerns():
    """``body.py`` imports at module level only what lies below it; inside its methods only the
    modules of the concerns it delegates to (FRF, time response, expansion, state space)."""
    path = ROOT / "body.py"
    modules = {module_name(p) for p in ROOT.rglob("*.py")}
    top = {unit(t) for t, _, _ in imports_of(path, modules, in_functions=False)} - {"flexmor.body"}
    assert top <= {"flexmor", "flexmor.damping", "flexmor.errors"}, top
    called = {t for t, _, _ in imports_of(path, modules)} - {t for t, _, _ in imports_of(path, modules,
                                                                                          in_functions=False)}
    assert called == {"flexmor.dynamics.frf", "flexmor.dynamics.time", "flexmor.expansion", "flexmor.io.statespace"}


def test_layers_shared_below_reduction_and_analysis():
    """The chosen direction: dynamics below both, analysis may judge with reduction, never back."""
    graph = import_graph()
    assert "flexmor.reduction" not in graph["flexmor.dynamics"]
    assert "flexmor.analysis" not in graph["flexmor.dynamics"]
    assert "flexmor.analysis" not in graph["flexmor.reduction"], graph["flexmor.reduction"].get("flexmor.analysis")


def test_no_private_names_imported_across_subpackages():
    files = sorted(ROOT.rglob("*.py"))
    modules = {module_name(p) for p in files}
    bad = [f"{p.relative_to(ROOT.parent)}:{line}: {name} from {target}"
           for p in files for target, name, line in imports_of(p, modules)
           if name and name.startswith("_") and not name.startswith("__")
           and unit(target) != unit(module_name(p))]
    assert not bad, "private names imported from another subpackage:\n" + "\n".join(bad)


@pytest.mark.parametrize("graph, expected", [
    ({"a": {"b": ""}, "b": {"c": ""}, "c": {"a": ""}}, ["a", "b", "c", "a"]),
    ({"a": {"b": ""}, "b": {}, "c": {"d": ""}, "d": {"c": ""}}, ["c", "d", "c"]),
    ({"a": {"b": "", "c": ""}, "b": {"c": ""}, "c": {}}, None),
])
def test_cycle_detector_finds_synthetic_cycles(graph, expected):
    assert find_cycle(graph) == expected


def test_graph_of_a_synthetic_package_with_function_level_and_relative_imports(tmp_path):
    """A cycle made only by a relative import inside a function is found, with its file and line."""
    pkg = tmp_path / "pkg"
    for sub in ("a", "b"):
        (pkg / sub).mkdir(parents=True)
        (pkg / sub / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "a" / "x.py").write_text("from ..b import y\n")
    (pkg / "b" / "y.py").write_text("import os\n\n\ndef f():\n    from ..a.x import g\n    return g\n")
    (pkg / "top.py").write_text("import pkg.a.x\nfrom . import b\n")
    graph = import_graph(pkg)
    assert graph["pkg.a"] == {"pkg.b": "pkg/a/x.py:1"}
    assert graph["pkg.b"] == {"pkg.a": "pkg/b/y.py:5"}
    assert graph["pkg.top"] == {"pkg.a": "pkg/top.py:1", "pkg.b": "pkg/top.py:2"}
    cycle = find_cycle(graph)
    assert cycle == ["pkg.a", "pkg.b", "pkg.a"]
    assert "pkg/b/y.py:5" in _describe(graph, cycle)
