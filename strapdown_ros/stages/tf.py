"""TF, map-frame odometry and increment topics derived from a stage's messages.

:class:`TFStage` turns the serialized output of the other stages into the messages ROS
tools expect (docs/interface.md, "Frames and TF"): ``/tf_static`` (``earth → map``,
``base_link → reference_imu``, ``base_link → variation_imu`` when its offsets are constant,
``base_link → <sensor>`` of each aiding sensor with a frame of its own),
``/tf`` (``map → base_link`` from the reference truth, ``base_link → variation_imu`` from the
variation's offsets, ``map → <navigator frame>`` from the navigation solution), map-frame
``nav_msgs/Odometry`` beside each ECEF Odometry topic, and optional Δv / Δq topics beside each
Imu topic. Every output message depends on one input message only (and the scenario), so
``generate`` and the nodes, feeding any chunking, produce identical bytes.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from rosbags.interfaces import QosDurability

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch, merge_order
from strapdown_ros.bag.writer import DEFAULT_QOS
from strapdown_ros.config import Scenario, tf_spec
from strapdown_ros.config.tf import sensor_frames
from strapdown_ros.core.frames import Datum, lever_arm_in_base_link, sensor_in_body
from strapdown_ros.core.variation import OffsetArrays
from strapdown_ros.messages import (
    BASE_LINK_FRAME,
    MAP_FRAME,
    OdometryFields,
    dcm_from_quat_ros,
    increment_fields,
    map_odometry_fields,
    tf_message_fields,
)
from strapdown_ros.plan.model import Plan, TopicPlan

__all__ = [
    "DERIVED_TOPICS",
    "EXTRA_FRAMES",
    "IMU_KEYS",
    "ODOM_KEYS",
    "STATIC_QOS",
    "TF_TOPICS",
    "TFStage",
    "derived_topic_plans",
    "derived_topics",
    "node_derived_topics",
    "plan_datum",
    "static_topic",
]

#: Offered QoS stored for ``/tf_static``: a latched (transient local) publisher, as
#: ``ros2 bag record`` stores tf2_ros' static broadcaster; ``ros2 bag play`` then replays it
#: latched. Every other topic has :data:`strapdown_ros.bag.writer.DEFAULT_QOS`.
STATIC_QOS = DEFAULT_QOS._replace(durability=QosDurability.TRANSIENT_LOCAL)

#: recording.topics key of each ECEF Odometry topic and of its map-frame twin.
ODOM_KEYS = ("reference_odom", "variation_odom", "variation_reference_odom", "navigator_odom")
#: recording.topics keys of the Imu topics that get Δv / Δq twins.
IMU_KEYS = ("reference_imu", "variation_imu", "variation_reference_imu", "variation_imu_measured")

#: Suffix of each derived topic's name on its source topic (``recording.topics`` key → (source
#: key, suffix)); the name is ``recording.topics[key]`` when given, else source name + suffix.
DERIVED_TOPICS: dict[str, tuple[str, str]] = {
    **{f"{k}_map": (k, "_map") for k in ODOM_KEYS},
    **{f"{k}_{d}": (k, f"_{d}") for k in IMU_KEYS for d in ("dv", "dq")},
}
#: Default names of the TF topics (``recording.topics`` keys ``tf``, ``tf_static``).
TF_TOPICS: dict[str, str] = {"tf": "/tf", "tf_static": "/tf_static"}
#: Default frame ids this stage adds (recording.frames keys).
EXTRA_FRAMES: dict[str, str] = {"map": MAP_FRAME, "base_link": BASE_LINK_FRAME}


def _topic(scenario: Scenario, key: str) -> str:
    topics = scenario.recording.topics
    if key in topics:
        return topics[key]
    if key in TF_TOPICS:
        return TF_TOPICS[key]
    source, suffix = DERIVED_TOPICS[key]
    return topics[source] + suffix


def _frame(scenario: Scenario, key: str) -> str:
    frames = scenario.recording.frames
    return frames[key] if key in frames else EXTRA_FRAMES[key]


def plan_datum(plan: Plan) -> Datum:
    """The ``map`` datum: ``tf.datum``, else the initial position (``initial``, else the
    trajectory's position at t0)."""
    scenario = plan.scenario
    spec = plan.tf.datum
    if spec is not None:
        lat, lon, alt = spec.latitude_deg, spec.longitude_deg, spec.altitude_m
    elif scenario.initial is not None:
        ini = scenario.initial
        lat, lon, alt = ini.latitude_deg, ini.longitude_deg, ini.altitude_m
    else:
        trajectory = plan.trajectory
        if trajectory is None:  # kind increments always has `initial`
            raise ValueError("the scenario has no initial position for the map datum")
        truth = trajectory.local_truth(np.zeros(1))
        return Datum.at(float(truth.lat[0]), float(truth.lon[0]), float(truth.alt[0]))
    return Datum.at(np.radians(lat), np.radians(lon), alt)


def _source_topics(scenario: Scenario, keys: Iterable[str]) -> dict[str, str]:
    return {_topic(scenario, k): k for k in keys}


def derived_topics(scenario: Scenario, produced: Mapping[str, str]) -> dict[str, str]:
    """The topics (name → message type) :class:`TFStage` adds to the scenario's
    ``produced`` topics (``topics.produced_topics``), in the order ``generate`` creates them:
    ``/tf_static``, ``/tf``, then each source topic's map odometry / increments."""
    spec = tf_spec(scenario)
    increments = bool(getattr(scenario.recording, "increments", False))
    odom = _source_topics(scenario, ODOM_KEYS)
    imu = _source_topics(scenario, IMU_KEYS)
    out: dict[str, str] = {}
    if spec.enabled:
        out[_topic(scenario, "tf_static")] = cdr.TF_MESSAGE
        out[_topic(scenario, "tf")] = cdr.TF_MESSAGE
    for topic in produced:
        if topic in odom and spec.map_odometry:
            out[_topic(scenario, f"{odom[topic]}_map")] = cdr.ODOMETRY
        if topic in imu and increments:
            out[_topic(scenario, f"{imu[topic]}_dv")] = cdr.VECTOR3_STAMPED
            out[_topic(scenario, f"{imu[topic]}_dq")] = cdr.QUATERNION_STAMPED
    return out


def _every(count: int, ratio: int) -> int:
    """Messages kept of ``count`` consecutive ones (the first kept) when keeping 1 in ratio."""
    return 0 if count <= 0 else (count - 1) // ratio + 1


def derived_topic_plans(plan: Plan, upstream: Mapping[str, TopicPlan]) -> list[TopicPlan]:
    """The topics :class:`TFStage` derives from the ``upstream`` topics of a plan, in the
    order ``generate`` creates them, with their counts and stamps: ``/tf_static`` (one message
    at t0), ``/tf`` (the reference poses, the variation's unless static, the navigator's, each
    at its ``tf`` rate), the map-frame twin of each Odometry topic and the increments of each
    Imu topic (those of their source)."""
    scenario = plan.scenario
    spec = plan.tf
    types = derived_topics(scenario, {t: p.msgtype for t, p in upstream.items()})
    by_key = {p.key: p for p in upstream.values() if p.key is not None}
    out: list[TopicPlan] = []
    if spec.enabled:
        body = 1
        if spec.body_rate_hz is not None:
            body = round(1e9 / spec.body_rate_hz) // plan.period_ns
        n = _every(_count(by_key, "reference_odom"), body)
        if not plan.variation_static:
            n += _every(_count(by_key, "variation_odom"), body)
        nav = _count(by_key, "navigator_odom")
        if nav:
            ratio = 1
            if spec.navigator_rate_hz is not None:
                steps = int(getattr(scenario.navigator, "n", 1))
                ratio = round(1e9 / spec.navigator_rate_hz) // (plan.period_ns * steps)
            n += _every(nav, ratio)
        static = _topic(scenario, "tf_static")
        out.append(TopicPlan(static, types[static], 1, "tf", "tf_static", plan.start_ns,
                             plan.start_ns))  # fmt: skip
        tf = _topic(scenario, "tf")
        out.append(TopicPlan(tf, types[tf], n, "tf", "tf", plan.start_ns))
    increments = bool(scenario.recording.increments)
    for key, source, suffixes in (
        *((k, k, ("map",)) for k in ODOM_KEYS if spec.map_odometry),
        *((k, k, ("dv", "dq")) for k in IMU_KEYS if increments),
    ):
        src = by_key.get(source)
        if src is None:
            continue
        for suffix in suffixes:
            topic = _topic(scenario, f"{key}_{suffix}")
            out.append(TopicPlan(topic, types[topic], src.count, "tf", f"{key}_{suffix}",
                                 src.first_ns, src.last_ns))  # fmt: skip
    order = list(types)
    return sorted(out, key=lambda p: order.index(p.topic))


def _count(by_key: Mapping[str, TopicPlan], key: str) -> int:
    p = by_key.get(key)
    return 0 if p is None else p.count


@dataclass(frozen=True)
class _Settings:
    t0_ns: int
    period_ns: int
    body_period_ns: int
    navigator_period_ns: int | None
    tf: bool
    map_odometry: bool
    increments: bool


class TFStage:
    """Derived TF / map-frame / increment batches of a scenario's message batches.

    Parameters
    ----------
    plan : Plan
        The scenario's plan (TF settings, datum, cycles, whether the variation is static).
    offsets : OffsetArrays or None
        The variation's offsets on the output cycle grid (FRD, as the variation used them);
        None: computed from the scenario when a variation topic is fed.
    variation_tf : bool
        Pair reference and variation truth for ``base_link → variation_imu`` (``generate``,
        the variation node); False where no variation Odometry is fed (the other nodes), so
        that reference poses are not kept.
    """

    def __init__(
        self,
        plan: Plan,
        *,
        offsets: OffsetArrays | None = None,
        variation_tf: bool = True,
    ) -> None:
        scenario = plan.scenario
        spec = plan.tf
        self.variation_tf = variation_tf
        self.scenario = scenario
        self.datum = plan_datum(plan)
        nav_period = None
        if scenario.navigator is not None:  # the section as written: N
            nav_period = scenario.period_ns * int(getattr(scenario.navigator, "n", 1))
            if spec.navigator_rate_hz is not None:
                nav_period = int(round(1e9 / spec.navigator_rate_hz))
        body = scenario.period_ns
        if spec.body_rate_hz is not None:
            body = int(round(1e9 / spec.body_rate_hz))
        self.settings = _Settings(
            t0_ns=scenario.start_time_ns,
            period_ns=scenario.period_ns,
            body_period_ns=body,
            navigator_period_ns=nav_period,
            tf=spec.enabled,
            map_odometry=spec.map_odometry,
            increments=bool(scenario.recording.increments),
        )
        self.frames = {k: _frame(scenario, k) for k in ("earth", "map", "base_link")}
        self.frames["reference_imu"] = _frame(scenario, "reference_imu")
        self.frames["variation_imu"] = _frame(scenario, "variation_imu")
        #: aiding sensors' (frame id, base_link → sensor translation FLU) in /tf_static
        self.sensor_frames = [
            (frame, lever_arm_in_base_link(lever))
            for frame, lever in sensor_frames(plan.aiding, self.frames["reference_imu"]).values()
            if frame != self.frames["reference_imu"]  # the magnetometer's default: the IMU's
        ]
        self._offsets = offsets
        self._cycles = plan.cycles
        self._variation_static = plan.variation_static
        self._static_variation: tuple[np.ndarray, np.ndarray] | None = None
        # reference truth poses waiting for the variation's (stamps, ECEF positions, quaternions)
        self._ref_t = np.zeros(0, dtype=np.int64)
        self._ref_p = np.zeros((0, 3))
        self._ref_q = np.zeros((0, 4))
        self.odom_topics = {_topic(scenario, k): k for k in ODOM_KEYS}
        self.imu_topics = {_topic(scenario, k): k for k in IMU_KEYS}

    # -- configuration ---------------------------------------------------------------------

    @property
    def tf_topic(self) -> str:
        return _topic(self.scenario, "tf")

    @property
    def tf_static_topic(self) -> str:
        return _topic(self.scenario, "tf_static")

    def topics(self, produced: Mapping[str, str]) -> dict[str, str]:
        """:func:`derived_topics` of this stage's scenario."""
        return derived_topics(self.scenario, produced)

    # -- offsets of the variation ----------------------------------------------------------

    def _variation_offsets(self, m_max: int) -> OffsetArrays:
        if self._offsets is None or len(self._offsets) <= m_max:
            from strapdown_ros.stages.variation import scenario_offsets

            cycles = max(m_max, self._cycles or 0)
            self._offsets = scenario_offsets(self.scenario, cycles + 1)
        return self._offsets

    def variation_is_static(self) -> bool:
        """Whether ``base_link → variation_imu`` is constant over the run (then in /tf_static;
        :func:`strapdown_ros.plan.variation_is_static`)."""
        if self._variation_static and self._static_variation is None:
            o = self._variation_offsets(0)
            self._static_variation = sensor_in_body(
                o.lever_arm[:1], o.displacement[:1], o.c_bvar_bref[:1]
            )
        return self._variation_static

    # -- batches ---------------------------------------------------------------------------

    def leading_batches(self) -> list[Batch]:
        """What ``generate`` writes before everything else: :meth:`static_batch`."""
        static = self.static_batch()
        return [] if static is None else [static]

    def static_batch(self) -> Batch | None:
        """``/tf_static`` (one message at the start stamp t0), None when TF is off: ``earth →
        map``, ``base_link → reference_imu``, ``base_link → variation_imu`` when static, and
        ``base_link → <sensor frame>`` of each aiding sensor at its lever arm (docs/frames.md)."""
        if not self.settings.tf:
            return None
        f = self.frames
        parents = [f["earth"], f["base_link"]]
        children = [f["map"], f["reference_imu"]]
        translation = [self.datum.r0_e, np.zeros(3)]
        rotation = [self.datum.c_map_e, np.eye(3)]
        if self.variation_is_static():
            assert self._static_variation is not None
            p, c = self._static_variation
            parents.append(f["base_link"])
            children.append(f["variation_imu"])
            translation.append(p[0])
            rotation.append(c[0])
        for frame, lever in self.sensor_frames:  # each aiding sensor at its lever arm
            parents.append(f["base_link"])
            children.append(frame)
            translation.append(lever)
            rotation.append(np.eye(3))
        fields = tf_message_fields(
            np.array([self.settings.t0_ns], dtype=np.int64),
            parents,
            children,
            np.asarray(translation)[None],
            np.asarray(rotation)[None],
        )
        return batch(self.tf_static_topic, fields)

    def _decimated(self, stamps: np.ndarray, period_ns: int) -> np.ndarray:
        return np.flatnonzero((stamps - self.settings.t0_ns) % period_ns == 0)

    def _odometry(self, key: str, fields: OdometryFields) -> list[Batch]:
        out: list[Batch] = []
        s = self.settings
        if fields.frame_id != self.frames["earth"] or not len(fields):
            return out
        if s.map_odometry:
            out.append(
                batch(
                    _topic(self.scenario, f"{key}_map"),
                    map_odometry_fields(
                        fields, self.datum.r0_e, self.datum.c_map_e, self.frames["map"]
                    ),
                )
            )
        if not s.tf:
            return out
        stamps = np.asarray(fields.stamps_ns, dtype=np.int64)
        if key == "reference_odom":
            rows = self._decimated(stamps, s.body_period_ns)
            child = self.frames["base_link"]
        elif key == "navigator_odom" and s.navigator_period_ns:
            rows = self._decimated(stamps, s.navigator_period_ns)
            child = fields.child_frame_id
        elif key == "variation_odom":
            return out + self._variation_tf(fields)
        else:
            return out
        if not rows.size:
            return out
        c_flu_e = dcm_from_quat_ros(np.asarray(fields.orientation)[rows])
        pos = self.datum.to_map(np.asarray(fields.position)[rows])
        tf = tf_message_fields(
            stamps[rows],
            [self.frames["map"]],
            [child],
            pos[:, None],
            (self.datum.c_map_e.T @ c_flu_e)[:, None],
        )
        out.append(batch(self.tf_topic, tf))
        return out

    def observe_reference(self, fields: OdometryFields) -> None:
        """Keep reference truth poses (ECEF Odometry) to pair with the variation's by stamp.

        ``base_link → variation_imu`` is the variation truth relative to the reference truth
        at the same stamp. ``generate`` feeds the reference Odometry before the variation's
        (:meth:`feed_batches` does it); the variation node feeds its reference input.
        """
        s = self.settings
        if not s.tf or not self.variation_tf or self.scenario.variation is None:
            return
        if self.variation_is_static():
            return
        if fields.frame_id != self.frames["earth"] or not len(fields):
            return
        t = np.concatenate([self._ref_t, np.asarray(fields.stamps_ns, dtype=np.int64)])
        p = np.concatenate([self._ref_p, np.asarray(fields.position, dtype=np.float64)])
        q = np.concatenate([self._ref_q, np.asarray(fields.orientation, dtype=np.float64)])
        order = np.argsort(t, kind="stable")
        t, p, q = t[order], p[order], q[order]
        keep = np.ones(t.shape, dtype=bool)
        keep[1:] = t[1:] != t[:-1]  # a repeated stamp: the first one
        self._ref_t, self._ref_p, self._ref_q = t[keep], p[keep], q[keep]

    def observe_reference_payloads(self, payloads: list[bytes]) -> None:
        """:meth:`observe_reference` of serialized reference Odometry messages."""
        if payloads:
            try:
                fields = cdr.deserialize(cdr.ODOMETRY, payloads)
            except cdr.CdrError:  # mixed frame ids: one by one (a bad one is skipped)
                if len(payloads) > 1:
                    for payload in payloads:
                        self.observe_reference_payloads([payload])
                return
            self.observe_reference(fields)  # type: ignore[arg-type]

    def _variation_tf(self, fields: OdometryFields) -> list[Batch]:
        """``base_link → variation_imu`` at the variation truth's stamps (body rate): the
        variation truth relative to the reference truth of the same stamp, body FLU axes."""
        s = self.settings
        if self.variation_is_static():
            return []
        stamps = np.asarray(fields.stamps_ns, dtype=np.int64)
        rows = self._decimated(stamps, s.body_period_ns)
        if not rows.size or not self._ref_t.size:
            return []
        i = np.minimum(np.searchsorted(self._ref_t, stamps[rows]), self._ref_t.size - 1)
        found = self._ref_t[i] == stamps[rows]
        rows, i = rows[found], i[found]
        if not rows.size:
            return []
        c_ref = dcm_from_quat_ros(self._ref_q[i])  # C_FLU,ref^E
        c_ref_t = np.swapaxes(c_ref, -1, -2)
        d = np.asarray(fields.position, dtype=np.float64)[rows] - self._ref_p[i]
        translation = (c_ref_t @ d[..., None])[..., 0]  # stacked: same bits for any chunking
        rotation = c_ref_t @ dcm_from_quat_ros(np.asarray(fields.orientation)[rows])
        # reference poses up to the last paired stamp are no longer needed
        last = np.searchsorted(self._ref_t, stamps[rows][-1], side="right")
        self._ref_t, self._ref_p, self._ref_q = (
            self._ref_t[last:],
            self._ref_p[last:],
            self._ref_q[last:],
        )
        tf = tf_message_fields(
            stamps[rows],
            [self.frames["base_link"]],
            [self.frames["variation_imu"]],
            translation[:, None],
            rotation[:, None],
        )
        return [batch(self.tf_topic, tf)]

    def feed_batches(self, batches: list[Batch]) -> list[Batch]:
        """The derived batches of ``batches`` (topics not concerned are ignored)."""
        out: list[Batch] = []
        odometry = {}
        for k, b in enumerate(batches):  # reference poses first: the variation pairs with them
            key = self.odom_topics.get(b.topic)
            if key is not None and b.msgtype == cdr.ODOMETRY and len(b.payloads):
                odometry[k] = cdr.deserialize(cdr.ODOMETRY, b.payloads)
                if key == "reference_odom":
                    self.observe_reference(odometry[k])  # type: ignore[arg-type]
        for k, b in enumerate(batches):
            if not len(b.payloads):
                continue
            key = self.odom_topics.get(b.topic)
            if k in odometry:
                out += self._odometry(key, odometry[k])  # type: ignore[arg-type]
                continue
            key = self.imu_topics.get(b.topic)
            if key is not None and b.msgtype == cdr.IMU and self.settings.increments:
                imu = cdr.deserialize(cdr.IMU, b.payloads)
                dv, dq = increment_fields(imu, self.settings.period_ns)  # type: ignore[arg-type]
                out.append(batch(_topic(self.scenario, f"{key}_dv"), dv))
                out.append(batch(_topic(self.scenario, f"{key}_dq"), dq))
        return out

    def derive_items(self, items: list[tuple[str, int, bytes]]) -> list[tuple[str, int, bytes]]:
        """The live nodes' path: derived messages ``(topic, stamp_ns, payload)`` of a node's
        serialized outputs, in stamp order (same payloads as :meth:`feed_batches`)."""
        by_topic: dict[str, tuple[list[int], list[bytes]]] = {}
        for topic, stamp, payload in items:
            if topic in self.odom_topics or topic in self.imu_topics:
                stamps, payloads = by_topic.setdefault(topic, ([], []))
                stamps.append(stamp)
                payloads.append(payload)
        if not by_topic:
            return []
        types = {
            **dict.fromkeys(self.odom_topics, cdr.ODOMETRY),
            **dict.fromkeys(self.imu_topics, cdr.IMU),
        }
        batches = [
            Batch(t, types[t], np.asarray(st, dtype=np.int64), pl)
            for t, (st, pl) in by_topic.items()
        ]
        derived = self.feed_batches(batches)
        return [
            (derived[k].topic, stamp, derived[k].payloads[i])
            for k, i, stamp in merge_order(derived)
        ]


class SolverWithTF:
    """A node's solver whose outputs come with their derived messages (:class:`TFStage`).

    ``on_batch(items)`` returns the solver's serialized outputs followed by the derived
    messages of those outputs whose topic is in ``topics`` (the ones the node publishes: TF is
    left out where tf2_msgs is not available). Everything else is the wrapped solver's.
    """

    def __init__(
        self,
        solver: object,
        frames: TFStage,
        topics: Iterable[str],
        reference_input: object | None = None,
    ) -> None:
        self.solver = solver
        self.frames = frames
        self.topics = set(topics)
        #: the ``kind`` of the node's input items that are reference Odometry payloads (the
        #: variation node's), fed to :meth:`TFStage.observe_reference_payloads`
        self.reference_input = reference_input

    def on_batch(self, items: list) -> list[tuple[str, int, bytes]]:
        if self.reference_input is not None and self.topics:
            self.frames.observe_reference_payloads(
                [payload for kind, payload in items if kind == self.reference_input]
            )
        out = self.solver.on_batch(items)  # type: ignore[attr-defined]
        if not out or not self.topics:
            return out
        derived = self.frames.derive_items(out)
        return out + [item for item in derived if item[0] in self.topics]

    def __getattr__(self, name: str) -> object:
        return getattr(self.solver, name)


def static_topic(scenario: Scenario) -> str | None:
    """The ``/tf_static`` topic name, None when the scenario's TF is off."""
    return _topic(scenario, "tf_static") if tf_spec(scenario).enabled else None


def node_derived_topics(
    plan: Plan, outputs: Iterable[str], *, static: bool = False
) -> dict[str, str]:
    """The derived topics (name → type) a node publishes beside its ``outputs``: ``/tf_static``
    only with ``static`` (``trajectory_node``), ``/tf`` when an output is a TF source
    (reference or navigator Odometry, variation Odometry with moving offsets), the map-frame
    odometry and increments of its outputs."""
    scenario = plan.scenario
    outputs = list(outputs)
    topics = dict(derived_topics(scenario, dict.fromkeys(outputs, "")))
    odom = _source_topics(scenario, ODOM_KEYS)
    sources = {odom.get(t) for t in outputs}
    tf_source = bool(sources & {"reference_odom", "navigator_odom"}) or (
        "variation_odom" in sources and not plan.variation_static
    )
    if not static:
        topics.pop(_topic(scenario, "tf_static"), None)
    if not tf_source:
        topics.pop(_topic(scenario, "tf"), None)
    return topics
