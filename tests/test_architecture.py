"""The package's import graph: no cycle between modules, no import up the layers, no private
names across subpackages.

The graph is built statically from the source (every ``import`` and ``from ... import``, also
those inside functions, relative imports resolved), so an import hidden in a function to dodge a
cycle at run time counts like any other; only imports under ``if TYPE_CHECKING:`` are left out
(they never run). Its nodes are modules: ``flexmor.reduction.krylov``, ``flexmor.reduction``
(the package's ``__init__``), ``flexmor`` (the root ``__init__``). ``from pkg import name`` is an
edge to ``pkg.name`` when that is a module, else to ``pkg``.

:data:`LAYERS` is the layer drawing of ``docs/architecture.md`` as data: a module may import
modules of its own layer and of the layers below it, never of a layer above.

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

#: The layers of ``docs/architecture.md``, top to bottom. Each entry is a module or a package
#: (the package with all its modules); the root entry ``flexmor`` is the root ``__init__`` alone.
#: A module belongs to its longest entry and may import its own layer and those below it.
LAYERS = [
    ["flexmor"],  # the public namespace (the root __init__)
    ["flexmor.__main__", "flexmor.cli"],  # the command line: alone prints and exits
    ["flexmor.ui"],  # web app (runs cli's main, handed in)
    ["flexmor.workflow", "flexmor.study", "flexmor.prepare", "flexmor.studyfile", "flexmor.tolerance",
     "flexmor.plan"],  # jobs: reduce and judge, study, its preparation, study files, target-error mode, the plan
    # before the run
    ["flexmor.report"],  # plots, HTML report, 3D view
    ["flexmor.analysis", "flexmor.moving"],  # judging reduced bodies, assemblies, the body held in its joints;
    # moving loads: their paths, compressed inputs, the judge over the path and crossings
    ["flexmor.reduction"],  # methods -> Basis, METHODS registry, reduce()
    ["flexmor.dynamics", "flexmor.io"],  # FRF, modes, time integration; formats, exporters, invariants
    ["flexmor.rigid", "flexmor.expansion", "flexmor.modal", "flexmor.stress", "flexmor.preload",
     "flexmor.stiffening", "flexmor.spin"],  # rigid motion, elastic body; expansion; modal form; element stresses
    # and strains; geometric stiffness of preloads and of unit loads; spinning bodies
    ["flexmor.projection", "flexmor.body", "flexmor.checks", "flexmor.models"],  # projection; the body; checks; models
    ["flexmor.origin", "flexmor.ports", "flexmor.selection", "flexmor.couplings", "flexmor.basis",
     "flexmor.options", "flexmor.support"],  # model fingerprint, ports, node sets, RBE2/RBE3, bases, option
    # values, how interfaces are held
    ["flexmor.model", "flexmor.damping", "flexmor.mesh", "flexmor.units", "flexmor.elements"],  # the FE model,
    # damping values, mesh surface, unit systems, elements and materials
    ["flexmor.linalg"],  # solver layer
    ["flexmor.errors", "flexmor.jsonutil", "flexmor._version", "flexmor.display"],  # errors, JSON values, the
    # version, short reprs and HTML tables
]

#: Modules whose methods delegate upward, importing at call time: their imports inside functions
#: are not edges of the graph (``test_body_delegates_only_to_its_concerns`` bounds them).
DELEGATING = {"flexmor.body"}



def module_name(path: Path, root: Path = ROOT) -> str:
    """Dotted module name of a source file below ``root`` (a package's ``__init__`` is the package)."""
    parts = [root.name, *path.relative_to(root).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
        (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _import_nodes(tree: ast.AST, in_functions: bool = True):
    """Every ``Import``/``ImportFrom`` node of ``tree`` except those under ``if TYPE_CHECKING:``
    (and those inside functions unless ``in_functions``)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        if isinstance(node, ast.If) and _type_checking(node.test):
            stack.extend(node.orelse)
            continue
        for child in ast.iter_child_nodes(node):
            if in_functions or not isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                stack.append(child)


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
    for node in sorted(_import_nodes(tree, in_functions), key=lambda n: n.lineno):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == top or alias.name.startswith(top + "."):
                    yield alias.name, None, node.lineno
        else:
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
    """The subpackage or top-level module that ``module`` belongs to (``flexmor`` for the root)."""
    return ".".join(module.split(".")[:2])


def import_graph(root: Path = ROOT) -> dict[str, dict[str, str]]:
    """``{module: {imported module: 'file:line' of the first such import}}`` between distinct modules.

    An import of a name that is no module (``from pkg.mod import f``) is an edge to the module it
    comes from; one of a module that does not exist goes to the nearest existing package.
    """
    files = sorted(root.rglob("*.py"))
    modules = {module_name(p, root) for p in files}
    graph: dict[str, dict[str, str]] = {}
    for p in files:
        a = module_name(p, root)
        graph.setdefault(a, {})
        inside = module_name(p, root) not in DELEGATING
        for target, _, line in imports_of(p, modules, root, in_functions=inside):
            while target not in modules and "." in target:
                target = target.rpartition(".")[0]
            if target != a and target in modules:
                graph[a].setdefault(target, f"{p.relative_to(root.parent)}:{line}")
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


def strongly_connected(graph: dict[str, dict]) -> list[list[str]]:
    """The strongly connected components of ``graph`` with more than one node (each sorted), sorted.

    Every cycle lies in one of them; the graph is acyclic when there is none.
    """
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return sorted(out)


def _describe(graph, cycle) -> str:
    return " -> ".join(cycle) + "\n" + "\n".join(
        f"  {a} -> {b}  ({graph[a][b]})" for a, b in zip(cycle, cycle[1:]))


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def _cycles(graph, tolerated=()) -> list[str]:
    """One cycle (with the file and line of each edge) per strongly connected component of
    ``graph``, except components that lie entirely within a package of ``tolerated``."""
    out = []
    for comp in strongly_connected(graph):
        if any(all(_within(m, p) for m in comp) for p in tolerated):
            continue
        members = set(comp)
        sub = {a: {b: w for b, w in graph[a].items() if b in members} for a in comp}
        out.append(_describe(graph, find_cycle(sub)))
    return out


def layer_of(module: str, layers=LAYERS, root: str = "flexmor") -> int | None:
    """Index (0 at the top) of the layer of ``module``'s longest entry in ``layers``, or None."""
    best, where = "", None
    for i, layer in enumerate(layers):
        for entry in layer:
            hit = module == entry if entry == root else _within(module, entry)
            if hit and len(entry) > len(best):
                best, where = entry, i
    return where


def upward_imports(graph, layers=LAYERS, root: str = "flexmor") -> list[str]:
    """``'file:line: a imports b, a layer above'`` for every import of a module of a higher layer
    (modules in no layer are left to :func:`test_every_module_has_a_layer`)."""
    out = []
    for a in sorted(graph):
        for b, where in sorted(graph[a].items()):
            la, lb = layer_of(a, layers, root), layer_of(b, layers, root)
            if la is not None and lb is not None and lb < la:
                out.append(f"{where}: {a} imports {b}, a layer above")
    return out


def test_the_graph_has_module_nodes_and_sees_function_level_imports():
    graph = import_graph()
    assert {"flexmor.reduction", "flexmor.reduction.krylov", "flexmor.linalg.factorization",
            "flexmor.cli"} <= set(graph)
    assert "flexmor.linalg.factorization" in graph["flexmor.linalg.pardiso"]
    assert "flexmor.reduction._registry" in graph["flexmor.reduction.krylov"]
    assert "flexmor.rigid" in graph["flexmor.expansion"]  # an import inside a function


def test_no_import_cycle_between_modules():
    cycles = _cycles(import_graph())
    assert not cycles, "import cycle(s) between modules:\n" + "\n".join(cycles)


def test_every_module_has_a_layer():
    graph = import_graph()
    missing = sorted(m for m in graph if layer_of(m) is None)
    assert not missing, "modules in no layer of LAYERS (tests/test_architecture.py, docs/architecture.md): " \
        + ", ".join(missing)
    entries = [e for layer in LAYERS for e in layer]
    assert len(entries) == len(set(entries))
    assert all(any(_within(m, e) for m in graph) for e in entries), "an entry of LAYERS names no module"


def test_no_import_up_the_layers():
    bad = upward_imports(import_graph())
    assert not bad, "imports of a higher layer (see LAYERS and docs/architecture.md):\n" + "\n".join(bad)


def test_body_delegates_only_to_its_concerns():
    """``body.py`` imports at module level only what lies below it (its reprs from ``display``); inside
    its methods only the modules of the concerns it delegates to (FRF, time response, expansion,
    state space)."""
    path = ROOT / "body.py"
    modules = {module_name(p) for p in ROOT.rglob("*.py")}
    top = {unit(t) for t, _, _ in imports_of(path, modules, in_functions=False)} - {"flexmor.body"}
    assert top <= {"flexmor._version", "flexmor.damping", "flexmor.errors", "flexmor.display"}, top
    called = {t for t, _, _ in imports_of(path, modules)} - {t for t, _, _ in imports_of(path, modules,
                                                                                          in_functions=False)}
    assert called == {"flexmor.dynamics.frf", "flexmor.dynamics.time", "flexmor.expansion", "flexmor.io.statespace"}


def test_layers_shared_below_reduction_and_analysis():
    """The chosen direction: dynamics below both, analysis may judge with reduction, never back;
    the rigid-body base below reduction and io."""
    order = {p: layer_of(p) for p in ("flexmor.analysis", "flexmor.reduction", "flexmor.dynamics", "flexmor.io",
                                      "flexmor.rigid")}
    assert order["flexmor.analysis"] < order["flexmor.reduction"] < order["flexmor.dynamics"]
    assert order["flexmor.reduction"] < order["flexmor.io"] < order["flexmor.rigid"]


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
    assert bool(strongly_connected(graph)) == (expected is not None)


def test_every_cycle_is_reported_and_a_tolerated_package_is_left_out():
    graph = {"flexmor.io": {"flexmor.io.x": "io/__init__.py:3"}, "flexmor.io.x": {"flexmor.io": "io/x.py:7"},
             "flexmor.a": {"flexmor.b": "a.py:1"}, "flexmor.b": {"flexmor.c": "b.py:2"},
             "flexmor.c": {"flexmor.a": "c.py:5", "flexmor.io": "c.py:6"},
             "flexmor.d": {"flexmor.d.e": "d/__init__.py:1"}, "flexmor.d.e": {"flexmor.d": "d/e.py:9"}}
    assert strongly_connected(graph) == [["flexmor.a", "flexmor.b", "flexmor.c"], ["flexmor.d", "flexmor.d.e"],
                                         ["flexmor.io", "flexmor.io.x"]]
    cycles = _cycles(graph, tolerated=("flexmor.io",))
    assert len(cycles) == 2
    assert cycles[0].startswith("flexmor.a -> flexmor.b -> flexmor.c -> flexmor.a\n") and "(c.py:5)" in cycles[0]
    assert "(d/e.py:9)" in cycles[1] and not any("io/x.py" in c for c in cycles)
    assert len(_cycles(graph)) == 3


def test_upward_import_is_found_with_its_file_and_line():
    layers = [["pkg.top"], ["pkg.mid", "pkg.sub"], ["pkg.low", "pkg"]]
    graph = {"pkg.top": {"pkg.mid": "top.py:1"}, "pkg.mid": {"pkg.low": "mid.py:2", "pkg.sub.x": "mid.py:3"},
             "pkg.sub.x": {"pkg": "sub/x.py:4"}, "pkg.low": {"pkg.sub.x": "low.py:8"}, "pkg": {}}
    assert layer_of("pkg.sub.x", layers, "pkg") == 1 and layer_of("pkg", layers, "pkg") == 2
    assert layer_of("pkg.other", layers, "pkg") is None  # the root entry is the root module alone
    assert upward_imports(graph, layers, "pkg") == ["low.py:8: pkg.low imports pkg.sub.x, a layer above"]


def test_graph_of_a_synthetic_package_with_function_level_and_relative_imports(tmp_path):
    """A cycle made only by a relative import inside a function is found, with its file and line;
    an import under ``if TYPE_CHECKING:`` is no edge."""
    pkg = tmp_path / "pkg"
    for sub in ("a", "b"):
        (pkg / sub).mkdir(parents=True)
        (pkg / sub / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "a" / "x.py").write_text("from ..b import y\n")
    (pkg / "b" / "y.py").write_text("import os\n\n\ndef f():\n    from ..a.x import g\n    return g\n")
    (pkg / "top.py").write_text("import pkg.a.x\nfrom . import b\n")
    (pkg / "typed.py").write_text("from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from .top import T\n"
                                  "else:\n    from .a import x\n")
    graph = import_graph(pkg)
    assert graph["pkg.a.x"] == {"pkg.b.y": "pkg/a/x.py:1"}
    assert graph["pkg.b.y"] == {"pkg.a.x": "pkg/b/y.py:5"}
    assert graph["pkg.top"] == {"pkg.a.x": "pkg/top.py:1", "pkg.b": "pkg/top.py:2"}
    assert graph["pkg.typed"] == {"pkg.a.x": "pkg/typed.py:6"}
    cycle = find_cycle(graph)
    assert cycle == ["pkg.a.x", "pkg.b.y", "pkg.a.x"]
    assert "pkg/b/y.py:5" in _describe(graph, cycle)
    (cycles,) = _cycles(graph, tolerated=())
    assert "pkg.a.x -> pkg.b.y  (pkg/a/x.py:1)" in cycles and "pkg.b.y -> pkg.a.x  (pkg/b/y.py:5)" in cycles
