"""Sensor timing errors on the published messages (the scenario's ``timing`` section).

:class:`TimingStage` rewrites the batches of the timed topics — the IMU error model's output
(or ``timing.imu.topic``) and the aiding sensors' topics — after every other stage of the
chain has used them: header stamps (offset, drift, jitter: :mod:`strapdown_ros.core.timing`),
bag log times (latency), dropped messages and, for the IMU, the increments of the dropped
ones (``lost`` or ``accumulated``). The truth topics are not touched. Message semantics:
docs/score.md ("Sensor timing errors").

The header stamp is patched in the serialized message (every timed type starts with a
``std_msgs/Header``: ``sec`` int32 and ``nanosec`` uint32 after the 4-byte CDR encapsulation);
only an accumulated IMU message is decoded and re-serialized.
"""

from __future__ import annotations

import struct
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch
from strapdown_ros.config.timing import SENSORS, SensorTiming
from strapdown_ros.core.array_types import I64
from strapdown_ros.core.timing import TimingModel, accumulate_dropped
from strapdown_ros.plan.model import Plan, TopicPlan

__all__ = ["TimingStage", "timed_topics", "timing_topic_plans"]

_STAMP = struct.Struct("<iI")
_NS = 1_000_000_000

#: The aiding topics of each aiding sensor key.
_AIDING = {
    "gnss": ("/gnss/fix", "/gnss/vel"),
    "barometer": ("/baro/pressure",),
    "magnetometer": ("/mag",),
    "wheel_odometer": ("/wheel/twist",),
}


def _imu_topic(plan: Plan, timing: SensorTiming) -> str:
    if timing.topic is not None:
        return timing.topic
    if plan.imu_errors_topics:  # the first IMU error model's output
        return plan.imu_errors_topics[0][1]
    return plan.scenario.recording.topics["reference_imu"]


def timed_topics(plan: Plan) -> dict[str, tuple[str, SensorTiming, TimingModel]]:
    """Topic → (sensor key, its timing, its model) of the scenario's ``timing`` section."""
    spec = plan.scenario.timing
    if spec is None:
        return {}
    t0 = plan.start_ns
    out: dict[str, tuple[str, SensorTiming, TimingModel]] = {}
    sensors = plan.aiding.sensors() if plan.aiding is not None else {}
    for stream, (key, timing) in enumerate(spec.sensors().items()):
        offset, latency = timing.ns()
        drops = tuple(t0 + int(round(s * 1e9)) for s in timing.drops_s)
        if SENSORS[key] is None:
            topics, period, grid0 = (_imu_topic(plan, timing),), plan.period_ns, t0
        else:
            sensor = sensors.get(key)
            if sensor is None:
                from strapdown_ros.config import ScenarioError

                raise ScenarioError(f"timing.{key}", f"the scenario has no aiding.{key} sensor")
            topics, period, grid0 = _AIDING[key], sensor.period_ns, 0
        model = TimingModel(t0, period, grid0, offset, timing.drift_ppm, timing.jitter_s, latency,
                            timing.drop_probability, drops, timing.seed, stream)  # fmt: skip
        for topic in topics:
            out[topic] = (key, timing, model)
    return out


def _planned_stamps(p: TopicPlan, period: int, plan: Plan, key: str) -> I64:
    """The header stamps ``p`` has without timing errors (its grid minus GNSS outages)."""
    if p.first_ns is None or p.last_ns is None or not p.count:
        return np.zeros(0, dtype=np.int64)
    t = np.arange(p.first_ns, p.last_ns + 1, period, dtype=np.int64)
    if key == "gnss" and plan.aiding is not None and plan.aiding.gnss is not None:
        for a, b in plan.aiding.gnss.outage_windows_ns(plan.start_ns):
            t = t[(t < a) | (t >= b)]
    if t.size != p.count:
        raise AssertionError(f"{p.topic}: {t.size} stamps planned, {p.count} expected")
    return t


def timing_topic_plans(plan: Plan, upstream: dict[str, TopicPlan] | Any) -> list[TopicPlan]:
    """The timed topics' plans: counts without the dropped messages, stamps after timing, log
    delay plus the latency."""
    out = []
    for topic, (key, _, model) in timed_topics(plan).items():
        p = upstream.get(topic)
        if p is None:
            continue
        t = _planned_stamps(p, model.period_ns, plan, key)
        t = t[~model.dropped(t)]
        s = model.stamps(t)
        first, last = (int(s[0]), int(s[-1])) if s.size else (None, None)
        out.append(replace(p, count=int(t.size), first_ns=first, last_ns=last, link="timing",
                           log_delay_ns=p.log_delay_ns + model.latency_ns))  # fmt: skip
    return out


def _header_stamps(payloads: Any) -> I64:
    out = np.empty(len(payloads), dtype=np.int64)
    for i, p in enumerate(payloads):
        sec, ns = _STAMP.unpack_from(p, 4)
        out[i] = sec * _NS + ns
    return out


def _with_stamps(payloads: Any, stamps: I64) -> list[bytes]:
    out = []
    for p, t in zip(payloads, stamps.tolist(), strict=True):
        b = bytearray(p)
        _STAMP.pack_into(b, 4, *divmod(t, _NS))
        out.append(bytes(b))
    return out


class TimingStage:
    """The timing errors of a plan's ``timing`` section on ``generate``'s batches.

    :meth:`apply` returns the batches with the timed topics rewritten (pure);
    :meth:`feed_batches` does the same in place for :func:`~strapdown_ros.plan.chain.
    feed_stages` (whose stages add batches: this one adds none, it replaces).
    Attributes ``dropped`` (count per topic) and ``pending`` (IMU increments waiting for the
    next kept message, ``accumulated``).
    """

    def __init__(self, plan: Plan) -> None:
        self.plan = plan
        self.topics = timed_topics(plan)
        self.dropped: dict[str, int] = dict.fromkeys(self.topics, 0)
        self.pending: tuple[Any, Any, int] | None = None

    def _imu(self, b: Batch, t: I64, drop: NDArray[np.bool_], timing: SensorTiming) -> Batch:
        fields = cdr.deserialize(b.msgtype, b.payloads)
        if timing.dropped_increment == "lost":
            self.pending = None
            return b._replace(stamps_ns=b.stamps_ns[~drop],
                              payloads=[p for p, d in zip(b.payloads, drop, strict=True) if not d])
        period = self.plan.period_ns * 1e-9
        w = np.asarray(fields.angular_velocity) * period  # FLU increments: Δα = ω T
        a = np.asarray(fields.linear_acceleration) * period
        da, dv, cycles, self.pending = accumulate_dropped(w, a, drop, self.pending)
        kept = fields.rows(0, len(fields))
        idx = np.flatnonzero(~drop)
        span = (cycles * period)[:, None]
        kept = replace(kept, **{k: np.asarray(getattr(fields, k))[idx] for k in (
            "stamps_ns", "orientation", "orientation_covariance", "angular_velocity_covariance",
            "linear_acceleration_covariance")}, angular_velocity=da / span,
            linear_acceleration=dv / span)  # fmt: skip
        out = batch(b.topic, kept)
        return out._replace(stamps_ns=b.stamps_ns[~drop])

    def apply(self, batches: list[Batch]) -> list[Batch]:
        """``batches`` with the timed topics' batches rewritten."""
        out = []
        for b in batches:
            item = self.topics.get(b.topic)
            if item is None or not len(b.payloads):
                out.append(b)
                continue
            key, timing, model = item
            t = _header_stamps(b.payloads)
            drop = model.dropped(t)
            self.dropped[b.topic] += int(drop.sum())
            if SENSORS[key] is None:
                b = self._imu(b, t, drop, timing)
            else:
                b = b._replace(stamps_ns=np.asarray(b.stamps_ns)[~drop],
                               payloads=[p for p, d in zip(b.payloads, drop, strict=True)
                                         if not d])  # fmt: skip
            t = t[~drop]
            out.append(Batch(b.topic, b.msgtype, np.asarray(b.stamps_ns) + model.latency_ns,
                             _with_stamps(b.payloads, model.stamps(t))))  # fmt: skip
        return out

    def feed_batches(self, batches: list[Batch]) -> list[Batch]:
        """``generate``'s path: rewrites ``batches`` in place; adds nothing."""
        batches[:] = self.apply(batches)
        return []
