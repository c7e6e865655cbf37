#!/usr/bin/env python3
"""Check that ``strapdown-sim generate`` writes the same numbers as an earlier commit.

For every shipped scenario (``config/scenarios/*.yaml``, or those named) the bag is generated
twice, in separate processes: once with the package source of ``--base`` (extracted with
``git archive`` into a temporary directory and put first on ``PYTHONPATH``) and once with the
working tree. The two bags are read back from disk and compared topic by topic, message by
message: the same topics, counts and log times, and the same serialized payloads. Where a
payload differs, both are decoded (rosbags' typestore) and every numeric field is compared bit
for bit; string fields (frame ids) may differ only with ``--ignore-strings``.

Usage::

    python tools/compare_generate.py --base 7249607 [--duration-cap 60] [SCENARIO ...]

Exit status 0 when every scenario matches, 1 otherwise. Used by
``test/test_bit_identity.py`` (with a duration cap) and run in full for refactors
(docs/development.md).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: Fields changed on purpose since the refactor's base (topic -> field paths, not compared):
#: the navigator's NavSatFix is an inertial-only solution and no longer claims a GNSS fix
#: (STATUS_NO_FIX, SERVICE_UNKNOWN; docs/interface.md §4).
INTENDED_CHANGES = {"/navigator/fix": ("status.status", "status.service")}


def extract_commit(commit: str, dest: Path) -> Path:
    """Extract the ``strapdown_ros`` package and ``config`` of ``commit`` into ``dest``."""
    data = subprocess.run(
        ["git", "-C", str(ROOT), "archive", "--format=tar", commit, "strapdown_ros", "config"],
        check=True,
        capture_output=True,
    ).stdout
    with tarfile.open(fileobj=BytesIO(data)) as tar:
        tar.extractall(dest, filter="data")
    return dest


def generate(source: Path | None, scenario: Path, out: Path, duration: float | None) -> None:
    """Run ``strapdown-sim generate`` with the package at ``source`` (None: the working tree)."""
    env = dict(os.environ)
    if source is not None:
        env["PYTHONPATH"] = str(source) + os.pathsep + env.get("PYTHONPATH", "")
    code = (
        "import sys, strapdown_ros.cli as c; "
        "sys.stderr.write('package: ' + c.__file__ + chr(10)); sys.exit(c.main(sys.argv[1:]))"
    )
    args = [sys.executable, "-c", code, "generate", str(scenario), "--out", str(out), "--quiet"]
    if duration is not None:
        args += ["--duration", repr(duration)]
    # not from ROOT: python -c puts the working directory first on sys.path
    proc = subprocess.run(args, env=env, capture_output=True, text=True, cwd=out.parent)
    expected = str(source) if source is not None else str(ROOT)
    if proc.returncode != 0 or f"package: {expected}" not in proc.stderr:
        raise RuntimeError(
            f"generate {scenario.name} with {source or 'the working tree'} failed "
            f"(exit {proc.returncode}):\n{proc.stderr[-3000:]}"
        )


def read_messages(bag: Path) -> dict[str, tuple[str, list[tuple[int, bytes]]]]:
    """``topic -> (msgtype, [(log time ns, payload)])`` of a bag read from disk."""
    from rosbags.rosbag2 import Reader

    out: dict[str, tuple[str, list[tuple[int, bytes]]]] = {}
    with Reader(bag) as reader:
        for conn in reader.connections:
            out.setdefault(conn.topic, (conn.msgtype, []))
        for conn, t, raw in reader.messages():
            out[conn.topic][1].append((t, bytes(raw)))
    return out


def _numbers_equal(
    a: object, b: object, ignore_strings: bool, where: str, ignore: tuple[str, ...] = ()
) -> str | None:
    """First difference between two decoded messages (numbers bit for bit), or None.

    ``ignore``: field paths (``status.status``) whose values are not compared."""
    if ignore and any(where.endswith("." + path) for path in ignore):
        return None
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a_arr, b_arr = np.asarray(a), np.asarray(b)
        if a_arr.shape != b_arr.shape or a_arr.tobytes() != b_arr.tobytes():
            return f"{where}: {a_arr!r} != {b_arr!r}"
        return None
    if isinstance(a, str):
        return None if ignore_strings or a == b else f"{where}: {a!r} != {b!r}"
    if isinstance(a, float | int):
        same = np.float64(a).tobytes() == np.float64(b).tobytes()  # type: ignore[arg-type]
        return None if same else f"{where}: {a!r} != {b!r}"
    if isinstance(a, list | tuple):
        if len(a) != len(b):  # type: ignore[arg-type]
            return f"{where}: lengths differ"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):  # type: ignore[call-overload]
            diff = _numbers_equal(x, y, ignore_strings, f"{where}[{i}]", ignore)
            if diff:
                return diff
        return None
    for name in getattr(a, "__dataclass_fields__", {}):
        diff = _numbers_equal(
            getattr(a, name), getattr(b, name), ignore_strings, f"{where}.{name}", ignore
        )
        if diff:
            return diff
    return None


def compare_bags(
    base: Path, new: Path, ignore_strings: bool = False, allow_new: frozenset = frozenset()
) -> list[str]:
    """Differences between two bags (empty: identical numbers, and payloads unless strings).

    Topics only in ``new`` that ``allow_new`` names (e.g. a new section's) are not a
    difference; every topic of ``base`` must still be identical.
    """
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    a, b = read_messages(base), read_messages(new)
    problems: list[str] = []
    differ = (set(a) ^ set(b)) - ((set(b) - set(a)) & set(allow_new))
    if differ:
        problems.append(f"topics differ: {sorted(differ)}")
    for topic in sorted(set(a) & set(b)):
        (type_a, msgs_a), (type_b, msgs_b) = a[topic], b[topic]
        if type_a != type_b:
            problems.append(f"{topic}: type {type_a} != {type_b}")
            continue
        if len(msgs_a) != len(msgs_b):
            problems.append(f"{topic}: {len(msgs_a)} != {len(msgs_b)} messages")
            continue
        for i, ((ta, pa), (tb, pb)) in enumerate(zip(msgs_a, msgs_b, strict=True)):
            if ta != tb:
                problems.append(f"{topic}[{i}]: log time {ta} != {tb}")
                break
            if pa == pb:
                continue
            diff = _numbers_equal(
                store.deserialize_cdr(pa, type_a),
                store.deserialize_cdr(pb, type_b),
                ignore_strings,
                f"{topic}[{i}]",
                INTENDED_CHANGES.get(topic, ()),
            )
            if diff:
                problems.append(diff)
                break
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenarios", nargs="*", help="scenario files (default: every shipped one)")
    parser.add_argument("--base", required=True, help="commit to compare against")
    parser.add_argument("--duration-cap", type=float, default=None, metavar="S",
                        help="generate at most S seconds of each scenario")  # fmt: skip
    parser.add_argument(
        "--ignore-strings",
        action="store_true",
        help="let string fields (frame ids) differ; numbers must still match",
    )
    parser.add_argument("--keep", default=None, help="keep the bags in this directory")
    parser.add_argument(
        "--allow-new-topics", default="", metavar="T1,T2",
        help="topics the working tree may add (a new section's); the base's must match",
    )
    args = parser.parse_args(argv)
    shipped = sorted((ROOT / "config/scenarios").glob("*.yaml"))
    scenarios = [Path(s) for s in args.scenarios] or shipped
    failed = 0
    with tempfile.TemporaryDirectory(prefix="strapdown-compare-") as tmp:
        work = Path(args.keep) if args.keep else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        source = extract_commit(args.base, Path(tmp) / "base")
        for scenario in scenarios:
            scenario = scenario.resolve()
            base_scenario = source / scenario.relative_to(ROOT)
            if not base_scenario.exists() and scenario.is_relative_to(ROOT / "config"):
                print(f"{scenario.stem}: new since {args.base}, not compared")
                continue
            duration = None
            if args.duration_cap is not None:
                import yaml

                declared = yaml.safe_load(scenario.read_text()).get("duration_s")
                if declared is None or declared > args.duration_cap:
                    duration = args.duration_cap
            name = scenario.stem
            generate(source, base_scenario if base_scenario.exists() else scenario,
                     work / f"{name}.base", duration)  # fmt: skip
            generate(None, scenario, work / f"{name}.new", duration)
            base_bag, new_bag = work / f"{name}.base", work / f"{name}.new"
            allow = frozenset(t for t in args.allow_new_topics.split(",") if t)
            problems = compare_bags(base_bag, new_bag, args.ignore_strings, allow)
            counts = {t: len(m) for t, (_, m) in read_messages(new_bag).items()}
            total = sum(counts.values())
            if problems:
                failed += 1
                print(f"{name}: DIFFERENT ({total} messages)")
                for p in problems[:20]:
                    print(f"  {p}")
            else:
                span = f"{duration:g} s" if duration is not None else "full length"
                print(f"{name}: identical ({len(counts)} topics, {total} messages, {span})")
    print(f"{len(scenarios) - failed} of {len(scenarios)} scenarios identical to {args.base}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
