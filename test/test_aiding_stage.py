"""The aiding stage (strapdown_ros.stages.aiding) on the default flight, read back from a bag.

Errors off: every message equals the truth of its sensor point, computed here independently
from the ``/reference/odom`` messages read back (own quaternion, geodetic and ENU formulas,
pyIGRF14's scalar synthesis, ambiance's atmosphere). Errors on: same seed → same bytes, any
chunking → same bytes, gaps skipped like an uninterrupted run, covariances = the model's,
outages and latency exact.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag import cdr
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.config import load_scenario
from strapdown_ros.config.aiding import AidingSpec
from strapdown_ros.config.base import validate_section
from strapdown_ros.stages.aiding import (
    NOT_MEASURED_VARIANCE,
    AidingStage,
    aiding_topic_plans,
    igrf_coefficients,
)
from strapdown_ros.stages.trajectory import reference_batch_chunks

REPO = Path(__file__).resolve().parent.parent
DURATION_S = 40.0
GNSS_LEVER = np.array([1.2, -0.4, -1.5])  # FRD
BARO_LEVER = np.array([0.3, 0.2, -0.2])
WHEEL_LEVER = np.array([-2.0, 0.8, 1.1])
LATENCY_S = 0.12
OUTAGES = [[10.0, 12.5], [30.2, 31.0]]

# WGS-84, written out here (independent of strapdown_ros.core.earth)
A = 6378137.0
E2 = (1.0 / 298.257223563) * (2.0 - 1.0 / 298.257223563)


def _ideal(**overrides) -> dict:
    doc = {
        "gnss": {"rate_hz": 5, "lever_arm_m": GNSS_LEVER.tolist(), "latency_s": LATENCY_S,
                 "outages": OUTAGES},
        "barometer": {"rate_hz": 25, "lever_arm_m": BARO_LEVER.tolist()},
        "magnetometer": {"rate_hz": 50},
        "wheel_odometer": {"rate_hz": 50, "lever_arm_m": WHEEL_LEVER.tolist()},
    }  # fmt: skip
    for key, value in overrides.items():
        doc[key] = {**doc[key], **value}
    return doc


def _noisy() -> dict:
    return _ideal(
        gnss={"preset": "spp", "seed": 1},
        barometer={"preset": "mems", "seed": 2},
        magnetometer={"preset": "mems", "seed": 3,
                      "soft_iron": [[1.02, 0.01, 0], [0.01, 0.99, 0], [0, 0, 1.0]]},
        wheel_odometer={"preset": "abs_sensor", "seed": 4},
    )  # fmt: skip


def _spec(doc: dict) -> AidingSpec:
    return validate_section(AidingSpec, doc, "aiding")  # type: ignore[return-value]


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(REPO / "config/scenarios/default.yaml", duration_s=DURATION_S)


@pytest.fixture(scope="module")
def reference(scenario):
    """The reference pieces' batches (as generate makes them)."""
    return [batches for _, batches in reference_batch_chunks(scenario)]


def _odom_payloads(scenario, reference) -> list[bytes]:
    topic = scenario.recording.topics["reference_odom"]
    return [p for batches in reference for b in batches if b.topic == topic for p in b.payloads]


def _run(scenario, spec, chunks) -> dict[str, tuple[list[bytes], np.ndarray]]:
    """Aiding payloads and log times per topic for odometry payload chunks."""
    stream = AidingStage(scenario, spec)
    out: dict[str, tuple[list[bytes], list[int]]] = {}
    for chunk in chunks:
        for b in stream.on_payloads(chunk):
            pay, log = out.setdefault(b.topic, ([], []))
            pay += list(b.payloads)
            log += list(b.stamps_ns)
    return {k: (v[0], np.array(v[1], dtype=np.int64)) for k, v in out.items()}


@pytest.fixture(scope="module")
def ideal_bag(scenario, reference, tmp_path_factory):
    """A bag with the reference streams and the error-free aiding topics, read back."""
    path = tmp_path_factory.mktemp("aiding") / "bag"
    stream = AidingStage(scenario, _spec(_ideal()))
    with BagWriter(path) as writer:
        for batches in reference:
            writer.write_batches(batches + stream.feed_batches(batches))
    return read_bag(path, raw=True)


# ---------------------------------------------------------------------------------------------
# independent truth of the sensor points


def _dcm(q_xyzw: np.ndarray) -> np.ndarray:
    x, y, z, w = (q_xyzw / np.linalg.norm(q_xyzw, axis=1, keepdims=True)).T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def _ecef(lat_deg, lon_deg, alt):
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    n = A / np.sqrt(1 - E2 * np.sin(lat) ** 2)
    return np.stack(
        [(n + alt) * np.cos(lat) * np.cos(lon), (n + alt) * np.cos(lat) * np.sin(lon),
         (n * (1 - E2) + alt) * np.sin(lat)], -1)  # fmt: skip


def _enu_rows(lat_deg, lon_deg):
    """Rows: east, north, up unit vectors in ECEF."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    sl, cl, sp, cp = np.sin(lon), np.cos(lon), np.sin(lat), np.cos(lat)
    east = np.stack([-sl, cl, 0 * sl], -1)
    north = np.stack([-sp * cl, -sp * sl, cp], -1)
    up = np.stack([cp * cl, cp * sl, sp], -1)
    return np.stack([east, north, up], -2)


FLU = np.array([1.0, -1.0, -1.0])


def _truth(bag, stamps):
    """ECEF position, C_FLU^E, Earth-relative velocity (ECEF) and rate (FLU) at ``stamps``."""
    odom = bag["/reference/odom"]
    idx = np.searchsorted(odom.stamps_ns, stamps)
    assert np.array_equal(odom.stamps_ns[idx], stamps)
    c = _dcm(odom.orientation[idx])
    v = np.einsum("nij,nj->ni", c, odom.twist_linear[idx])
    return odom.position[idx], c, v, odom.twist_angular[idx]


def _expected_epochs(scenario, period_s, outages=()):
    t0 = scenario.start_time_ns
    p = int(round(period_s * 1e9))
    t_end = t0 + int(round(DURATION_S * 1e9))
    k = np.arange(-(-t0 // p), t_end // p + 1)
    stamps = k * p
    keep = np.ones(len(stamps), bool)
    for a, b in outages:
        keep &= ~((stamps >= t0 + a * 1e9) & (stamps < t0 + b * 1e9))
    return stamps[keep], t_end


# ---------------------------------------------------------------------------------------------
# errors off: truth


def test_gnss_equals_antenna_truth(ideal_bag, scenario):
    """Position = r + C l to 1e-6 m and ENU velocity = v + C (ω × l) to 1e-9 m/s, every epoch;
    epochs, outages and latency exact; covariance diagonal-known zeros; status/service."""
    fix = ideal_bag["/gnss/fix"]
    vel = ideal_bag["/gnss/vel"]
    stamps, t_end = _expected_epochs(scenario, 0.2, OUTAGES)
    latency = int(round(LATENCY_S * 1e9))
    stamps = stamps[stamps + latency <= t_end]  # later ones are never published
    assert np.array_equal(fix.stamps_ns, stamps) and np.array_equal(vel.stamps_ns, stamps)
    for topic in ("/gnss/fix", "/gnss/vel"):
        assert np.array_equal(ideal_bag.topics[topic].log_time_ns, stamps + latency)
    r, c, v, w = _truth(ideal_bag, stamps)
    lever = GNSS_LEVER * FLU
    r_a = r + np.einsum("nij,j->ni", c, lever)
    v_a = v + np.einsum("nij,nj->ni", c, np.cross(w, lever))
    assert np.max(np.linalg.norm(_ecef(fix.latitude, fix.longitude, fix.altitude) - r_a,
                                 axis=1)) < 1e-6  # fmt: skip
    v_enu = np.einsum("nij,nj->ni", _enu_rows(fix.latitude, fix.longitude), v_a)
    assert np.max(np.abs(vel.linear - v_enu)) < 1e-9
    assert np.all(np.abs(v_a).max(axis=1) > 10)  # not vacuous: the aircraft flies
    # errors off: no variance describes the fix; COVARIANCE_TYPE_UNKNOWN (0), not an all-zero
    # DIAGONAL_KNOWN (2) that a filter would take as an exact measurement
    assert np.all(fix.position_covariance == 0) and np.all(fix.position_covariance_type == 0)
    assert np.all(fix.status == 0) and np.all(fix.service == 1)
    assert np.all(vel.angular == 0)
    assert fix.frame_id == "gnss" and vel.frame_id == "gnss"


def test_wheel_speed_equals_contact_point_truth(ideal_bag, scenario):
    wheel = ideal_bag["/wheel/twist"]
    stamps, _ = _expected_epochs(scenario, 0.02)
    assert np.array_equal(wheel.stamps_ns, stamps)
    _, c, v, w = _truth(ideal_bag, stamps)
    v_c = np.einsum("nji,nj->ni", c, v) + np.cross(w, WHEEL_LEVER * FLU)
    assert np.max(np.abs(wheel.linear[:, 0] - v_c[:, 0])) < 1e-9
    assert np.all(wheel.linear[:, 1:] == 0) and np.all(wheel.angular == 0)
    cov = wheel.covariance.reshape(-1, 6, 6)
    assert np.all(cov[:, 0, 0] == 0) and np.all(cov[:, 1, 1] == 0.05**2)
    assert np.all(cov[:, 2, 2] == 0.05**2) and np.all(cov[:, 3, 3] == NOT_MEASURED_VARIANCE)


def test_magnetometer_equals_model_field_in_body(ideal_bag, scenario):
    """Body FLU field = C_E^FLU C_N^E B^N: with our synthesis to round-off (1e-15 T), with
    pyIGRF14's scalar synthesis to 0.05 nT."""
    pyigrf = pytest.importorskip("pyIGRF14")
    mag = ideal_bag["/mag"]
    stamps, _ = _expected_epochs(scenario, 0.02)
    assert np.array_equal(mag.stamps_ns, stamps)
    assert mag.frame_id == scenario.recording.frames["reference_imu"]
    r, c, _, _ = _truth(ideal_bag, stamps)
    fix = ideal_bag["/reference/fix"]
    idx = np.searchsorted(fix.stamps_ns, stamps)
    lat, lon, alt = fix.latitude[idx], fix.longitude[idx], fix.altitude[idx]
    year = 2026.0  # default.yaml starts 2026-01-01T00:00:00Z
    rows = _enu_rows(lat, lon)  # east, north, up
    n_e = np.stack([rows[:, 1], rows[:, 0], -rows[:, 2]], 1)  # rows: north, east, down
    sel = np.arange(0, len(stamps), 97)
    points = zip(lat[sel], lon[sel], alt[sel], strict=True)
    b_ned = np.array([pyigrf.igrf_value(a, o % 360, z / 1000, year)[3:6] for a, o, z in points])
    b_ned = b_ned * 1e-9
    b_e = np.einsum("nji,nj->ni", n_e[sel], b_ned)
    b_flu = np.einsum("nji,nj->ni", c[sel], b_e)
    assert np.max(np.abs(mag.magnetic_field[sel] - b_flu)) < 0.05e-9
    from strapdown_ros.core.aiding import igrf_field_ned

    g, h = igrf_coefficients(year)
    ours = igrf_field_ned(r, np.radians(lat), g, h) * 1e-9
    b_flu = np.einsum("nji,nj->ni", c, np.einsum("nji,nj->ni", n_e, ours))
    assert np.max(np.abs(mag.magnetic_field - b_flu)) < 1e-15  # |B| ~ 5e-5 T: round-off
    assert np.all(mag.magnetic_field_covariance == 0)


def test_barometer_equals_icao_at_sensor_altitude(ideal_bag, scenario):
    ambiance = pytest.importorskip("ambiance")
    baro = ideal_bag["/baro/pressure"]
    stamps, _ = _expected_epochs(scenario, 0.04)
    assert np.array_equal(baro.stamps_ns, stamps)
    r, c, _, _ = _truth(ideal_bag, stamps)
    r_s = r + np.einsum("nij,j->ni", c, BARO_LEVER * FLU)
    # altitude of r_s: Newton on the ellipsoid (independent of core.earth)
    p = np.hypot(r_s[:, 0], r_s[:, 1])
    lat = np.arctan2(r_s[:, 2], p * (1 - E2))
    for _ in range(6):
        n = A / np.sqrt(1 - E2 * np.sin(lat) ** 2)
        alt = p / np.cos(lat) - n
        lat = np.arctan2(r_s[:, 2], p * (1 - E2 * n / (n + alt)))
    assert np.max(np.abs(baro.fluid_pressure / ambiance.Atmosphere(alt).pressure - 1)) < 3e-6
    from strapdown_ros.core.aiding import icao_pressure

    assert np.max(np.abs(baro.fluid_pressure / icao_pressure(alt) - 1)) < 1e-12
    assert np.all(baro.variance == 0)


def test_new_types_decode_with_rosbags(ideal_bag):
    """An independent decoder (rosbags' typestore) reads our payloads to the same values."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    for topic, check in (
        ("/gnss/vel", lambda m, f, i: m.twist.twist.linear.x == f.linear[i, 0]),
        ("/wheel/twist", lambda m, f, i: m.twist.covariance[0] == f.covariance[i, 0]),
        ("/baro/pressure", lambda m, f, i: m.fluid_pressure == f.fluid_pressure[i]),
        ("/mag", lambda m, f, i: m.magnetic_field.z == f.magnetic_field[i, 2]),
    ):
        data = ideal_bag.topics[topic]
        for i in (0, len(data) // 2, len(data) - 1):
            msg = ts.deserialize_cdr(data.payloads[i], data.msgtype)
            assert check(msg, data.fields, i), topic
            assert bytes(ts.serialize_cdr(msg, data.msgtype)) == data.payloads[i]


# ---------------------------------------------------------------------------------------------
# errors on: reproducibility, chunks, gaps, covariances


def _difference(topic: str, got: list[bytes], want: list[bytes]) -> str:
    """Where two payload lists of ``topic`` differ: the counts, or the first differing message
    with its decoded fields (for an intermittent difference, the evidence of its cause)."""
    if len(got) != len(want):
        return f"{topic}: {len(got)} messages vs {len(want)}"
    rows = [i for i, (a, b) in enumerate(zip(got, want, strict=True)) if a != b]
    if not rows:
        return f"{topic}: equal"
    i = rows[0]
    a, b = (cdr.deserialize(topic_type(topic), [p[i]]) for p in (got, want))
    fields = {  # full precision (tolist: Python floats print 17 digits)
        k: (np.asarray(va).tolist(), np.asarray(vb).tolist()) for k, va in vars(a).items()
        if not np.array_equal(va, vb := getattr(b, k))
    }  # fmt: skip
    return f"{topic}: {len(rows)} of {len(got)} messages differ, first #{i}: {fields}"


def test_same_seed_same_bytes_any_chunking(scenario, reference):
    """Whole pieces, uneven chunks and message-by-message (first 2 001 messages) give the same
    bytes; the same seed twice too; another seed changes every noisy value."""
    payloads = _odom_payloads(scenario, reference)
    spec = _spec(_noisy())
    whole = _run(scenario, spec, [payloads])
    again = _run(scenario, spec, [payloads])
    cuts = [0, 1, 2, 3, 5, 8, 13, 200, 1999, 4000, 7777, len(payloads)]
    uneven = _run(scenario, spec, [payloads[a:b] for a, b in zip(cuts, cuts[1:], strict=False)])
    for topic, (pay, log) in whole.items():
        assert again[topic][0] == pay, _difference(topic, again[topic][0], pay)
        assert uneven[topic][0] == pay, _difference(topic, uneven[topic][0], pay)
        assert np.array_equal(uneven[topic][1], log), topic
    head = payloads[:2001]
    one = _run(scenario, spec, [[p] for p in head])
    block = _run(scenario, spec, [head])
    for topic, (pay, log) in block.items():
        assert one[topic][0] == pay, _difference(topic, one[topic][0], pay)
        assert np.array_equal(one[topic][1], log), topic
    other = _run(scenario, _spec({**_noisy(), "gnss": {**_noisy()["gnss"], "seed": 99}}),
                 [payloads])  # fmt: skip
    a = cdr.deserialize(cdr.NAVSATFIX, whole["/gnss/fix"][0])
    b = cdr.deserialize(cdr.NAVSATFIX, other["/gnss/fix"][0])
    assert np.all(a.latitude != b.latitude)
    assert other["/mag"][0] == whole["/mag"][0]  # seeds are per sensor


def test_gap_continues_like_uninterrupted(scenario, reference):
    """Truth messages missing (a live gap): later messages equal the uninterrupted run's
    (quantization off: the encoder would miss the gap's distance)."""
    payloads = _odom_payloads(scenario, reference)
    doc = _noisy()
    doc["wheel_odometer"]["pulses_per_m"] = 0.0
    spec = _spec(doc)
    full = _run(scenario, spec, [payloads])
    gap = _run(scenario, spec, [payloads[:1500], payloads[2600:]])
    resume = scenario.start_time_ns + 13 * 10**9  # payload 2600 at 200 Hz
    for topic, (pay, _) in full.items():
        stamps_full = cdr.deserialize(topic_type(topic), pay).stamps_ns
        stamps_gap = cdr.deserialize(topic_type(topic), gap[topic][0]).stamps_ns
        after = [p for p, t in zip(pay, stamps_full, strict=True) if t >= resume]
        later = [p for p, t in zip(gap[topic][0], stamps_gap, strict=True) if t >= resume]
        assert after and after == later, topic
        assert len(gap[topic][0]) < len(pay)


def topic_type(topic: str) -> str:
    return {
        "/gnss/fix": cdr.NAVSATFIX,
        "/gnss/vel": cdr.TWIST_WITH_COVARIANCE_STAMPED,
        "/baro/pressure": cdr.FLUID_PRESSURE,
        "/mag": cdr.MAGNETIC_FIELD,
        "/wheel/twist": cdr.TWIST_WITH_COVARIANCE_STAMPED,
    }[topic]


def test_covariances_are_the_models(scenario, reference):
    payloads = _odom_payloads(scenario, reference)
    spec = _spec(_noisy())
    out = _run(scenario, spec, [payloads])
    fix = cdr.deserialize(cdr.NAVSATFIX, out["/gnss/fix"][0])
    pos = spec.gnss.errors().position_variance  # NED
    assert np.all(fix.position_covariance == np.diag([pos[1], pos[0], pos[2]]).reshape(9))
    assert np.all(fix.position_covariance_type == 2)
    vel = cdr.deserialize(cdr.TWIST_WITH_COVARIANCE_STAMPED, out["/gnss/vel"][0])
    v = spec.gnss.errors().velocity_variance
    assert np.all(vel.covariance[:, [0, 7, 14]] == [v[1], v[0], v[2]])
    baro = cdr.deserialize(cdr.FLUID_PRESSURE, out["/baro/pressure"][0])
    assert np.all(baro.variance == spec.barometer.errors().variance)
    q = baro.fluid_pressure / 0.1
    assert np.max(np.abs(q - np.round(q))) < 1e-6  # the preset's 0.1 Pa quantum
    mag = cdr.deserialize(cdr.MAGNETIC_FIELD, out["/mag"][0])
    sigma = 0.3e-6
    assert np.allclose(mag.magnetic_field_covariance[0], np.diag([sigma**2] * 3).reshape(9),
                       rtol=1e-12, atol=0)  # fmt: skip
    wheel = cdr.deserialize(cdr.TWIST_WITH_COVARIANCE_STAMPED, out["/wheel/twist"][0])
    period = 0.02
    assert wheel.covariance[0, 0] == spec.wheel_odometer.errors().variance(period)
    assert math.isclose(wheel.covariance[0, 0], 0.02**2 + (1 / 48 / period) ** 2 / 6)


def test_expected_counts(ideal_bag, scenario):
    """aiding_topic_plans (the live pipeline's expectation) = what the stage wrote: counts,
    first and last header stamps."""
    cycles = len(ideal_bag["/reference/odom"]) - 1
    plans = aiding_topic_plans(scenario, _spec(_ideal()), cycles)
    expected = {p.topic: p.count for p in plans}
    assert expected == {t: len(ideal_bag.topics[t]) for t in expected}
    for p in plans:
        stamps = ideal_bag.topics[p.topic].fields.stamps_ns
        assert (p.first_ns, p.last_ns) == (int(stamps[0]), int(stamps[-1]))
    assert set(expected) == {"/gnss/fix", "/gnss/vel", "/baro/pressure", "/mag", "/wheel/twist"}


def test_nonfinite_and_out_of_order_truth_dropped(scenario, reference):
    """A NaN in a truth message drops it (its epoch skipped, later ones unchanged); a repeated
    or older message is dropped; warnings say so."""
    import dataclasses

    payloads = _odom_payloads(scenario, reference)[:2001]
    doc = _noisy()
    doc["wheel_odometer"]["pulses_per_m"] = 0.0  # the encoder would miss the epoch's distance
    spec = _spec(doc)
    full = _run(scenario, spec, [payloads])
    odom = cdr.deserialize(cdr.ODOMETRY, payloads)
    position = np.array(odom.position)
    bad = 400  # t = 2.0 s: an epoch of every sensor
    position[bad, 0] = np.nan
    broken = cdr.serialize(dataclasses.replace(odom, position=position))
    warnings: list[str] = []
    stream = AidingStage(scenario, spec, warn=warnings.append, error=warnings.append)
    out: dict[str, list[bytes]] = {}
    for chunk in (broken[:1000], broken[990:1000], broken[1000:]):  # NaN; then repeats
        for b in stream.on_payloads(chunk):
            out.setdefault(b.topic, []).extend(b.payloads)
    assert any("NaN" in w for w in warnings) and any("not after" in w for w in warnings)
    t_bad = int(odom.stamps_ns[bad])
    for topic, (pay, _) in full.items():
        stamps = cdr.deserialize(topic_type(topic), pay).stamps_ns
        want = [p for p, t in zip(pay, stamps, strict=True) if t != t_bad]
        assert out[topic] == want, _difference(topic, out[topic], want)


def test_wheel_at_rest_reports_exactly_zero(tmp_path):
    """A vehicle at rest (the static scenario) with the ABS encoder preset (scale factor,
    noise, 48 pulses/m): no pulse is counted, every speed is exactly 0; a GNSS with errors off
    types its fix covariance UNKNOWN, one with errors DIAGONAL_KNOWN."""
    from strapdown_ros.generate import generate_dataset

    scenario = load_scenario(
        REPO / "config/scenarios/static.yaml",
        [
            "aiding.wheel_odometer={preset: abs_sensor, rate_hz: 50, seed: 3, "
            "lever_arm_m: [0.5, -0.8, 0.45]}",
            "aiding.gnss={rate_hz: 5}",
        ],
        duration_s=20.0,
    )
    generate_dataset(scenario, tmp_path / "bag", progress=None)
    contents = read_bag(tmp_path / "bag")
    wheel = contents["/wheel/twist"]
    assert len(wheel.stamps_ns) == 20 * 50 + 1
    assert np.all(wheel.linear == 0.0), np.abs(wheel.linear).max()
    assert np.all(contents["/gnss/fix"].position_covariance_type == 0)
