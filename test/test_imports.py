"""No import cycle in ``strapdown_ros``, function-level imports included (static, AST only).

Every ``import`` of every module counts: module level and inside functions (a cycle closed by a
deferred import still means two modules that need each other). Imports under ``if
TYPE_CHECKING:`` never run and are left out of the cycle check, but not out of the direction
rule below. How imports are resolved: ``test/import_graph.py``.
"""

from __future__ import annotations

from pathlib import Path

import import_graph
import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "strapdown_ros"


@pytest.fixture(scope="module")
def graph() -> import_graph.Graph:
    return import_graph.Graph(import_graph.package_modules(PACKAGE))


def _runtime_cycles(graph: import_graph.Graph) -> list[list]:
    runtime = import_graph.Graph.__new__(import_graph.Graph)
    runtime.modules = graph.modules
    runtime.imports = {
        name: [imp for imp in imports if not imp.type_checking]
        for name, imports in graph.imports.items()
    }
    return runtime.cycles()


def test_no_import_cycle(graph: import_graph.Graph) -> None:
    cycles = _runtime_cycles(graph)
    report = "\n".join(f"  {import_graph.describe_cycle(c)}" for c in cycles)
    assert not cycles, f"{len(cycles)} import cycle(s) in strapdown_ros:\n{report}"


def test_config_does_not_import_stages_nodes_or_generate(graph: import_graph.Graph) -> None:
    """The scenario model is read by the stages and nodes, never the reverse (any import)."""
    later = ("strapdown_ros.stages", "strapdown_ros.nodes", "strapdown_ros.generate",
             "strapdown_ros.cli", "strapdown_ros.pipeline")  # fmt: skip
    bad = [
        f"  {imp.source} imports {imp.target} ({imp.where()})"
        for name, imports in graph.imports.items()
        if name == "strapdown_ros.config" or name.startswith("strapdown_ros.config.")
        for imp in imports
        if any(imp.target == p or imp.target.startswith(p + ".") for p in later)
    ]
    assert not bad, "strapdown_ros.config imports what depends on it:\n" + "\n".join(bad)


# --- the checker itself -------------------------------------------------------------------


def _write(root: Path, files: dict[str, str]) -> import_graph.Graph:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return import_graph.Graph(import_graph.package_modules(root / "pkg"))


def test_checker_finds_cycles_of_every_import_form(tmp_path: Path) -> None:
    graph = _write(
        tmp_path,
        {
            "pkg/__init__.py": "",
            "pkg/a.py": "from pkg import b\n",  # from package import module
            "pkg/b.py": "def f():\n    from .sub import c\n",  # relative, in a function
            "pkg/sub/__init__.py": "",
            "pkg/sub/c.py": "import pkg.a\n",  # plain import
            "pkg/d.py": "from .e import thing\n",
            "pkg/e.py": "class K:\n    def m(self):\n        from . import d\n",  # in a method
            "pkg/f.py": "from .g import thing\n",
            "pkg/g.py": "from typing import TYPE_CHECKING\n"
            "if TYPE_CHECKING:\n    from pkg.f import y\n",  # never runs
            "pkg/ok.py": "import pkg.a\nfrom pkg.sub import c\n",  # imports into a cycle only
        },
    )
    cycles = {tuple(m for m, _ in c) for c in graph.cycles()}
    assert cycles == {("pkg.a", "pkg.b", "pkg.sub.c"), ("pkg.d", "pkg.e"), ("pkg.f", "pkg.g")}
    text = {import_graph.describe_cycle(c) for c in graph.cycles()}
    assert (
        "pkg.a --(line 1, module level: from pkg import b)--> pkg.b "
        "--(line 2, in f(): from .sub import c)--> pkg.sub.c "
        "--(line 1, module level: import pkg.a)--> pkg.a"
    ) in text, text
    assert any("in K.m()" in t for t in text), text
    assert any("TYPE_CHECKING: from pkg.f import y" in t for t in text), text
    runtime = {tuple(m for m, _ in c) for c in _runtime_cycles(graph)}
    assert runtime == {("pkg.a", "pkg.b", "pkg.sub.c"), ("pkg.d", "pkg.e")}


def test_checker_accepts_a_package_that_reexports_its_modules(tmp_path: Path) -> None:
    graph = _write(
        tmp_path,
        {
            "pkg/__init__.py": "from pkg.a import A\nfrom .b import B\n",
            "pkg/a.py": "A = 1\n",
            "pkg/b.py": "from pkg.a import A\nB = A\n",
        },
    )
    assert graph.cycles() == []
