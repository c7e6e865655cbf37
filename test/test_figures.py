"""Every quantitative figure in the docs traces to the command that produces it.

``docs/figures.yaml`` is the register: one entry per measured figure (its file, its text as it
appears there, the command that produces it, the commit and load average it was measured at, or
``unknown``), and an allow-list of numbers that are not measurements (scenario parameters,
limits, definitions, constants), each with the reason. This module checks

* every entry's text occurs in its file (a figure edited in the docs must be edited here too);
* every measured entry names a command whose script, test (and test function), make target,
  ``strapdown-sim`` subcommand or ``python -m strapdown_ros...`` module exists in the repository;
* every paragraph, table row and code block of README.md and docs/*.md that holds a figure-like
  token (a number followed by a unit: ``x``/``×``, s, ms, µs, Hz, kHz, MiB, MB, m, m/s, rad,
  msgs/s, %, ...) either names a command itself (a backticked script, test, make target or
  ``strapdown-sim`` subcommand; a table row or code block also by a command named before it in
  the same section) or is covered by a register entry;
* entries produced by ``make figures`` (``key``) carry the text that ``tools/figures.py`` wrote
  into ``docs/figures_measured.json``, where that file has the key.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parent.parent
REGISTER = REPO / "docs" / "figures.yaml"
MEASURED = REPO / "docs" / "figures_measured.json"
SCANNED = sorted([REPO / "README.md", *(REPO / "docs").glob("*.md")])

# A number (decimal, thousands grouped by spaces or commas, exponent) followed by a unit.
_NUMBER = r"(?<![\w.\-/])[~≈<>≤≥]?\s?-?\d[\d  ,]*(?:\.\d+)?(?:e[-+−]?\d+)?"
_UNIT = (
    r"(?:x|×|s|ms|µs|us|ns|min|Hz|kHz|MHz|MiB|KiB|GiB|kB|MB|GB|m|km|m/s|rad|msgs/s"
    r"|k msgs/s|%)"
)
FIGURE = re.compile(_NUMBER + r"\s?" + _UNIT + r"(?![\w/])")

# A backticked span that names a producing command.
COMMAND = re.compile(
    r"`[^`]*(?:(?:bench|tools|test)/[\w/]+\.py|\b(?:bench|test)_\w+\.py|waldmann_table3\.py"
    r"|compare_generate\.py|\w+\.py::\w+|make [a-z-]+|strapdown-sim [a-z]+|pytest|\.ci/run"
    r"|-m strapdown_ros(?:\.\w+)+)[^`]*`"
)


def _normalize(text: str) -> str:
    return re.sub(r"\s+", " ", text).strip()


def units(text: str) -> list[tuple[int, str, str]]:
    """(first line, text, kind) of each paragraph ("para"), table row ("row") and fenced code
    block ("code") of a markdown text."""
    lines = text.splitlines()
    out: list[tuple[int, str, str]] = []
    buf: list[str] = []
    start = 0

    def flush() -> None:
        if buf:
            out.append((start, "\n".join(buf), "para"))
            buf.clear()

    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("```"):
            flush()
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            out.append((i + 1, "\n".join(lines[i : j + 1]), "code"))
            i = j + 1
            continue
        if line.lstrip().startswith("|"):
            flush()
            out.append((i + 1, line, "row"))
        elif not line.strip():
            flush()
        else:
            if not buf:
                start = i + 1
            buf.append(line)
        i += 1
    flush()
    return out


def uncovered(path: Path, texts: list[str], root: Path = REPO) -> list[str]:
    """Units of ``path`` with figure-like tokens that neither name a command nor contain one of
    ``texts`` (the register's entries for this file), as ``file:line: tokens``."""
    problems = []
    section_names_command = False  # a command named earlier in the same section (heading)
    needles = [_normalize(t) for t in texts]
    for line, text, kind in units(path.read_text()):
        if kind == "para" and text.startswith("#"):
            section_names_command = False
        names_command = bool(COMMAND.search(text))
        tokens = [_normalize(t) for t in FIGURE.findall(text)]
        section_names_command |= names_command
        if not tokens or names_command:
            continue
        if kind != "para" and section_names_command:
            continue
        flat = _normalize(text)
        if any(n in flat for n in needles):
            continue
        problems.append(f"{path.relative_to(root)}:{line}: {tokens}")
    return problems


def _register() -> dict:
    return yaml.safe_load(REGISTER.read_text())


def _entries() -> list[dict]:
    return _register()["figures"]


def _allowed() -> list[dict]:
    return _register()["allow"]


def _makefile_targets() -> set[str]:
    return set(re.findall(r"^([a-z][a-z-]*):", (REPO / "Makefile").read_text(), re.M))


def _cli_commands() -> set[str]:
    """The ``strapdown-sim`` subcommands: cli.py's parsers and those a module adds to it
    (``score``: strapdown_ros/score/cli.py)."""
    texts = [(REPO / "strapdown_ros" / f).read_text() for f in ("cli.py", "score/cli.py")]
    return {name for text in texts for name in re.findall(r"add_parser\(\s*\"([a-z]+)\"", text)}


def command_problems(command: str) -> list[str]:
    """What a register command names that does not exist (empty: everything it names exists;
    a command naming nothing recognisable is a problem too)."""
    problems = []
    named = 0
    for script, _, func in re.findall(r"((?:bench|tools|test)/[\w/]+\.py)(::(\w+))?", command):
        named += 1
        path = REPO / script
        if not path.is_file():
            problems.append(f"{script}: no such file")
        elif func and not re.search(rf"^\s*def {func}\b", path.read_text(), re.M):
            problems.append(f"{script}::{func}: no such test")
    for target in re.findall(r"\bmake ([a-z][a-z-]*)", command):
        named += 1
        if target not in _makefile_targets():
            problems.append(f"make {target}: no such target")
    for sub in re.findall(r"\bstrapdown-sim ([a-z]+)", command):
        named += 1
        if sub not in _cli_commands():
            problems.append(f"strapdown-sim {sub}: no such subcommand")
    for module in re.findall(r"-m (strapdown_ros(?:\.\w+)+)", command):
        named += 1
        path = REPO / (module.replace(".", "/") + ".py")
        if not path.is_file():
            problems.append(f"python -m {module}: no such module")
    if re.search(r"(?:^|[\s;])(?:python -m )?pytest(?:\s|$)", command):
        named += 1  # the test runner itself (a collection, a marker selection)
    if not named:
        problems.append(f"{command!r}: names no script, test, make target or strapdown-sim command")
    return problems


REQUIRED = {"id", "file", "text", "command", "commit", "load"}


def test_register_entries_are_complete_and_unique() -> None:
    ids = [e.get("id") for e in _entries()]
    assert len(ids) == len(set(ids)), "duplicate ids"
    bad = [e.get("id", e) for e in _entries() if not REQUIRED <= set(e)]
    assert not bad, f"entries missing one of {sorted(REQUIRED)}: {bad}"
    bad = [a for a in _allowed() if not {"file", "text", "why"} <= set(a)]
    assert not bad, f"allow-list entries need file, text, why: {bad}"


@pytest.mark.parametrize("entry", [*_entries(), *_allowed()], ids=lambda e: e.get("id", e["text"]))
def test_register_text_occurs_in_its_file(entry: dict) -> None:
    path = REPO / entry["file"]
    assert path.is_file(), f"{entry['file']}: no such file"
    assert _normalize(entry["text"]) in _normalize(path.read_text()), (
        f"{entry['file']} no longer holds {entry['text']!r}: edit the register with the doc"
    )


@pytest.mark.parametrize("entry", _entries(), ids=lambda e: e["id"])
def test_register_command_exists(entry: dict) -> None:
    problems = command_problems(entry["command"])
    assert not problems, f"{entry['id']}: {problems}"


@pytest.mark.parametrize("path", SCANNED, ids=lambda p: p.relative_to(REPO).as_posix())
def test_every_figure_names_its_command_or_is_registered(path: Path) -> None:
    rel = path.relative_to(REPO).as_posix()
    texts = [e["text"] for e in [*_entries(), *_allowed()] if e["file"] == rel]
    problems = uncovered(path, texts)
    assert not problems, (
        "figures without a producing command beside them and without an entry in "
        "docs/figures.yaml (a measured figure: name its command; a parameter, limit or "
        "definition: add it to the allow-list with the reason):\n" + "\n".join(problems)
    )


def test_figures_produced_by_make_figures_match_the_measured_file() -> None:
    if not MEASURED.is_file():
        pytest.skip("docs/figures_measured.json not written yet (make figures)")
    measured = json.loads(MEASURED.read_text())
    assert {"commit", "load_average", "results"} <= set(measured)
    results = measured["results"]
    checked = 0
    for entry in _entries():
        key = entry.get("key")
        if key is None or key not in results:
            continue
        checked += 1
        text = results[key]["text"]
        assert _normalize(text) in _normalize(entry["text"]), (
            f"{entry['id']}: make figures measured {text!r}, the docs say {entry['text']!r}"
        )
    assert checked, "no register entry is produced by make figures"


# The checker itself, on small texts (a figure the scan must flag, and ones it must accept).


def _scan(tmp_path: Path, text: str, texts: tuple[str, ...] = ()) -> list[str]:
    page = tmp_path / "page.md"
    page.write_text(text)
    return uncovered(page, list(texts), root=tmp_path)


def test_scan_flags_an_unsourced_figure_and_accepts_sourced_ones(tmp_path: Path) -> None:
    assert _scan(tmp_path, "The report takes 8 s.\n") == ["page.md:1: ['8 s']"]
    assert _scan(tmp_path, "The report takes 8 s (`strapdown-sim report out/x`).\n") == []
    assert _scan(tmp_path, "It is 10.1 x faster.\n", ("10.1 x",)) == []
    table = "Measured by `bench/bench_exact.py`:\n\n| a | b |\n|---|---|\n| x | 3.2 ms |\n"
    assert _scan(tmp_path, table) == []
    assert _scan(tmp_path, "`make bench`.\n\n# Next\n\n| a | b |\n|---|---|\n| x | 3.2 ms |\n") == [
        "page.md:7: ['3.2 ms']"
    ]
    assert _scan(tmp_path, "No figure: 12 cycles, eq. (31).\n") == []


def test_command_check_rejects_what_does_not_exist() -> None:
    assert command_problems("python bench/bench_exact.py --cycles 1000") == []
    assert command_problems("make figures") == []
    assert command_problems("strapdown-sim report out/default") == []
    assert command_problems("pytest test/test_figures.py::test_register_command_exists") == []
    missing = "bench/bench_nothing.py"
    assert command_problems(f"python {missing}") == [f"{missing}: no such file"]
    assert command_problems("pytest test/test_figures.py::nope") == [
        "test/test_figures.py::nope: no such test"
    ]
    assert command_problems("make nothing") == ["make nothing: no such target"]
    assert command_problems("python -m strapdown_ros.cli --help") == []
    assert command_problems("python -m strapdown_ros.nothing") == [
        "python -m strapdown_ros.nothing: no such module"
    ]
    assert command_problems('python -m pytest --collect-only -q -m "not slow"') == []
    assert len(command_problems("measured by hand")) == 1
