"""Run mutmut on one module (or the whole list of setup.cfg [mutmut]) in a scratch copy.

mutmut reads its configuration from ``setup.cfg`` in the directory it runs in and keeps its
mutants and results in ``mutants/`` there. To run one module against only the tests that cover
it, this copies the working tree (tracked and untracked, not ignored files) into
``out/mutation/<module>/``, rewrites the copy's ``[mutmut]`` section (``only_mutate`` = the
module, ``pytest_add_cli_args_test_selection`` = its tests, ``also_copy`` = the tree's other
top-level entries, which some tests read) and runs ``mutmut run`` there.

    python tools/mutation.py core/method2.py            # the module's tests from TESTS below
    python tools/mutation.py core/method2.py --tests test/test_method2.py
    python tools/mutation.py                            # setup.cfg's list, as configured
    python tools/mutation.py core/method2.py --results  # survivors of the last run
    python tools/mutation.py stages/tf.py --timeout 1800  # a slow module fixture under tracing

Extra arguments after ``--`` go to ``mutmut run`` (e.g. mutant names). The run is niced
(``nice -n 19``) and uses ``--max-children`` 2 unless given.
"""

from __future__ import annotations

import argparse
import configparser
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "strapdown_ros"

# The fast tests that cover each module (module path relative to strapdown_ros/).
TESTS: dict[str, list[str]] = {
    "core/method2.py": [
        "test/test_method2.py",
        "test/test_savage_example.py",
        "test/test_compiled.py",
        "test/test_method2_mutants.py",
    ],
    "core/offsets.py": ["test/test_offsets.py", "test/test_offsets_mutants.py"],
    "core/variation.py": [
        "test/test_variation_core.py",
        "test/test_variation_geometry.py",
        "test/test_savage_example.py",
        "test/test_variation_mutants.py",
    ],
    "core/exact_update.py": [
        "test/test_exact_update.py",
        "test/test_method2.py",
        "test/test_exact_update_mutants.py",
    ],
    "core/imu_errors.py": [
        "test/test_imu_errors.py",
        "test/test_covariance.py",
        "test/test_imu_errors_mutants.py",
    ],
    "core/frames.py": ["test/test_frames.py", "test/test_tf.py", "test/test_frames_mutants.py"],
    "core/allan.py": [
        "test/test_imu_errors.py",
        "test/test_allan_closed_forms.py",
        "test/test_allan_mutants.py",
    ],
    "core/aiding/gnss.py": [
        "test/test_aiding_models.py",
        "test/test_aided_models.py",
        "test/test_gnss_mutants.py",
    ],
    "core/aiding/common.py": [
        "test/test_aiding_models.py",
        "test/test_aided_models.py",
        "test/test_aiding_common_mutants.py",
        "test/test_gnss_mutants.py",
    ],
    "stages/tf.py": [
        "test/test_tf.py",
        "test/test_frames.py",
        "test/test_tf_mutants.py",
        "test/test_tf_live_paths.py",
    ],
    "messages/imu.py": [
        "test/test_messages.py",
        "test/test_imu_orientation.py",
        "test/test_messages_mutants.py",
    ],
    "messages/odometry.py": ["test/test_messages.py", "test/test_odometry_mutants.py"],
    "messages/navsatfix.py": [
        "test/test_messages.py",
        "test/test_messages_mutants.py",
        "test/test_navsatfix_mutants.py",
    ],
}


def _tree_files() -> list[str]:
    out = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard", "-z"],
        cwd=ROOT, check=True, capture_output=True, text=True,
    ).stdout  # fmt: skip
    return [p for p in out.split("\0") if p and (ROOT / p).is_file()]


def _copy_tree(dest: Path) -> list[str]:
    files = _tree_files()
    for rel in files:
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / rel, target)
    return sorted({rel.split("/", 1)[0] for rel in files})


def _configure(dest: Path, module: str | None, tests: list[str], top: list[str],
               timeout_s: int | None = None) -> None:  # fmt: skip
    cfg = configparser.ConfigParser(interpolation=None)
    cfg.read(dest / "setup.cfg")
    if timeout_s is not None:  # pytest-timeout's per-test limit, also for mutmut's stats run
        cfg["tool:pytest"]["timeout"] = str(timeout_s)
    section = cfg["mutmut"]
    if module is not None:
        section["only_mutate"] = "\n" + f"{PACKAGE}/{module}"
    if tests:
        missing = [t for t in tests if not (dest / t).is_file()]
        if missing:
            sys.exit(f"mutation: no such test file: {', '.join(missing)}")
        section["pytest_add_cli_args_test_selection"] = "\n" + "\n".join(tests)
    skip = {PACKAGE, "test", "setup.cfg", "out", "mutants"}
    section["also_copy"] = "\n" + "\n".join(p for p in top if p not in skip)
    with open(dest / "setup.cfg", "w") as fh:
        cfg.write(fh)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("module", nargs="?", help="path under strapdown_ros/, e.g. core/method2.py")
    parser.add_argument("--tests", nargs="+", help="test files (default: the module's in TESTS)")
    parser.add_argument("--results", action="store_true", help="list the last run's survivors")
    parser.add_argument("--keep", action="store_true", help="reuse the copy's mutmut state")
    parser.add_argument("--timeout", type=int, default=None, metavar="S",
                        help="pytest-timeout's per-test limit in the copy (default: "
                        "setup.cfg's; tracing slows a module fixture several times)")
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = argv[argv.index("--") + 1 :] if "--" in argv else []
    args = parser.parse_args(argv[: argv.index("--")] if "--" in argv else argv)

    module = args.module.removeprefix(f"{PACKAGE}/") if args.module else None
    if module is not None and not (ROOT / PACKAGE / module).is_file():
        print(f"mutation: no such module: {PACKAGE}/{module}", file=sys.stderr)
        return 2
    name = module.replace("/", ".").removesuffix(".py") if module else "all"
    dest = ROOT / "out" / "mutation" / name
    mutmut = [str(Path(sys.executable).with_name("mutmut"))]
    if args.results:
        if not (dest / "mutants").is_dir():
            print(f"mutation: no run in {dest}", file=sys.stderr)
            return 2
        return subprocess.run([*mutmut, "results"], cwd=dest).returncode

    tests = args.tests or (TESTS.get(module, []) if module else [])
    if module is not None and not tests:
        print(f"mutation: no tests listed for {module}; give --tests", file=sys.stderr)
        return 2
    if dest.exists() and not args.keep:
        shutil.rmtree(dest)
    dest.mkdir(parents=True, exist_ok=True)
    top = _copy_tree(dest)
    if args.timeout is not None and args.timeout <= 0:
        print("mutation: --timeout must be > 0", file=sys.stderr)
        return 2
    _configure(dest, module, [t for t in tests if (ROOT / t).is_file()], top, args.timeout)
    run_args = list(extra)
    if not any(a.startswith("--max-children") for a in run_args):
        run_args = ["--max-children", "2", *run_args]
    cmd = ["nice", "-n", "19", *mutmut, "run", *run_args]
    print(f"mutation: {' '.join(cmd)} in {dest}", flush=True)
    # generate's producer as a thread: mutmut records which tests reach a function in the test
    # process, and a forked producer would hide every stage it runs from that record
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1", STRAPDOWN_PRODUCER="thread")
    return subprocess.run(cmd, cwd=dest, env=env).returncode


if __name__ == "__main__":
    sys.exit(main())
