"""``variation_node``: the variation and the regenerated reference, live (docs/interface.md §4, §6).

A thin rclpy shell over :class:`~strapdown_ros.stages.variation.VariationStage` (the same
streaming stage ``strapdown-sim generate`` runs): it subscribes raw to the reference Imu and
Odometry topics, hands the payloads to the stage in batches (:class:`~strapdown_ros.nodes.
batching.InputBatch`) and publishes the serialized ``/variation/*`` and ``/variation/reference/*``
messages it returns, which are byte-identical to the bag's. The stage pairs the messages by
stamp on the scenario's cycle grid, solves Method 2 in windows of at most
:data:`~strapdown_ros.stages.variation.MAX_WINDOW` cycles, and logs and handles gaps, repeats,
out-of-order stamps, frame mismatches and restarts (a new run, which differs from an
uninterrupted offline run by design). Method 1 is offline only. Parameters and behaviour:
docs/nodes.md.

Exit status: 0 done (or stopped by SIGINT/SIGTERM), 1 failure while running, 2 invalid
parameter or scenario.
"""

from __future__ import annotations

from strapdown_ros.bag import cdr
from strapdown_ros.config import Scenario, ScenarioError
from strapdown_ros.nodes._batched import BatchedInputNode
from strapdown_ros.nodes._tf import derived_outputs
from strapdown_ros.nodes.lifecycle import run_node
from strapdown_ros.nodes.parameters import ParameterError, declare_scenario, declare_string
from strapdown_ros.plan import resolve_plan
from strapdown_ros.stages.tf import SolverWithTF, TFStage
from strapdown_ros.stages.variation import IMU, ODOM, VariationStage

NODE_NAME = "variation_node"
#: Input topic parameters and the recording.topics key each defaults to.
INPUT_PARAMETERS = {
    "reference_imu_topic": "reference_imu",
    "reference_odom_topic": "reference_odom",
}
#: Output topic parameters and the recording.topics key each defaults to.
OUTPUT_PARAMETERS = {
    "variation_imu_topic": "variation_imu",
    "variation_odom_topic": "variation_odom",
    "variation_fix_topic": "variation_fix",
    "variation_reference_imu_topic": "variation_reference_imu",
    "variation_reference_odom_topic": "variation_reference_odom",
}


class VariationNode(BatchedInputNode):
    """Reference Imu/Odometry in; variation and regenerated reference out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario = declare_scenario(self)
        if scenario.variation is None:
            raise ScenarioError("variation", "missing: the scenario defines no variation")
        method, gravity = _check_settings(scenario)

        topics = dict(scenario.recording.topics)
        names: dict[str, str] = {}
        for name, key in {**INPUT_PARAMETERS, **OUTPUT_PARAMETERS}.items():
            topic = declare_string(
                self, name, topics[key], f"topic (default recording.topics.{key})"
            )
            if not topic:
                raise ParameterError(name, "must not be empty")
            topics[key] = topic
            names[topic] = name
        used = [topics[k] for k in {**INPUT_PARAMETERS, **OUTPUT_PARAMETERS}.values()]
        for topic in used:
            if used.count(topic) > 1:
                raise ParameterError(names[topic], f"topic {topic} is used twice: {used}")
        # A window has a fixed cost (numpy calls on small arrays) beside its cost per cycle:
        # batches of batch_period_s keep 1 kHz affordable (docs/benchmarks.md).
        self.declare_batched_input("the last cycle")

        self.scenario = scenario.with_recording(topics=topics)
        self.plan = resolve_plan(self.scenario)
        cycles = self.plan.cycles
        log = self.get_logger()
        self.solver = VariationStage(
            self.scenario,
            cycles,
            info=log.info,
            warn=lambda msg: log.warning(msg),
            error=lambda msg: log.error(msg),
        )
        self.inputs = {IMU: topics["reference_imu"], ODOM: topics["reference_odom"]}
        for key in OUTPUT_PARAMETERS.values():
            topic = topics[key]
            msgtype = cdr.NAVSATFIX if key.endswith("fix") else cdr.IMU
            msgtype = cdr.ODOMETRY if key.endswith("odom") else msgtype
            self.add_output(topic, msgtype, names[topic])
        # base_link -> variation_imu (variation truth relative to the reference input) and the
        # map-frame odometry of the outputs
        frames = TFStage(self.plan, offsets=self.solver.offsets)
        outputs = [topics[k] for k in OUTPUT_PARAMETERS.values()]
        derived = derived_outputs(self, self.plan, outputs)
        for topic, msgtype in derived.items():
            self.add_output(topic, msgtype)
        self.solver = SolverWithTF(self.solver, frames, derived, reference_input=ODOM)
        self._input_subscriptions: list = []
        m_var = self.plan.variation_cycles
        log.info(
            f"scenario {scenario.path} ({scenario.name}): reference cycles 0..{cycles} at "
            f"{scenario.rate_hz:g} Hz, variation cycles 0..{m_var}, method {method}, gravity "
            f"{gravity}; input {self.inputs[IMU]}, {self.inputs[ODOM]}; output "
            + ", ".join(self.output_pubs)
        )

    # -- BatchedInputNode hooks -----------------------------------------------------------------

    def _subscribe(self) -> str:
        for kind, topic in self.inputs.items():
            msgtype = cdr.IMU if kind == IMU else cdr.ODOMETRY
            param = next(p for p, k in INPUT_PARAMETERS.items() if k == f"reference_{kind}")
            self._input_subscriptions.append(self.subscribe_input(topic, msgtype, kind, param))
        return f"{self.inputs[IMU]} and {self.inputs[ODOM]}"

    def _idle_stop(self) -> None:
        self.get_logger().warning(
            f"no input for {self.run_control.idle_timeout_s:g} s; stopping before the end of "
            f"the scenario (last published: cycle {self.solver.published})"
        )

    def _summary(self, wall_s: float, cpu_s: float) -> str:
        s = self.solver
        total = sum(self.counts.values())
        lines = [
            f"published {total} messages ({s.published_cycles} cycles, {s.runs} run(s)) in "
            f"{wall_s:.3f} s of wall time; process CPU {cpu_s:.3f} s "
            f"({100 * cpu_s / max(wall_s, 1e-9):.0f} % of one core)",
            f"processing: {s.timing.summary(s.published_cycles)}",
        ]
        lines += [f"  {t}: {n}" for t, n in self.counts.items()]
        return "\n".join(lines)


def _check_settings(scenario: Scenario) -> tuple[int, str]:
    """``variation.method`` / ``gravity`` the node supports (ScenarioError naming the key)."""
    spec = scenario.variation
    assert spec is not None
    if spec.method == 1:
        raise ScenarioError(
            "variation.method",
            "variation_node implements Method 2 only (Method 1's velocity recursion runs "
            "through the whole stream); use strapdown-sim generate for Method 1",
        )
    return spec.method, spec.gravity


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(VariationNode, NODE_NAME, args)
