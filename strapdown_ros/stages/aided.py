"""The aided-INS stage: measured IMU, truth and aiding messages in, ``/aided/*`` messages out.

:class:`AidedStage` runs the filter of :mod:`strapdown_ros.core.aided` on serialized batches
(``feed_batches``, in any chunking and any interleaving of topics) exactly as a live node would
(docs/aided.md):

* **Time order, waiting.** The stage processes time τ only once every input due at or before
  τ by the scenario's schedule is *settled*: arrived, or lost because a later message of the
  same topic arrived. Inputs: the IMU (every cycle), the truth at the start and at the output
  epochs, each sensor at its epochs (GNSS: outside outages, arriving ``latency`` after the
  epoch). So the output is the same whatever the chunking or interleaving.
* **Measurements** are applied at their time of validity (the header stamp); one that arrives
  later (GNSS latency) rolls the filter back and re-runs it
  (:class:`~strapdown_ros.core.aided.engine.AidedFilter`). A message with a NaN or an infinity,
  off the sensor's epochs, before the filter's start, repeated or out of order is dropped and
  logged; one rejected by the χ² gate is logged with its stamp (and published as rejected).
* **Log-time rule.** Outputs at an output epoch t are logged at t; innovations and NIS have the
  measurement's stamp (its validity time) and are logged at its arrival (stamp + latency).

The filter starts at the first truth message at or after the scenario's start (normally the
start itself): truth plus a draw from N(0, P0) (``aided.seed``). A gap in the IMU ends the
filter (nothing is integrated across it; logged).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, header_stamps_ns, subset
from strapdown_ros.config import Scenario
from strapdown_ros.config.aided import SENSOR_SOURCE, AidedSpec, aided_spec
from strapdown_ros.config.aiding import AIDING_TOPICS, GnssSpec
from strapdown_ros.config.base import required_section
from strapdown_ros.config.imu_errors import ImuErrorsSpec
from strapdown_ros.core.aided.engine import AidedFilter, FilterSetup, Snapshots
from strapdown_ros.core.aided.initial import initial_covariance, initial_error, perturbed_state
from strapdown_ros.core.aided.layout import B_BARO_DRIFT, B_GNSS_POS, B_GNSS_VEL, B_WHEEL_QUANT
from strapdown_ros.core.aided.measurement_models import KINDS
from strapdown_ros.core.aided.model import FilterModel, SensorModels, StateOptions, build_model
from strapdown_ros.core.aided.outputs import nees, reported
from strapdown_ros.core.aided.schedule import NEVER, Schedule, count_in
from strapdown_ros.core.earth import (
    OMEGA_IE_VEC,
    dcm_ecef_to_ned,
    ecef_to_geodetic,
    geodetic_to_ecef,
)
from strapdown_ros.core.imu_errors import ImuErrorModel
from strapdown_ros.core.navigation.errors import (
    attitude_error_young,
    position_error_ned,
    velocity_error_ned,
)
from strapdown_ros.logs import Log, quiet
from strapdown_ros.messages import (
    COVARIANCE_TYPE_KNOWN,
    SERVICE_UNKNOWN,
    STATUS_FIX,
    STATUS_NO_FIX,
    TwistWithCovarianceStampedFields,
    imu_increments,
    navsatfix_fields_from_geodetic,
    odometry_fields_from_ecef,
    odometry_state,
    twist_covariance_flu,
    vector3_stamped_fields,
)
from strapdown_ros.plan.model import TopicPlan
from strapdown_ros.stages.intake import InputEvents, format_stamp, nonfinite_rows, without_rows

__all__ = [
    "AIDED_MSGTYPES",
    "AidedStage",
    "R_FLOOR",
    "aided_expected_counts",
    "aided_imu_topic",
    "aided_imu_errors",
    "aided_input_topics",
    "aided_output_topics",
    "aided_sensors",
    "aided_topic_plans",
    "aided_topic_types",
]

F64 = np.ndarray

#: Variance floors of a measurement whose message gives 0 (an ideal sensor): GNSS position m²,
#: velocity (m/s)², pressure Pa², field T², wheel (m/s)².
R_FLOOR = {
    "gnss_position": 1e-6,
    "gnss_velocity": 1e-6,
    "baro": 1e-4,
    "mag": 1e-18,
    "wheel": 1e-6,
}
#: Truth messages kept as start candidates before the filter starts (then: output epochs).
START_CANDIDATES = 16
#: Variance given to twist components not estimated (the angular part of ``/aided/vel``).
NOT_ESTIMATED_VARIANCE = 1e6
#: Message type of each output key (innovation and NIS topics are Vector3Stamped).
AIDED_MSGTYPES = {
    "odom": cdr.ODOMETRY,
    "fix": cdr.NAVSATFIX,
    "vel": cdr.TWIST_WITH_COVARIANCE_STAMPED,
}
#: Aiding topic key of each measurement.
_SOURCE_TOPIC = {
    "gnss_position": AIDING_TOPICS["gnss_fix"],
    "gnss_velocity": AIDING_TOPICS["gnss_vel"],
    "baro": AIDING_TOPICS["baro"],
    "mag": AIDING_TOPICS["mag"],
    "wheel": AIDING_TOPICS["wheel"],
}
_MSGTYPE = {
    "gnss_position": cdr.NAVSATFIX,
    "gnss_velocity": cdr.TWIST_WITH_COVARIANCE_STAMPED,
    "baro": cdr.FLUID_PRESSURE,
    "mag": cdr.MAGNETIC_FIELD,
    "wheel": cdr.TWIST_WITH_COVARIANCE_STAMPED,
}
_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # NED <-> ENU
_FLU = np.array([1.0, -1.0, -1.0])  # FRD <-> FLU
def _require(scenario: Scenario) -> AidedSpec:
    return required_section(scenario, "aided")


def aided_sensors(scenario: Scenario) -> list[str]:
    """The measurements the scenario's filter uses (canonical order)."""
    spec = _require(scenario)
    return spec.used_sensors(set() if scenario.aiding is None else set(scenario.aiding.sensors()))


def aided_output_topics(scenario: Scenario) -> dict[str, str]:
    """Output key -> topic of the scenario's filter (``odom``, ``nees``, ``nis_baro``, ...)."""
    return _require(scenario).output_topics(aided_sensors(scenario))


def aided_imu_topic(scenario: Scenario) -> str:
    """The measured IMU topic the filter integrates."""
    reference = scenario.recording.topics["reference_imu"]
    imu = _require(scenario).resolved_imu_topic(scenario.measured_imu_topics(), reference)
    assert imu is not None  # check_aided
    return imu


def aided_imu_errors(scenario: Scenario) -> ImuErrorsSpec:
    """The ``imu_errors`` model writing the filter's IMU topic (its matched Q and P0)."""
    spec = scenario.imu_errors_of(aided_imu_topic(scenario))
    assert spec is not None  # check_aided
    return spec


def aided_topic_types(scenario: Scenario) -> dict[str, str]:
    """Topic -> message type of the ``/aided/*`` topics of the scenario (empty without one)."""
    spec = aided_spec(scenario)
    if spec is None:
        return {}
    return {t: AIDED_MSGTYPES.get(k, cdr.VECTOR3_STAMPED)
            for k, t in aided_output_topics(scenario).items()}  # fmt: skip


def aided_input_topics(scenario: Scenario) -> list[str]:
    """The topics the stage reads: the measured IMU, the truth, the sensors used."""
    spec = _require(scenario)
    return [aided_imu_topic(scenario), spec.truth_topic,
            *(_SOURCE_TOPIC[s] for s in aided_sensors(scenario))]  # fmt: skip


def _merged(windows: Sequence[tuple[int, int]]) -> tuple[tuple[int, int], ...]:
    out: list[list[int]] = []
    for a, b in sorted(windows):
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return tuple((a, b) for a, b in out)


def _sensor_schedule(scenario: Scenario, sensor: str, end_ns: int = NEVER) -> Schedule:
    assert scenario.aiding is not None
    spec = scenario.aiding.sensors()[SENSOR_SOURCE[sensor]]
    t0 = scenario.start_time_ns
    if isinstance(spec, GnssSpec):
        return Schedule(spec.period_ns, t0, spec.latency_ns,
                        _merged(spec.outage_windows_ns(t0)), end_ns)  # fmt: skip
    return Schedule(spec.period_ns, t0, 0, (), end_ns)


def aided_expected_counts(scenario: Scenario, cycles: int) -> dict[str, int]:
    """Messages per ``/aided/*`` topic for reference cycles 0..``cycles`` (what the stage
    publishes on complete input): one per output epoch in ``[t0, t0 + cycles T]`` on the base
    topics; one innovation and one NIS per measurement message the aiding stage publishes."""
    spec = aided_spec(scenario)
    if spec is None:
        return {}
    t0 = scenario.start_time_ns
    t_end = t0 + cycles * scenario.period_ns
    topics = aided_output_topics(scenario)
    n_out = count_in(t0, t_end, spec.output_period_ns)
    out = {t: n_out for k, t in topics.items() if not k.startswith(("innovation_", "nis_"))}
    for s in aided_sensors(scenario):
        n = _sensor_schedule(scenario, s).count(t_end)
        out[topics[f"innovation_{s}"]] = n
        out[topics[f"nis_{s}"]] = n
    return out


def aided_topic_plans(scenario: Scenario, cycles: int, link: str = "aided") -> list[TopicPlan]:
    """The ``/aided/*`` topics for reference cycles 0..``cycles`` as the chain's
    :class:`~strapdown_ros.plan.model.TopicPlan` rows (the ``outputs`` of a chain link): counts
    of :func:`aided_expected_counts`; the output topics' first and last stamps (the output
    epochs in ``[t0, t0 + cycles T]``); innovation and NIS topics logged ``latency`` after their
    stamps."""
    spec = aided_spec(scenario)
    if spec is None:
        return []
    counts = aided_expected_counts(scenario, cycles)
    types = aided_topic_types(scenario)
    t0 = scenario.start_time_ns
    p = spec.output_period_ns
    first = -(-t0 // p) * p
    last = (t0 + cycles * scenario.period_ns) // p * p
    latency = {s: _sensor_schedule(scenario, s).latency_ns for s in aided_sensors(scenario)}
    out = []
    for key, topic in aided_output_topics(scenario).items():
        n = counts[topic]
        if key.startswith(("innovation_", "nis_")):
            sensor = key.split("_", 1)[1]
            out.append(TopicPlan(topic, types[topic], n, link, None, None, None,
                                 latency[sensor]))  # fmt: skip
        else:
            out.append(TopicPlan(topic, types[topic], n, link, None,
                                 first if n else None, last if n else None))  # fmt: skip
    return out


# --------------------------------------------------------------------------------------------
# Inputs held until processed
# --------------------------------------------------------------------------------------------


@dataclass
class _Topic:
    """Per-topic bookkeeping: the latest arrival (log time) seen and the schedule."""

    name: str
    schedule: Schedule | None
    latest: int | None = None
    last: dict[str, int | None] = field(default_factory=dict)


def velocity_fields(stamps: np.ndarray, frame_id: str, rep: Any) -> Any:
    """The ``P/vel`` messages: the NED velocity of ``rep`` (:class:`~strapdown_ros.core.aided.
    outputs.Reported`) as ENU with its covariance; the angular part is not estimated
    (:data:`NOT_ESTIMATED_VARIANCE`)."""
    k = len(stamps)
    vcov = np.zeros((k, 6, 6))
    vcov[:, :3, :3] = _ENU @ rep.vel_cov_ned @ _ENU
    vcov[:, 3:, 3:] = np.eye(3) * NOT_ESTIMATED_VARIANCE
    return TwistWithCovarianceStampedFields(
        stamps_ns=stamps, frame_id=frame_id, linear=rep.v_ned @ _ENU, angular=np.zeros((k, 3)),
        covariance=vcov.reshape(k, 36))  # fmt: skip


class AidedStage:
    """The aided filter on serialized messages (see the module docstring).

    Parameters
    ----------
    scenario : Scenario
        With an enabled ``aided`` section (and the ``imu_errors``/``aiding`` sections it uses).
    info, warn, error : callables
        Log sinks.

    Attributes
    ----------
    rejections : list of (sensor, stamp_ns, nis)
        Measurements rejected by the χ² gate.
    published : dict
        Messages produced per topic.
    """

    def __init__(self, scenario: Scenario, *, info: Log = quiet, warn: Log = quiet,
                 error: Log = quiet) -> None:  # fmt: skip
        self.scenario = scenario
        self.spec = spec = _require(scenario)
        self.info, self.warn, self.error = info, warn, error
        self.events = InputEvents(warn, error)
        self.t0 = scenario.start_time_ns
        self.T = scenario.period_ns
        self.imu_topic = aided_imu_topic(scenario)
        self.truth_topic = spec.truth_topic
        self.sensors = aided_sensors(scenario)
        self.topics = aided_output_topics(scenario)
        self.published = dict.fromkeys(self.topics.values(), 0)
        self.earth_frame = scenario.recording.frames["earth"]
        self.body_frame = scenario.recording.frames["reference_imu"]
        self.rejections: list[tuple[str, int, float]] = []
        self.model, self.sensor_models = self._model()
        self.out_period = spec.output_period_ns
        # inputs
        self._in: dict[str, _Topic] = {}
        self._in[self.imu_topic] = _Topic(self.imu_topic, None)
        self._in[self.truth_topic] = _Topic(self.truth_topic, None)
        self._sensor_of_topic: dict[str, list[str]] = {}
        for s in self.sensors:
            t = _SOURCE_TOPIC[s]
            self._in[t] = _Topic(t, _sensor_schedule(scenario, s))
            self._sensor_of_topic.setdefault(t, []).append(s)
        self.latency = {s: self._in[_SOURCE_TOPIC[s]].schedule.latency_ns for s in self.sensors}
        self._imu: list[tuple[int, F64, F64]] = []  # (stamp, dα, dv) not given to the filter
        self._imu_last: int | None = None
        self._imu_frame: str | None = None
        self._truth: dict[int, tuple[F64, ...]] = {}  # stamp -> (r_e, v_e, c_b_e, ω)
        self._candidates = 0
        #: measurements not given to the filter yet: (kind, stamps, arrivals, z, R, dims)
        self._pending: list[tuple[np.ndarray, ...]] = []
        self.filter: AidedFilter | None = None
        self.start_ns: int | None = None
        self.stopped = False
        self._done_until: int | None = None
        self._uid = 0
        self._outputs: list[dict[str, Any]] = []
        self._results: dict[str, list[tuple]] = {}

    # -- setup --------------------------------------------------------------------------------

    def _model(self) -> tuple[FilterModel, SensorModels]:
        sc, spec = self.scenario, self.spec
        params = aided_imu_errors(sc).parameters()
        sensors = sc.aiding.sensors() if sc.aiding is not None else {}
        used = {SENSOR_SOURCE[s] for s in self.sensors}
        sm = SensorModels(
            gnss=sensors["gnss"].errors() if "gnss" in used else None,
            baro=sensors["barometer"].errors() if "barometer" in used else None,
            mag=sensors["magnetometer"].errors() if "magnetometer" in used else None,
            wheel=sensors["wheel_odometer"].errors() if "wheel_odometer" in used else None,
            wheel_period_s=(sensors["wheel_odometer"].period_ns * 1e-9
                            if "wheel_odometer" in used else 0.0),
        )  # fmt: skip
        options = StateOptions(spec.states.gauss_markov, spec.states.scale_factors,
                               spec.states.sensor_errors)  # fmt: skip
        model = build_model(params, self.T * 1e-9, sm, options).scaled(spec.tuning.q_scale)
        self._rate_variance = ImuErrorModel(params, self.T * 1e-9).rate_noise_variance()[0]
        return model, sm

    def _setup(self, start_ns: int) -> FilterSetup:
        sc, spec = self.scenario, self.spec
        levers = np.zeros((5, 3))
        periods = [spec.covariance_period_ns // self.T, self.out_period // self.T]
        window = 0
        igrf = None
        sensors = sc.aiding.sensors() if sc.aiding is not None else {}
        for k, s in enumerate(KINDS):
            if s not in self.sensors:
                continue
            src = sensors[SENSOR_SOURCE[s]]
            periods.append(src.period_ns // self.T)
            if hasattr(src, "lever_arm_m"):
                levers[k] = src.lever_arm_m  # type: ignore[attr-defined]
            lat = self.latency[s]
            if lat:
                window = max(window, -(-lat // self.T) + 1)
            if s == "mag":
                from strapdown_ros.stages.aiding import igrf_coefficients

                igrf = igrf_coefficients(src.year(sc.start_time_ns))  # type: ignore[attr-defined]
        mask = {"both": (True, True, True), "lateral": (True, True, False),
                "none": (True, False, False)}[spec.wheel_constraints]  # fmt: skip
        return FilterSetup(
            period_ns=self.T, start_cycle=start_ns // self.T, grid_periods=tuple(periods),
            levers=levers, wheel_mask=np.array(mask), igrf=igrf,
            gate_probability=spec.gate_probability, window_cycles=window,
            gravity_model=str(sc.gravity_model), gravity_steps=spec.gravity_steps,
            output_period=self.out_period // self.T,
        )  # fmt: skip

    def _start(self, stamp: int) -> None:
        r_e, v_e, c_b_e, _ = self._truth[stamp]
        lat, lon, _ = ecef_to_geodetic(r_e)
        sig = self.spec.initial_sigma
        pos, vel = np.array(sig.position_m), np.array(sig.velocity_mps)
        att = np.radians(np.array(sig.attitude_deg))
        r0 = np.array(r_e, dtype=np.float64)
        v0 = np.asarray(v_e) + np.cross(OMEGA_IE_VEC, r0)  # inertial velocity, E0 = E at start
        dx = initial_error(self.spec.seed, float(lat), float(lon), pos, vel, att)
        r, v, c = perturbed_state(r0, v0, np.asarray(c_b_e), dx)
        p0 = initial_covariance(self.model, float(lat), float(lon), pos, vel, att)
        self.filter = AidedFilter(self.model, self._setup(stamp), r, v, c, p0)
        self.start_ns = stamp
        self.info(f"aided: filter starts at {format_stamp(stamp)} ({self.model.layout.n} states)")

    @property
    def done_until(self) -> int | None:
        """The latest time (ns) processed so far (None: none): every output logged up to it
        has been returned (the live node is done once it reaches the last IMU stamp)."""
        return self._done_until

    # -- input ----------------------------------------------------------------------------------

    def feed_batches(self, batches: Sequence[Batch]) -> list[Batch]:
        """Serialized batches in (any topics, any chunking); the ``/aided/*`` batches now
        complete out (log times as Batch stamps)."""
        for b in batches:
            if b.topic in self._in and len(b.payloads):
                self._take(b)
        self._process(self._settled())
        return self._serialize()

    def flush(self) -> list[Batch]:
        """End of input: every input still due is lost; process and return what is left."""
        self._process(NEVER, final=True)
        return self._serialize()

    def _decode(self, b: Batch, msgtype: str) -> list[Any]:
        """The batch decoded at once, or message by message (a bad message alone dropped)."""
        try:
            fields = cdr.deserialize(msgtype, list(b.payloads))
            return [(np.asarray(b.stamps_ns, dtype=np.int64), fields)]
        except Exception:  # noqa: BLE001 - each message gets its own verdict
            out = []
            for t, p in zip(b.stamps_ns, b.payloads, strict=True):
                try:
                    out.append((np.array([t], dtype=np.int64), cdr.deserialize(msgtype, [p])))
                except Exception as exc:  # noqa: BLE001
                    self.events("malformed", f"{b.topic}: a message does not decode ({exc}); "
                                "dropped", error=True)  # fmt: skip
            return out

    def _take(self, b: Batch) -> None:
        top = self._in[b.topic]
        if b.topic == self.imu_topic:
            for log, f in self._decode(b, cdr.IMU):
                self._take_imu(f)
                top.latest = max(top.latest or log[-1], int(log[-1]))
        elif b.topic == self.truth_topic:
            latest = int(np.max(b.stamps_ns))
            needed = self._needed_truth_messages(b)
            if len(needed.payloads):
                for _, f in self._decode(needed, cdr.ODOMETRY):
                    self._take_truth(f)
            top.latest = latest if top.latest is None else max(top.latest, latest)
        else:
            sensors = self._sensor_of_topic[b.topic]
            for log, f in self._decode(b, _MSGTYPE[sensors[0]]):
                for s in sensors:
                    self._take_sensor(s, f, top)
                top.latest = max(top.latest or log[-1], int(log[-1]))

    def _take_imu(self, f: Any) -> None:
        stamps = np.asarray(f.stamps_ns, dtype=np.int64)
        if self._imu_frame is None:
            self._imu_frame = f.frame_id
        elif f.frame_id != self._imu_frame:
            self.events("wrong frame", f"{self.imu_topic}: frame_id {f.frame_id!r} differs from "
                        f"{self._imu_frame!r}; dropped", error=True)  # fmt: skip
            return
        bad = nonfinite_rows(f)
        inc = imu_increments(f, self.T)
        for i, t in enumerate(stamps.tolist()):
            if bad is not None and bad[i]:
                self.events("non-finite", f"{self.imu_topic}: stamp {format_stamp(t)}: NaN or "
                            "infinity; dropped (a gap: the filter stops there)",
                            error=True)  # fmt: skip
                continue
            if (t - self.t0) % self.T or t <= self.t0:
                self.events("off-grid stamp", f"{self.imu_topic}: stamp {format_stamp(t)} is not "
                            "a cycle of the scenario; dropped", error=True)  # fmt: skip
                continue
            if self._imu_last is not None and t <= self._imu_last:
                self.events("out-of-order stamp", f"{self.imu_topic}: stamp {format_stamp(t)} "
                            f"not after {format_stamp(self._imu_last)}; dropped")  # fmt: skip
                continue
            self._imu_last = t
            self._imu.append((t, inc.dalpha[i], inc.dv[i]))

    def _needed_truth_messages(self, b: Batch) -> Batch:
        """The messages of a truth batch whose header stamp (read from the CDR bytes) the
        filter needs: every cycle until it starts, then the output epochs."""
        t = header_stamps_ns(b)
        if t is None:
            return b
        on_output = (t % self.out_period == 0) & (t >= (self.start_ns or self.t0))
        if self.filter is None:  # the first few start candidates, then the output epochs
            cand = np.flatnonzero((t >= self.t0) & ((t - self.t0) % self.T == 0))
            room = max(0, START_CANDIDATES - self._candidates)
            on_output[cand[:room]] = True
            self._candidates += min(room, len(cand))
        return subset(b, on_output)

    def _take_truth(self, f: Any) -> None:
        if f.frame_id != self.earth_frame:
            self.events("wrong frame", f"{self.truth_topic}: frame_id {f.frame_id!r} is not "
                        f"{self.earth_frame!r}; dropped (lost)", error=True)  # fmt: skip
            return
        bad = nonfinite_rows(f)
        stamps = np.asarray(f.stamps_ns, dtype=np.int64)
        keep = [i for i in range(len(stamps)) if bad is None or not bad[i]]
        if bad is not None:
            self.events("non-finite", f"{self.truth_topic}: {int(bad.sum())} message(s) with a "
                        "NaN or an infinity dropped (lost)")  # fmt: skip
        if not keep:
            return
        drop = np.ones(len(stamps), dtype=bool)
        drop[keep] = False
        st = odometry_state(without_rows(f, drop))
        for j, i in enumerate(keep):
            self._truth[int(stamps[i])] = (st.r_e[j], st.v_e[j], st.c_b_e[j], st.omega_eb_b[j])

    def _take_sensor(self, sensor: str, f: Any, top: _Topic) -> None:
        stamps = np.asarray(f.stamps_ns, dtype=np.int64)
        sched = top.schedule
        assert sched is not None
        name = f"{top.name} ({sensor})"
        bad = nonfinite_rows(f)
        bad = np.zeros(len(stamps), dtype=bool) if bad is None else bad
        epoch = (stamps % sched.period_ns == 0) & (stamps >= sched.start_ns)
        for a, b in sched.outages:
            epoch &= ~((stamps >= a) & (stamps < b))
        last = top.last.get(sensor)
        prev = np.maximum.accumulate(np.concatenate([[-1 if last is None else last], stamps]))
        order = stamps > prev[:-1]  # not after an earlier stamp: dropped
        late = np.zeros(len(stamps), dtype=bool)
        if self._done_until is not None:
            late = stamps + sched.latency_ns <= self._done_until
        keep = ~bad & epoch & order & ~late
        if not keep.all():
            for i in np.flatnonzero(~keep).tolist():
                t = int(stamps[i])
                if bad[i]:
                    self.events("non-finite", f"{name}: stamp {format_stamp(t)}: NaN or "
                                "infinity; dropped")  # fmt: skip
                elif not epoch[i]:
                    self.events("off-grid stamp", f"{name}: stamp {format_stamp(t)} is not an "
                                "epoch of the sensor; dropped", error=True)  # fmt: skip
                elif not order[i]:
                    self.events("out-of-order stamp", f"{name}: stamp {format_stamp(t)} not "
                                "after an earlier one; dropped")  # fmt: skip
                else:
                    self.events("late", f"{name}: stamp {format_stamp(t)} arrived after the "
                                "filter passed its arrival time; dropped")  # fmt: skip
        idx = np.flatnonzero(keep)
        if not idx.size:
            return
        top.last[sensor] = int(stamps[idx[-1]])
        z, r = self._measurements(sensor, f, idx)
        k, d = len(idx), r.shape[1]
        zz = np.zeros((k, 6))
        zz[:, : z.shape[1]] = z
        rr = np.zeros((k, 3, 3))
        rr[:, :d, :d] = r
        st = stamps[idx]
        self._pending.append((np.full(k, KINDS.index(sensor), dtype=np.int64), st,
                              st + sched.latency_ns, zz, rr,
                              np.full(k, d, dtype=np.int64)))  # fmt: skip

    def _measurements(self, sensor: str, f: Any, idx: np.ndarray) -> tuple[F64, F64]:
        """Model inputs ``z`` (k, ·) and covariances R (k, d, d) of messages ``idx`` (after the
        modelled correlated parts, floors and tuning)."""
        lay = self.model.layout
        sm = self.sensor_models
        if sensor == "gnss_position":
            lat, lon = np.radians(f.latitude[idx]), np.radians(f.longitude[idx])
            r_e = geodetic_to_ecef(lat, lon, np.asarray(f.altitude[idx]))
            z = np.column_stack([r_e, lat, lon])
            r = _ENU @ np.asarray(f.position_covariance[idx]).reshape(-1, 3, 3) @ _ENU
            if lay.has(B_GNSS_POS):
                r = r - np.diag(np.asarray(sm.gnss.position_gm_sigma) ** 2)  # type: ignore[union-attr]
        elif sensor == "gnss_velocity":
            z = np.asarray(f.linear[idx]) @ _ENU
            r = _ENU @ np.asarray(f.covariance[idx]).reshape(-1, 6, 6)[:, :3, :3] @ _ENU
            if lay.has(B_GNSS_VEL):
                r = r - np.diag(np.asarray(sm.gnss.velocity_gm_sigma) ** 2)  # type: ignore[union-attr]
        elif sensor == "baro":
            z = np.asarray(f.fluid_pressure[idx])[:, None]
            var = np.asarray(f.variance[idx], dtype=np.float64).copy()
            if lay.has(B_BARO_DRIFT):
                var -= sm.baro.drift_sigma ** 2  # type: ignore[union-attr]
            r = var[:, None, None]
        elif sensor == "mag":
            z = np.asarray(f.magnetic_field[idx]) * _FLU
            cov = np.asarray(f.magnetic_field_covariance[idx]).reshape(-1, 3, 3)
            r = cov * _FLU[:, None] * _FLU[None, :]
        else:
            z = np.asarray(f.linear[idx]) * _FLU
            cov = np.asarray(f.covariance[idx]).reshape(-1, 6, 6)[:, :3, :3]
            mask = self._setup_mask()
            r = (cov * _FLU[:, None] * _FLU[None, :])[:, mask][:, :, mask]
            if lay.has(B_WHEEL_QUANT):  # the speed's quantization is in the states
                r[:, 0, 0] -= sm.wheel.quantization_variance(sm.wheel_period_s)  # type: ignore[union-attr]
        return z, self._tuned(sensor, r)

    def _setup_mask(self) -> np.ndarray:
        return np.array({"both": (True, True, True), "lateral": (True, True, False),
                         "none": (True, False, False)}[self.spec.wheel_constraints])  # fmt: skip

    def _tuned(self, sensor: str, r: F64) -> F64:
        """R (k, d, d): ``r_sigma`` if given, else the messages' (symmetric, diagonal floored)
        times ``r_scale``."""
        tuning = self.spec.tuning
        k, d = r.shape[0], r.shape[1]
        if sensor in tuning.r_sigma:
            return np.broadcast_to(np.eye(d) * tuning.r_sigma[sensor] ** 2, (k, d, d)).copy()
        r = 0.5 * (r + np.swapaxes(r, -1, -2))
        ii = np.arange(d)
        diag = r[:, ii, ii]
        r[:, ii, ii] = np.where(diag > R_FLOOR[sensor], diag, R_FLOOR[sensor])
        return r * tuning.r_scale.get(sensor, 1.0)

    # -- time ---------------------------------------------------------------------------------

    def _settled(self) -> int:
        """The latest τ up to which every input due is settled."""
        tau = NEVER
        tau = min(tau, self._imu_last if self._imu_last is not None else self.t0 - 1)
        truth = self._in[self.truth_topic].latest
        nxt = self._next_truth_needed(truth)
        tau = min(tau, max(truth if truth is not None else self.t0 - 1, nxt - 1))
        for top in self._in.values():
            if top.schedule is not None:
                tau = min(tau, top.schedule.settled_until(top.latest))
        return tau

    def _next_truth_needed(self, latest: int | None) -> int:
        base = self.t0 - 1 if latest is None else latest
        if self.filter is None:
            return max(self.t0, base + 1) if latest is None else base + self.T
        return (base // self.out_period + 1) * self.out_period

    def _cycle(self, t: int) -> int:
        assert self.start_ns is not None
        return (t - self.start_ns) // self.T

    def _process(self, tau: int, final: bool = False) -> None:
        if self.stopped:
            return
        if self.filter is None and not self._try_start(tau, final):
            return
        f = self.filter
        assert f is not None and self.start_ns is not None
        # IMU up to τ, stopping at a gap
        last_imu = self.start_ns + f.imu_end * self.T
        self._imu = [x for x in self._imu if x[0] > self.start_ns]
        take = []
        for item in self._imu:
            if item[0] != last_imu + self.T:
                if item[0] > last_imu + self.T:
                    self.events("gap", f"{self.imu_topic}: IMU gap after "
                                f"{format_stamp(last_imu)} (next {format_stamp(item[0])}); the "
                                "aided filter stops (nothing is integrated across a gap)",
                                error=True)  # fmt: skip
                    self.stopped = True
                break
            take.append(item)
            last_imu = item[0]
        self._imu = self._imu[len(take):] if not self.stopped else []
        if take:
            f.add_imu(np.array([x[1] for x in take]), np.array([x[2] for x in take]))
        end = min(tau, last_imu)
        # measurements: zero-latency ones are inserted up front, delayed ones at their arrival
        ready = self._ready(end)
        if ready is not None:
            kind, st, arr, z, r, dim = ready
            direct = arr == st
            if direct.any():
                self._insert(f, kind[direct], st[direct], z[direct], r[direct], dim[direct])
            delayed = np.flatnonzero(~direct)
            if delayed.size:
                # by arrival, then (stamp, kind): the order a live filter receives them in
                key = np.lexsort((kind[delayed], st[delayed], arr[delayed]))
                delayed = delayed[key]
                groups = np.split(delayed, np.flatnonzero(np.diff(arr[delayed])) + 1)
                for g in groups:
                    when = int(arr[g[0]])
                    m = self._cycle(when)
                    f.advance(m)
                    if self.start_ns + m * self.T < when:  # arrival between cycles
                        f.record_now()
                    self._insert(f, kind[g], st[g], z[g], r[g], dim[g])
                    f.make_posterior()
                    self._collect()
        if end >= self.start_ns:
            f.advance(self._cycle(end))
            f.record_now()
        self._collect()
        self._done_until = end
        snaps = f.outputs()
        if len(snaps.m):
            self._outputs.append(self._state_fields(snaps))
        if final and self._pending:
            for p in self._pending:
                for t, k in zip(p[1].tolist(), p[0].tolist(), strict=True):
                    self.warn(f"aided: {KINDS[k]} at {format_stamp(t)} arrives after the last "
                              "IMU message; not processed")  # fmt: skip
            self._pending = []

    def _ready(self, end: int) -> tuple[np.ndarray, ...] | None:
        """The pending measurements arriving at or before ``end`` (arrays; removed from the
        pending ones), without those before the filter's start (dropped, logged)."""
        if not self._pending:
            return None
        cat = [np.concatenate([p[i] for p in self._pending]) for i in range(6)]
        now = cat[2] <= end
        rest = ~now
        self._pending = [tuple(a[rest] for a in cat)] if rest.any() else []
        if not now.any():
            return None
        out = [a[now] for a in cat]
        assert self.start_ns is not None
        early = out[1] < self.start_ns
        for t, k in zip(out[1][early].tolist(), out[0][early].tolist(), strict=True):
            self.events("before start", f"aided: {KINDS[k]} at {format_stamp(t)} is before the "
                        "filter's start; dropped")  # fmt: skip
        return tuple(a[~early] for a in out) if (~early).any() else None

    def _insert(self, f: AidedFilter, kind: np.ndarray, st: np.ndarray, z: F64, r: F64,
                dim: np.ndarray) -> None:  # fmt: skip
        k = len(kind)
        uid = np.arange(self._uid + 1, self._uid + 1 + k)
        self._uid += k
        f.insert_arrays(kind, self._cycle_array(st), z, r, dim, uid)

    def _cycle_array(self, t: np.ndarray) -> np.ndarray:
        assert self.start_ns is not None
        return (t - self.start_ns) // self.T

    def _collect(self) -> None:
        assert self.filter is not None and self.start_ns is not None
        res = self.filter.collect()
        if not len(res.uid):
            return
        for code in np.unique(res.kind).tolist():
            s = KINDS[code]
            sel = np.flatnonzero(res.kind == code)
            stamps = self.start_ns + res.m[sel] * self.T
            arrival = stamps + self.latency[s]
            self._results.setdefault(s, []).append(
                (stamps, arrival, res.innovation[sel], res.nis[sel], res.dof[sel],
                 res.accepted[sel]))  # fmt: skip
            for j in np.flatnonzero(~res.accepted[sel]):
                self.rejections.append((s, int(stamps[j]), float(res.nis[sel][j])))
                self.warn(f"aided: {s} at stamp {format_stamp(int(stamps[j]))} rejected by the "
                          f"χ² gate (NIS {res.nis[sel][j]:.4g}, {res.dof[sel][j]} dof, p = "
                          f"{self.spec.gate_probability:g})")  # fmt: skip

    def _try_start(self, tau: int, final: bool) -> bool:
        """Start at the first settled truth stamp with its next IMU message received."""
        cands = sorted(t for t in self._truth if t <= tau)
        for t in cands:
            if any(s == t + self.T for s, _, _ in self._imu):
                for s in [s for s in self._truth if s < t]:
                    del self._truth[s]
                self._start(t)
                return True
            if final:
                continue
            break
        return False

    # -- output -------------------------------------------------------------------------------

    def _serialize(self) -> list[Batch]:
        out: list[Batch] = []
        if self._outputs:
            merged: dict[str, Any] = {}
            for part in self._outputs:
                for key, fields in part.items():
                    merged[key] = fields if key not in merged else merged[key].append(fields)
            self._outputs = []
            out += [self._batch(key, fields) for key, fields in merged.items()]
        for s in self.sensors:
            parts = self._results.pop(s, None)
            if parts:
                cat = [np.concatenate([p[i] for p in parts]) for i in range(6)]
                out += self._result_batches(s, *cat)
        for b in out:
            self.published[b.topic] += len(b.payloads)
        return out

    def _batch(self, key: str, fields: Any, log_ns: np.ndarray | None = None) -> Batch:
        stamps = np.asarray(fields.stamps_ns, dtype=np.int64) if log_ns is None else log_ns
        return Batch(self.topics[key], cdr.msgtype_of(fields), stamps, cdr.serialize(fields))

    def _state_fields(self, snaps: Snapshots) -> dict[str, Any]:
        """Field containers of the output topics at the stored output epochs."""
        assert self.start_ns is not None
        stamps = self.start_ns + snaps.m * self.T
        t = (snaps.m * self.T) * 1e-9
        rep = reported(t, snaps.nav, snaps.est, snaps.p, self.model.layout, self.T * 1e-9,
                       self._rate_variance)  # fmt: skip
        k = len(stamps)
        frame = self.spec.frame_id
        twist = twist_covariance_flu(rep.twist_cov_frd)
        out: dict[str, Any] = {"odom": odometry_fields_from_ecef(
            stamps, rep.r_e, rep.v_e, rep.c_b_e, rep.omega_eb_b, frame, self.earth_frame,
            pose_covariance=rep.pose_cov.reshape(k, 36), twist_covariance=twist.reshape(k, 36))}
        cen = dcm_ecef_to_ned(rep.lat, rep.lon).reshape(k, 3, 3)
        p_e = rep.pose_cov[:, :3, :3]
        enu_pos = _ENU @ cen @ p_e @ np.swapaxes(cen, -1, -2) @ _ENU
        gnss = "gnss_position" in self.sensors or "gnss_velocity" in self.sensors
        service = SERVICE_UNKNOWN
        if gnss:
            service = self.scenario.aiding.gnss.service_code  # type: ignore[union-attr]
        out["fix"] = navsatfix_fields_from_geodetic(
            stamps, rep.lat, rep.lon, rep.alt, frame, position_covariance=enu_pos.reshape(k, 9),
            position_covariance_type=COVARIANCE_TYPE_KNOWN,
            status=STATUS_FIX if gnss else STATUS_NO_FIX, service=service)  # fmt: skip
        out["vel"] = velocity_fields(stamps, frame, rep)
        have = np.array([int(s) in self._truth for s in stamps])
        for s in stamps[~have]:
            self.events("truth lost", f"{self.truth_topic}: no truth at output stamp "
                        f"{format_stamp(int(s))}; no error or NEES messages for it")  # fmt: skip
        if have.any():
            sel = np.flatnonzero(have)
            rows = [self._truth[int(s)] for s in stamps[sel]]
            r_true = np.array([r[0] for r in rows])
            v_true_e = np.array([r[1] for r in rows])
            c_true = np.array([r[2] for r in rows])
            lat, lon, _ = ecef_to_geodetic(r_true)
            c_true_en = dcm_ecef_to_ned(lat, lon).reshape(-1, 3, 3)
            dr = position_error_ned(rep.r_e[sel], r_true, lat, lon)
            dv = velocity_error_ned(rep.v_ned[sel], np.einsum("kij,kj->ki", c_true_en, v_true_e))
            da = attitude_error_young(cen[sel] @ rep.c_b_e[sel], c_true_en @ c_true)
            st = stamps[sel]
            nees_v = np.stack([nees(dr, rep.pos_cov_ned[sel]), nees(dv, rep.vel_cov_ned[sel]),
                               nees(da, rep.att_cov_young[sel])], axis=-1)  # fmt: skip
            out["error_position"] = vector3_stamped_fields(st, dr, "ned")
            out["error_velocity"] = vector3_stamped_fields(st, dv, "ned")
            out["error_attitude"] = vector3_stamped_fields(st, da, "young_uen")
            out["nees"] = vector3_stamped_fields(st, nees_v, "nees")
        body = self.body_frame
        out["bias_gyro"] = vector3_stamped_fields(stamps, rep.gyro_bias * _FLU, body)
        out["bias_accel"] = vector3_stamped_fields(stamps, rep.accel_bias * _FLU, body)
        out["bias_gyro_sigma"] = vector3_stamped_fields(stamps, rep.gyro_bias_sigma, body)
        out["bias_accel_sigma"] = vector3_stamped_fields(stamps, rep.accel_bias_sigma, body)
        last = int(stamps[-1])
        for s in [s for s in self._truth if s <= last]:
            del self._truth[s]
        return out

    def _result_batches(self, sensor: str, stamps: np.ndarray, log: np.ndarray, inno: F64,
                        nis: F64, dof: np.ndarray, accepted: np.ndarray) -> list[Batch]:
        inno = inno.copy()
        if sensor in ("gnss_position", "gnss_velocity"):
            inno, frame = inno @ _ENU, "enu"
        elif sensor in ("mag", "wheel"):
            if sensor == "wheel":  # the rows used, placed back on their axes
                mask = self._setup_mask()
                full = np.zeros_like(inno)
                full[:, mask] = inno[:, : int(mask.sum())]
                inno = full
            inno, frame = inno * _FLU, self.body_frame
        else:
            frame = "baro"
        v = np.column_stack([nis, dof.astype(np.float64), accepted.astype(np.float64)])
        return [
            self._batch(f"innovation_{sensor}", vector3_stamped_fields(stamps, inno, frame), log),
            self._batch(f"nis_{sensor}", vector3_stamped_fields(stamps, v, "nis"), log),
        ]
