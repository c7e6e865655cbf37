"""Aiding measurements: GNSS, barometer, magnetometer and wheel odometer from the truth.

One streaming stage used by ``strapdown-sim generate`` and the live node: the reference truth
``nav_msgs/Odometry`` goes in (decoded fields or CDR payloads, in chunks of any size, state
carried), serialized messages come out per topic, the same bytes for any chunking. The models
are in :mod:`strapdown_ros.core.aiding`; the section in :mod:`strapdown_ros.config.aiding`;
equations, frames and presets in docs/aiding.md.

* **Epochs.** A truth message is an epoch of a sensor when its stamp is a multiple of the
  sensor's period P (absolute time; GNSS epochs fall on whole seconds). The error model of a
  sensor counts epochs from the first one at or after the scenario's start, so a live input
  that starts late or has gaps gets the noise of an uninterrupted run (missing epochs are
  skipped: their random numbers are drawn, the processes advanced, nothing is published).
* **Latency** (GNSS). Header stamp = measurement time; the message is released (published,
  bag log time) at ``stamp + latency_s``, i.e. with the first truth message at or after that
  time; messages due after the last truth message are never released.
* **Outages** (GNSS). No message whose measurement time is inside a window (the errors still
  run through it).
* **Geomagnetic field.** IGRF-14 Gauss coefficients from ``pyIGRF14`` (the package's
  coefficient table and its date interpolation) at the scenario's decimal year, synthesized by
  :func:`~strapdown_ros.core.aiding.magnetometer.igrf_field_ned` (vectorized, numpy). The
  package is imported here, not in the core (the core is numpy/scipy only).
"""

from __future__ import annotations

import functools
from typing import Any, NamedTuple

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch
from strapdown_ros.config import Scenario, ScenarioError
from strapdown_ros.config.aiding import (
    AIDING_TOPICS,
    AidingSpec,
    GnssSpec,
    MagnetometerSpec,
    WheelOdometerSpec,
)
from strapdown_ros.config.base import validate_section
from strapdown_ros.core.aiding.baro import BaroErrorModel, icao_pressure
from strapdown_ros.core.aiding.common import mat_t_vec, mat_vec
from strapdown_ros.core.aiding.gnss import GnssErrorModel, antenna_state, gnss_measurement
from strapdown_ros.core.aiding.magnetometer import MagnetometerErrorModel, igrf_field_ned
from strapdown_ros.core.aiding.odometer import OdometerErrorModel, contact_point_velocity
from strapdown_ros.core.earth import dcm_ned_to_ecef, ecef_to_geodetic
from strapdown_ros.core.rotations import frd_to_flu
from strapdown_ros.logs import Log, quiet
from strapdown_ros.messages import (
    COVARIANCE_TYPE_DIAGONAL_KNOWN,
    COVARIANCE_TYPE_UNKNOWN,
    FluidPressureFields,
    MagneticFieldFields,
    OdometryFields,
    TwistWithCovarianceStampedFields,
    navsatfix_fields_from_geodetic,
    odometry_state,
)
from strapdown_ros.plan.model import TopicPlan
from strapdown_ros.stages.intake import (
    MAX_LATE_CYCLES,
    InputEvents,
    decode_runs,
    format_stamp,
    screen,
    stamp_span,
    stretches,
    without_rows,
)

__all__ = [
    "AIDING_MSGTYPES",
    "NOT_MEASURED_VARIANCE",
    "AidingOutput",
    "AidingStage",
    "TruthRows",
    "aiding_topic_plans",
    "aiding_spec",
    "aiding_topic_types",
    "epochs_in",
    "error_free_spec",
    "igrf_coefficients",
]


#: Variance given to twist components a sensor does not measure (the angular rates).
NOT_MEASURED_VARIANCE = 1e6


#: Marks a restart of the source between two stretches of truth (AidingStage._intake).
_RESTART: Any = object()


def aiding_spec(scenario: Scenario) -> AidingSpec | None:
    """The scenario's ``aiding`` section (None without one)."""
    return getattr(scenario, "aiding", None)


#: Message type of each aiding topic.
AIDING_MSGTYPES: dict[str, str] = {
    AIDING_TOPICS["gnss_fix"]: cdr.NAVSATFIX,
    AIDING_TOPICS["gnss_vel"]: cdr.TWIST_WITH_COVARIANCE_STAMPED,
    AIDING_TOPICS["baro"]: cdr.FLUID_PRESSURE,
    AIDING_TOPICS["mag"]: cdr.MAGNETIC_FIELD,
    AIDING_TOPICS["wheel"]: cdr.TWIST_WITH_COVARIANCE_STAMPED,
}


def aiding_topic_types(scenario: Scenario) -> dict[str, str]:
    """Topic -> message type of the aiding topics the scenario produces (enabled sensors)."""
    spec = aiding_spec(scenario)
    return {} if spec is None else {t: AIDING_MSGTYPES[t] for t in spec.topics()}


@functools.lru_cache(maxsize=8)
def igrf_coefficients(year: float) -> tuple[np.ndarray, np.ndarray]:
    """IGRF-14 Gauss coefficients ``g[n, m]``, ``h[n, m]`` (nT) at a decimal year, from pyIGRF14.

    Degree 13 from 2000 on (10 before 1995, per IGRF); linear between the 5-year models,
    secular variation after 2025. Arrays are read-only (cached).
    """
    from strapdown_ros.requirements_check import require

    get_coeffs = require("pyIGRF14.loadCoeffs", "magnetometer").get_coeffs

    if not 1900.0 <= year <= 2030.0:
        raise ValueError(f"IGRF-14 covers 1900-2030, got the year {year}")
    gl, hl = get_coeffs(float(year))
    nmax = len(gl) - 1
    g = np.zeros((nmax + 1, nmax + 1))
    h = np.zeros((nmax + 1, nmax + 1))
    for n in range(1, nmax + 1):
        for m in range(n + 1):
            g[n, m] = gl[n][m]
            if m:
                h[n, m] = hl[n][m]
    g.setflags(write=False)
    h.setflags(write=False)
    return g, h


class TruthRows(NamedTuple):
    """Truth at some epochs (core frames): stamps (ns), ``r_e``, ``v_e`` (ECEF), ``c_b_e``
    (``C_FRD^E``), ``omega_eb_b`` (FRD, rad/s)."""

    stamps_ns: np.ndarray
    r_e: np.ndarray
    v_e: np.ndarray
    c_b_e: np.ndarray
    omega_eb_b: np.ndarray

    def take(self, idx: np.ndarray) -> TruthRows:
        return TruthRows(*(a[idx] for a in self))


def _take_rows(odom: OdometryFields, idx: np.ndarray) -> OdometryFields:
    """Odometry messages ``idx`` (any rows) as a field container."""
    return OdometryFields(
        stamps_ns=np.asarray(odom.stamps_ns)[idx],
        frame_id=odom.frame_id,
        child_frame_id=odom.child_frame_id,
        position=np.asarray(odom.position)[idx],
        orientation=np.asarray(odom.orientation)[idx],
        pose_covariance=np.asarray(odom.pose_covariance)[idx],
        twist_linear=np.asarray(odom.twist_linear)[idx],
        twist_angular=np.asarray(odom.twist_angular)[idx],
        twist_covariance=np.asarray(odom.twist_covariance)[idx],
    )


class AidingOutput(NamedTuple):
    """Messages of one topic: field container and their release (bag log) times, ns."""

    topic: str
    fields: Any
    log_ns: np.ndarray


def _diag(values: np.ndarray, size: int, n: int) -> np.ndarray:
    out = np.zeros((size, size))
    out[np.arange(len(values)), np.arange(len(values))] = values
    return np.broadcast_to(out.reshape(size * size), (n, size * size))


class _Channel:
    """One sensor: its epochs, its error model and the messages it builds.

    ``error_model``: the core model's class, built from the spec's ``errors()``, the period
    (s) and the seed; ``lever``: the sensor from the reference IMU (body FRD, m; zero for a
    sensor without ``lever_arm_m``, the magnetometer, which is at the IMU).
    """

    key = ""
    error_model: Any = None

    def __init__(self, spec: Any, t0_ns: int, warn: Log) -> None:
        self.spec = spec
        self.period_ns = spec.period_ns
        self.period_s = self.period_ns * 1e-9
        self.first_epoch = -(-t0_ns // self.period_ns)  # ceil(t0 / P)
        self.last_epoch = self.first_epoch - 1
        self.warn = warn
        self.errors = spec.errors()
        self.model = self.error_model(self.errors, self.period_s, spec.seed)
        self.lever = np.array(getattr(spec, "lever_arm_m", (0.0, 0.0, 0.0)), dtype=np.float64)

    def feed(self, truth: TruthRows) -> list[AidingOutput]:
        k = truth.stamps_ns // self.period_ns
        is_epoch = (truth.stamps_ns % self.period_ns == 0) & (k >= self.first_epoch)
        idx = np.flatnonzero(is_epoch)
        out: list[list[AidingOutput]] = []
        i = 0
        while i < len(idx):
            kk = int(k[idx[i]])
            if kk <= self.last_epoch:
                self.warn(f"{self.key}: epoch {kk} again or out of order; dropped")
                i += 1
                continue
            self.model.skip(kk - self.last_epoch - 1)
            j = i + 1
            while j < len(idx) and k[idx[j]] == k[idx[j - 1]] + 1:
                j += 1
            out.append(self.measure(truth.take(idx[i:j])))
            self.last_epoch = int(k[idx[j - 1]])
            i = j
        return _merge(out)

    def measure(self, truth: TruthRows) -> list[AidingOutput]:
        raise NotImplementedError

    def release(self, last_truth_ns: int) -> list[AidingOutput]:
        """Messages held back by a latency that are due at ``last_truth_ns``."""
        return []


def _merge(parts: list[list[AidingOutput]]) -> list[AidingOutput]:
    """Outputs of several runs, one per topic (in first-seen order)."""
    by_topic: dict[str, AidingOutput] = {}
    for part in parts:
        for o in part:
            if not len(o.fields):
                continue
            prev = by_topic.get(o.topic)
            by_topic[o.topic] = (
                o
                if prev is None
                else AidingOutput(
                    o.topic, prev.fields.append(o.fields), np.concatenate([prev.log_ns, o.log_ns])
                )
            )
    return list(by_topic.values())


class _Gnss(_Channel):
    key = "gnss"
    error_model = GnssErrorModel

    def __init__(self, spec: GnssSpec, t0_ns: int, warn: Log) -> None:
        super().__init__(spec, t0_ns, warn)
        self.latency_ns = spec.latency_ns
        self.outages = spec.outage_windows_ns(t0_ns)
        pos = self.errors.position_variance
        vel = self.errors.velocity_variance
        self.pos_cov = np.diag([pos[1], pos[0], pos[2]]).reshape(9)  # ENU
        # Errors off: the fix is the antenna truth to round-off and no variance describes it;
        # UNKNOWN (as the ideal streams' fixes) rather than an all-zero "known" covariance.
        self.pos_cov_type = (
            COVARIANCE_TYPE_DIAGONAL_KNOWN if np.any(pos > 0) else COVARIANCE_TYPE_UNKNOWN
        )
        twist = np.zeros(6)
        twist[:3] = [vel[1], vel[0], vel[2]]
        twist[3:] = NOT_MEASURED_VARIANCE
        self.twist_cov = np.diag(twist).reshape(36)
        self.pending: list[AidingOutput] = []

    def measure(self, truth: TruthRows) -> list[AidingOutput]:
        r_a, v_a = antenna_state(truth.r_e, truth.v_e, truth.c_b_e, truth.omega_eb_b, self.lever)
        dpos, dvel = self.model.take(len(truth.stamps_ns))
        meas = gnss_measurement(r_a, v_a, dpos, dvel)
        keep = np.ones(len(truth.stamps_ns), dtype=bool)
        for a, b in self.outages:
            keep &= ~((truth.stamps_ns >= a) & (truth.stamps_ns < b))
        sel = np.flatnonzero(keep)
        stamps = truth.stamps_ns[sel]
        n = len(sel)
        spec: GnssSpec = self.spec
        fix = navsatfix_fields_from_geodetic(
            stamps,
            meas.lat[sel],
            meas.lon[sel],
            meas.alt[sel],
            spec.frame_id or "gnss",
            position_covariance=self.pos_cov,
            position_covariance_type=self.pos_cov_type,
            status=spec.status_code,
            service=spec.service_code,
        )
        vel = TwistWithCovarianceStampedFields(
            stamps_ns=stamps,
            frame_id=spec.frame_id or "gnss",
            linear=meas.v_enu[sel],
            angular=np.zeros((n, 3)),
            covariance=np.broadcast_to(self.twist_cov, (n, 36)),
        )
        log = stamps + self.latency_ns
        if not n:  # every epoch inside an outage
            return []
        self.pending += [
            AidingOutput(AIDING_TOPICS["gnss_fix"], fix, log),
            AidingOutput(AIDING_TOPICS["gnss_vel"], vel, log),
        ]
        return []

    def release(self, last_truth_ns: int) -> list[AidingOutput]:
        if not self.pending or self.pending[0].log_ns[0] > last_truth_ns:
            return []  # the earliest held message is not due yet
        merged = _merge([self.pending])
        out, rest = [], []
        for o in merged:
            due = int(np.searchsorted(o.log_ns, last_truth_ns, side="right"))
            out.append(AidingOutput(o.topic, o.fields.rows(0, due), o.log_ns[:due]))
            if due < len(o.log_ns):
                rest.append(AidingOutput(o.topic, o.fields.rows(due, len(o.log_ns)),
                                         o.log_ns[due:]))  # fmt: skip
        self.pending = rest
        return [o for o in out if len(o.log_ns)]


class _Baro(_Channel):
    key = "barometer"
    error_model = BaroErrorModel

    def measure(self, truth: TruthRows) -> list[AidingOutput]:
        r_s, _ = antenna_state(truth.r_e, truth.v_e, truth.c_b_e, truth.omega_eb_b, self.lever)
        _, _, alt = ecef_to_geodetic(r_s)
        pressure = self.model.apply(icao_pressure(alt))
        n = len(pressure)
        fields = FluidPressureFields(
            stamps_ns=truth.stamps_ns,
            frame_id=self.spec.frame_id or "baro",
            fluid_pressure=pressure,
            variance=np.full(n, self.errors.variance),
        )
        return [AidingOutput(AIDING_TOPICS["baro"], fields, truth.stamps_ns)]


class _Mag(_Channel):
    key = "magnetometer"
    error_model = MagnetometerErrorModel

    def __init__(self, spec: MagnetometerSpec, t0_ns: int, frame_id: str, warn: Log) -> None:
        super().__init__(spec, t0_ns, warn)
        self.frame_id = spec.frame_id or frame_id
        self.g, self.h = igrf_coefficients(spec.year(t0_ns))
        self.cov = np.diag(self.errors.variance).reshape(9)  # diagonal: the same in FLU

    def model_field_body(self, truth: TruthRows) -> np.ndarray:
        """Model field (T) in body FRD at the IMU: ``C_E^B C_N^E B^N``."""
        lat, lon, _ = ecef_to_geodetic(truth.r_e)
        b_ned = igrf_field_ned(truth.r_e, lat, self.g, self.h) * 1e-9
        b_e = mat_vec(dcm_ned_to_ecef(lat, lon), b_ned)
        return mat_t_vec(truth.c_b_e, b_e)

    def measure(self, truth: TruthRows) -> list[AidingOutput]:
        measured = self.model.apply(self.model_field_body(truth))
        n = len(measured)
        fields = MagneticFieldFields(
            stamps_ns=truth.stamps_ns,
            frame_id=self.frame_id,
            magnetic_field=frd_to_flu(measured),
            magnetic_field_covariance=np.broadcast_to(self.cov, (n, 9)),
        )
        return [AidingOutput(AIDING_TOPICS["mag"], fields, truth.stamps_ns)]


class _Wheel(_Channel):
    key = "wheel_odometer"
    error_model = OdometerErrorModel

    def __init__(self, spec: WheelOdometerSpec, t0_ns: int, warn: Log) -> None:
        super().__init__(spec, t0_ns, warn)
        nhc = spec.nhc_sigma_mps**2
        diag = [self.errors.variance(self.period_s), nhc, nhc] + [NOT_MEASURED_VARIANCE] * 3
        self.cov = np.diag(diag).reshape(36)

    def measure(self, truth: TruthRows) -> list[AidingOutput]:
        v_c = contact_point_velocity(truth.v_e, truth.c_b_e, truth.omega_eb_b, self.lever)
        speed = self.model.apply(v_c[:, 0])
        n = len(speed)
        linear = np.zeros((n, 3))
        linear[:, 0] = speed  # FLU x = FRD x; y, z = 0: the non-holonomic constraint
        fields = TwistWithCovarianceStampedFields(
            stamps_ns=truth.stamps_ns,
            frame_id=self.spec.frame_id or "wheel",
            linear=linear,
            angular=np.zeros((n, 3)),
            covariance=np.broadcast_to(self.cov, (n, 36)),
        )
        return [AidingOutput(AIDING_TOPICS["wheel"], fields, truth.stamps_ns)]


class AidingStage:
    """Reference truth Odometry in (any chunking), aiding messages out; no rclpy.

    Parameters
    ----------
    scenario : Scenario
        Supplies the start time, the frames and (unless ``spec`` is given) the ``aiding``
        section.
    spec : AidingSpec, optional
        The section to simulate (default: the scenario's).
    truth_topic : str, optional
        The Odometry truth topic (default ``recording.topics.reference_odom``).
    warn : callable
        Logger for dropped (repeated or out-of-order) truth messages.

    Attributes
    ----------
    topics : list of str
        The topics produced, in output order.
    published : dict
        Messages produced per topic.
    """

    def __init__(
        self,
        scenario: Scenario,
        spec: AidingSpec | None = None,
        *,
        truth_topic: str | None = None,
        warn: Log = quiet,
        error: Log | None = None,
    ) -> None:
        spec = spec if spec is not None else scenario.aiding
        if spec is None:
            raise ScenarioError("aiding", "missing: the scenario defines no aiding sensors")
        self._setup(
            spec,
            scenario.start_time_ns,
            scenario.recording.frames["reference_imu"],
            truth_topic or scenario.recording.topics["reference_odom"],
            warn,
            warn if error is None else error,
            scenario.period_ns,
            scenario.recording.frames["earth"],
        )

    @classmethod
    def for_truth(
        cls,
        spec: AidingSpec,
        start_time_ns: int,
        body_frame: str,
        truth_topic: str = "/reference/odom",
        warn: Log = quiet,
    ) -> AidingStage:
        """A stream without a scenario: its start time, the IMU frame and the truth topic
        (e.g. the report re-running a bag's aiding section with its errors off)."""
        self = cls.__new__(cls)
        self._setup(spec, start_time_ns, body_frame, truth_topic, warn, warn, None, None)
        return self

    def _setup(self, spec: AidingSpec, t0: int, body: str, truth_topic: str, warn: Log,
               error: Log, period_ns: int | None, earth_frame: str | None) -> None:  # fmt: skip
        self.spec = spec
        self.truth_topic = truth_topic
        self.t0_ns, self.body_frame = t0, body
        self.period_ns, self.earth_frame = period_ns, earth_frame
        self.warn = warn
        #: Input events by class (flood-limited log lines; counted for the node's summary).
        self.events = InputEvents(warn, error)
        self.topics = spec.topics()
        self.published = dict.fromkeys(self.topics, 0)
        self.runs = 1
        self._start_channels()

    def _start_channels(self) -> None:
        """The sensors' error models from their seeds, epochs counted from the start."""
        spec, t0, warn = self.spec, self.t0_ns, self.warn
        self.channels: list[_Channel] = []
        sensors = spec.sensors()
        if "gnss" in sensors:
            self.channels.append(_Gnss(spec.gnss, t0, warn))  # type: ignore[arg-type]
        if "barometer" in sensors:
            self.channels.append(_Baro(spec.barometer, t0, warn))  # type: ignore[arg-type]
        if "magnetometer" in sensors:
            self.channels.append(_Mag(spec.magnetometer, t0, self.body_frame, warn))  # type: ignore[arg-type]
        if "wheel_odometer" in sensors:
            self.channels.append(_Wheel(spec.wheel_odometer, t0, warn))  # type: ignore[arg-type]
        self.last_truth_ns: int | None = None

    def _intake(self, odom: OdometryFields) -> list[OdometryFields]:
        """The truth messages fit to use, as the stretches of one run each: messages with a
        NaN, an infinity or a degenerate orientation, or in another frame than the Earth frame,
        are dropped (their epochs skipped); a stamp not after the last one is dropped, unless it
        jumps back more than :data:`~strapdown_ros.stages.intake.MAX_LATE_CYCLES` periods (the
        source restarted: the sensors restart from their seeds, a new run)."""
        topic = self.truth_topic
        odom, _ = screen(odom, topic, self.events, "dropped (its sensor epochs are skipped)")
        if odom is None:
            return []
        if self.earth_frame is not None and odom.frame_id != self.earth_frame:
            self.events("wrong frame", f"{topic}: stamp {stamp_span(odom.stamps_ns)}: "
                        f"header.frame_id {odom.frame_id!r} is not the Earth frame "
                        f"{self.earth_frame!r}; dropped", error=True)  # fmt: skip
            return []
        stamps = np.asarray(odom.stamps_ns, dtype=np.int64)
        last = self.last_truth_ns if self.last_truth_ns is not None else np.iinfo(np.int64).min
        before = np.maximum.accumulate(np.concatenate([[last], stamps]))[:-1]
        late = stamps <= before  # repeated or out of order
        period = self.period_ns
        if period is not None and late.any():
            jump = np.flatnonzero(late & (stamps < before - MAX_LATE_CYCLES * period))
            if jump.size:  # the source restarted at row r
                r = int(jump[0])
                head = [] if r == 0 else self._intake(odom.rows(0, r))
                self.events("restart", f"{topic}: stamp {format_stamp(int(stamps[r]))} jumps "
                            f"back from {format_stamp(int(before[r]))}: the source restarted; "
                            "the sensors restart from their seeds (a new run)")  # fmt: skip
                self.runs += 1
                return [*head, _RESTART, *self._intake(odom.rows(r, len(odom)))]
        if late.any():
            for a, b in stretches(late):
                what = "duplicate stamp" if stamps[a] == before[a] else "out-of-order stamp"
                self.events(what, f"{topic}: stamp {stamp_span(stamps[a : b + 1])} not after an "
                            "earlier one; dropped")  # fmt: skip
            odom = without_rows(odom, late)
            if odom is None:
                return []
        self.last_truth_ns = int(odom.stamps_ns[-1])
        return [odom]

    def feed_fields(self, odom: OdometryFields) -> list[AidingOutput]:
        """The aiding messages due after the truth messages ``odom`` (input faults:
        :meth:`_intake`, docs/reliability.md)."""
        if not len(odom):
            return []
        parts: list[list[AidingOutput]] = []
        for run in self._intake(odom):
            if run is _RESTART:
                parts.append(_merge([ch.release(self.last_truth_ns) for ch in self.channels])
                             if self.last_truth_ns is not None else [])  # fmt: skip
                self._start_channels()
                continue
            parts.append(self._epochs(run))
        out = [o for p in parts for o in p]
        order = {t: i for i, t in enumerate(self.topics)}
        out.sort(key=lambda o: order[o.topic])
        for o in out:
            self.published[o.topic] += len(o.log_ns)
        return out

    def _epochs(self, odom: OdometryFields) -> list[AidingOutput]:
        """The messages of the sensors' epochs among ``odom`` and those now released."""
        stamps = np.asarray(odom.stamps_ns, dtype=np.int64)
        assert self.last_truth_ns is not None
        # The truth state of the messages that are an epoch of some sensor (row by row: the
        # same numbers whatever rows are decoded together).
        epoch = np.zeros(len(stamps), dtype=bool)
        for ch in self.channels:
            epoch |= stamps % ch.period_ns == 0
        parts = []
        if np.any(epoch):
            st = odometry_state(_take_rows(odom, np.flatnonzero(epoch)))
            truth = TruthRows(st.stamps_ns, st.r_e, st.v_e, st.c_b_e, st.omega_eb_b)
            parts += [ch.feed(truth) for ch in self.channels]
        parts += [ch.release(self.last_truth_ns) for ch in self.channels]
        return _merge(parts)

    def feed(self, odom: OdometryFields) -> list[Batch]:
        """:meth:`feed_fields`, serialized: one :class:`Batch` per topic (log time = release)."""
        return [
            batch(o.topic, o.fields, log_ns=o.log_ns) for o in self.feed_fields(odom)
        ]

    def on_payloads(self, payloads: list[bytes | memoryview]) -> list[Batch]:
        """Serialized truth Odometry messages in, serialized aiding batches out (the node):
        decoded in one CDR call, or message by message when they do not decode together."""
        out: list[Batch] = []
        for _, odom in decode_runs(cdr.ODOMETRY, payloads, self.truth_topic, self.events):
            out += self.feed(odom)
        return out

    def feed_batches(self, batches: list[Batch]) -> list[Batch]:
        """``generate``'s path: the aiding batches of the truth topic's batch among ``batches``."""
        out: list[Batch] = []
        for b in batches:
            if b.topic == self.truth_topic and len(b.payloads):
                out += self.on_payloads(list(b.payloads))
        return out


#: Keys of a sensor that shape its messages (epochs, geometry, frames) but not its errors.
_STRUCTURAL_KEYS = (
    "enabled", "rate_hz", "lever_arm_m", "latency_s", "outages", "status", "constellations",
    "frame_id", "model", "decimal_year", "nhc_sigma_mps",
)  # fmt: skip


def error_free_spec(document: dict[str, Any]) -> AidingSpec:
    """The aiding section ``document`` with every error key removed (the truth of its sensors:
    same epochs, lever arms, outages, latency and frames)."""
    stripped = {
        sensor: {k: v for k, v in body.items() if k in _STRUCTURAL_KEYS}
        for sensor, body in document.items()
        if isinstance(body, dict)
    }
    return validate_section(AidingSpec, stripped, "aiding")  # type: ignore[return-value]


def epochs_in(start_ns: int, stop_ns: int, period_ns: int) -> int:
    """Number of epochs (multiples of ``period_ns``) in ``[start_ns, stop_ns]``."""
    if stop_ns < start_ns:
        return 0
    return stop_ns // period_ns - (-(-start_ns // period_ns)) + 1


def aiding_topic_plans(scenario: Scenario, spec: AidingSpec, cycles: int) -> list[TopicPlan]:
    """The aiding topics for truth cycles 0..``cycles`` (what ``generate`` writes): per topic its
    message count, first and last header stamps and log delay (the GNSS latency).

    Epochs in ``[t0, t0 + cycles T]``; GNSS: minus the epochs inside outages and those whose
    release time ``stamp + latency`` is after the last truth stamp.
    """
    t0 = scenario.start_time_ns
    t_end = t0 + cycles * scenario.period_ns
    out: list[TopicPlan] = []
    sensors = spec.sensors()
    for key, topics in (("gnss", ("gnss_fix", "gnss_vel")), ("barometer", ("baro",)),
                        ("magnetometer", ("mag",)), ("wheel_odometer", ("wheel",))):  # fmt: skip
        sensor = sensors.get(key)
        if sensor is None:
            continue
        p = sensor.period_ns
        delay = sensor.latency_ns if isinstance(sensor, GnssSpec) else 0
        stamps = np.arange(-(-t0 // p), (t_end - delay) // p + 1, dtype=np.int64) * p
        if isinstance(sensor, GnssSpec):
            keep = np.ones(len(stamps), dtype=bool)
            for a, b in sensor.outage_windows_ns(t0):
                keep &= ~((stamps >= a) & (stamps < b))
            stamps = stamps[keep]
        first, last = (int(stamps[0]), int(stamps[-1])) if stamps.size else (None, None)
        for t in topics:
            topic = AIDING_TOPICS[t]
            out.append(TopicPlan(topic, AIDING_MSGTYPES[topic], int(stamps.size), "aiding", None,
                                 first, last, delay))  # fmt: skip
    return out
