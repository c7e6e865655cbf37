"""Hostile or absurd scenario files get a one-line message, within bounded time and memory.

Nested thousands of levels deep (a ``RecursionError`` before), a "billion laughs" alias bomb
(no answer within 30 s and 4 GiB before: validation walked, and the message echoed, the
expanded value), a recursive alias, a file of megabytes, a value of thousands of characters in
a message, a segments trajectory lasting 10⁶ s (37 s before the clean message) or more than
10⁷ s (an internal error after minutes). The limits: ``strapdown_ros/config/yaml_limits.py``
(file and ``--set`` values alike). The command-line cases run ``strapdown-sim`` as a process
under a 1 GiB address-space limit and a timeout, as a user would meet them.
"""

from __future__ import annotations

import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from strapdown_ros.config import ScenarioError, apply_overrides, load_scenario, parse_scenario
from strapdown_ros.config.base import ECHO_LIMIT, shorten
from strapdown_ros.config.yaml_limits import (
    MAX_ALIASES,
    MAX_BYTES,
    MAX_DEPTH,
    MAX_VALUES,
    LimitError,
    check_document,
    load_yaml,
)

REPO = Path(__file__).resolve().parent.parent
DEFAULT = REPO / "config" / "scenarios" / "default.yaml"
#: Address space of a command-line process here (Python, numpy and pydantic need ~0.5 GiB).
ADDRESS_SPACE = 1 << 30
#: Wall time allowed to one refused command (measured 0.5-0.8 s; the machine is shared).
WALL_S = 15.0

GOOD = """\
rate_hz: 100
initial: {latitude_deg: 45.0, longitude_deg: 7.0, velocity_ned_mps: [50.0, 0.0, 0.0]}
trajectory: {kind: segments, segments: [{duration_s: 10}]}
"""


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


def _cli(*args: str) -> tuple[int, str, float]:
    """``strapdown-sim ARGS`` as a process (1 GiB address space): exit status, stderr, wall s."""
    start = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "strapdown_ros.cli", *args], cwd=REPO, capture_output=True,
        text=True, timeout=120, preexec_fn=_limit_memory,
    )  # fmt: skip
    return proc.returncode, proc.stderr, time.monotonic() - start


def _refused(stderr: str, command: str = "validate") -> str:
    """The one-line message of a refused scenario (no traceback), without its prefix."""
    assert "Traceback" not in stderr, stderr
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1, stderr
    prefix = f"strapdown-sim {command}: invalid scenario: "
    assert lines[0].startswith(prefix), stderr
    return lines[0][len(prefix) :]


def _bomb(levels: int = 9, at: str = "rate_hz") -> str:
    """A "billion laughs" document: ``a_i`` lists ten ``a_{i-1}``, 10^levels strings at ``at``."""
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, levels + 1)]
    return "\n".join([*lines, f"{at}: *a{levels}", ""])


# --- the command line ---------------------------------------------------------------------


def test_alias_bomb_is_refused_at_once_in_bounded_memory(tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(_bomb())
    rc, stderr, wall = _cli("validate", str(path))
    assert rc == 2, stderr
    message = _refused(stderr)
    assert message.startswith(f"{path} has more than {MAX_VALUES} values with its aliases"), message
    assert wall < WALL_S, wall


@pytest.mark.parametrize("form", ["flow", "block"])
def test_deep_nesting_is_refused_with_the_line(tmp_path, form):
    """5000 levels of ``[`` (or 100 of indented mappings): no RecursionError, the limit and
    where it was passed."""
    if form == "flow":
        text = GOOD + "description: " + "[" * 5000 + "]" * 5000 + "\n"
        line = 4
    else:
        text = GOOD + "".join("  " * i + f"k{i}:\n" for i in range(100)) + "  " * 100 + "v: 1\n"
        line = 4 + MAX_DEPTH
    path = tmp_path / "deep.yaml"
    path.write_text(text)
    rc, stderr, wall = _cli("validate", str(path))
    assert rc == 2, stderr
    message = _refused(stderr)
    assert message.startswith(f"{path} has lists and mappings nested more than {MAX_DEPTH} "
                              "levels deep"), message  # fmt: skip
    assert f"(at line {line}, column " in message, message
    assert wall < WALL_S, wall


def test_a_set_value_is_bounded_like_the_file():
    bomb = "[" + ", ".join(f"&a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, 8))
    bomb = bomb.replace("*a0", "1") + "]"
    rc, stderr, wall = _cli("validate", str(DEFAULT), "--set", f"variation.lever_arm_m={bomb}")
    assert rc == 2, stderr
    message = _refused(stderr)
    assert message.startswith("variation.lever_arm_m: the value has more than "), message
    rc, stderr, _ = _cli("validate", str(DEFAULT), "--set", "initial.altitude_m=" + "[" * 40)
    assert _refused(stderr).startswith(
        f"initial.altitude_m: the value has lists and mappings nested more than {MAX_DEPTH}"
    )


@pytest.mark.parametrize(
    ("duration", "problem"),
    [
        (1_000_000, "trajectory.segments[0]: latitude would exceed ±89.9° by t = "),
        (10_000_000, "trajectory.segments: the segments last 1.00006e+07 s in total, more than "
                     "the 1e+07 s (about 116 days) a segments trajectory may last"),
        (10**12, "trajectory.segments: the segments last 1e+12 s in total"),
    ],
)  # fmt: skip
@pytest.mark.parametrize("command", ["validate", "generate"])
def test_absurd_duration_gets_the_clean_message_at_once(tmp_path, command, duration, problem):
    """The default flight with its first segment lasting 10⁶ s heads north-east past the
    pole (46 s to the message before); 10⁷ s and more are beyond what the model solves."""
    args = [command, str(DEFAULT), "--set", f"trajectory.segments.0.duration_s={duration}"]
    out = tmp_path / "bag"
    if command == "generate":
        args += ["--out", str(out), "--quiet"]
    rc, stderr, wall = _cli(*args)
    assert rc == 2, stderr
    assert _refused(stderr, command).startswith(problem), stderr
    assert wall < WALL_S, wall
    assert not out.exists()


# --- the reader, in process ---------------------------------------------------------------


def test_recursive_alias_is_refused(tmp_path):
    path = tmp_path / "self.yaml"
    path.write_text(GOOD + "description: &x [1, *x]\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.problem == f"{path} has an alias inside the value it refers to (a " \
        "recursive document) (at line 4, column 14)"  # fmt: skip
    with pytest.raises(ScenarioError, match=r"^description: the value has an alias inside"):
        apply_overrides({}, ["description=&x {a: *x}"])


def test_file_size_limit(tmp_path):
    """A file of exactly :data:`MAX_BYTES` is read; one byte more is refused (by its size)."""
    path = tmp_path / "big.yaml"
    text = GOOD + "#" * (MAX_BYTES - len(GOOD) - 1) + "\n"
    path.write_text(text)
    assert path.stat().st_size == MAX_BYTES
    assert load_scenario(path).rate_hz == 100
    path.write_text(text + "\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.problem == (
        f"{path} has {MAX_BYTES + 1} bytes, more than the {MAX_BYTES} (1 MiB) a scenario may have"
    )
    with pytest.raises(ScenarioError, match=r"^description: the value has \d+ bytes, more than"):
        apply_overrides({}, ["description=" + "x" * (MAX_BYTES + 1)])


def test_alias_reference_limit():
    """:data:`MAX_ALIASES` references are read; one more is refused while composing."""
    text = "v: &v 1\nx: [" + ", ".join(["*v"] * MAX_ALIASES) + "]\n"
    assert len(load_yaml(text)["x"]) == MAX_ALIASES
    with pytest.raises(LimitError) as info:
        load_yaml(text.replace("*v]", "*v, *v]"))
    assert info.value.problem.startswith(f"has more than {MAX_ALIASES} alias references")
    assert info.value.line == 2


def test_expanded_size_limit():
    """The values are counted with the aliases expanded: a list of :data:`MAX_VALUES` - 2 ...
    values under a mapping key is the most a document holds (mapping, key, list and items)."""
    items = 1000
    refs = (MAX_VALUES - 3) // (items + 1)  # each reference: a list of `items` scalars
    base = "b: &b [" + ", ".join(["0"] * items) + "]\n"
    fits = base + "x: [" + ", ".join(["*b"] * (refs - 1)) + "]\n"
    document = load_yaml(fits)
    assert len(document["x"]) == refs - 1
    check_document(document)
    too_many = base + "x: [" + ", ".join(["*b"] * (refs + 1)) + "]\n"
    with pytest.raises(LimitError, match=r"^has more than 200000 values with its aliases"):
        load_yaml(too_many)


def test_documents_in_memory_are_bounded_too():
    """``parse_scenario`` of a mapping built by a program (or with overrides applied): the same
    depth and size limits, shared parts counted each time, and no value inside itself."""
    doc = yaml.safe_load(GOOD)
    loop: list = []
    loop.append(loop)
    with pytest.raises(ScenarioError, match=r"^the scenario has a value inside itself"):
        parse_scenario({**doc, "description": loop})
    deep: list = []
    for _ in range(MAX_DEPTH + 5):
        deep = [deep]
    with pytest.raises(ScenarioError, match=r"^the scenario has lists and mappings nested more"):
        parse_scenario({**doc, "description": deep})
    shared = [0] * 1000
    wide = [shared] * 300  # 300 001 values once expanded, 1 001 distinct objects
    with pytest.raises(ScenarioError, match=r"^the scenario has more than 200000 values"):
        parse_scenario({**doc, "description": wide})


# --- values echoed in messages ------------------------------------------------------------


def test_long_value_is_shortened_in_the_message(tmp_path):
    path = tmp_path / "long.yaml"
    path.write_text(GOOD.replace("{duration_s: 10}", "{duration_s: '" + "y" * 5000 + "'}"))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.key == "trajectory.segments[0].duration_s"
    assert info.value.problem == "must be a number, got str " + ("'" + "y" * 5000)[:ECHO_LIMIT] \
        + "…"  # fmt: skip


def test_shortened_value_message_of_a_smaller_bomb(tmp_path):
    """10⁴ strings through aliases where a number belongs: the message was 4 MB; now the value
    is shown up to :data:`ECHO_LIMIT` characters."""
    path = tmp_path / "bomb.yaml"
    path.write_text(_bomb(4, "initial") .replace("initial: *a4", "") + GOOD.replace(
        "latitude_deg: 45.0", "latitude_deg: *a3"))  # fmt: skip
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.key == "initial.latitude_deg"
    assert info.value.problem.startswith("must be a number, got list [[[['lol', 'lol'")
    assert len(info.value.problem) == len("must be a number, got list ") + ECHO_LIMIT + 1


@pytest.mark.parametrize(
    "value",
    [0, -1.5, 1e-300, float("nan"), "a'b\"c", "", None, True, b"\x00", [], (), (1,), (1, 2),
     [1, [2.5, "x"]], {}, {"a": [1, {"b": None}], 2: (3,)}],
)  # fmt: skip
def test_shorten_is_repr_for_short_values(value):
    assert shorten(value) == repr(value)


def test_shorten_formats_no_more_than_it_shows():
    """A value expanding to 10⁹ items, or containing itself, costs the echo limit only."""
    huge: list = ["lol"] * 10
    for _ in range(8):
        huge = [huge] * 10
    start = time.perf_counter()
    text = shorten(huge)
    assert time.perf_counter() - start < 0.1
    assert text.startswith("[" * 9 + "'lol', 'lol'") and text.endswith("…")
    assert len(text) == ECHO_LIMIT + 1
    loop: dict = {}
    loop["self"] = loop
    assert shorten(loop).startswith("{'self': {'self': {'self': ")
    assert shorten("z" * 10**7) == "'" + "z" * (ECHO_LIMIT - 1) + "…"


def test_a_huge_key_is_shortened():
    doc = yaml.safe_load(GOOD)
    with pytest.raises(ScenarioError) as info:
        parse_scenario({**doc, "k" * 10_000: 1})
    assert info.value.key == "k" * ECHO_LIMIT + "…"
    assert info.value.problem.startswith("unknown key; expected one of: name, description")
