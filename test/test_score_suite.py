"""The benchmark suite's scenarios (config/suite/, docs/suite.md) are valid and plan their
topics; ``make suite`` lists every file of config/suite/."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from strapdown_ros.config import load_scenario
from strapdown_ros.plan import resolve_plan

ROOT = Path(__file__).resolve().parents[1]
SUITE = sorted((ROOT / "config" / "suite").glob("*.yaml"))


@pytest.mark.parametrize("path", SUITE, ids=[p.stem for p in SUITE])
def test_suite_scenario_plans(path: Path) -> None:
    plan = resolve_plan(load_scenario(path))
    assert plan.scenario.name.startswith("suite_")
    assert "/reference/odom" in plan.topics


def test_make_suite_lists_every_suite_file() -> None:
    text = (ROOT / "Makefile").read_text()
    listed = set(re.findall(r"config/suite/(\w+)\.yaml", text))
    assert listed == {p.stem for p in SUITE}
    doc = (ROOT / "docs" / "suite.md").read_text()
    assert all(f"config/suite/{p.name}" in doc for p in SUITE)
