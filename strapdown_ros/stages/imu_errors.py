"""Measured IMU messages: the scenario's ``imu_errors`` model applied to an ideal Imu stream.

The one implementation of the measurement stage, between
:mod:`strapdown_ros.core.imu_errors` (the model, ROS-free) and the message world:
``strapdown-sim generate`` and ``imu_model_node`` both feed :class:`ImuErrorsStage`, so the
bag and the live topic carry the same bytes.

* **Topics.** ``imu_errors.input_topic`` (default ``recording.topics.variation_imu``) becomes
  ``imu_errors.output_topic`` (default ``recording.topics.variation_imu_measured``).
* **Messages** (docs/interface.md §2, §4). Increments ``FRD(angular_velocity) T``,
``FRD(linear_acceleration)
  T`` go through the model and out as ``FLU(Δα̃) / T``, ``FLU(Δṽ) / T`` with the input's stamp
  and ``frame_id``; no orientation (``orientation_covariance[0] = -1``); diagonal rate and
  acceleration covariances from
  :meth:`~strapdown_ros.core.imu_errors.ImuErrorModel.rate_noise_variance`.
* **Cycles.** Message m (``stamp = start_time + m T``) is cycle m of the model. Off-grid stamps
  are rejected, older ones dropped, missing cycles skipped
  (:meth:`~strapdown_ros.core.imu_errors.ImuErrorModel.skip`), cycle 1 after later cycles
  restarts the model from its seed; all logged. Details: docs/theory/imu_errors.md.
"""

from __future__ import annotations

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch
from strapdown_ros.config import Scenario, ScenarioError
from strapdown_ros.config.imu_errors import ImuErrorsSpec
from strapdown_ros.core.imu_errors import ImuErrorModel
from strapdown_ros.logs import Log, quiet
from strapdown_ros.messages import (
    COVARIANCE_NOT_PROVIDED,
    ImuFields,
    imu_fields_from_increments,
    imu_increments,
)
from strapdown_ros.stages.intake import (
    InputEvents,
    decode_runs,
    format_stamp,
    screen,
    stamp_verdict,
)

__all__ = [
    "ImuErrorsStage",
    "ImuErrorsStages",
    "imu_errors_spec",
    "imu_errors_topics",
    "imu_model_node_name",
    "measured_covariances",
    "measured_imu_fields",
]


def imu_errors_spec(scenario: Scenario, model: int = 0) -> ImuErrorsSpec:
    """Model ``model`` (its index in ``imu_errors``) of the scenario (ScenarioError
    ``imu_errors`` if it has no such model)."""
    models = scenario.imu_errors
    if not models:
        raise ScenarioError("imu_errors", "missing: the scenario defines no IMU error model")
    if not 0 <= model < len(models):
        raise ScenarioError(
            "imu_errors", f"no model {model}: the scenario has {len(models)} (0..{len(models) - 1})"
        )
    return models[model]


def imu_errors_topics(scenario: Scenario, model: int = 0) -> tuple[str, str]:
    """``(input, output)`` topics of model ``model``: the section's, else
    ``recording.topics``'."""
    return imu_errors_spec(scenario, model).topics(scenario.recording.topics)


def imu_model_node_name(model: int) -> str:
    """The ROS node name of ``imu_model_node`` running model ``model``: ``imu_model_node``
    for the first, ``imu_model_node_<model>`` for the others (distinct names: flow control
    and the logs tell them apart)."""
    return "imu_model_node" if model == 0 else f"imu_model_node_{model}"


def measured_covariances(model: ImuErrorModel) -> tuple[np.ndarray, np.ndarray]:
    """Row-major 3×3 covariances (9,) of the measured angular velocity ((rad/s)²) and linear
    acceleration ((m/s²)²), diagonal in FLU axes (the FRD per-axis variances: the axis flips
    do not change a diagonal)."""
    gyro, accel = model.rate_noise_variance()
    return np.diag(gyro).reshape(9), np.diag(accel).reshape(9)


def measured_imu_fields(ideal: ImuFields, model: ImuErrorModel, period_ns: int) -> ImuFields:
    """Measured Imu fields of the next ideal messages (consecutive cycles of the model).

    Parameters
    ----------
    ideal : ImuFields
        Ideal Imu messages of consecutive cycles (docs/interface.md §2), FLU.
    model : ImuErrorModel
        The run's model; advanced by ``len(ideal)`` cycles.
    period_ns : int
        T (ns) of the stream.

    Returns
    -------
    ImuFields
        Same stamps and ``frame_id``; measured rates and specific forces; covariances from the
        model; orientation not provided.
    """
    inc = imu_increments(ideal, period_ns)
    dalpha, dv = model.apply(inc.dalpha, inc.dv)
    cov_w, cov_a = measured_covariances(model)
    return imu_fields_from_increments(
        inc.stamps_ns,
        dalpha,
        dv,
        period_ns,
        ideal.frame_id,
        c_frd_ned=None,
        orientation_covariance=COVARIANCE_NOT_PROVIDED,
        angular_velocity_covariance=cov_w,
        linear_acceleration_covariance=cov_a,
    )


class ImuErrorsStage:
    """Ideal Imu messages in (in chunks of any size), measured ones out; no rclpy.

    Parameters
    ----------
    scenario : Scenario
        Supplies the cycle grid (``start_time_ns``, T) and the ``imu_errors`` section.
    input_topic, output_topic : str, optional
        Override the topics of :func:`imu_errors_topics` (node parameters).
    model : int
        Which model of ``imu_errors`` (its index; 0: the first).
    info, warn, error : callable
        Loggers (the node's); gaps and dropped messages go to ``warn``, rejected ones to
        ``error``.

    Attributes
    ----------
    spec : ImuErrorsSpec
        The model (``imu_errors[model]``).
    last_cycle : int
        Last cycle processed (0: none yet).
    published : int
        Measured messages produced.
    runs : int
        Model runs (1 + restarts of the input at cycle 1).
    """

    def __init__(
        self,
        scenario: Scenario,
        input_topic: str | None = None,
        output_topic: str | None = None,
        *,
        model: int = 0,
        info: Log = quiet,
        warn: Log = quiet,
        error: Log = quiet,
    ) -> None:
        self.spec = imu_errors_spec(scenario, model)
        self.params = self.spec.parameters()
        default_in, default_out = self.spec.topics(scenario.recording.topics)
        self.input_topic = input_topic or default_in
        self.output_topic = output_topic or default_out
        self.t0_ns = scenario.start_time_ns
        self.period_ns = scenario.period_ns
        self.info, self.warn, self.error = info, warn, error
        self.model = ImuErrorModel(self.params, self.period_ns * 1e-9)
        self.last_cycle = 0
        self.published = 0
        self.runs = 1
        #: Input events by class (logged one line each; counted for the node's summary).
        self.events = InputEvents(warn, error)

    def describe(self, m: int) -> str:
        """``stamp (cycle m)`` of cycle m."""
        return f"{format_stamp(self.t0_ns + m * self.period_ns)} (cycle {m})"

    def _cycles(self, stamps_ns: np.ndarray) -> np.ndarray:
        """Cycle index of each stamp; -1 for a stamp off the grid or before cycle 1."""
        offset = stamps_ns - self.t0_ns
        m = offset // self.period_ns
        bad = (offset % self.period_ns != 0) | (m < 1)
        return np.where(bad, -1, m)

    def feed(self, ideal: ImuFields) -> ImuFields | None:
        """Measured messages of the ideal messages ``ideal`` (None if all were dropped)."""
        topic = self.input_topic
        ideal, _ = screen(ideal, topic, self.events, "dropped (no measured message for it; the "
                          "model is advanced over the missing cycle)",
                          lambda stamps: self.events.dropped(topic, stamps))  # fmt: skip
        if ideal is None:
            return None
        stamps = np.asarray(ideal.stamps_ns, dtype=np.int64)
        cycles = self._cycles(stamps)
        parts: list[ImuFields] = []
        i, n = 0, len(stamps)
        while i < n:
            m = int(cycles[i])
            if m < 0:
                self.events(
                    "off-grid stamp",
                    f"{self.input_topic}: stamp {format_stamp(int(stamps[i]))} is not a cycle "
                    f"m >= 1 of the scenario's grid (start {format_stamp(self.t0_ns)}, T = "
                    f"{self.period_ns} ns); rejected",
                    error=True,
                )
                i += 1
                continue
            last = self.last_cycle
            verdict = stamp_verdict(m, last, 1, restart_below=1)
            if verdict in ("restart", "duplicate", "out-of-order"):
                if verdict == "restart":
                    self.events(
                        "restart",
                        f"{self.input_topic}: stamp {self.describe(m)} after {self.describe(last)}"
                        ": the input restarted; the model restarts from its seed (a new run)",
                    )
                    self.model = ImuErrorModel(self.params, self.period_ns * 1e-9)
                    self.last_cycle = last = 0
                    self.runs += 1
                else:
                    what = f"{verdict} stamp"
                    self.events(
                        what,
                        f"{self.input_topic}: {what} {self.describe(m)} after "
                        f"{self.describe(last)}: dropped",
                    )
                    i += 1
                    continue
            if m > last + 1:
                missing = m - last - 1
                if last == 0:
                    self.warn(
                        f"{self.input_topic}: the input starts at {self.describe(m)}; the model "
                        f"is advanced over cycles 1..{m - 1}"
                    )
                else:
                    self.events.gap(
                        self.input_topic,
                        (self.t0_ns + k * self.period_ns for k in range(last + 1, m)),
                        f"{self.input_topic}: gap: stamp {self.describe(m)} follows "
                        f"{self.describe(last)}; the model is advanced over the {missing} "
                        "missing cycle(s) (noise continues; the quantizer misses their "
                        "increments)",
                        self.info,
                    )
                self.model.skip(missing)
            j = i + 1
            while j < n and cycles[j] == cycles[j - 1] + 1:
                j += 1
            parts.append(measured_imu_fields(ideal.rows(i, j), self.model, self.period_ns))
            self.last_cycle = int(cycles[j - 1])
            i = j
        if not parts:
            return None
        out = parts[0]
        for p in parts[1:]:
            out = out.append(p)
        self.published += len(out)
        return out

    def on_payload(self, payload: bytes | memoryview) -> bytes | None:
        """One serialized ideal Imu message in, its measured message out (None: dropped)."""
        out = self.on_payloads([payload])
        return out[0] if out else None

    def on_payloads(self, payloads: list[bytes | memoryview]) -> list[bytes]:
        """Serialized ideal Imu messages in, the serialized measured messages out: the same
        bytes for any chunking (the model applied in chunks is the model applied to the whole
        stream). Decoded in one CDR call, or message by message when they do not decode
        together (:func:`~strapdown_ros.stages.intake.decode_runs`: a malformed message is
        reported and only it is dropped)."""
        out: list[bytes] = []
        for _, ideal in decode_runs(cdr.IMU, payloads, self.input_topic, self.events):
            measured = self.feed(ideal)
            if measured is not None:
                out += [bytes(d) for d in batch(self.output_topic, measured).payloads]
        return out

    def feed_batches(self, batches: list[Batch]) -> list[Batch]:
        """``generate``'s path: the output batch of the input topic's batch among ``batches``."""
        out = []
        for b in batches:
            if b.topic != self.input_topic or not len(b.payloads):
                continue
            fields = self.feed(cdr.deserialize(b.msgtype, b.payloads))  # type: ignore[arg-type]
            if fields is not None:
                out.append(batch(self.output_topic, fields))
        return out


class ImuErrorsStages:
    """Every model of the scenario's ``imu_errors``, one :class:`ImuErrorsStage` each, fed
    the same batches (``generate``'s path). Each model has its own generator (its own seed):
    one model's draws do not change another's stream."""

    def __init__(self, scenario: Scenario) -> None:
        self.stages = [
            ImuErrorsStage(scenario, model=i) for i in range(len(scenario.imu_errors))
        ]

    def feed_batches(self, batches: list[Batch]) -> list[Batch]:
        """The output batches of every model, in ``imu_errors`` order."""
        return [b for stage in self.stages for b in stage.feed_batches(batches)]
