"""``strapdown-sim report``: every plot from generated bags, omissions, comparison, errors.

The bags are generated from ``config/scenarios/default.yaml`` (10 s) and rewritten with
known navigator and measured-IMU topics whatever the generator currently writes: synthetic
navigator errors (``/navigator/*``) and a measured variation IMU (``/variation/imu_measured``:
the ideal increments plus bias and white noise, with the noise in the message covariance).
``test_report_of_the_generated_bag_as_is`` reports the generator's own bag.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from matplotlib import image as mpimg

from strapdown_ros.bag.batches import batch
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.cli import main
from strapdown_ros.messages import navsatfix_fields_from_geodetic, vector3_stamped_fields
from strapdown_ros.report import PLOT_FILES, write_report
from strapdown_ros.report.data import alternation, load_bag
from strapdown_ros.report.plots import eng_scale, max_decimate, minmax_decimate

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = str(ROOT / "config/scenarios/default.yaml")
DURATION = "10"
GYRO_WHITE = 1e-3  # rad/s per sample (σ of Δα/T)
ACCEL_WHITE = 2e-2  # m/s² per sample
EVERY_PLOT = (
    "trajectory",
    "attitude_velocity",
    "imu",
    "exactness",
    "navigation_errors",
    "method_comparison",
    "allan",
    "aiding",  # default.yaml has aiding sensors (issue 16)
    "free_inertial",  # the report's navigator on the measured IMU
)


#: default.yaml with the variation IMU's error model only and no aided filter: the bag these
#: plot tests were written for (the aided filter's report: test_report_solutions.py).
VARIATION_MODEL_ONLY = (
    "imu_errors={preset: tactical, seed: 1, input_topic: /variation/imu, "
    "output_topic: /variation/imu_measured}",
    "aided=null",
)


def _generate(out: Path, *overrides: str) -> Path:
    args = ["generate", SCENARIO, "--duration", DURATION, "--out", str(out), "--quiet"]
    for o in (*VARIATION_MODEL_ONLY, *overrides):
        args += ["--set", o]
    assert main(args) == 0
    return out


def _rewrite(src: Path, dst: Path, keep, extra=()) -> Path:  # noqa: ANN001
    """Copy the topics of ``src`` that ``keep(topic)`` accepts, plus ``extra`` batches."""
    contents = read_bag(src)
    batches = [  # /tf (several frame pairs on one topic) is not re-batched
        batch(t, d.fields) for t, d in contents.topics.items() if keep(t) and d.fields is not None
    ]
    with BagWriter(dst) as w:
        w.write_batches(batches + list(extra))
    return dst


def _navigator_batches(contents) -> list:  # noqa: ANN001
    """Synthetic navigator output at 20 Hz: errors that grow with time, solution = truth."""
    fix = contents["/variation/fix"]
    stamps = np.asarray(fix.stamps_ns)[::10]
    t = (stamps - stamps[0]) * 1e-9
    pos = np.stack([0.02 * t, -0.01 * t, 0.003 * t**2], axis=1)
    vel = np.stack([0.02 + 0 * t, -0.01 + 0 * t, 0.006 * t], axis=1)
    att = np.stack([2e-5 * t, 1e-6 * np.sin(t), -1e-6 * t], axis=1)
    nav_fix = navsatfix_fields_from_geodetic(
        stamps,
        np.radians(np.asarray(fix.latitude)[::10]),
        np.radians(np.asarray(fix.longitude)[::10]),
        np.asarray(fix.altitude)[::10] + pos[:, 2],
        "variation_imu",
    )
    return [
        batch("/navigator/fix", nav_fix),
        batch("/navigator/error/position", vector3_stamped_fields(stamps, pos, "ned")),
        batch("/navigator/error/velocity", vector3_stamped_fields(stamps, vel, "ned")),
        batch("/navigator/error/attitude", vector3_stamped_fields(stamps, att, "ned")),
    ]


def _measured_batch(contents, seed: int = 3):  # noqa: ANN001, ANN202
    """The variation increments after a simple error model (bias + white noise)."""
    ideal = contents["/variation/imu"]
    rng = np.random.default_rng(seed)
    n = len(ideal)
    gyro = (
        ideal.angular_velocity + np.radians(10.0 / 3600) + GYRO_WHITE * rng.standard_normal((n, 3))
    )
    accel = ideal.linear_acceleration + 1e-3 + ACCEL_WHITE * rng.standard_normal((n, 3))
    cov_g = np.tile(np.diag([GYRO_WHITE**2] * 3).ravel(), (n, 1))
    cov_a = np.tile(np.diag([ACCEL_WHITE**2] * 3).ravel(), (n, 1))
    not_provided = np.zeros((n, 9))
    not_provided[:, 0] = -1.0
    measured = dataclasses.replace(
        ideal,
        orientation=np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)),
        orientation_covariance=not_provided,
        angular_velocity=gyro,
        angular_velocity_covariance=cov_g,
        linear_acceleration=accel,
        linear_acceleration_covariance=cov_a,
    )
    return batch("/variation/imu_measured", measured)


def _generated_only(topic: str) -> bool:
    """Topics of the ideal streams (the generator may also write navigator and measured IMU
    topics; the tests replace them with their own)."""
    return not topic.startswith("/navigator") and not topic.endswith("/imu_measured")


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("report")
    m2 = _generate(d / "gen_m2")
    m1 = _generate(d / "gen_m1", "variation.method=1")
    contents = read_bag(m2)
    extra = _navigator_batches(contents) + [_measured_batch(contents)]
    full = _rewrite(m2, d / "full", _generated_only, extra)
    plain = _rewrite(m2, d / "plain", _generated_only)
    method1 = _rewrite(m1, d / "method1", _generated_only)
    return {"generated": m2, "full": full, "plain": plain, "method1": method1, "dir": d}


def _check_png(path: Path) -> None:
    assert path.is_file(), path
    assert path.stat().st_size > 20_000, f"{path} is suspiciously small"
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] >= 400 and img.shape[1] >= 600, img.shape
    gray = img[..., :3].mean(axis=-1)
    assert gray.std() > 0.05, f"{path} is nearly uniform"
    assert (gray < 0.9).mean() > 0.02, f"{path} is nearly blank"
    # more than a handful of colours: lines in several colours, not just axes
    colours = np.unique((img[..., :3] * 255).astype(np.uint8).reshape(-1, 3), axis=0)
    assert colours.shape[0] > 50, f"{path} has only {colours.shape[0]} colours"


@pytest.mark.slow
def test_every_plot_renders_from_a_generated_bag(bags: dict[str, Path]) -> None:
    result = write_report(bags["full"], compare=[bags["method1"]])
    assert result.out_dir == bags["full"] / "report"
    assert sorted(result.plots) == sorted(EVERY_PLOT)
    assert list(result.omitted) == ["aided", "transfer"]  # no filter in these bags
    for name in EVERY_PLOT:
        path = result.out_dir / f"{name}.png"
        assert result.plots[name] == path
        _check_png(path)
    md = result.markdown.read_text(encoding="utf-8")
    for name in EVERY_PLOT:
        assert f"![{name}]({name}.png)" in md
    for heading in (
        "## Topics",
        "## Exactness (docs/interface.md §3)",
        "## Navigation errors of `/navigator`",
        "## Variation comparison",
        "## Allan deviation of `/variation/imu_measured`",
    ):
        assert heading in md
    assert "DEFECT" not in md
    # the topic table: one row per topic with its count and rate
    assert "| `/reference/imu` | sensor_msgs/msg/Imu | 2000 | 200 |" in md
    assert "| `/navigator/error/position` | geometry_msgs/msg/Vector3Stamped | 200 | 20 |" in md
    # final and max errors of the synthetic navigator (horizontal RSS at the last output)
    t_end = 199 * 0.05
    horiz = np.hypot(0.02 * t_end, 0.01 * t_end)
    assert f"| horizontal position (RSS north, east) | {horiz:.2e} | {horiz:.2e} | m |" in md


def test_allan_deviation_of_the_measured_increments(bags: dict[str, Path]) -> None:
    """The measured-minus-ideal Allan deviation recovers the injected white noise."""
    data = load_bag(bags["full"], exactness=False)
    mi = data.measured["/variation"]
    assert mi.ideal is not None and mi.error_gyro is not None and mi.error_accel is not None
    T = 0.005
    for res, sigma in ((mi.error_gyro, GYRO_WHITE), (mi.error_accel, ACCEL_WHITE)):
        short = res.taus <= 0.1
        expected = sigma * np.sqrt(T / res.taus[short])
        np.testing.assert_allclose(res.adev[short], expected[:, None] * np.ones(3), rtol=0.15)
    # the message covariance is read back as the white noise level
    np.testing.assert_allclose(mi.measured.gyro_var, GYRO_WHITE**2)
    np.testing.assert_allclose(mi.measured.accel_var, ACCEL_WHITE**2)
    # the total (motion included) is larger than the error alone at long τ (the scan)
    assert mi.total_gyro.adev[-1].max() > 10 * mi.error_gyro.adev[-1].max()


@pytest.mark.slow
def test_bag_without_navigator_omits_those_plots(bags: dict[str, Path], capsys) -> None:
    out = bags["dir"] / "plain_report"
    assert main(["report", str(bags["plain"]), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "navigation_errors    omitted" in printed
    for name in ("trajectory", "attitude_velocity", "imu", "exactness"):
        _check_png(out / f"{name}.png")
    for pattern in ("navigation_errors*.png", "allan*.png", "method_comparison*.png"):
        assert not list(out.glob(pattern)), pattern
    md = (out / "report.md").read_text(encoding="utf-8")
    assert "## Omitted plots" in md
    assert "- **navigation_errors**: no navigator error topics" in md
    assert "- **allan**: no measured IMU topic" in md
    assert "- **method_comparison**: 1 variation stream" in md
    assert "Navigation errors of" not in md


@pytest.mark.slow
def test_report_of_the_generated_bag_as_is(bags: dict[str, Path]) -> None:
    """Whatever the generator writes today, the report of it is complete for its topics."""
    result = write_report(bags["generated"])
    topics = set(read_bag(bags["generated"]).topics)
    assert ("navigation_errors" in result.plots) == ("/navigator/error/position" in topics)
    assert ("allan" in result.plots) == ("/variation/imu_measured" in topics)
    for path in result.plots.values():
        _check_png(path)


def test_method1_vs_method2(bags: dict[str, Path]) -> None:
    """Both methods meet the position constraint at even cycles; Method 1's sign-flipping
    velocity error shows as a steady alternation (neutral, |Λ| = 1)."""
    from strapdown_ros.report.data import compare_streams

    m2 = load_bag(bags["plain"], exactness=False)
    m1 = load_bag(bags["method1"], exactness=False)
    cmp = compare_streams(m1.streams["/variation"], "M1", m2.streams["/variation"], "M2")
    assert not isinstance(cmp, str)
    assert cmp.even_cycles_dr < 1e-6 < cmp.odd_cycles_dr
    assert cmp.dv.max() > 1e-4
    mag1 = np.linalg.norm(cmp.alt_a, axis=1)
    # neutral oscillation: between the scan's rate changes (every 3 s) its size is constant
    window = (cmp.t_alt > 2.0) & (cmp.t_alt < 4.0)
    assert np.ptp(mag1[window]) < 0.05 * mag1[window].mean()
    # a one-bag comparison is rejected with a reason when stamps do not match
    shifted = dataclasses.replace(
        m2.streams["/variation"], stamps_ns=m2.streams["/variation"].stamps_ns + 1
    )
    assert "share 0 time stamps" in compare_streams(m1.streams["/variation"], "a", shifted, "b")


def test_generate_records_the_method_for_the_labels(bags: dict[str, Path]) -> None:
    """``generate`` stores how the streams were made in the bag's custom_data, and the report
    names the variation method in its legends from it."""
    from strapdown_ros.report import method_of

    for src, method in ((bags["generated"], 2), (bags["dir"] / "gen_m1", 1)):
        custom = read_bag(src).custom_data
        assert custom["variation.method"] == str(method), custom
        assert custom["scenario"] and custom["rate_hz"] == "200"
        assert method_of(load_bag(src, exactness=False)) == method
    custom = read_bag(bags["generated"]).custom_data
    assert custom["navigator.mode"] == "exact" and custom["imu_errors.preset"] == "tactical"


@pytest.mark.slow  # ~4 s: a second full report
def test_rerun_replaces_old_plots(bags: dict[str, Path]) -> None:
    """Plots of an earlier report that no longer apply are removed, other files kept."""
    out = bags["dir"] / "rerun"
    out.mkdir()
    for name in ("navigation_errors.png", "allan_x.png", "method_comparison_2.png",
                 "transfer_mounting.png"):
        (out / name).write_bytes(b"stale")
    (out / "notes.txt").write_text("mine")
    result = write_report(bags["plain"], out, exactness=False)
    assert not list(out.glob("navigation_errors*")) and not list(out.glob("allan*"))
    assert not list(out.glob("method_comparison*")) and not list(out.glob("transfer_*"))
    assert (out / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in out.glob("*.png")) == sorted(
        p.name for p in result.plots.values()
    )
    assert "not requested (--no-exactness)" in result.markdown.read_text(encoding="utf-8")
    # + free_inertial, aided_errors, aided_consistency, transfer_errors, transfer_consistency,
    # transfer_mounting
    assert len(PLOT_FILES) == 14


def test_fix_only_bag(tmp_path: Path, bags: dict[str, Path]) -> None:
    """A bag with only NavSatFix: ground track, no attitude (no Odometry), no exactness."""
    bag = _rewrite(bags["plain"], tmp_path / "fix_only", lambda t: t == "/reference/fix")
    result = write_report(bag)
    assert list(result.plots) == ["trajectory"]
    _check_png(result.plots["trajectory"])
    assert "attitude_velocity" in result.omitted and "exactness" in result.omitted


@pytest.mark.parametrize("kind", ["missing", "not_a_bag", "empty_bag"])
def test_bad_path_is_a_clear_error(tmp_path: Path, capsys, kind: str) -> None:
    path = tmp_path / kind
    if kind == "not_a_bag":
        path.mkdir()
        (path / "notes.txt").write_text("hello")
    elif kind == "empty_bag":
        with BagWriter(path):
            pass
    assert main(["report", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("strapdown-sim report: ")
    assert str(path) in err
    expected = {
        "missing": "does not exist",
        "not_a_bag": "no metadata.yaml",
        "empty_bag": "no messages",
    }[kind]
    assert expected in err
    assert not (path / "report").exists()


def test_helpers() -> None:
    t = np.arange(100_000) * 0.005
    y = np.sin(2 * np.pi * 3.0 * t)  # aliased by plain striding, kept by min/max binning
    t2, y2 = minmax_decimate(t, y, 1000)
    assert t2.size <= 2001 and y2.max() > 0.999 and y2.min() < -0.999
    tb, yb = max_decimate(t, np.abs(y), 100)
    assert tb.size <= 101 and yb.min() > 0.99
    e = 1e-3 * (-1.0) ** np.arange(50)[:, None] * np.array([1.0, 0.0, 0.0])
    smooth = np.stack([np.sin(0.05 * np.arange(50))] * 3, axis=1)
    alt = alternation(e + smooth)
    np.testing.assert_allclose(np.abs(alt[:, 0]), 1e-3, rtol=1e-3)
    assert eng_scale([2e-9, -3e-9], "m") == (1e9, "nm")
    assert eng_scale([0.2], "rad")[1] == "deg"
    assert eng_scale([5e-6], "rad") == (1e6, "µrad")
    assert eng_scale([1500.0], "m") == (1e-3, "km")
    assert eng_scale([0.0], "m/s") == (1.0, "m/s")
