"""No import cycle in ``strapdown_ros``, function-level imports included (static, AST only).

Every ``import`` of every module counts: module level and inside functions (a cycle closed by a
deferred import still means two modules that need each other). Imports under ``if
TYPE_CHECKING:`` never run and are left out of the package-wide cycle check, but not out of the
direction rules below, nor out of the configuration package's own cycle check: its section
modules take the values they need as arguments and never name the scenario model. How imports
are resolved: ``test/import_graph.py``.
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


CONFIG = "strapdown_ros.config"


def _in(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def config_cycles(graph: import_graph.Graph, package: str = CONFIG) -> list[list]:
    """Cycles among the modules of the configuration package, every import counted
    (``TYPE_CHECKING`` ones too)."""
    inner = import_graph.Graph.__new__(import_graph.Graph)
    inner.modules = {n: p for n, p in graph.modules.items() if _in(n, package)}
    inner.imports = {n: graph.imports[n] for n in inner.modules}
    return inner.cycles()


def section_back_imports(graph: import_graph.Graph, package: str = CONFIG) -> list[str]:
    """Imports of any kind by which a section module of the configuration package names its
    scenario model: ``<package>.scenario`` or the package itself (which re-exports it)."""
    top = (package, f"{package}.scenario")
    return [
        f"  {imp.source} imports {imp.target} ({imp.where()}: {imp.statement})"
        for name, imports in graph.imports.items()
        if _in(name, package) and name not in top
        for imp in imports
        if imp.target in top
    ]


def test_config_sections_do_not_name_the_scenario(graph: import_graph.Graph) -> None:
    """A section's cross-field rules take explicit arguments (rates, topics, the initial
    state, other sections) from ``Scenario._cross_checks``; no section module imports the
    scenario model, not even for a type annotation."""
    bad = section_back_imports(graph)
    assert not bad, "config section modules import the scenario model:\n" + "\n".join(bad)


def test_no_import_cycle_in_config_type_checking_included(graph: import_graph.Graph) -> None:
    cycles = config_cycles(graph)
    report = "\n".join(f"  {import_graph.describe_cycle(c)}" for c in cycles)
    assert not cycles, f"import cycle(s) in strapdown_ros.config:\n{report}"


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


def test_checker_finds_a_section_naming_the_scenario(tmp_path: Path) -> None:
    graph = _write(
        tmp_path,
        {
            "pkg/__init__.py": "",
            "pkg/config/__init__.py": "from pkg.config.scenario import Scenario\n",
            "pkg/config/base.py": "X = 1\n",
            "pkg/config/scenario.py": "from pkg.config import a, b, c\n",
            "pkg/config/a.py": "from typing import TYPE_CHECKING\n"
            "if TYPE_CHECKING:\n    from pkg.config.scenario import Scenario\n",
            "pkg/config/b.py": "def f():\n    from pkg.config import Scenario\n",
            "pkg/config/c.py": "from pkg.config.base import X\n",  # fine
        },
    )
    bad = section_back_imports(graph, "pkg.config")
    assert len(bad) == 2, bad
    assert "pkg.config.a imports pkg.config.scenario (line 3, module level, TYPE_CHECKING" in bad[0]
    assert "pkg.config.b imports pkg.config (line 2, in f()" in bad[1]
    cycles = {tuple(m for m, _ in c) for c in config_cycles(graph, "pkg.config")}
    assert cycles == {
        ("pkg.config.a", "pkg.config.scenario"),  # TYPE_CHECKING counts here
        ("pkg.config", "pkg.config.scenario", "pkg.config.b"),  # through the re-export
    }, cycles
