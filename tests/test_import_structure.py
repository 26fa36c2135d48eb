"""No module of mimarble imports one that imports it back.

The graph is read from the source with :mod:`ast`, nothing is imported. Every
``import`` and ``from … import`` counts, at module level or inside a function
(a function's import runs at its first call, and a circle through it is still a
circle: a module half-initialised, or two modules that cannot be read alone).
Only modules of the ``mimarble`` package are nodes; relative imports are resolved
against the importing file's package.

What an import is an edge to:

* ``import a.b.c`` and ``from a.b.c import name`` (``name`` not a submodule):
  an edge to ``a.b.c``, the module whose code or names are used.
* ``from a.b import c`` where ``c`` is a submodule (``mimarble/a/b/c.py`` or a
  package ``c/``): an edge to ``a.b.c``; names that are not submodules, in the
  same statement, add the edge to ``a.b``.
* The packages an import passes through on the way (``a`` and ``a.b`` for
  ``a.b.c``; ``a.b`` for ``from a.b import c``): their ``__init__`` runs first,
  so they are edges too — except the packages that contain the importing module.
  Those have begun initialising before the importing module runs at all: an edge
  to them would say nothing, and would make every submodule that a package's
  ``__init__`` imports look like a circle with it (``mimarble/__init__.py`` does
  ``from . import environment``; ``environment`` reaching a sibling through
  ``from . import llvm_target`` does not make it depend on ``mimarble``).

So the package's own face is no circle: ``__init__`` importing its submodules
gives edges from the package to them, and submodules importing one another with
``from . import x`` give edges between them. A submodule importing the package
*for a name defined in its* ``__init__`` (``import mimarble``, ``from mimarble
import render``, ``from . import render`` where ``render`` is no submodule) is an
edge to the package, and a circle when ``__init__`` leads back to it.

Imports written as ``importlib.import_module(...)`` calls are not read (the
package's ``__init__`` loads its heavy submodules that way, by computed name);
``if TYPE_CHECKING:`` blocks would count like any other import (there are none).
"""

from __future__ import annotations

import ast
import os
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "mimarble"


def module_files(package_dir: Path) -> dict[str, Path]:
    """Every module of the package under ``package_dir``: dotted name -> file."""
    modules = {}
    base = package_dir.parent
    for path in sorted(package_dir.rglob("*.py")):
        parts = list(path.relative_to(base).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        modules[".".join(parts)] = path
    return modules


def _is_package(name: str, modules: dict[str, Path]) -> bool:
    return name in modules and modules[name].name == "__init__.py"


def _containing_packages(importer: str, modules: dict[str, Path]) -> set[str]:
    """The packages whose initialisation has begun before ``importer``'s code runs."""
    parts = importer.split(".")
    packages = {".".join(parts[:i]) for i in range(1, len(parts))}
    if _is_package(importer, modules):
        packages.add(importer)          # a package's __init__ is the package itself
    return packages


def _resolve(importer: str, node: ast.ImportFrom, modules: dict[str, Path]) -> str:
    """The absolute module a ``from … import`` names (``from .x``, ``from ..``)."""
    if not node.level:
        return node.module or ""
    package = importer.split(".") if _is_package(importer, modules) else importer.split(".")[:-1]
    package = package[:len(package) - (node.level - 1)]
    return ".".join(package + ([node.module] if node.module else []))


def imports_of(importer: str, path: Path, modules: dict[str, Path], root: str):
    """The edges of one module: (imported module, line) for each import inside the package."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    skip = _containing_packages(importer, modules)
    edges = []

    def add(name: str, line: int, passed_through: bool) -> None:
        if name != root and not name.startswith(root + "."):
            return
        if name not in modules:
            return                      # a name the package does not define as a module
        if passed_through and name in skip:
            return
        if name != importer:
            edges.append((name, line))

    def through(name: str, line: int) -> None:
        parts = name.split(".")
        for i in range(1, len(parts)):
            add(".".join(parts[:i]), line, passed_through=True)

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                through(alias.name, node.lineno)
                add(alias.name, node.lineno, passed_through=False)
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(importer, node, modules)
            through(base, node.lineno)
            names_from_base = False
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                if alias.name != "*" and sub in modules:
                    add(sub, node.lineno, passed_through=False)
                    add(base, node.lineno, passed_through=True)
                else:
                    names_from_base = True
            if names_from_base:
                add(base, node.lineno, passed_through=False)
    return edges


def import_graph(package_dir: Path) -> dict[str, dict[str, list[int]]]:
    """module -> {imported module: [lines]} for every module of the package."""
    modules = module_files(package_dir)
    root = package_dir.name
    graph = {}
    for name, path in modules.items():
        targets = defaultdict(list)
        for target, line in imports_of(name, path, modules, root):
            targets[target].append(line)
        graph[name] = {t: sorted(set(lines)) for t, lines in targets.items()}
    return graph


def strongly_connected(graph: dict[str, dict[str, list[int]]]) -> list[list[str]]:
    """The components of modules that reach one another: those of more than one
    module, or of a module importing itself; each sorted, the list sorted."""
    index, low, on_stack, stack, components = {}, {}, set(), [], []

    def connect(v):                      # Tarjan's algorithm
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in graph.get(v, ()):
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return sorted(components)


def shortest_circle(graph, component: list[str]) -> list[str]:
    """A shortest circle through the component's first module, staying inside it."""
    inside, start = set(component), component[0]
    paths, queue = {start: [start]}, [start]
    while queue:                         # breadth first
        v = queue.pop(0)
        for w in sorted(graph.get(v, ())):
            if w == start:
                return paths[v] + [start]
            if w in inside and w not in paths:
                paths[w] = paths[v] + [w]
                queue.append(w)
    raise AssertionError(f"{component} is no strongly connected component")


def cycles(graph: dict[str, dict[str, list[int]]]) -> list[list[str]]:
    """One circle (first module repeated at the end) for each circle-forming component."""
    return [shortest_circle(graph, c) for c in strongly_connected(graph)]


def describe(component: list[str], graph, modules) -> str:
    """The component's modules, then one circle through them, edge by edge with file:line."""
    circle = shortest_circle(graph, component)
    steps = []
    for a, b in zip(circle, circle[1:]):
        lines = ",".join(map(str, sorted(set(graph[a][b]))))
        steps.append(f"{a} imports {b} ({os.path.relpath(modules[a], ROOT)}:{lines})")
    return (f"{', '.join(component)}:\n      " + " -> ".join(circle) + "\n      "
            + "\n      ".join(steps))


def test_no_module_imports_one_that_imports_it_back():
    package_dir = ROOT / PACKAGE
    graph = import_graph(package_dir)
    modules = module_files(package_dir)
    assert f"{PACKAGE}.runtime.environment" in graph[PACKAGE]          # the reading sees imports at all
    found = strongly_connected(graph)
    assert not found, "modules of mimarble that import one another in a circle:\n  " + (
        "\n  ".join(describe(c, graph, modules) for c in found))


def test_the_checker_finds_a_circle_and_passes_the_package_face(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    files = {
        # The package's face: __init__ imports submodules, submodules import siblings.
        "__init__.py": "from . import a\nfrom .a import A\nNAME = 1\nfrom . import f\n",
        "a.py": "from . import b\nA = 1\n",
        "b.py": "import os\n\ndef f():\n    from .sub import c\n",
        "sub/__init__.py": "from .c import C\n",
        "sub/c.py": "C = 1\n",
        # A circle through a function-level import and a parent-relative one.
        "d.py": "def g():\n    from .sub.e import E\n",
        "sub/e.py": "from .. import d\nE = 1\n",
        # A submodule importing the package for a name of its __init__: an edge to
        # the package, a circle when the package imports that submodule (f), none
        # otherwise (g).
        "f.py": "import pkg\n",
        "g.py": "from . import NAME\n",
    }
    for name, text in files.items():
        (pkg / name).write_text(text)
    graph = import_graph(pkg)
    assert graph["pkg"] == {"pkg.a": [1, 2], "pkg.f": [4]}
    assert graph["pkg.a"] == {"pkg.b": [1]}
    assert graph["pkg.b"] == {"pkg.sub": [4], "pkg.sub.c": [4]}
    assert graph["pkg.sub"] == {"pkg.sub.c": [1]}
    assert graph["pkg.sub.c"] == {}
    assert graph["pkg.d"] == {"pkg.sub": [2], "pkg.sub.e": [2]}
    assert graph["pkg.sub.e"] == {"pkg.d": [1]}
    assert graph["pkg.g"] == {"pkg": [1]}
    assert cycles(graph) == [["pkg", "pkg.f", "pkg"], ["pkg.d", "pkg.sub.e", "pkg.d"]]


def _imported_names(path: Path) -> set[str]:
    """The top-level names of every absolute import in a file (``lark``, ``drjit``, …)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_the_marble_parameter_table_needs_neither_lark_nor_drjit():
    """mimarble/parameters.py and the modules it reaches inside mimarble import only
    the standard library: the command line reads the table before Dr.Jit loads, and the
    scene package (Lark) and the plugin (Dr.Jit) both read it."""
    import sys
    modules = module_files(ROOT / PACKAGE)
    graph = import_graph(ROOT / PACKAGE)
    reached, todo = set(), ["mimarble.parameters"]
    while todo:
        name = todo.pop()
        if name not in reached:
            reached.add(name)
            todo.extend(m for m in graph.get(name, {}) if m != PACKAGE)
    for name in sorted(reached):
        outside = _imported_names(modules[name]) - set(sys.stdlib_module_names) - {PACKAGE}
        assert not outside, f"{name} imports {sorted(outside)}"
