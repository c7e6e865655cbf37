"""The navigator on messages: scenario settings, initialization and output messages.

One implementation for ``strapdown-sim generate`` and ``navigator_node``: both decode the IMU
and truth messages of the input stream (:func:`strapdown_ros.messages.imu_increments`,
:func:`~strapdown_ros.messages.odometry_state`), feed them to a :class:`NavigatorRun`, and
serialize what it returns, so their ``/navigator/*`` messages are identical. The mathematics is
in :mod:`strapdown_ros.core.navigation` (Waldmann Table 1 / Table 2, the ``exact`` mode).

Conventions (docs/navigator.md):

* A run starts at a truth stamp ``t_s`` (the initial state, SPEC §2) and consumes the IMU
  messages ``t_s + T, t_s + 2T, …`` without a gap; outputs are stamped ``t_s + j N T``,
  j = 0, 1, … (j = 0 is the initial state, so its errors are the initial errors).
* Errors (SPEC §4) are computed against the truth message with the output's stamp: position
  ``C_E^N(true) (r_nav − r_true)`` NED, velocity ``v_nav − v_true`` NED, Young 1980 eq. (28)
  angles of ``C_B^N(nav) C_B^N(true)ᵀ``.
* ``/navigator/odom`` follows the Odometry semantics of SPEC §4; ``twist.angular`` is the
  cycle's mean body rate relative to the Earth, ``ΣΔα / T_nav − C_E^B ω_ie``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch, merge_order
from strapdown_ros.config import Scenario
from strapdown_ros.config._legacy_readers import (
    ScenarioError,
    check_mapping,
    read_bool,
    read_choice,
    read_int,
    read_number,
    read_vector,
)
from strapdown_ros.core.earth import (
    OMEGA_IE_VEC,
    dcm_ecef_to_ned,
    dcm_ned_to_ecef,
    ecef_to_geodetic,
    geodetic_to_ecef,
)
from strapdown_ros.core.gravity import GRAVITY_MODELS
from strapdown_ros.core.navigation import (
    MODES,
    MultirateNavigator,
    NavSolution,
    NavState,
    SimultaneousNavigator,
    VerticalDamping,
)
from strapdown_ros.core.rotations import (
    dcm_from_euler,
    dcm_from_quat,
    euler_from_dcm,
    quat_from_dcm,
)
from strapdown_ros.core.young import young_error_angles
from strapdown_ros.messages import (
    EarthState,
    NavSatFixFields,
    OdometryFields,
    Vector3StampedFields,
    imu_increments,
    navsatfix_fields_from_geodetic,
    odometry_fields_from_ecef,
    odometry_state,
    vector3_stamped_fields,
)

__all__ = [
    "ALGORITHMS",
    "NavigatorOutputs",
    "NavigatorRun",
    "NavigatorSettings",
    "StreamError",
    "initial_state_from_scenario",
    "initial_state_from_truth",
    "navigate_messages",
    "navigator_settings",
    "parse_navigator",
]

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

ALGORITHMS = ("multirate", "simultaneous")
INITIALIZATIONS = ("truth", "scenario")
NAVIGATOR_KEYS = (
    "algorithm",
    "mode",
    "n",
    "p",
    "imu_topic",
    "truth_topic",
    "initialization",
    "initial_errors",
    "vertical_damping",
    "gravity_model",
    "table1_radii",
    "normalize_quaternion",
    "frame_id",
)
INITIAL_ERROR_KEYS = ("position_ned_m", "velocity_ned_mps", "attitude_rph_deg")
DAMPING_KEYS = ("k1", "k2", "paper_signs")
#: Input IMU topic key → (truth topic key, scenario section it needs).
INPUT_STREAMS = {
    "reference_imu": ("reference_odom", None),
    "variation_imu": ("variation_odom", "variation"),
    "variation_reference_imu": ("variation_reference_odom", "variation"),
    "variation_imu_measured": ("variation_odom", "imu_errors"),
}
#: Output keys of :class:`NavigatorOutputs` → scenario recording.topics keys.
OUTPUT_TOPICS = {
    "odom": "navigator_odom",
    "fix": "navigator_fix",
    "error_position": "navigator_error_position",
    "error_velocity": "navigator_error_velocity",
    "error_attitude": "navigator_error_attitude",
}


class StreamError(ValueError):
    """The input messages cannot be integrated as they are (gap, out of order, wrong rate)."""


@dataclass(frozen=True)
class NavigatorSettings:
    """The scenario's ``navigator`` section, validated (docs/scenarios.md).

    Attributes
    ----------
    algorithm : str
        ``multirate`` (Waldmann Table 1) or ``simultaneous`` (Table 2).
    mode : str
        ``paper`` or ``exact`` (multirate only).
    n, p : int
        ``N = T_nav / T_gyr``, ``P = T_nav / T_int``.
    imu_topic, truth_topic : str
        Input topics (truth: initial state and errors; empty string: none).
    initialization : str
        ``truth`` (first message of the truth topic) or ``scenario`` (the scenario's initial
        state; reference input only).
    position_error_ned, velocity_error_ned, attitude_error_rph : arrays (3,)
        Initial errors added to the initial state: m (NED), m/s (NED), rad (roll, pitch,
        heading offsets).
    damping : VerticalDamping or None
        Vertical damping with the truth altitude as the auxiliary altitude.
    gravity_model : str
        The generator's gravitation model unless set.
    table1_radii, normalize : bool
        Paper-mode options (Table 1's radii; normalizing ``q_b^l`` each fast step).
    frame_id : str
        Child frame of ``/navigator/odom`` and frame of ``/navigator/fix``.
    """

    algorithm: str = "multirate"
    mode: str = "exact"
    n: int = 10
    p: int = 2
    imu_topic: str = "/variation/imu"
    truth_topic: str = "/variation/odom"
    initialization: str = "truth"
    position_error_ned: F64 = field(default_factory=lambda: np.zeros(3))
    velocity_error_ned: F64 = field(default_factory=lambda: np.zeros(3))
    attitude_error_rph: F64 = field(default_factory=lambda: np.zeros(3))
    damping: VerticalDamping | None = None
    gravity_model: str = "j2"
    table1_radii: bool = False
    normalize: bool = True
    frame_id: str = "navigator"

    def make(self, initial: NavState, t_gyr: float) -> MultirateNavigator | SimultaneousNavigator:
        """A navigator of these settings starting at ``initial`` with IMU period ``t_gyr``."""
        if self.algorithm == "simultaneous":
            return SimultaneousNavigator(
                initial, t_gyr, self.n, self.gravity_model, self.normalize, self.table1_radii,
                self.damping,
            )  # fmt: skip
        return MultirateNavigator(
            initial, t_gyr, self.n, self.p, mode=self.mode, gravity_model=self.gravity_model,
            normalize=self.normalize, table1_radii=self.table1_radii, damping=self.damping,
        )  # fmt: skip


def _topic_key(topics: Mapping[str, str], name: str) -> str | None:
    for key, value in topics.items():
        if value == name:
            return key
    return None


def parse_navigator(
    section: Mapping[str, Any] | None,
    topics: Mapping[str, str],
    gravity_model: str,
    sections: Mapping[str, object] | None = None,
) -> NavigatorSettings:
    """Validate a ``navigator`` section; errors name the dotted key (:class:`ScenarioError`).

    Parameters
    ----------
    section : mapping or None
        The section (None: all defaults).
    topics : mapping
        The scenario's ``recording.topics`` (stream key → topic name).
    gravity_model : str
        The scenario's gravitation model (the default).
    sections : mapping, optional
        The scenario's other sections (``variation``, ``imu_errors``): the input stream must be
        one the scenario produces. None: not checked (the node's standalone use).
    """
    path = "navigator"
    d = check_mapping(section, path, NAVIGATOR_KEYS)
    algorithm = read_choice(d, "algorithm", path, ALGORITHMS, "multirate")
    mode = read_choice(d, "mode", path, MODES, "exact" if algorithm == "multirate" else "paper")
    if algorithm == "simultaneous" and mode != "paper":
        raise ScenarioError(f"{path}.mode", "the simultaneous scheme (Table 2) has only 'paper'")
    n = read_int(d, "n", path, default=10, minimum=1)
    p = read_int(d, "p", path, default=2, minimum=1)
    imu_topic = d.get("imu_topic", topics.get("variation_imu", "/variation/imu"))
    if not isinstance(imu_topic, str) or not imu_topic.startswith("/"):
        raise ScenarioError(f"{path}.imu_topic", f"must be an absolute topic, got {imu_topic!r}")
    key = _topic_key(topics, imu_topic)
    if sections is not None:
        if key not in INPUT_STREAMS:
            names = ", ".join(topics[k] for k in INPUT_STREAMS if k in topics)
            raise ScenarioError(
                f"{path}.imu_topic", f"{imu_topic!r} is not an IMU stream; one of: {names}"
            )
        needs = INPUT_STREAMS[key][1]
        if needs is not None and sections.get(needs) is None:
            raise ScenarioError(
                f"{path}.imu_topic", f"{imu_topic!r} needs a '{needs}' section in the scenario"
            )
    default_truth = topics.get(INPUT_STREAMS[key][0], "") if key in INPUT_STREAMS else ""
    truth_topic = d.get("truth_topic", default_truth)
    if truth_topic is None:
        truth_topic = ""
    if not isinstance(truth_topic, str) or (truth_topic and not truth_topic.startswith("/")):
        raise ScenarioError(
            f"{path}.truth_topic", f"must be an absolute topic or empty, got {truth_topic!r}"
        )
    init = read_choice(d, "initialization", path, INITIALIZATIONS, "truth")
    if init == "truth" and not truth_topic:
        raise ScenarioError(f"{path}.initialization", "'truth' needs a truth_topic")
    if init == "scenario" and key not in (None, "reference_imu"):
        raise ScenarioError(
            f"{path}.initialization",
            "'scenario' initializes from the reference IMU's initial state; use it with "
            f"imu_topic {topics.get('reference_imu', '/reference/imu')!r} or use 'truth'",
        )
    e = check_mapping(d.get("initial_errors"), f"{path}.initial_errors", INITIAL_ERROR_KEYS)
    ep = f"{path}.initial_errors"
    pos = read_vector(e, "position_ned_m", ep, default=[0.0, 0.0, 0.0])
    vel = read_vector(e, "velocity_ned_mps", ep, default=[0.0, 0.0, 0.0])
    att = read_vector(e, "attitude_rph_deg", ep, default=[0.0, 0.0, 0.0])
    damping = None
    if d.get("vertical_damping") not in (None, False):
        dp = f"{path}.vertical_damping"
        raw = {} if d["vertical_damping"] is True else d["vertical_damping"]
        v = check_mapping(raw, dp, DAMPING_KEYS)
        if mode == "exact":
            raise ScenarioError(dp, "vertical damping is a 'paper' mode option")
        if not truth_topic:
            raise ScenarioError(dp, "needs a truth_topic (its altitude is the auxiliary altitude)")
        damping = VerticalDamping(
            k1=read_number(v, "k1", dp, default=1.0, minimum=0.0),  # type: ignore[arg-type]
            k2=read_number(v, "k2", dp, default=1.0, minimum=0.0),  # type: ignore[arg-type]
            paper_signs=read_bool(v, "paper_signs", dp, False),
        )
    gravity = read_choice(d, "gravity_model", path, GRAVITY_MODELS, gravity_model)
    frame = d.get("frame_id", "navigator")
    if not isinstance(frame, str) or not frame or " " in frame:
        raise ScenarioError(f"{path}.frame_id", f"must be a frame id, got {frame!r}")
    assert algorithm and mode and n and p and init and gravity and pos and vel and att
    return NavigatorSettings(
        algorithm=algorithm,
        mode=mode,
        n=n,
        p=p,
        imu_topic=imu_topic,
        truth_topic=truth_topic,
        initialization=init,
        position_error_ned=np.array(pos),
        velocity_error_ned=np.array(vel),
        attitude_error_rph=np.radians(att),
        damping=damping,
        gravity_model=gravity,
        table1_radii=read_bool(d, "table1_radii", path, False),
        normalize=read_bool(d, "normalize_quaternion", path, True),
        frame_id=frame,
    )


# --------------------------------------------------------------------------------------------
# Truth and initialization
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Truth:
    """Truth rows in navigation terms (from Odometry messages)."""

    r_e: F64
    lat: F64
    lon: F64
    alt: F64
    v_ned: F64
    c_b_n: F64
    omega_eb_b: F64


def _truth(state: EarthState) -> _Truth:
    lat, lon, alt = ecef_to_geodetic(state.r_e)
    c_e_n = dcm_ecef_to_ned(lat, lon)
    return _Truth(
        state.r_e,
        lat,
        lon,
        alt,
        np.einsum("nij,nj->ni", c_e_n, state.v_e),
        c_e_n @ state.c_b_e,
        state.omega_eb_b,
    )


def initial_state_from_truth(
    truth: EarthState, row: int, settings: NavigatorSettings, t: float = 0.0
) -> NavState:
    """The initial state from truth row ``row`` plus the settings' initial errors.

    Position error: NED metres in the true local level, applied in ECEF; velocity error: NED;
    attitude error: offsets of roll, pitch and heading (Euler angles of ``C_B^N``).
    """
    tr = _truth(EarthState(*(np.asarray(a)[row : row + 1] for a in truth)))
    r = tr.r_e[0] + dcm_ned_to_ecef(tr.lat[0], tr.lon[0]) @ settings.position_error_ned
    lat, lon, alt = ecef_to_geodetic(r)
    c = tr.c_b_n[0]
    if np.any(settings.attitude_error_rph):
        c = dcm_from_euler(*(np.asarray(euler_from_dcm(c)) + settings.attitude_error_rph))
    return NavState(
        float(t), float(lat), float(lon), float(alt),
        tr.v_ned[0] + settings.velocity_error_ned, quat_from_dcm(c),
    )  # fmt: skip


def initial_state_from_scenario(
    initial: Mapping[str, Any], settings: NavigatorSettings
) -> NavState:
    """The initial state from a scenario's ``initial`` section (the reference IMU at t0) plus
    the settings' initial errors (see :func:`initial_state_from_truth`)."""
    lat, lon = np.radians(initial["latitude_deg"]), np.radians(initial["longitude_deg"])
    alt = float(initial["altitude_m"])
    r = geodetic_to_ecef(lat, lon, alt) + dcm_ned_to_ecef(lat, lon) @ settings.position_error_ned
    lat, lon, alt = ecef_to_geodetic(r)
    rph = np.radians(np.asarray(initial["attitude_rph_deg"], dtype=np.float64))
    v = np.asarray(initial["velocity_ned_mps"], dtype=np.float64) + settings.velocity_error_ned
    c = dcm_from_euler(*(rph + settings.attitude_error_rph))
    return NavState(0.0, float(lat), float(lon), float(alt), v, quat_from_dcm(c))


def navigator_settings(scenario: Any) -> NavigatorSettings:
    """The validated settings of a scenario's ``navigator`` section."""
    return parse_navigator(
        scenario.navigator,
        scenario.recording.topics,
        scenario.gravity_model,
        {"variation": scenario.variation, "imu_errors": scenario.imu_errors},
    )


# --------------------------------------------------------------------------------------------
# Outputs
# --------------------------------------------------------------------------------------------


@dataclass
class NavigatorOutputs:
    """Fields of the navigator topics for consecutive output stamps (errors: None without
    truth)."""

    odom: OdometryFields
    fix: NavSatFixFields
    error_position: Vector3StampedFields | None = None
    error_velocity: Vector3StampedFields | None = None
    error_attitude: Vector3StampedFields | None = None

    def __len__(self) -> int:
        return len(self.odom)

    def items(self) -> list[tuple[str, object]]:
        """``(output key, fields)`` of the topics present (keys of :data:`OUTPUT_TOPICS`)."""
        return [(k, getattr(self, k)) for k in OUTPUT_TOPICS if getattr(self, k) is not None]


def _output_fields(
    stamps: I64,
    sol: NavSolution,
    omega_eb_b: F64,
    truth: _Truth | None,
    frame_id: str,
    earth_frame: str,
) -> NavigatorOutputs:
    r_e = geodetic_to_ecef(sol.lat, sol.lon, sol.alt)
    c_n_e = dcm_ned_to_ecef(sol.lat, sol.lon)
    v_e = np.einsum("nij,nj->ni", c_n_e, sol.v_ned)
    c_b_n = dcm_from_quat(sol.q_b_n)
    out = NavigatorOutputs(
        odometry_fields_from_ecef(
            stamps, r_e, v_e, c_n_e @ c_b_n, omega_eb_b, frame_id, earth_frame
        ),  # fmt: skip
        navsatfix_fields_from_geodetic(stamps, sol.lat, sol.lon, sol.alt, frame_id),
    )
    if truth is not None:
        dr = np.einsum("nij,nj->ni", dcm_ecef_to_ned(truth.lat, truth.lon), r_e - truth.r_e)
        out.error_position = vector3_stamped_fields(stamps, dr, "ned")
        out.error_velocity = vector3_stamped_fields(stamps, sol.v_ned - truth.v_ned, "ned")
        out.error_attitude = vector3_stamped_fields(
            stamps, young_error_angles(c_b_n, truth.c_b_n), "young_uen"
        )
    return out


# --------------------------------------------------------------------------------------------
# A run over contiguous messages
# --------------------------------------------------------------------------------------------


class NavigatorRun:
    """The navigator over one contiguous stretch of IMU messages (no gap).

    Feed decoded IMU increments (:meth:`add_imu`) and truth states (:meth:`add_truth`) in any
    interleaving; :meth:`outputs` returns the messages of every output that is complete (its
    cycle integrated and, with a truth topic, its truth received).

    Parameters
    ----------
    settings : NavigatorSettings
    start_ns : int
        Stamp of the initial state ``t_s``.
    period_ns : int
        IMU period T (ns); ``T_gyr = T``.
    initial : NavState
        State at ``t_s`` (with the initial errors already applied).
    use_truth : bool
        Compute errors (and wait for the truth of each output stamp).
    initial_omega : array (3,), optional
        Body rate relative to the Earth for the j = 0 output (truth's, if known).
    earth_frame : str
        Odometry ``header.frame_id``.
    """

    def __init__(
        self,
        settings: NavigatorSettings,
        start_ns: int,
        period_ns: int,
        initial: NavState,
        use_truth: bool,
        initial_omega: F64 | None = None,
        earth_frame: str = "earth",
    ) -> None:
        if period_ns <= 0:
            raise StreamError(f"IMU period must be positive, got {period_ns} ns")
        self.settings = settings
        self.start_ns, self.period_ns = int(start_ns), int(period_ns)
        self.nav_period_ns = settings.n * self.period_ns
        self.use_truth = use_truth
        self.earth_frame = earth_frame
        self.navigator = settings.make(initial, self.period_ns * 1e-9)
        self.next_imu_ns = self.start_ns + self.period_ns
        self._da: list[F64] = []
        self._dv: list[F64] = []
        self._buffered = 0
        self._truth: dict[int, tuple[F64, ...]] = {}
        w0 = np.zeros(3) if initial_omega is None else np.asarray(initial_omega, dtype=np.float64)
        self._held: list[tuple[int, NavSolution, F64]] = [
            (self.start_ns, _solution_rows(initial, settings.n), w0[None])
        ]
        self.cycles = 0

    # -- input -------------------------------------------------------------------------------

    def add_imu(self, stamps_ns: I64, dalpha: F64, dv: F64) -> None:
        """Append IMU increments (FRD) with stamps continuing the run exactly.

        Raises
        ------
        StreamError
            If the first stamp is not the expected next one, or the stamps are not spaced by T
            (a gap or out-of-order data): nothing is integrated across it.
        """
        stamps = np.asarray(stamps_ns, dtype=np.int64)
        if not stamps.size:
            return
        expected = self.next_imu_ns + self.period_ns * np.arange(stamps.size)
        if not np.array_equal(stamps, expected):
            bad = int(np.argmax(stamps != expected))
            raise StreamError(
                f"IMU stamp {int(stamps[bad])} ns where {int(expected[bad])} ns was expected "
                f"(T = {self.period_ns} ns): "
                + ("gap" if stamps[bad] > expected[bad] else "out of order or repeated")
            )
        self._da.append(np.asarray(dalpha, dtype=np.float64))
        self._dv.append(np.asarray(dv, dtype=np.float64))
        self._buffered += stamps.size
        self.next_imu_ns = int(stamps[-1]) + self.period_ns

    def add_truth(self, state: EarthState) -> None:
        """Remember truth rows by stamp (those on the navigation grid are kept)."""
        stamps = np.asarray(state.stamps_ns, dtype=np.int64)
        rel = stamps - self.start_ns
        keep = np.flatnonzero((rel >= 0) & (rel % self.nav_period_ns == 0))
        for i in keep:
            self._truth[int(stamps[i])] = tuple(np.asarray(a)[i] for a in state[1:])

    # -- output ------------------------------------------------------------------------------

    def outputs(self) -> NavigatorOutputs | None:
        """Integrate every complete cycle; return the outputs now complete (None if none)."""
        self._integrate()
        ready = []
        for item in self._held:
            if self.use_truth and item[0] not in self._truth:
                break
            ready.append(item)
        if not ready:
            return None
        self._held = self._held[len(ready) :]
        stamps = np.array([s for s, _, _ in ready], dtype=np.int64)
        sol = _concat([r[1] for r in ready])
        omega = np.concatenate([r[2] for r in ready])
        truth = None
        if self.use_truth:
            rows = [self._truth[int(s)] for s in stamps]
            truth = _truth(EarthState(stamps, *(np.array([r[i] for r in rows]) for i in range(4))))
        self._prune_truth()
        return _output_fields(stamps, sol, omega, truth, self.settings.frame_id, self.earth_frame)

    def _integrate(self) -> None:
        n = self.settings.n
        cycles = self._buffered // n
        if self.settings.damping is not None:
            # h_aux of cycle k: truth altitude at its start stamp (must have arrived).
            have = 0
            while have < cycles and self._cycle_start(self.cycles + have) in self._truth:
                have += 1
            cycles = have
        if not cycles:
            return
        da = np.concatenate(self._da) if len(self._da) > 1 else self._da[0]
        dv = np.concatenate(self._dv) if len(self._dv) > 1 else self._dv[0]
        used = cycles * n
        h_aux = None
        if self.settings.damping is not None:
            starts = [self._cycle_start(self.cycles + k) for k in range(cycles)]
            h_aux = ecef_to_geodetic(np.array([self._truth[s][0] for s in starts]))[2]
        sol = self.navigator.run(da[:used], dv[:used], h_aux)
        self._da, self._dv = [da[used:]], [dv[used:]]
        self._buffered -= used
        # Mean body rate relative to the Earth over each cycle: ΣΔα/T_nav - C_E^B ω_ie.
        t_nav = self.nav_period_ns * 1e-9
        rate = da[:used].reshape(cycles, n, 3).sum(axis=1) / t_nav
        c_b_e = dcm_ned_to_ecef(sol.lat, sol.lon) @ dcm_from_quat(sol.q_b_n)
        omega = rate - np.einsum("nji,j->ni", c_b_e, OMEGA_IE_VEC)
        for k in range(cycles):
            stamp = self._cycle_start(self.cycles + k + 1)
            self._held.append((stamp, _solution_rows(sol, n, k), omega[k : k + 1]))
        self.cycles += cycles

    def _prune_truth(self) -> None:
        """Forget truth older than both the next held output and the next cycle start."""
        oldest = self._cycle_start(self.cycles)
        if self._held:
            oldest = min(oldest, self._held[0][0])
        for s in [s for s in self._truth if s < oldest]:
            del self._truth[s]

    def _cycle_start(self, k: int) -> int:
        return self.start_ns + k * self.nav_period_ns


def _solution_rows(sol: NavSolution | NavState, n: int, k: int | None = None) -> NavSolution:
    """One output row as a NavSolution (from a state or row k of a solution)."""
    if isinstance(sol, NavState):
        return NavSolution(
            np.array([sol.t]), np.array([sol.lat]), np.array([sol.lon]), np.array([sol.alt]),
            np.asarray(sol.v_ned, dtype=np.float64)[None],
            np.asarray(sol.q_b_n, dtype=np.float64)[None], n,
        )  # fmt: skip
    sl = slice(k, k + 1)
    return NavSolution(
        sol.t[sl], sol.lat[sl], sol.lon[sl], sol.alt[sl], sol.v_ned[sl], sol.q_b_n[sl], n
    )


def _concat(parts: list[NavSolution]) -> NavSolution:
    return NavSolution(
        *(np.concatenate([getattr(p, f) for p in parts]) for f in
          ("t", "lat", "lon", "alt", "v_ned", "q_b_n")),
        parts[0].n,
    )  # fmt: skip


def navigate_messages(
    settings: NavigatorSettings,
    imu: Any,
    truth: Any | None,
    earth_frame: str = "earth",
) -> NavigatorOutputs | None:
    """The offline navigator over whole topics (what ``navigator_node`` publishes for them).

    ``imu``: :class:`~strapdown_ros.messages.ImuFields` of the input (uniformly stamped),
    ``truth``: :class:`~strapdown_ros.messages.OdometryFields` (the first message whose stamp
    is one period before the first Imu message starts the run). Used by ``strapdown-sim
    replay`` to check a live replay. Raises :class:`StreamError` on gaps.
    """
    from strapdown_ros.messages import imu_increments, odometry_state

    inc = imu_increments(imu)
    if truth is None:
        raise StreamError("the offline navigator needs the truth topic to start")
    state = odometry_state(truth)
    start = int(inc.stamps_ns[0]) - inc.period_ns
    rows = np.flatnonzero(np.asarray(state.stamps_ns) == start)
    if not rows.size:
        raise StreamError(f"no truth message at {start} ns (one period before the first Imu)")
    run = NavigatorRun(
        settings, start, inc.period_ns, initial_state_from_truth(state, int(rows[0]), settings),
        bool(settings.truth_topic), state.omega_eb_b[int(rows[0])], earth_frame,
    )  # fmt: skip
    run.add_truth(state)
    run.add_imu(inc.stamps_ns, inc.dalpha, inc.dv)
    return run.outputs()


class _NavigatorStreamer:
    """The scenario's navigator fed piece by piece with the decoded messages of its input
    stream (as ``navigator_node`` is), returning the ``/navigator/*`` batches now complete."""

    def __init__(self, scenario: Scenario) -> None:
        from strapdown_ros.stages.navigation import OUTPUT_TOPICS, navigator_settings

        self.scenario = scenario
        self.settings = navigator_settings(scenario)
        self.topics = {k: scenario.recording.topics[v] for k, v in OUTPUT_TOPICS.items()}
        self.run: object = None
        self.final_errors: dict[str, float] = {}

    def feed(self, batches: list[Batch]) -> list[Batch]:
        """Take one piece's batches; return the navigator batches now computable."""
        from strapdown_ros.stages.navigation import (
            NavigatorRun,
            initial_state_from_scenario,
            initial_state_from_truth,
        )

        st = self.settings
        by_topic = {b.topic: b for b in batches}
        truth = None
        if st.truth_topic and st.truth_topic in by_topic and by_topic[st.truth_topic].payloads:
            b = by_topic[st.truth_topic]
            truth = odometry_state(cdr.deserialize(b.msgtype, b.payloads))
        if self.run is None:
            period = self.scenario.period_ns
            if st.initialization == "truth":
                if truth is None:
                    return []
                initial = initial_state_from_truth(truth, 0, st)
                start, omega = int(truth.stamps_ns[0]), truth.omega_eb_b[0]
            else:
                assert self.scenario.initial is not None
                initial = initial_state_from_scenario(self.scenario.initial.as_dict(), st)
                start, omega = self.scenario.start_time_ns, None
            self.run = NavigatorRun(
                st, start, period, initial, bool(st.truth_topic), omega,
                self.scenario.recording.frames["earth"],
            )  # fmt: skip
        run: NavigatorRun = self.run  # type: ignore[assignment]
        if truth is not None:
            run.add_truth(truth)
        if st.imu_topic in by_topic and by_topic[st.imu_topic].payloads:
            b = by_topic[st.imu_topic]
            inc = imu_increments(cdr.deserialize(b.msgtype, b.payloads), self.scenario.period_ns)
            run.add_imu(inc.stamps_ns, inc.dalpha, inc.dv)
        out = run.outputs()
        if out is None:
            return []
        if out.error_position is not None:
            dr = np.asarray(out.error_position.vector)
            self.final_errors = {
                "horizontal_m": float(np.hypot(dr[-1, 0], dr[-1, 1])),
                "vertical_m": float(abs(dr[-1, 2])),
                "max_horizontal_m": max(
                    self.final_errors.get("max_horizontal_m", 0.0),
                    float(np.hypot(dr[:, 0], dr[:, 1]).max()),
                ),
            }
        return [batch(self.topics[k], f) for k, f in out.items()]


#: Truth messages kept for (re)starting runs.
TRUTH_KEEP = 4096


Log = Callable[[str], None]


def format_stamp(stamp_ns: int) -> str:
    """``sec.nanosec`` of a stamp (ns since the epoch)."""
    return f"{stamp_ns // 1_000_000_000}.{stamp_ns % 1_000_000_000:09d}"


class NavigatorSolver:
    """The streaming navigator (no rclpy): raw payloads in, serialized outputs out.

    Parameters
    ----------
    settings : NavigatorSettings
        Algorithm, mode, N, P, topics, initialization, initial errors.
    output_topics : dict
        Output key (:data:`~strapdown_ros.stages.navigation.OUTPUT_TOPICS`) → topic name.
    scenario_initial : mapping or None
        The scenario's ``initial`` section (``initialization: scenario``).
    start_ns : int or None
        The scenario's start stamp (``initialization: scenario``).
    nav_period_s : float
        If > 0, ``T_nav`` (s): N = T_nav / T must be an integer (checked when T is known).
    end_ns : int or None
        Last IMU stamp of the input stream, if known (the scenario's): :attr:`finished`.
    earth_frame : str
        Odometry frame id.
    """

    def __init__(
        self,
        settings: NavigatorSettings,
        output_topics: dict[str, str],
        scenario_initial: dict[str, Any] | None = None,
        start_ns: int | None = None,
        nav_period_s: float = 0.0,
        end_ns: int | None = None,
        earth_frame: str = "earth",
        info: Log = print,
        warn: Log = print,
        error: Log = print,
    ) -> None:
        self.settings = settings
        self.output_topics = output_topics
        self.scenario_initial = scenario_initial
        self.start_ns = start_ns
        self.nav_period_s = nav_period_s
        self.end_ns = end_ns
        self.earth_frame = earth_frame
        self.info, self.warn, self.error = info, warn, error
        self.period_ns: int | None = None
        self.first_imu: tuple[int, Any] | None = None  # (stamp, fields) before T is known
        self.imu_buffer: list[tuple[int, np.ndarray, np.ndarray]] = []  # waiting for a run
        self.truth: dict[int, EarthState] = {}
        self.run: NavigatorRun | None = None
        self.runs = 0
        self.published_outputs = 0
        self.last_output_ns: int | None = None
        self.failed: str | None = None
        self._flush_pending: list[tuple[str, int, bytes]] = []

    # -- helpers -------------------------------------------------------------------------------

    @property
    def started(self) -> bool:
        return self.run is not None or self.runs > 0

    @property
    def finished(self) -> bool:
        """True when the last output the input stream allows has been published."""
        if self.end_ns is None or self.run is None:
            return False
        nav = self.run.nav_period_ns
        last = self.run.start_ns + (self.end_ns - self.run.start_ns) // nav * nav
        return self.last_output_ns is not None and self.last_output_ns >= last

    def _set_period(self, period_ns: int) -> bool:
        if period_ns <= 0:
            return False
        if self.nav_period_s > 0:
            n = self.nav_period_s * 1e9 / period_ns
            if abs(n - round(n)) > 1e-6 or round(n) < 1:
                self.failed = (
                    f"nav_period_s = {self.nav_period_s:g} s is not a whole multiple of the IMU "
                    f"period T = {period_ns} ns detected from the stamps"
                )
                self.error(self.failed)
                return False
            self.settings = dataclasses.replace(self.settings, n=int(round(n)))
        self.period_ns = period_ns
        self.info(
            f"IMU period T = {period_ns} ns ({1e9 / period_ns:g} Hz) from the stamps; "
            f"T_nav = N T = {self.settings.n} x T = {self.settings.n * period_ns * 1e-9:g} s, "
            f"P = {self.settings.p}"
        )
        return True

    # -- input -------------------------------------------------------------------------------

    def on_truth(self, payload: bytes) -> list[tuple[str, int, bytes]]:
        """One raw Odometry payload of the truth topic; returns what to publish."""
        try:
            fields = cdr.deserialize(cdr.ODOMETRY, [payload])
        except cdr.CdrError as exc:
            self.error(f"{self.settings.truth_topic}: rejected a malformed Odometry: {exc}")
            return []
        if not self._earth_frame_ok(fields):
            return []
        self._add_truth(odometry_state(fields))  # type: ignore[arg-type]
        return self._advance()

    def on_imu(self, payload: bytes) -> list[tuple[str, int, bytes]]:
        """One raw Imu payload; returns what to publish."""
        try:
            fields = cdr.deserialize(cdr.IMU, [payload])
        except cdr.CdrError as exc:
            self.error(f"{self.settings.imu_topic}: rejected a malformed Imu: {exc}")
            return []
        return self._on_imu_fields(fields)

    def on_batch(self, items: list[tuple[str, bytes]]) -> list[tuple[str, int, bytes]]:
        """Raw payloads ``(kind, payload)`` (kind 'imu' | 'truth') in arrival order.

        Returns what :meth:`on_imu` / :meth:`on_truth` called one by one return, in the same
        order (the same bytes; tested), at a fraction of the cost: each topic's payloads are
        decoded with one CDR call, and outputs are collected once per batch while the run
        simply continues. A message that could change the run (no run yet, a gap, a repeat)
        takes the one-by-one path, which flushes the run's pending outputs first. A batch
        that does not decode as a whole (a malformed message, mixed frame ids) is taken one by
        one, so every message gets its own verdict.
        """
        imu = self._decode_rows(cdr.IMU, [p for k, p in items if k == "imu"])
        truth = self._decode_rows(cdr.ODOMETRY, [p for k, p in items if k == "truth"])
        states = None  # a wrong frame id: one by one, each message is reported
        if truth is not None and truth[0].frame_id == self.earth_frame:
            states = odometry_state(truth[0])
        out: list[tuple[str, int, bytes]] = []
        i_imu = i_truth = 0
        for kind, payload in items:
            if kind == "truth":
                i, i_truth = i_truth, i_truth + 1
                if states is None:
                    out += self.on_truth(payload)
                    continue
                self._add_truth(EarthState(*(a[i : i + 1] for a in states)))
                continue
            i, i_imu = i_imu, i_imu + 1
            if imu is None:
                out += self.on_imu(payload)
                continue
            fields, stamps = imu
            run = self.run
            if run is None or self.period_ns is None or int(stamps[i]) != run.next_imu_ns:
                out += self._on_imu_fields(fields.rows(i, i + 1))  # type: ignore[attr-defined]
            else:
                self._queue(int(stamps[i]), fields.rows(i, i + 1))  # type: ignore[attr-defined]
        return out + self._advance()

    @staticmethod
    def _decode_rows(msgtype: str, payloads: list[bytes]) -> tuple[Any, np.ndarray] | None:
        """All ``payloads`` decoded at once (fields, stamps), or None if they do not decode."""
        if not payloads:
            return None
        try:
            fields = cdr.deserialize(msgtype, payloads)
        except cdr.CdrError:
            return None
        return fields, np.asarray(fields.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]

    def _earth_frame_ok(self, fields: Any) -> bool:
        if fields.frame_id == self.earth_frame:
            return True
        self.error(
            f"{self.settings.truth_topic}: header.frame_id "
            f"{fields.frame_id!r} is not the Earth frame {self.earth_frame!r}; dropped"
        )
        return False

    def _add_truth(self, state: EarthState) -> None:
        """Keep one truth row (for run starts) and hand it to the current run."""
        stamp = int(state.stamps_ns[0])
        self.truth[stamp] = state
        if len(self.truth) > TRUTH_KEEP:
            for s in sorted(self.truth)[: len(self.truth) - TRUTH_KEEP]:
                del self.truth[s]
        if self.run is not None:
            self.run.add_truth(state)

    def _on_imu_fields(self, fields: Any) -> list[tuple[str, int, bytes]]:
        """One decoded Imu message; returns what to publish."""
        stamp = int(fields.stamps_ns[0])
        if self.period_ns is None:
            if self.failed:
                return []
            if self.first_imu is None or stamp <= self.first_imu[0]:
                self.first_imu = (stamp, fields)
                return []
            if not self._set_period(stamp - self.first_imu[0]):
                return []
            first_stamp, first_fields = self.first_imu
            self._queue(first_stamp, first_fields)
        self._queue(stamp, fields)
        return self._advance()

    def _queue(self, stamp: int, fields: Any) -> None:
        assert self.period_ns is not None
        inc = imu_increments(fields, self.period_ns)
        da, dv = inc.dalpha, inc.dv
        if self.run is not None:
            try:
                self.run.add_imu(inc.stamps_ns, da, dv)
                return
            except StreamError as exc:
                expected = self.run.next_imu_ns
                if stamp < expected:
                    self.warn(f"{self.settings.imu_topic}: {exc}; dropped")
                    return
                self.warn(
                    f"{self.settings.imu_topic}: {exc} "
                    f"({(stamp - expected) // self.period_ns} message(s) missing after "
                    f"{format_stamp(expected - self.period_ns)}); the run that started at "
                    f"{format_stamp(self.run.start_ns)} ends at its last complete cycle and a "
                    "new run starts from the truth before the next message"
                )
                self._flush_pending = self._outputs_of(self.run)
                self.run = None
        if self.imu_buffer and stamp <= self.imu_buffer[-1][0]:
            self.warn(
                f"{self.settings.imu_topic}: stamp {format_stamp(stamp)} out of order; dropped"
            )
            return
        if self.imu_buffer and stamp != self.imu_buffer[-1][0] + self.period_ns:
            self.imu_buffer.clear()  # a gap before any run started: restart the search
        self.imu_buffer.append((stamp, da, dv))

    # -- runs --------------------------------------------------------------------------------

    def _try_start(self) -> None:
        if self.run is not None or self.period_ns is None or not self.imu_buffer:
            return
        st, t = self.settings, self.period_ns
        if st.initialization == "scenario":
            assert self.start_ns is not None and self.scenario_initial is not None
            while self.imu_buffer and self.imu_buffer[0][0] < self.start_ns + t:
                self.imu_buffer.pop(0)
            if not self.imu_buffer or self.imu_buffer[0][0] != self.start_ns + t:
                if self.imu_buffer and not self.failed:
                    self.failed = (
                        f"initialization 'scenario' needs the IMU message at "
                        f"{format_stamp(self.start_ns + t)} (scenario start + T); the first one "
                        f"received is {format_stamp(self.imu_buffer[0][0])}"
                    )
                    self.error(self.failed)
                return
            initial = initial_state_from_scenario(self.scenario_initial, st)
            self._start(self.start_ns, initial, None)
            return
        for s in sorted(self.truth):
            while self.imu_buffer and self.imu_buffer[0][0] < s + t:
                self.imu_buffer.pop(0)
            if not self.imu_buffer:
                return
            if self.imu_buffer[0][0] == s + t:
                state = self.truth[s]
                self._start(s, initial_state_from_truth(state, 0, st), state.omega_eb_b[0])
                return

    def _start(self, start_ns: int, initial: Any, omega: Any) -> None:
        assert self.period_ns is not None
        st = self.settings
        self.run = NavigatorRun(
            st, start_ns, self.period_ns, initial, bool(st.truth_topic), omega, self.earth_frame
        )
        for s in sorted(self.truth):
            if s >= start_ns:
                self.run.add_truth(self.truth[s])
        buf, self.imu_buffer = self.imu_buffer, []
        if buf:
            self.run.add_imu(
                np.array([b[0] for b in buf], dtype=np.int64),
                np.concatenate([b[1] for b in buf]),
                np.concatenate([b[2] for b in buf]),
            )
        self.runs += 1
        how = "truth" if st.initialization == "truth" else "the scenario's initial state"
        self.info(f"run {self.runs} starts at {format_stamp(start_ns)} (initial state from {how})")

    def _advance(self) -> list[tuple[str, int, bytes]]:
        flushed, self._flush_pending = self._flush_pending, []
        self._try_start()
        if self.run is None:
            return flushed
        return flushed + self._outputs_of(self.run)

    def _outputs_of(self, run: NavigatorRun) -> list[tuple[str, int, bytes]]:
        out = run.outputs()
        if out is None:
            return []
        batches: list[Batch] = [batch(self.output_topics[k], f) for k, f in out.items()]
        self.published_outputs += len(out)
        self.last_output_ns = int(out.odom.stamps_ns[-1])
        return [
            (batches[b].topic, int(batches[b].stamps_ns[i]), batches[b].payloads[i])
            for b, i, _ in merge_order(batches)
        ]
