"""``strapdown-sim report``: the solutions table (which IMU each solution consumes), the
free-inertial navigator on a measured IMU and the aided filter's section, on generated bags.

Bags (20 s): ``config/scenarios/default.yaml`` (navigator on the ideal ``/variation/imu``, a
measured ``/variation/imu_measured``), the same with the navigator on the measured IMU
(``--set navigator.imu_topic=/variation/imu_measured``: the package's navigator stage, run by
``generate``, is the independent reference of the report's own run), and
``test/data/aided_default_noisy.yaml`` (the aided filter on ``/reference/imu_measured``).
Generating and reporting them takes ~40 s, so the tests that use them are ``slow``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag.batches import batch
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.cli import main
from strapdown_ros.messages import odometry_state
from strapdown_ros.report import write_report
from strapdown_ros.report.aided import chi2_bounds, frame_turn

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = str(ROOT / "config/scenarios/default.yaml")
AIDED = str(ROOT / "test/data/aided_default_noisy.yaml")
DURATION = "20"


#: default.yaml with the variation IMU's error model only and no aided filter (the aided
#: filter's own bag: AIDED).
VARIATION_MODEL_ONLY = (
    "imu_errors={preset: tactical, seed: 1, input_topic: /variation/imu, "
    "output_topic: /variation/imu_measured}",
    "aided=null",
)


def _generate(scenario: str, out: Path, *overrides: str) -> Path:
    args = ["generate", scenario, "--duration", DURATION, "--out", str(out), "--quiet"]
    for o in overrides:
        args += ["--set", o]
    assert main(args) == 0
    return out


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("report_solutions")
    default = _generate(DEFAULT, d / "default", *VARIATION_MODEL_ONLY)
    measured = _generate(DEFAULT, d / "measured", *VARIATION_MODEL_ONLY,
                         "navigator.imu_topic=/variation/imu_measured")
    aided = _generate(AIDED, d / "aided")
    # the default bag without its measured IMU (and no aided filter): no such sections
    contents = read_bag(default)
    plain = d / "plain"
    with BagWriter(plain, custom_data=contents.custom_data) as w:
        w.write_batches([batch(t, x.fields) for t, x in contents.topics.items()
                         if x.fields is not None and not t.endswith("/imu_measured")])  # fmt: skip
    return {"default": default, "measured": measured, "aided": aided, "plain": plain, "dir": d}


def _solution_rows(md: str) -> dict[str, list[str]]:
    """Rows of the solutions table: solution name -> cells."""
    lines = md.split("## Solutions and the IMU each consumes", 1)[1].split("\n## ", 1)[0]
    rows = [ln for ln in lines.splitlines() if ln.startswith("| `")]
    out = {}
    for ln in rows:
        cells = [c.strip() for c in ln.strip("|").split(" | ")]
        out[cells[0].strip("`")] = cells
    return out


@pytest.fixture(scope="module")
def reports(bags: dict[str, Path]):  # noqa: ANN201
    return {k: write_report(bags[k], bags["dir"] / f"{k}_report")
            for k in ("default", "measured", "aided", "plain")}  # fmt: skip


@pytest.mark.slow  # the module's bags and reports: ~40 s once
def test_header_names_each_solution_and_its_imu(reports) -> None:  # noqa: ANN001
    expected = {
        "default": {
            "/navigator": ("navigator", "`/variation/imu`", "ideal", "`/variation/odom`"),
            "free-inertial on /variation/imu_measured": (
                "free-inertial (report)", "`/variation/imu_measured`", "measured",
                "`/variation/odom`"),
        },
        "measured": {
            "/navigator": ("navigator", "`/variation/imu_measured`", "measured",
                           "`/variation/odom`"),
            "free-inertial on /variation/imu_measured": (
                "free-inertial (report)", "`/variation/imu_measured`", "measured",
                "`/variation/odom`"),
            "free-inertial on /variation/imu": (
                "free-inertial (report)", "`/variation/imu`", "ideal", "`/variation/odom`"),
        },
        "aided": {
            "/aided": ("aided filter", "`/reference/imu_measured`", "measured",
                       "`/reference/odom`"),
            "free-inertial on /reference/imu_measured": (
                "free-inertial (report)", "`/reference/imu_measured`", "measured",
                "`/reference/odom`"),
            "free-inertial on /reference/imu": (
                "free-inertial (report)", "`/reference/imu`", "ideal", "`/reference/odom`"),
        },
        "plain": {"/navigator": ("navigator", "`/variation/imu`", "ideal", "`/variation/odom`")},
    }  # fmt: skip
    for key, want in expected.items():
        md = reports[key].markdown.read_text(encoding="utf-8")
        rows = _solution_rows(md)
        assert set(rows) == set(want), (key, rows)
        for name, cells in want.items():
            assert tuple(rows[name][1:5]) == cells, (key, name, rows[name])
    aided_md = reports["aided"].markdown.read_text(encoding="utf-8")
    assert "solution `/aided` consumes the measured IMU `/reference/imu_measured`" in aided_md


@pytest.mark.slow  # the module's bags and reports: ~40 s once
def test_free_inertial_equals_the_package_navigator_on_the_measured_imu(bags, reports) -> None:  # noqa: ANN001
    """The report's run on /variation/imu_measured and generate's navigator stage on the same
    topic (its published odometry and errors) agree to round-off; the errors are real (metres),
    while the same navigator on the ideal twin stays below a micrometre."""
    runs = {r.imu_topic: r for r in reports["measured"].free_inertial}
    run = runs["/variation/imu_measured"]
    contents = read_bag(bags["measured"])
    nav = odometry_state(contents["/navigator/odom"])
    assert np.array_equal(run.stamps_ns, nav.stamps_ns)
    assert np.max(np.linalg.norm(run.r_e - nav.r_e, axis=1)) < 1e-6
    for leaf, mine, tol in (("position", run.position, 1e-6), ("velocity", run.velocity, 1e-9),
                            ("attitude", run.attitude, 1e-12)):  # fmt: skip
        f = contents[f"/navigator/error/{leaf}"]
        assert np.array_equal(np.asarray(f.stamps_ns), run.stamps_ns)
        published = np.asarray(f.vector)
        assert np.max(np.abs(mine - published)) < tol, leaf
    assert np.max(np.linalg.norm(run.position, axis=1)) > 0.1  # a tactical IMU: metres in 20 s
    ideal = runs["/variation/imu"]
    assert np.max(np.linalg.norm(ideal.position, axis=1)) < 1e-6
    assert np.max(np.linalg.norm(ideal.velocity, axis=1)) < 1e-8
    # the default bag: the ideal comparison is the bag's own navigator (no second run)
    assert [r.imu_topic for r in reports["default"].free_inertial] == ["/variation/imu_measured"]
    md = reports["default"].markdown.read_text(encoding="utf-8")
    assert "## Free-inertial navigation on the measured IMU `/variation/imu_measured`" in md
    assert "/navigator (in the bag) on /variation/imu (ideal)" in md


@pytest.mark.slow  # the module's bags and reports: ~40 s once
def test_aided_errors_and_nees_recomputed_match_the_published_ones(reports) -> None:  # noqa: ANN001
    a = reports["aided"].aided["/aided"]
    assert a.t.size == 201  # 10 Hz over 20 s, every output with its truth
    for q, tol in (("position", 1e-9), ("velocity", 1e-9), ("attitude", 1e-12)):
        pub = a.published_errors[q]
        assert pub is not None and np.all(np.isfinite(pub))
        assert np.max(np.abs(a.errors[q] - pub)) < tol, q
        assert np.max(np.abs(pub)) > 1e3 * tol  # not trivially zero
    assert a.published_nees is not None
    np.testing.assert_allclose(a.nees, a.published_nees, rtol=1e-8)
    assert np.all(a.sigma["position"] > 0.1) and np.all(a.sigma["attitude"] > 0)
    assert {n.sensor for n in a.nis} == {"gnss_position", "gnss_velocity", "baro", "mag"}
    md = reports["aided"].markdown.read_text(encoding="utf-8")
    assert "## Aided filter `/aided`" in md
    assert "| NEES position (3 dof) |" in md and "| NIS baro (1 dof) |" in md
    for name in ("aided_errors", "aided_consistency", "free_inertial"):
        assert reports["aided"].plots[name].stat().st_size > 20_000


def test_chi2_bounds_and_frame_turn() -> None:
    """The χ² 95 % intervals of tables (3 dof: 0.216, 9.348; 1 dof: 0.000982, 5.024), and D of
    a north/east displacement at the equator (1 / radius)."""
    lo, hi = chi2_bounds(np.array([3.0, 1.0]))
    np.testing.assert_allclose(lo, [0.2158, 0.000982], rtol=2e-3)
    np.testing.assert_allclose(hi, [9.348, 5.024], rtol=1e-3)
    d = frame_turn(np.zeros(1), np.zeros(1))[0]
    a, b = 6378137.0, 6356752.314245  # WGS 84; meridian radius at the equator b²/a
    assert d[0, 1] == pytest.approx(1 / a) and d[1, 0] == pytest.approx(-a / b**2)
    assert d[2, 1] == 0.0


@pytest.mark.slow  # the module's bags and reports: ~40 s once
def test_bags_without_measured_imu_or_aided_filter_say_why(bags, reports, capsys) -> None:  # noqa: ANN001
    plain = reports["plain"]
    assert plain.omitted["free_inertial"] == "no measured IMU topic (`P/imu_measured`)"
    assert plain.omitted["aided"].startswith("no aided filter outputs")
    assert plain.free_inertial == [] and plain.aided == {}
    md = plain.markdown.read_text(encoding="utf-8")
    assert "## Free-inertial" not in md and "## Aided filter" not in md
    assert "- **aided**: no aided filter outputs" in md
    assert not list(plain.out_dir.glob("free_inertial*.png"))
    assert "aided" in reports["default"].omitted and "aided" not in reports["aided"].omitted
    # switched off on the command line
    out = bags["dir"] / "off"
    assert main(["report", str(bags["default"]), "--out", str(out), "--no-free-inertial",
                 "--no-exactness"]) == 0  # fmt: skip
    assert "free_inertial        omitted: not requested (--no-free-inertial)" in (
        capsys.readouterr().out)  # fmt: skip
    assert not list(out.glob("free_inertial*.png"))


@pytest.mark.slow  # the module's bags
def test_free_inertial_stops_at_an_imu_gap(bags, reports) -> None:  # noqa: ANN001
    """Five IMU messages missing after 10 s: the run ends at the gap (noted) and matches the
    full run up to it."""
    from strapdown_ros.report.free_inertial import free_inertial
    from strapdown_ros.stages.intake import without_rows

    contents = read_bag(bags["measured"])
    imu = contents["/variation/imu_measured"]
    stamps = np.asarray(imu.stamps_ns)
    drop = np.zeros(stamps.size, dtype=bool)
    drop[2000:2005] = True
    path = bags["dir"] / "gap"
    with BagWriter(path) as w:
        w.write_batches([batch("/variation/odom", contents["/variation/odom"]),
                         batch("/variation/imu_measured", without_rows(imu, drop))])  # fmt: skip
    start = int(np.min(np.asarray(contents["/variation/odom"].stamps_ns)))
    run = free_inertial(read_bag(path), "/variation/imu_measured", "/variation/odom", start)
    assert not isinstance(run, str)
    assert "gap after" in run.note
    assert run.stamps_ns[-1] <= stamps[1999]
    full = next(r for r in reports["measured"].free_inertial
                if r.imu_topic == "/variation/imu_measured")  # fmt: skip
    n = run.stamps_ns.size
    assert n > 150 and np.array_equal(full.stamps_ns[:n], run.stamps_ns)
    assert np.max(np.abs(full.position[:n] - run.position)) < 1e-9
