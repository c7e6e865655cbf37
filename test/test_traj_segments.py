"""The ``segments`` trajectory: smooth transitions, maneuver targets, consistency, validation."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from truth_checks import velocity_and_position_derivative

from strapdown_ros.config import ScenarioError, parse_scenario
from strapdown_ros.core.earth import radii
from strapdown_ros.core.rotations import euler_from_dcm, vee
from strapdown_ros.core.trajectory.base import TrajectoryError
from strapdown_ros.core.trajectory.latlon_path import LatLonPath
from strapdown_ros.core.trajectory.segments import Segment, SegmentsTrajectory
from strapdown_ros.plan import build_trajectory

INITIAL = {
    "latitude_deg": 45.0,
    "longitude_deg": 7.0,
    "altitude_m": 300.0,
    "velocity_ned_mps": [0.0, 0.0, 0.0],
    "attitude_rph_deg": [0.0, 0.0, 30.0],
}

# Every kind of transition: track→track (speed, turn, climb), track→NED, NED→track.
MIXED = [
    {"duration_s": 10},
    {"duration_s": 30, "accel_mps2": 5, "transition_s": 2},
    {"duration_s": 60, "heading_rate_dps": 3},
    {"duration_s": 30, "heading_rate_dps": -1.5, "climb_rate_mps": 8, "transition_s": 5},
    {"duration_s": 40, "accel_ned_mps2": [1, -2, 0.3]},
    {
        "duration_s": 30,
        "pitch_rate_dps": 0.2,
        "heading_rate_dps": 2,
        "climb_rate_mps": 0,
        "transition_s": 4,
    },
    {"duration_s": 100, "roll_rate_dps": 1.0},
]


def build(initial, segments) -> SegmentsTrajectory:
    """The trajectory of a scenario's ``initial`` and ``trajectory.segments`` (typed model)."""
    scenario = parse_scenario(
        {
            "rate_hz": 100,
            "initial": initial,
            "trajectory": {"kind": "segments", "segments": segments},
        }
    )
    return build_trajectory(scenario)


@pytest.fixture(scope="module")
def mixed():
    return build(INITIAL, MIXED)


def boundaries(durations):
    return np.cumsum(durations)[:-1]


def accel_jump(traj, tb, d=1e-4):
    """|a(t_b+) - a(t_b-)| from one-sided differences of the NED velocity (m/s²)."""
    v = traj.local_truth(np.array([tb - d, tb, tb + d])).v_ned
    return np.linalg.norm((v[2] - v[1]) / d - (v[1] - v[0]) / d)


def rate_jump(traj, tb, d=1e-4):
    """|ω_nb(t_b+) - ω_nb(t_b-)| from one-sided differences of C_B^N (rad/s)."""
    c = traj.local_truth(np.array([tb - d, tb, tb + d])).c_b_n
    left = vee(c[1].T @ (c[1] - c[0])) / d
    right = vee(c[1].T @ (c[2] - c[1])) / d
    return np.linalg.norm(right - left)


def test_transitions_are_smooth(mixed):
    """No step in acceleration or angular rate at any boundary (FD noise ~ d · jerk ≤ 1e-4)."""
    for tb in boundaries([s["duration_s"] for s in MIXED]):
        assert accel_jump(mixed, tb) < 1e-3, tb
        assert rate_jump(mixed, tb) < 1e-5, tb


def test_zero_transition_is_a_step():
    """transition_s = 0: the turn starts at once, the lateral acceleration s ψ' steps."""
    segs = [
        {"duration_s": 5, "accel_mps2": 2, "transition_s": 0},
        {"duration_s": 5, "accel_mps2": 2, "heading_rate_dps": 10, "transition_s": 0},
    ]
    traj = build(INITIAL, segs)
    assert accel_jump(traj, 2.5) < 1e-6  # inside a segment: constant acceleration
    assert accel_jump(traj, 5.0) == pytest.approx(10.0 * math.radians(10), rel=1e-3)
    assert rate_jump(traj, 5.0) == pytest.approx(math.radians(10), rel=1e-3)
    smooth = build(INITIAL, [dict(s, transition_s=1.0) for s in segs])
    assert accel_jump(smooth, 5.0) < 1e-3
    assert rate_jump(smooth, 5.0) < 1e-5


def test_ninety_degree_turn():
    """9°/s for 10 s: the ramps in and out (½ τ r each) add up to exactly 90°."""
    init = dict(
        INITIAL,
        velocity_ned_mps=[
            100.0 * math.cos(math.radians(30)),
            100.0 * math.sin(math.radians(30)),
            0.0,
        ],
    )
    segs = [{"duration_s": 10, "heading_rate_dps": 9}, {"duration_s": 5}]
    traj = build(init, segs)
    end = traj.local_truth(np.array([15.0]))
    _, _, heading = euler_from_dcm(end.c_b_n[0])
    assert math.degrees(heading) == pytest.approx(120.0, abs=1e-9)
    # No sideslip: the track follows the heading, the speed is unchanged.
    v = end.v_ned[0]
    assert math.degrees(math.atan2(v[1], v[0])) == pytest.approx(120.0, abs=1e-9)
    assert np.hypot(v[0], v[1]) == pytest.approx(100.0, abs=1e-9)


def test_speed_after_acceleration():
    segs = [{"duration_s": 20, "accel_mps2": 2.5}, {"duration_s": 10}]
    traj = build(INITIAL, segs)
    lt = traj.local_truth(np.array([30.0]))
    assert np.linalg.norm(lt.v_ned[0]) == pytest.approx(50.0, abs=1e-9)
    assert math.degrees(math.atan2(lt.v_ned[0, 1], lt.v_ned[0, 0])) == pytest.approx(30.0)


def test_climb_reaches_target():
    segs = [{"duration_s": 20, "climb_rate_mps": 6, "transition_s": 8}, {"duration_s": 10}]
    traj = build(dict(INITIAL, velocity_ned_mps=[50, 0, 0]), segs)
    t = np.array([4.0, 8.0, 15.0, 30.0])
    lt = traj.local_truth(t)
    assert 0.0 < -lt.v_ned[0, 2] < 6.0
    np.testing.assert_allclose(-lt.v_ned[1:, 2], 6.0, atol=1e-12)  # held after the ramp
    # Altitude gained: 6 m/s for 30 s minus half the ramp (symmetric quintic: ½ τ v).
    assert lt.alt[-1] - 300.0 == pytest.approx(6.0 * 30.0 - 0.5 * 8.0 * 6.0, abs=1e-9)


def test_velocity_is_derivative_of_position(mixed):
    """4th-order central differences of ECEF position match C_N^E v^N to < 1e-6 m/s."""
    rng = np.random.default_rng(0)
    h = 0.01
    t = np.sort(rng.uniform(0.1, mixed.duration - 0.1, 3000))
    bounds = boundaries([s["duration_s"] for s in MIXED])
    knots = np.concatenate([bounds, bounds + 1.0, bounds + 2.0, bounds + 4.0, bounds + 5.0])
    t = t[np.min(np.abs(t[:, None] - knots[None, :]), axis=1) > 3 * h]  # stencil off the knots

    v_e, fd = velocity_and_position_derivative(mixed, t, h)
    err = np.abs(fd - v_e).max()
    assert err < 1e-6, err
    assert np.abs(v_e).max() > 100.0  # the check is not vacuous


def test_vectorized_evaluation(mixed):
    # How fast (was asserted here: build < 0.25 s, 120 000 times < 1 s): bench/bench_trajectory.py
    t = np.linspace(0.0, mixed.duration, 120_000)
    lt = mixed.local_truth(t)
    assert lt.c_b_n.shape == (120_000, 3, 3)
    # Same values one by one as vectorized.
    one = mixed.local_truth(t[[12345]])
    assert one.lat[0] == lt.lat[12345] and np.array_equal(one.c_b_n[0], lt.c_b_n[12345])


# Beyond MIXED: fast turns at high speed (forces interval halving), an eastward flight near the
# south pole (λ' ill-conditioned through cos φ), crossing the equator and the antimeridian.
FAST_TURNS = (
    dict(
        INITIAL, latitude_deg=60.0, velocity_ned_mps=[250.0, 0.0, 0.0], attitude_rph_deg=[0, 0, 0]
    ),
    [
        {"duration_s": 40, "heading_rate_dps": 20, "transition_s": 3},
        {"duration_s": 30, "accel_ned_mps2": [3, -5, 0.5], "transition_s": 5},
        {"duration_s": 40, "heading_rate_dps": -12, "accel_mps2": 0.3, "climb_rate_mps": 20},
    ],
)
NEAR_POLE = (
    dict(INITIAL, latitude_deg=-89.8, velocity_ned_mps=[0, 100, 0], attitude_rph_deg=[0, 0, 90]),
    [{"duration_s": 60, "heading_rate_dps": 1.5}, {"duration_s": 60, "heading_rate_dps": -3}],
)
EQUATOR = (
    dict(INITIAL, latitude_deg=0.001, longitude_deg=179.999, velocity_ned_mps=[-150, 150, 0]),
    [{"duration_s": 30}, {"duration_s": 30, "accel_mps2": -2}],
)


def piece_breaks(traj):
    """Boundaries of the blending and steady pieces (where the velocity's derivatives jump)."""
    edges, t = [0.0], 0.0
    for seg in traj.segments:
        edges += [t + seg.blend, t + seg.duration]
        t += seg.duration
    return np.unique(edges)


def velocity_of(traj):
    def velocity(tt):
        lt = traj.local_truth(np.clip(tt, 0.0, traj.duration))
        return lt.v_ned[:, 0], lt.v_ned[:, 1], lt.alt

    return velocity


def dop853_latlon(traj, t):
    """Reference latitude/longitude: DOP853 (rtol 1e-13), restarted at every piece boundary."""
    velocity = velocity_of(traj)
    first = traj.local_truth(np.array([0.0]))
    start = np.array([first.lat[0], first.lon[0]])
    out = np.full((t.size, 2), np.nan)
    breaks = piece_breaks(traj)
    for a, b in zip(breaks[:-1], breaks[1:], strict=True):

        def rhs(tt, y, start=start):
            vn, ve, h = velocity(np.array([tt]))
            lat = start[0] + y[0]
            rn, re = radii(lat)
            return np.array([vn[0] / (rn + h[0]), ve[0] / ((re + h[0]) * np.cos(lat))])

        sel = (t >= a) & (t < b) if b < breaks[-1] else (t >= a)
        sol = solve_ivp(
            rhs,
            (a, b),
            np.zeros(2),
            method="DOP853",
            rtol=1e-13,
            atol=1e-17,
            max_step=20.0,
            dense_output=True,
        )
        out[sel] = start + sol.sol(t[sel]).T
        start = start + sol.y[:, -1]
    return out


@pytest.mark.parametrize(
    "case", [(INITIAL, MIXED), FAST_TURNS, NEAR_POLE, EQUATOR], ids=["mixed", "fast", "pole", "eq"]
)
def test_latlon_against_dop853(case):
    """The collocation path matches DOP853 (rtol 1e-13) to 4e-9 m (2-3 ulp of the coordinates).

    The bound is the reference's own error: against a 34-digit Taylor reference (mpmath, run
    offline), the path is within 0.5 ulp of latitude (3.5e-10 m over the 600 s default
    scenario, 6.3e-10 m for FAST_TURNS) while DOP853 drifts to 1.6e-9 m and 2.0e-9 m.
    """
    traj = build(*case)
    t = np.concatenate([np.linspace(0.0, traj.duration, 401), piece_breaks(traj)])
    ref = dop853_latlon(traj, t)
    lt = traj.local_truth(t)
    r = 6.371e6
    assert np.abs(lt.lat - ref[:, 0]).max() * r < 4e-9
    assert np.abs((lt.lon - ref[:, 1]) * np.cos(ref[:, 0])).max() * r < 4e-9
    assert np.abs(lt.lon - lt.lon[0]).max() > 1e-4  # the path moves


@pytest.mark.parametrize(
    "case", [(INITIAL, MIXED), FAST_TURNS, NEAR_POLE], ids=["mixed", "fast", "pole"]
)
def test_path_derivative_is_the_geodetic_rate(case):
    """d/dt of the returned latitude/longitude equals the rates at off-node times (< 1e-11 m/s)."""
    traj = build(*case)
    first = traj.local_truth(np.array([0.0]))
    path = LatLonPath(piece_breaks(traj), first.lat[0], first.lon[0], velocity_of(traj))
    t = np.random.default_rng(3).uniform(0.0, traj.duration, 5000)
    lat, lon = path(t)
    d_lat, d_lon = path.derivative(t)
    r_lat, r_lon = path.rates(t, lat)
    r = 6.371e6
    assert np.abs(d_lat - r_lat).max() * r < 1e-11
    assert np.abs((d_lon - r_lon) * np.cos(lat)).max() * r < 1e-11
    np.testing.assert_array_equal(lat, traj.local_truth(t).lat)  # same path, bit for bit


def test_unsorted_times_and_determinism(mixed):
    t = np.random.default_rng(4).uniform(0.0, mixed.duration, 20_000)
    a = mixed.local_truth(t)
    order = np.argsort(t)
    b = mixed.local_truth(t[order])
    for name in ("lat", "lon", "alt", "v_ned", "c_b_n"):
        np.testing.assert_array_equal(getattr(a, name)[order], getattr(b, name), err_msg=name)
    again = build(INITIAL, MIXED).local_truth(t)
    np.testing.assert_array_equal(again.lat, a.lat)
    np.testing.assert_array_equal(again.lon, a.lon)


def test_initial_state_is_reproduced(mixed):
    lt = mixed.local_truth(np.array([0.0]))
    assert lt.lat[0] == math.radians(45.0) and lt.lon[0] == math.radians(7.0)
    assert lt.alt[0] == 300.0
    np.testing.assert_array_equal(lt.v_ned[0], 0.0)
    roll, pitch, heading = euler_from_dcm(lt.c_b_n[0])
    assert math.degrees(heading[()]) == pytest.approx(30.0, abs=1e-12)


@pytest.mark.parametrize(
    ("segments", "key"),
    [
        ([{"duration_s": -1}], "segments[0].duration_s"),
        ([{"duration_s": 5, "heading_rate_dps": float("nan")}], "segments[0].heading_rate_dps"),
        ([{"duration_s": 5, "accel_mps2": "fast"}], "segments[0].accel_mps2"),
        ([{"duration_s": 5, "transition_s": 6}], "segments[0].transition_s"),
        ([{"duration_s": 5, "accel_ned_mps2": [1, 2]}], "segments[0].accel_ned_mps2"),
        (
            [{"duration_s": 5, "accel_ned_mps2": [1, 2, 3], "climb_rate_mps": 1}],
            "segments[0].accel_ned_mps2",
        ),
        ([{"duration_s": 5, "wobble": 1}], "segments[0].wobble"),
        ([{"duration_s": 5}, {"heading_rate_dps": 1}], "segments[1].duration_s"),
        # Impossible trajectories.
        ([{"duration_s": 10}, {"duration_s": 10, "accel_mps2": -3}], "segments[1].accel_mps2"),
        ([{"duration_s": 100, "pitch_rate_dps": 1}], "segments[0].pitch_rate_dps"),
        (
            [{"duration_s": 100, "climb_rate_mps": -200, "transition_s": 10}],
            "segments[0].climb_rate_mps",
        ),
        ([{"duration_s": 5, "climb_rate_mps": 3, "transition_s": 0}], "segments[0].climb_rate_mps"),
        (
            [{"duration_s": 10}, {"duration_s": 100, "accel_ned_mps2": [0, 0, 5]}],
            "segments[1].accel_ned_mps2",
        ),
    ],
)
def test_bad_values_name_the_key(segments, key):
    with pytest.raises(ScenarioError) as info:
        build(dict(INITIAL, velocity_ned_mps=[20, 0, 0]), segments)
    assert info.value.key == f"trajectory.{key}", str(info.value)


def test_bad_initial_names_the_key():
    with pytest.raises(ScenarioError) as info:
        build(dict(INITIAL, latitude_deg=95.0), [{"duration_s": 1}])
    assert info.value.key == "initial.latitude_deg"
    with pytest.raises(ScenarioError) as info:
        build(dict(INITIAL, velocity_ned_mps=[0, None, 0]), [{"duration_s": 1}])
    assert info.value.key == "initial.velocity_ned_mps[1]"


@pytest.mark.parametrize(
    ("field", "value", "key"),
    [("latitude_deg", 89.95, "initial.latitude_deg"),
     ("attitude_rph_deg", [0.0, -89.95, 0.0], "initial.attitude_rph_deg[1]")],
)  # fmt: skip
def test_start_beyond_the_segments_limits_is_rejected_at_load(field, value, key):
    """±89.9° of latitude and pitch for segments (the top-level ``initial`` allows ±90°)."""
    with pytest.raises(ScenarioError) as info:
        parse_scenario(
            {"rate_hz": 100, "initial": dict(INITIAL, **{field: value}),
             "trajectory": {"kind": "segments", "segments": [{"duration_s": 1}]}}
        )  # fmt: skip
    assert info.value.key == key and "89.9" in info.value.problem
    build(dict(INITIAL, **{field: 89.85 if field == "latitude_deg" else [0, -89.85, 0]}),
          [{"duration_s": 1}])  # fmt: skip


def test_latitude_beyond_the_limit_names_the_segment():
    with pytest.raises(ScenarioError) as info:
        build(
            dict(INITIAL, latitude_deg=89.8, velocity_ned_mps=[0, 0, 0]),
            [{"duration_s": 10}, {"duration_s": 100, "accel_mps2": 5}],
        )
    assert info.value.key == "trajectory.segments[1]"
    assert info.value.problem.startswith("latitude would exceed ±89.9°")


def test_core_errors_name_the_segment_attribute():
    """The core model raises TrajectoryError with ``where`` = (segments, index, attribute)."""
    segments = [Segment(duration=10.0), Segment(duration=10.0, accel=-3.0)]
    with pytest.raises(TrajectoryError) as info:
        SegmentsTrajectory(math.radians(45), 0.0, 0.0, [20, 0, 0], [0, 0, 0], segments)
    assert info.value.where == ("segments", 1, "accel")
    assert str(info.value).startswith("segments[1].accel: the ground speed would become negative")
    with pytest.raises(TrajectoryError) as info:
        SegmentsTrajectory(math.radians(89.95), 0.0, 0.0, [0, 0, 0], [0, 0, 0], segments[:1])
    assert info.value.where == ("lat",)


def test_times_outside_the_trajectory_are_rejected(mixed):
    with pytest.raises(ValueError, match="times must lie"):
        mixed.local_truth(np.array([mixed.duration + 1.0]))


# --- the latitude reach: a path certain to pass ±89.9° is refused before it is solved ----------

A_WGS84, F_WGS84 = 6378137.0, 1.0 / 298.257223563  # defining constants of WGS-84


def _crossing_time(lat0_deg: float, speed: float, alt: float) -> float:
    """Time (s) a due-north (speed > 0) or due-south flight at constant speed and altitude
    takes from ``lat0_deg`` to ±89.9°: ``t = ∫ (R_N(φ) + h) dφ / |v|``, with the textbook
    meridian radius ``R_N = a (1 - e²) / (1 - e² sin² φ)^{3/2}`` (not the package's)."""
    from scipy.integrate import quad

    e2 = F_WGS84 * (2.0 - F_WGS84)

    def r_n(phi: float) -> float:
        return A_WGS84 * (1.0 - e2) / (1.0 - e2 * math.sin(phi) ** 2) ** 1.5

    end = math.copysign(math.radians(89.9), speed)
    arc, _ = quad(lambda phi: r_n(phi) + alt, math.radians(lat0_deg), end, epsabs=1e-6)
    return arc / speed


@pytest.mark.parametrize(("lat0", "speed"), [(45.0, 300.0), (-45.0, -300.0)])
def test_latitude_reach_is_refused_before_the_path_is_solved(monkeypatch, lat0, speed):
    """A 10⁶ s flight due north (south) passes the pole after about 5·10⁴ s: refused at once
    (the whole-path solver is never started: it took 46 s on a 10⁶ s path), by a time no
    earlier than the exact crossing and at most 2 % + one 20 s interval later (the bound
    carries ±0.5 % of the distance flown for the unknown meridian radius)."""
    import strapdown_ros.core.trajectory.segments as segments_module

    def no_solve(*args, **kwargs):
        raise AssertionError("the whole path was solved")

    monkeypatch.setattr(segments_module, "LatLonPath", no_solve)
    heading = 0.0 if speed > 0 else math.pi
    with pytest.raises(TrajectoryError) as info:
        SegmentsTrajectory(math.radians(lat0), 0.0, 1000.0, [speed, 0.0, 0.0],
                           [0.0, 0.0, heading], [Segment(duration=1e6)])  # fmt: skip
    assert info.value.where == ("segments", 0)
    problem = info.value.problem
    assert problem.startswith("latitude would exceed ±89.9° by t = "), problem
    t_bad = float(problem.removeprefix("latitude would exceed ±89.9° by t = ").removesuffix(" s"))
    t_cross = _crossing_time(lat0, speed, 1000.0)
    assert t_cross <= t_bad <= 1.02 * t_cross + 20.0, (t_cross, t_bad)


def test_latitude_reach_lets_a_path_that_turns_back_pass():
    """From 89.0° north 500 s at 100 m/s, a 180° turn, 600 s south: the speeds alone could
    carry the latitude past the limit (so the reach is integrated), the path peaks near 89.5°
    and is built."""
    segments = [{"duration_s": 500}, {"duration_s": 60, "heading_rate_dps": 3.0},
                {"duration_s": 600, "transition_s": 1}]  # fmt: skip
    traj = build(dict(INITIAL, latitude_deg=89.0, velocity_ned_mps=[100.0, 0.0, 0.0],
                      attitude_rph_deg=[0.0, 0.0, 0.0]), segments)  # fmt: skip
    lat = np.degrees(traj.local_truth(np.linspace(0.0, traj.duration, 2001)).lat)
    assert 89.4 < lat.max() < 89.9
