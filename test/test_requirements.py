"""The runtime library table (strapdown_ros/requirements_check.py) and the files built on it.

* requirements/minimum.txt pins exactly the table's minimums (what ``make test-minimum``
  measures), setup.py declares them (``install_requires``, extras), and
  requirements/ros-overlay.txt asks for at least them;
* a library older than its minimum, or missing, stops ``strapdown-sim`` and the nodes with
  the pip command that fixes it (exit status 1); a missing optional library (campaign,
  magnetometer) is reported where the feature starts, with its command, not as an ImportError
  traceback.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from strapdown_ros import requirements_check as rc

REPO = Path(__file__).resolve().parent.parent


def _pins(path: Path, op: str) -> dict[str, str]:
    out = {}
    for line in path.read_text().splitlines():
        line = line.split("#")[0].strip()
        if m := re.fullmatch(rf"([A-Za-z0-9_.-]+)\s*{re.escape(op)}\s*([0-9.]+)(,.*)?", line):
            out[m.group(1)] = m.group(2)
    return out


def test_minimum_txt_is_the_table() -> None:
    assert _pins(REPO / "requirements" / "minimum.txt", "==") == rc.MINIMUM


def test_overlay_asks_for_at_least_the_minimums() -> None:
    overlay = _pins(REPO / "requirements" / "ros-overlay.txt", ">=")
    noble_apt = {"numpy", "scipy", "PyYAML", "matplotlib"}  # from apt (package.xml)
    assert set(overlay) == (set(rc.MINIMUM) - noble_apt) | {"numpy"}
    for dist, version in overlay.items():
        assert version == rc.MINIMUM[dist], dist


def test_setup_py_declares_the_minimums() -> None:
    sys.path.insert(0, str(REPO / "tools"))
    try:
        import install_ament_prefix
    finally:
        sys.path.remove(str(REPO / "tools"))
    kwargs = install_ament_prefix.read_setup(REPO)
    want = {f"{d}>={rc.MINIMUM[d]}" for d in rc.CORE}
    assert want <= set(kwargs["install_requires"])
    assert kwargs["extras_require"] == {
        "campaign": ["dask>=2023.9.0", "distributed>=2023.9.0", "pyarrow>=14.0.0"],
        "magnetometer": ["pyIGRF14>=1.0.3"],
    }
    assert kwargs["python_requires"] == ">=3.11"
    assert set(rc.CORE) | {d for _, ds in rc.EXTRAS.values() for d in ds} == set(rc.MINIMUM)


def test_this_environment_is_supported() -> None:
    assert rc.check_versions(tuple(rc.MINIMUM)) == []


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("1.26.4+ds", (1, 26, 4)),
        ("2.0b3", (2, 0)),
        ("0.59.0", (0, 59, 0)),
        ("2023.9.0", (2023, 9, 0)),
    ],
)
def test_version_tuple(text, value) -> None:
    assert rc._version_tuple(text) == value


def test_old_pydantic_stops_with_the_fix(monkeypatch, capsys) -> None:
    real = rc._installed
    monkeypatch.setattr(rc, "_installed", lambda d: "1.10.14" if d == "pydantic" else real(d))
    (problem,) = rc.check_versions()
    assert str(problem) == "pydantic >= 2.11.5 is required (1.10.14 is installed)"
    with pytest.raises(SystemExit) as exit_:
        rc.exit_if_unsupported("navigator_node")
    assert exit_.value.code == 1
    err = capsys.readouterr().err
    assert "fix: pip install 'pydantic>=2.11.5'" in err
    assert "requirements/ros-overlay.txt" in err


def test_missing_core_library_is_named(monkeypatch) -> None:
    real = rc._installed
    monkeypatch.setattr(rc, "_installed", lambda d: None if d == "numba" else real(d))
    assert [str(p) for p in rc.check_versions()] == [
        "numba >= 0.59.0 is required (not installed)"
    ]


def test_missing_extra_names_feature_and_command(monkeypatch) -> None:
    real = rc._installed
    monkeypatch.setattr(rc, "_installed", lambda d: None if d == "pyarrow" else real(d))
    with pytest.raises(rc.MissingDependencyError) as err:
        rc.require("pyarrow", "campaign")
    text = str(err.value)
    assert text.startswith("Monte Carlo campaigns (strapdown-sim campaign) needs pyarrow")
    assert "pip install 'dask>=2023.9.0' 'distributed>=2023.9.0' 'pyarrow>=14.0.0'" in text
    assert isinstance(err.value, ImportError)


def test_magnetometer_without_pyigrf14(monkeypatch) -> None:
    from strapdown_ros.stages import aiding

    real = rc._installed
    monkeypatch.setattr(rc, "_installed", lambda d: None if d == "pyIGRF14" else real(d))
    aiding.igrf_coefficients.cache_clear()
    with pytest.raises(rc.MissingDependencyError, match=r"pip install 'pyIGRF14>=1.0.3'"):
        aiding.igrf_coefficients(2026.0)
    aiding.igrf_coefficients.cache_clear()


def test_cli_reports_a_missing_campaign_library(tmp_path) -> None:
    """strapdown-sim campaign without pyarrow: one line naming the command, exit status 1."""
    code = (
        "import sys\n"
        "from strapdown_ros import requirements_check as rc\n"
        "real = rc._installed\n"
        "rc._installed = lambda d: None if d == 'pyarrow' else real(d)\n"
        "from strapdown_ros.cli import main\n"
        f"sys.exit(main(['campaign', {str(REPO / 'config/scenarios/car.yaml')!r}, '--runs', '1',"
        f" '--out', {str(tmp_path / 'c')!r}]))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    assert "strapdown-sim campaign: Monte Carlo campaigns" in proc.stderr
    assert "pip install 'dask>=2023.9.0'" in proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr


def test_minimums_of_apt_libraries_are_nobles_or_older() -> None:
    """The libraries package.xml takes from apt (rosdep) are not upgraded by the pip step, so
    their minimums must admit noble's versions (test/data/rosdep/noble_apt.yaml), or every node
    of a system install would stop at its version check."""
    import yaml

    noble = yaml.safe_load((REPO / "test" / "data" / "rosdep" / "noble_apt.yaml").read_text())
    apt = {"numpy": "python3-numpy", "scipy": "python3-scipy", "PyYAML": "python3-yaml",
           "matplotlib": "python3-matplotlib"}  # fmt: skip
    overlay = _pins(REPO / "requirements" / "ros-overlay.txt", ">=")
    for dist, package in apt.items():
        version = noble[package].split(":")[-1].split("-")[0]  # 1:1.26.4+ds-6ubuntu1 → 1.26.4+ds
        assert rc._version_tuple(version) >= rc._version_tuple(rc.MINIMUM[dist]), (dist, version)
        assert dist not in overlay or dist == "numpy", dist  # numpy: kept below 2 only
