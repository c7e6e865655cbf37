"""Every key of package.xml resolves for ROS 2 Jazzy on Ubuntu 24.04 (noble), so that
``rosdep install --from-paths src --ignore-src -y`` succeeds.

Resolved against rosdistro's own rules, vendored in test/data/rosdep/ (README there: source
commit, what was copied) the way rosdep resolves them for ``ubuntu``/``noble``:

* a ROS package key must be a package released in Jazzy (``jazzy_packages.yaml``);
* any other key must have a rule in ``python.yaml`` whose ``ubuntu`` entry (its ``noble`` or
  ``'*'`` entry when it lists releases) names apt packages, and each of those must exist in
  noble (``noble_apt.yaml``: rosdep would resolve a key whose package noble lacks, and apt
  would then stop the install);
* a key resolving to rosdep's pip installer (``*-pip`` keys, ``mcap-ros2-support``) is
  refused: on noble the system Python is externally managed (PEP 668) and rosdep's
  ``sudo pip install`` fails unless the user reconfigures pip; such libraries belong to the
  documented pip step (requirements/ros-overlay.txt).

The resolver is checked on rules whose answers are known (a key that does not exist, a release
that nulls a key out, a pip rule) so that a test passing means resolution, not a resolver that
accepts everything.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parent.parent
DATA = REPO / "test" / "data" / "rosdep"
OS, RELEASE = "ubuntu", "noble"
INSTALLERS = ("apt", "pip", "source")


def _load(name: str):
    return yaml.safe_load((DATA / name).read_text())


RULES: dict = _load("python.yaml")
JAZZY: dict = _load("jazzy_packages.yaml")
NOBLE_APT: dict = _load("noble_apt.yaml")
ROS_PACKAGES = {p for repo in JAZZY["repositories"].values() for p in repo["packages"]}


class UnresolvedError(Exception):
    """rosdep would stop at this key."""


def resolve(key: str, rules: dict = RULES) -> tuple[str, list[str]]:
    """``(installer, packages)`` of ``key`` for ubuntu noble, as rosdep resolves it."""
    if key in ROS_PACKAGES:
        return "ros", [f"ros-jazzy-{key.replace('_', '-')}"]
    if key not in rules:
        raise UnresolvedError(f"{key}: no rosdep definition (Cannot locate rosdep definition)")
    rule = rules[key]
    if OS not in rule:
        raise UnresolvedError(f"{key}: no rule for {OS}")
    entry = rule[OS]
    if isinstance(entry, dict) and not set(entry) & set(INSTALLERS):  # per release
        if RELEASE in entry:
            entry = entry[RELEASE]
        elif "*" in entry:
            entry = entry["*"]
        else:
            raise UnresolvedError(f"{key}: {OS} rule names releases, not {RELEASE}")
    if entry is None:
        raise UnresolvedError(f"{key}: not available on {OS} {RELEASE} (null)")
    if isinstance(entry, list):
        return "apt", entry
    if isinstance(entry, dict) and len(entry) == 1:
        (installer, spec), = entry.items()
        packages = spec.get("packages", []) if isinstance(spec, dict) else spec
        return installer, list(packages)
    raise UnresolvedError(f"{key}: unreadable rule {entry!r}")


def check_key(key: str) -> str:
    """Raise :class:`UnresolvedError` unless ``key`` installs on noble; return how it installs."""
    installer, packages = resolve(key)
    if installer == "ros":
        return f"{key}: ROS 2 Jazzy package {packages[0]}"
    if installer == "pip":
        raise UnresolvedError(
            f"{key}: resolves to rosdep's pip installer ({packages}), which fails on noble's "
            "externally managed Python (PEP 668); install it with the pip step instead "
            "(requirements/ros-overlay.txt)"
        )
    if installer != "apt":
        raise UnresolvedError(f"{key}: installer {installer!r} is not apt")
    for pkg in packages:
        if pkg not in NOBLE_APT:
            raise UnresolvedError(f"{key}: apt package {pkg} has no entry in noble_apt.yaml")
        if NOBLE_APT[pkg] is None:
            raise UnresolvedError(f"{key}: noble has no apt package {pkg} (Unable to locate it)")
    return f"{key}: apt {', '.join(f'{p} {NOBLE_APT[p]}' for p in packages)}"


def _package_keys() -> list[str]:
    root = ET.parse(REPO / "package.xml").getroot()
    tags = ("depend", "exec_depend", "test_depend", "build_depend", "buildtool_depend",
            "build_export_depend")  # fmt: skip
    return sorted({(e.text or "").strip() for tag in tags for e in root.findall(tag)})


def test_vendored_rules_target_jazzy_on_noble() -> None:
    assert RELEASE in JAZZY["release_platforms"][OS]


@pytest.mark.parametrize("key", _package_keys())
def test_package_xml_key_resolves_on_noble(key: str) -> None:
    try:
        how = check_key(key)
    except UnresolvedError as exc:
        pytest.fail(
            f"package.xml key does not install with rosdep on Jazzy/noble: {exc}. If the key "
            "exists in a newer rosdistro, vendor its rule (test/data/rosdep/README.md)."
        )
    assert how.startswith(key)


@pytest.mark.parametrize(
    ("key", "why"),
    [
        ("python3-mcap-pip", "no rosdep definition"),
        ("python3-dask-pip", "no rosdep definition"),
        ("python3-numba", "noble has no apt package python3-numba"),
        ("python3-rosbags-pip", "pip installer"),
        ("mcap-ros2-support", "pip installer"),
        ("no_such_ros_package", "no rosdep definition"),
    ],
)
def test_keys_that_would_break_rosdep_are_refused(key: str, why: str) -> None:
    with pytest.raises(UnresolvedError, match=why):
        check_key(key)


def test_resolver_follows_release_entries() -> None:
    rules = {
        "k": {"ubuntu": {"*": ["a"], "noble": None}},
        "j": {"ubuntu": {"bionic": {"pip": ["x"]}, "*": ["b"]}},
        "i": {"ubuntu": {"focal": ["c"]}},
        "h": {"debian": ["d"]},
        "g": {"ubuntu": {"pip": {"packages": ["e"]}}},
    }
    with pytest.raises(UnresolvedError, match="null"):
        resolve("k", rules)
    assert resolve("j", rules) == ("apt", ["b"])
    with pytest.raises(UnresolvedError, match="names releases"):
        resolve("i", rules)
    with pytest.raises(UnresolvedError, match="no rule for ubuntu"):
        resolve("h", rules)
    assert resolve("g", rules) == ("pip", ["e"])
    # the real pydantic rule: apt on noble ('*'), pip only on bionic
    assert resolve("python3-pydantic") == ("apt", ["python3-pydantic"])


def test_every_vendored_apt_package_is_a_rule_target() -> None:
    """noble_apt.yaml describes only packages the vendored rules resolve to (no stale rows)."""
    targets = set()
    for key in RULES:
        try:
            installer, packages = resolve(key)
        except UnresolvedError:
            continue
        if installer == "apt":
            targets |= set(packages)
    assert set(NOBLE_APT) == targets
