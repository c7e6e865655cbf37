"""Static import graph of Python sources (AST only, nothing is imported).

Used by ``test/test_imports.py`` (import cycles in ``strapdown_ros``), ``test/test_layering.py``
(what ``strapdown_ros.core`` may import) and ``test/tiers.py`` (which tests need rclpy).

Every ``import`` statement counts, wherever it is: module level, inside functions, under
``if TYPE_CHECKING:`` (flagged). Resolution:

* ``import a.b.c`` -> ``a.b.c``;
* ``from a.b import c`` -> ``a.b.c`` when that is a module of the scanned sources (``from pkg
  import module``), else ``a.b``;
* relative imports (``from . import x``, ``from ..a import b``) are resolved against the
  importing module's package first, then as above.

An edge names the most specific module imported; the parent packages that Python also executes
(``a``, ``a.b`` for ``import a.b.c``) are not edges of the graph (a package ``__init__`` that
re-exports its submodules would otherwise be a cycle with each of them), but
:func:`loads_at_import` follows them.
"""

from __future__ import annotations

import ast
from collections import deque
from dataclasses import dataclass
from functools import cache
from pathlib import Path


@dataclass(frozen=True)
class Import:
    """One imported module as written in a source file."""

    source: str  #: importing module (dotted name)
    target: str  #: imported module (dotted name, resolved as described in the module docstring)
    names: tuple[str, ...]  #: names taken with ``from target import ...`` (empty for ``import``)
    line: int
    function: str | None  #: enclosing function (``Class.method``), None at module/class level
    type_checking: bool  #: under ``if TYPE_CHECKING:``
    statement: str = ""  #: the statement as written

    @property
    def top_level(self) -> bool:
        """Executed when the module is imported (not deferred to a function call)."""
        return self.function is None and not self.type_checking

    def where(self) -> str:
        scope = f"in {self.function}()" if self.function else "module level"
        if self.type_checking:
            scope += ", TYPE_CHECKING"
        return f"line {self.line}, {scope}"


def package_modules(package_dir: Path, name: str | None = None) -> dict[str, Path]:
    """``dotted name -> file`` of every module of the package at ``package_dir``, whose dotted
    name is ``name`` (default: the directory's name, i.e. a top-level package)."""
    prefix = tuple((name or package_dir.name).split("."))
    modules = {}
    for path in sorted(package_dir.rglob("*.py")):
        parts = prefix + path.relative_to(package_dir).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _absolute(module: str, is_package: bool, level: int, name: str | None) -> str:
    """Absolute dotted name of ``from <level dots><name> import ...`` inside ``module``."""
    if level == 0:
        return name or ""
    package = module.split(".") if is_package else module.split(".")[:-1]
    base = package[: len(package) - (level - 1)] if level > 1 else package
    return ".".join([*base, name] if name else base)


#: The nodes a statement can stand in: statements, ``except`` clauses, ``match`` cases.
_STATEMENT_LIKE = (ast.stmt, ast.excepthandler, ast.match_case)


@cache
def parse(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def imports_of(
    path: Path, module: str, known: frozenset[str] | set[str] = frozenset()
) -> list[Import]:
    """Every import of the file ``path`` (module ``module``), resolved; ``known``: module names
    that exist (to tell ``from pkg import module`` from ``from module import name``)."""
    is_package = path.name == "__init__.py"
    found: list[Import] = []
    # Imports are statements; expressions matter only for pytest.importorskip("x") calls, so a
    # file that never names it is walked statement by statement (a few times faster).
    walk_expressions = "importorskip" in path.read_text(encoding="utf-8")

    def visit(node: ast.AST, function: str | None, scope: str, tc: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if not walk_expressions and not isinstance(child, _STATEMENT_LIKE):
                continue
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                name = getattr(child, "name", "<lambda>")
                qual = f"{scope}.{name}" if scope else name
                visit(child, function or qual, qual, tc)
            elif isinstance(child, ast.ClassDef):
                visit(child, function, f"{scope}.{child.name}" if scope else child.name, tc)
            elif isinstance(child, ast.If) and _is_type_checking(child.test):
                for stmt in child.body:
                    visit(ast.Module(body=[stmt], type_ignores=[]), function, scope, True)
                for stmt in child.orelse:
                    visit(ast.Module(body=[stmt], type_ignores=[]), function, scope, tc)
            elif isinstance(child, ast.Import):
                text = ast.unparse(child)
                for alias in child.names:
                    found.append(Import(module, alias.name, (), child.lineno, function, tc, text))
            elif isinstance(child, ast.ImportFrom):
                base = _absolute(module, is_package, child.level, child.module)
                text = ast.unparse(child)
                plain = [a.name for a in child.names if f"{base}.{a.name}" not in known]
                for alias in child.names:
                    if f"{base}.{alias.name}" in known:  # from pkg import module
                        target = f"{base}.{alias.name}"
                        found.append(Import(module, target, (), child.lineno, function, tc, text))
                if plain:
                    found.append(
                        Import(module, base, tuple(plain), child.lineno, function, tc, text)
                    )
            elif isinstance(child, ast.Call) and _importorskip_target(child):
                target = _importorskip_target(child)
                text = f"importorskip({target!r})"
                found.append(Import(module, target, (), child.lineno, function, tc, text))
                visit(child, function, scope, tc)
            else:
                visit(child, function, scope, tc)

    visit(parse(path), None, "", False)
    return found


def _importorskip_target(call: ast.Call) -> str | None:
    """``pytest.importorskip("x")`` imports ``x``."""
    func = call.func
    named = (isinstance(func, ast.Attribute) and func.attr == "importorskip") or (
        isinstance(func, ast.Name) and func.id == "importorskip"
    )
    if named and call.args and isinstance(call.args[0], ast.Constant):
        value = call.args[0].value
        return value if isinstance(value, str) else None
    return None


class Graph:
    """Import graph of one or more source roots (``dotted name -> file``)."""

    def __init__(self, modules: dict[str, Path]) -> None:
        self.modules = dict(modules)
        known = frozenset(self.modules)
        self.imports: dict[str, list[Import]] = {
            name: imports_of(path, name, known) for name, path in self.modules.items()
        }

    def internal(self, target: str) -> str | None:
        """The scanned module ``target`` names (itself, else its longest scanned prefix)."""
        parts = target.split(".")
        for n in range(len(parts), 0, -1):
            name = ".".join(parts[:n])
            if name in self.modules:
                return name
        return None

    def edges(self, top_level_only: bool = False) -> dict[str, list[tuple[str, Import]]]:
        """``module -> [(imported scanned module, the import)]``: one import per pair, the one
        that runs soonest (module level, then in a function, then under TYPE_CHECKING)."""
        out: dict[str, list[tuple[str, Import]]] = {name: [] for name in self.modules}
        for name, imports in self.imports.items():
            best: dict[str, Import] = {}  # module level first, then functions, TYPE_CHECKING last
            for imp in imports:
                if top_level_only and not imp.top_level:
                    continue
                target = self.internal(imp.target)
                if target is None or target == name:
                    continue
                rank = (imp.type_checking, imp.function is not None, imp.line)
                old = best.get(target)
                if old is None or rank < (old.type_checking, old.function is not None, old.line):
                    best[target] = imp
            out[name] = sorted(best.items(), key=lambda e: e[1].line)
        return out

    def cycles(self) -> list[list[tuple[str, Import]]]:
        """Import cycles: for every edge inside a strongly connected component, the shortest
        cycle through it (deduplicated). Each cycle is ``[(module, its import of the next)]``."""
        edges = self.edges()
        found: dict[tuple[str, ...], list[tuple[str, Import]]] = {}
        for component in _strongly_connected({m: [t for t, _ in e] for m, e in edges.items()}):
            members = set(component)
            for source in sorted(members):
                for target, imp in edges[source]:
                    if target not in members:
                        continue
                    path = _shortest_path(edges, target, source, members)
                    cycle = [(source, imp), *path]
                    nodes = [m for m, _ in cycle]
                    k = nodes.index(min(nodes))
                    found.setdefault(tuple(nodes[k:] + nodes[:k]), cycle[k:] + cycle[:k])
        return [found[key] for key in sorted(found)]

    def loads_at_import(self, name: str, external_prefixes: tuple[str, ...]) -> list[str] | None:
        """The chain of module-level imports by which importing ``name`` loads a module starting
        with one of ``external_prefixes`` (e.g. ``("rclpy",)``), or None. Parent packages count
        (importing ``a.b.c`` runs ``a/__init__.py`` and ``a/b/__init__.py``)."""

        def hits(target: str) -> bool:
            return any(target == p or target.startswith(p + ".") for p in external_prefixes)

        def with_parents(target: str) -> list[str]:
            parts = target.split(".")
            return [".".join(parts[:n]) for n in range(1, len(parts) + 1)]

        start = [m for m in with_parents(name) if m in self.modules]
        queue = deque((m, [m]) for m in start)
        seen = set(start)
        while queue:
            module, chain = queue.popleft()
            for imp in self.imports[module]:
                if not imp.top_level:
                    continue
                if hits(imp.target):
                    return [*chain, imp.target]
                for target in with_parents(imp.target):
                    if target in self.modules and target not in seen:
                        seen.add(target)
                        queue.append((target, [*chain, target]))
        return None


def _strongly_connected(graph: dict[str, list[str]]) -> list[list[str]]:
    """Tarjan's algorithm (iterative); components with a cycle only (size > 1)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    result: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(graph[child])))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    result.append(sorted(component))
    return result


def _shortest_path(
    edges: dict[str, list[tuple[str, Import]]], start: str, goal: str, members: set[str]
) -> list[tuple[str, Import]]:
    """Shortest ``[(module, import of the next)]`` from ``start`` to ``goal`` within ``members``
    (``start`` itself first; empty when ``start == goal``)."""
    if start == goal:
        return []
    previous: dict[str, tuple[str, Import]] = {}
    queue = deque([start])
    seen = {start}
    while queue:
        node = queue.popleft()
        for target, imp in edges[node]:
            if target not in members or target in seen:
                continue
            previous[target] = (node, imp)
            if target == goal:
                path = []
                while target != start:
                    node_, imp_ = previous[target]
                    path.append((node_, imp_))
                    target = node_
                return path[::-1]
            seen.add(target)
            queue.append(target)
    raise AssertionError(f"no path {start} -> {goal} inside its component")


def describe_cycle(cycle: list[tuple[str, Import]]) -> str:
    """``a --(line 3, module level: from b import x)--> b --(line 9, in f(): import a)--> a``."""
    text = cycle[0][0]
    for i, (_, imp) in enumerate(cycle):
        following = cycle[(i + 1) % len(cycle)][0]
        text += f" --({imp.where()}: {imp.statement})--> {following}"
    return text
