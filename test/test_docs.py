"""The docs are self-contained: README.md, docs/**/*.md and the command-line help refer only to
what a clone of the repository has.

* no link that leaves the repository (``../shared/SPEC.md`` and the like) and no ``../`` link at
  all (pages below docs/ link from the repository root, ``/docs/...``); every relative link
  resolves to a file (and, for ``.md#anchor``, to a heading of that file);
* no "SPEC §N" (the interface is docs/interface.md, with the same section numbers) and no
  "issue N" (the issue tracker is not part of a clone);
* ``strapdown-sim --help`` and every subcommand's help likewise; the command list names
  docs/interface.md (``check``: its §3).
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
DOCS = sorted([REPO / "README.md", *(REPO / "docs").rglob("*.md")])

LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FORBIDDEN = [
    (re.compile(r"SPEC\s*§|SPEC\.md|shared/"), "a reference to the interface contract outside"),
    (re.compile(r"\bissues?\s*#?\d+", re.IGNORECASE), "an issue-tracker reference"),
]


def _ids(path: Path) -> list[str]:
    return [path.relative_to(REPO).as_posix()]


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"`|\*|_(?=\W)|\[|\]\([^)]*\)", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    out: set[str] = set()
    seen: dict[str, int] = {}
    in_code = False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            in_code = not in_code
        if in_code or not line.startswith("#"):
            continue
        slug = _slug(line.lstrip("#"))
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


def _prose(path: Path) -> str:
    """The file without fenced code blocks (links in code are not links)."""
    return re.sub(r"(?ms)^```.*?^```", "", path.read_text())


@pytest.mark.parametrize("path", DOCS, ids=lambda p: p.relative_to(REPO).as_posix())
def test_links_stay_inside_the_repository_and_resolve(path: Path) -> None:
    problems = []
    for target in LINK.findall(_prose(path)):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
            continue
        file_part, _, anchor = target.partition("#")
        if file_part.startswith("/"):  # from the repository root (GitHub's convention)
            dest = (REPO / file_part.lstrip("/")).resolve()
        else:
            dest = path if not file_part else (path.parent / file_part).resolve()
        if "../" in file_part:
            problems.append(f"{target}: a ../ link")
        if REPO != dest and REPO not in dest.parents:
            problems.append(f"{target}: outside the repository")
        elif not dest.exists():
            problems.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            problems.append(f"{target}: no heading #{anchor} in {dest.name}")
    assert not problems, problems


@pytest.mark.parametrize("path", DOCS, ids=lambda p: p.relative_to(REPO).as_posix())
def test_no_reference_outside_the_repository(path: Path) -> None:
    text = path.read_text()
    found = [
        f"line {text[: m.start()].count(chr(10)) + 1}: {m.group(0)!r} ({what})"
        for pattern, what in FORBIDDEN
        for m in pattern.finditer(text)
    ]
    assert not found, found


def _helps() -> dict[str, str]:
    from strapdown_ros import cli

    parser = cli.build_parser()
    out = {"strapdown-sim": parser.format_help()}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[name] = sub.format_help()
                for inner in sub._actions:
                    if isinstance(inner, argparse._SubParsersAction):
                        for name2, sub2 in inner.choices.items():
                            out[f"{name} {name2}"] = sub2.format_help()
    return out


def test_cli_help_is_self_contained() -> None:
    helps = _helps()
    assert {"generate", "run", "check", "validate", "report"} <= set(helps)
    for name, text in helps.items():
        for pattern, what in FORBIDDEN:
            assert not pattern.search(text), f"{name} --help has {what}: {text}"
    # the command list names the repository's own interface document (check: its §3)
    assert "docs/interface.md §3" in " ".join(helps["strapdown-sim"].split())


def test_interface_doc_has_the_numbered_sections() -> None:
    """Code and docs cite "docs/interface.md §N"; the sections must exist with those numbers."""
    anchors = _anchors(REPO / "docs" / "interface.md")
    for n, slug in enumerate(
        [
            "1-frames-and-units",
            "2-cycles-and-time-stamps",
            "3-the-exactness-rule",
            "4-topics",
            "5-scenario-file",
            "6-command-line-and-executables",
        ],
        1,
    ):
        assert slug in anchors, (n, sorted(anchors))
