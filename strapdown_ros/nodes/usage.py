"""``--help`` and the argument check of the node executables, without importing rclpy.

Each node executable (``setup.py`` console scripts, ``ros2 run strapdown_ros NAME``) enters
here: :func:`front` answers ``-h``/``--help`` with the node's usage (what it does, every
parameter with its default and description; exit status 0) and rejects arguments a node does
not take (exit status 2) before ROS starts; then the node's ``main`` runs. Node parameters are
ROS arguments, ``NAME --ros-args -p name:=value [--params-file FILE]``: everything after
``--ros-args`` (up to a lone ``--``) is left to rclpy, except that a ``-p``/``--param`` naming
no parameter of the node is an error here (rclpy would ignore it silently). Each node's
``main`` calls :func:`front` too, through ``run_node`` (``python -m strapdown_ros.nodes.NAME
--help``; it does nothing the second time in a process).

:data:`PARAMETERS` is what each node declares, in declaration order (checked against the nodes
themselves by ``test/test_node_usage_params.py``; print it anew with
``python test/ros_helpers/node_parameters.py BAG``).
"""

from __future__ import annotations

import difflib
import importlib
import sys
import textwrap
from collections.abc import Callable, Sequence

__all__ = ["DESCRIPTIONS", "PARAMETERS", "front", "usage"]

#: Parameters rclpy declares on every node.
RCLPY_PARAMETERS = ("use_sim_time", "start_type_description_service")

#: What each node does (the first lines of its ``--help``).
DESCRIPTIONS: dict[str, str] = {
    "trajectory_node": (
        "Publishes the reference stream of a scenario live: /reference/imu (exact increments\n"
        "as Imu), /reference/odom, /reference/fix, /clock on simulated time, and TF. Waits for\n"
        "its subscribers (subscribers_per_topic) before the first message, paces at rate_factor\n"
        "x real time and exits after the last message."
    ),
    "variation_node": (
        "Subscribes to the reference IMU and odometry and publishes the variation trajectory\n"
        "(Savage 2020 Method 2: /variation/imu, /variation/odom, /variation/fix) and the\n"
        "regenerated reference (/variation/reference/*), live, byte for byte what\n"
        "`strapdown-sim generate` writes."
    ),
    "navigator_node": (
        "Runs the strapdown navigator (multirate b-l split, or exact mode) on an IMU topic and\n"
        "publishes the solution (/navigator/odom, /navigator/fix) and, with a truth topic, its\n"
        "errors (/navigator/error/*). Settings: the scenario's navigator section, or the\n"
        "parameters below."
    ),
    "imu_model_node": (
        "Applies one of the scenario's IMU error models (imu_errors; parameter model: its\n"
        "index) to an IMU topic and publishes the measured IMU (/variation/imu_measured by\n"
        "default). strapdown-sim run starts one per model: imu_model_node, imu_model_node_1, ..."
    ),
    "aiding_node": (
        "Publishes the scenario's aiding sensors from the reference odometry: GNSS (/gnss/fix,\n"
        "/gnss/vel), barometer (/baro/pressure), magnetometer (/mag), wheel odometer."
    ),
    "aided_node": (
        "Runs the reference aided INS (error-state Kalman filter) on the measured IMU and the\n"
        "aiding sensors and publishes its solution, its errors against the truth and its NEES,\n"
        "innovations and NIS (/aided/*), byte for byte what `strapdown-sim generate` writes."
    ),
    "transfer_node": (
        "Runs the transfer alignment of the variation (slave) IMU's INS: velocity (and attitude)\n"
        "matching against the reference (master) state carried to the slave, with the mounting\n"
        "misalignment as states; publishes the slave solution, its errors against the slave\n"
        "truth, the mounting estimate, its error, σ and NEES (/transfer/*), byte for byte what\n"
        "`strapdown-sim generate` writes."
    ),
    "bag_recorder": (
        "Records topics (the scenario's, or `topics`) into a rosbag2 directory (mcap or\n"
        "sqlite3), flushed every flush_period_s; with stop_when_done it finalizes the bag when\n"
        "every recorded publisher is gone. Refuses an existing `output` unless force:=true\n"
        "(exit status 2)."
    ),
    "bag_player": (
        "Publishes a rosbag2 directory's serialized messages with their original timing\n"
        "(rate_factor x real time), optionally /clock, selected topics and renames."
    ),
}

def _scenario(required: bool = True, what: str = "") -> tuple[tuple[str, object, str], ...]:
    """``scenario``, ``overrides`` and ``duration_s``, as ``nodes.parameters.declare_scenario``
    declares them (``what`` the node takes from the scenario)."""
    return (
        ("scenario", "", f"scenario YAML file{f' ({what})' if what else ''}"
         + (" (required)" if required else "")),
        ("overrides", [""], "scenario overrides dotted.key=value"),
        ("duration_s", 0.0, "duration (s); 0 = the scenario's"),
    )  # fmt: skip


#: Parameters several nodes declare alike: the publishers' QoS, ...
_PUBLISHER_QOS: tuple[tuple[str, object, str], ...] = (
    ("qos_reliability", "reliable", "publisher reliability: reliable | best_effort"),
    ("qos_depth", 1000, "publisher history depth (KEEP_LAST)"),
)
#: ... the subscriptions to wait for, per topic, ...
_SUBSCRIBERS_PER_TOPIC = (
    "subscribers_per_topic", [""], "TOPIC=COUNT: subscriptions to wait for on that topic"
)
#: ... how long to wait for them ...
_WAIT_TIMEOUT = ("wait_timeout_s", 10.0, "seconds to wait")
#: ... and the executor.
_EXECUTOR = ("executor", "events", "rclpy executor: events | single_threaded")

#: What every batched-input node (nodes/_batched.py) declares: its QoS and batching ...
_BATCHED_QOS: tuple[tuple[str, object, str], ...] = (
    *_PUBLISHER_QOS,
    (
        "batch_period_s",
        0.01,
        "longest wait (s) of a received message before it is processed while input keeps "
        "coming: messages are decoded, computed and serialized in batches (latency vs "
        "CPU)",
    ),
)
#: ... and its end, handshake, flow-control and executor parameters.
_BATCHED_TAIL: tuple[tuple[str, object, str], ...] = (
    ("idle_timeout_s", 5.0, "with exit_when_done: exit after this long without input"),
    ("wait_for_subscribers", 0, "output subscriptions to wait for before subscribing"),
    _WAIT_TIMEOUT,
    _SUBSCRIBERS_PER_TOPIC,
    (
        "report_progress",
        False,
        "publish the input taken / output published per topic for flow control "
        "(nodes/flow.py)",
    ),
    _EXECUTOR,
)

#: Every parameter each node declares: (name, default, description), in declaration order.
PARAMETERS: dict[str, tuple[tuple[str, object, str], ...]] = {
    "trajectory_node": (
        *_scenario(),
        ("time_source", "sim", "sim | wall"),
        ("rate_factor", 1.0, "speed-up over real time; <= 0: as fast as possible"),
        (
            "publish_period_s", 0.0,
            "publish in groups of this much data time (s): each message waits for its group's "
            "end, never early, at most this late; 0: every message at its own time",
        ),  # fmt: skip
        ("imu_topic", "/reference/imu", "topic (default recording.topics.reference_imu)"),
        ("odom_topic", "/reference/odom", "topic (default recording.topics.reference_odom)"),
        ("fix_topic", "/reference/fix", "topic (default recording.topics.reference_fix)"),
        ("clock_topic", "/clock", "topic (default recording.topics.clock)"),
        *_PUBLISHER_QOS,
        ("wait_for_subscribers", 0, "subscriptions to wait for before publishing"),
        _SUBSCRIBERS_PER_TOPIC,
        ("wait_for_all_topics", True, "wait on every published topic, not only the IMU"),
        _WAIT_TIMEOUT,
        ("exit_when_done", True, "exit after the last"),
        ("flow_nodes", [""], "flow control: nodes whose progress reports pace the publishing"),
        ("flow_window", 1000, "flow control: messages a consumer may lag"),
        _EXECUTOR,
    ),
    "variation_node": (
        *_scenario(),
        ("reference_imu_topic", "/reference/imu", "topic (default recording.topics.reference_imu)"),
        (
            "reference_odom_topic",
            "/reference/odom",
            "topic (default recording.topics.reference_odom)",
        ),
        ("variation_imu_topic", "/variation/imu", "topic (default recording.topics.variation_imu)"),
        (
            "variation_odom_topic",
            "/variation/odom",
            "topic (default recording.topics.variation_odom)",
        ),
        ("variation_fix_topic", "/variation/fix", "topic (default recording.topics.variation_fix)"),
        (
            "variation_reference_imu_topic",
            "/variation/reference/imu",
            "topic (default recording.topics.variation_reference_imu)",
        ),
        (
            "variation_reference_odom_topic",
            "/variation/reference/odom",
            "topic (default recording.topics.variation_reference_odom)",
        ),
        *_BATCHED_QOS,
        ("exit_when_done", True, "exit after the last cycle or idle_timeout_s"),
        *_BATCHED_TAIL,
    ),
    "navigator_node": (
        *_scenario(False, "its navigator section"),
        ("algorithm", "", "multirate | simultaneous"),
        ("mode", "", "paper | exact"),
        ("imu_topic", "", "input Imu topic (default navigator.imu_topic, /variation/imu)"),
        ("truth_topic", "", "truth Odometry topic; '-' for none"),
        ("initialization", "", "truth | scenario"),
        ("n", 0, "N (0: the scenario's or 10/2)"),
        ("p", 0, "P (0: the scenario's or 10/2)"),
        ("nav_period_s", 0.0, "T_nav (s), a multiple of the IMU period (overrides n)"),
        ("odom_topic", "/navigator/odom", "output topic (recording.topics.navigator_odom)"),
        ("fix_topic", "/navigator/fix", "output topic (recording.topics.navigator_fix)"),
        (
            "error_position_topic",
            "/navigator/error/position",
            "output topic (recording.topics.navigator_error_position)",
        ),
        (
            "error_velocity_topic",
            "/navigator/error/velocity",
            "output topic (recording.topics.navigator_error_velocity)",
        ),
        (
            "error_attitude_topic",
            "/navigator/error/attitude",
            "output topic (recording.topics.navigator_error_attitude)",
        ),
        *_BATCHED_QOS,
        ("exit_when_done", True, "exit after the last output or idle_timeout_s"),
        *_BATCHED_TAIL,
    ),
    "imu_model_node": (
        *_scenario(),
        ("model", 0, "which imu_errors model (its index)"),
        ("input_topic", "/variation/imu", "ideal Imu topic (default imu_errors.input_topic)"),
        ("output_topic", "/variation/imu_measured", "measured Imu topic (imu_errors.output_topic)"),
        *_BATCHED_QOS,
        ("exit_when_done", True, "exit after the last cycle or idle_timeout_s"),
        *_BATCHED_TAIL,
    ),
    "aiding_node": (
        *_scenario(),
        (
            "truth_topic",
            "/reference/odom",
            "truth Odometry topic (default recording.topics.reference_odom)",
        ),
        *_BATCHED_QOS,
        ("exit_when_done", True, "exit after the last truth message or idle_timeout_s"),
        *_BATCHED_TAIL,
    ),
    "aided_node": (
        *_scenario(),
        *_BATCHED_QOS,
        ("exit_when_done", True, "exit after the last IMU cycle or idle_timeout_s"),
        *_BATCHED_TAIL,
    ),
    "transfer_node": (
        *_scenario(),
        *_BATCHED_QOS,
        ("exit_when_done", True, "exit after the last transfer epoch or idle_timeout_s"),
        *_BATCHED_TAIL,
    ),
    "bag_recorder": (
        *_scenario(False, "topic list"),
        ("topics", [""], "topics to record: NAME[=pkg/msg/Type]"),
        ("output", "", "bag directory to write (required)"),
        ("storage", "", "mcap | sqlite3 (default: scenario's)"),
        ("compression", "", "MCAP chunk compression none | zstd | lz4 (default: scenario's, "
         "else none)"),
        ("force", False, "replace an existing bag directory"),
        ("flush_period_s", 1.0, "seconds per flush"),
        ("fsync", False, "fsync the data file at every flush"),
        ("log_time", "header", "header | receive"),
        ("qos_reliability", "auto", "auto | reliable | best_effort"),
        ("qos_depth", 0, "subscription queue depth; 0 = KEEP_ALL"),
        ("discovery_period_s", 0.1, "seconds between looks for new publishers"),
        ("max_duration_s", 0.0, "stop after this many seconds; 0 = until a signal"),
        ("stop_when_done", False, "stop when every recorded topic lost its publishers"),
        ("progress_period_s", 10.0, "seconds between progress lines; 0 = none"),
        (
            "lag_warning_s",
            0.0,
            "real-time runs: warn when a topic's data is this far behind the wall clock; 0 = off",
        ),
        ("drain_timeout_s", 2.0, "at a stop, longest time taking queued messages"),
        (
            "report_progress",
            False,
            "publish the messages recorded per topic for flow control (nodes/flow.py)",
        ),
        _EXECUTOR,
    ),
    "bag_player": (
        ("bag", "", "bag directory to play (required)"),
        ("rate_factor", 1.0, "speed over real time; <= 0: as fast as possible"),
        ("start_offset_s", 0.0, "skip this many seconds from the bag's start"),
        ("duration_s", 0.0, "play this many seconds of the bag from the start; 0: all"),
        ("loop", False, "start over at the end, until stopped"),
        ("topics", [""], "topics to play (default: all)"),
        ("remap", [""], "renames FROM:=TO"),
        ("publish_clock", True, "publish /clock"),
        ("clock_topic", "/clock", "topic of the clock"),
        ("clock_rate_hz", 0.0, "/clock ticks per second of bag time; 0: every log time"),
        ("pacing_warn_ms", 50.0, "warn while playing when publications are later than this; "
         "0: never"),
        ("qos_depth", 1000, "publisher history depth"),
        ("wait_for_subscribers", 0, "subscriptions to wait for on every topic"),
        _WAIT_TIMEOUT,
        ("drain_timeout_s", 10.0, "at the end, longest wait for acknowledgements"),
        ("read_ahead", 20000, "messages buffered ahead of the publisher"),
        ("realtime_priority", 0, "SCHED_FIFO priority of the publishing thread; 0: off"),
        _EXECUTOR,
    ),
}

_HELP = ("-h", "--help")
_PARAM_FLAGS = ("-p", "--param")
_done: set[str] = set()


def _format_default(value: object) -> str:
    if isinstance(value, list) and value == [""]:
        return "[]"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f"'{value}'" if value else "''"
    return repr(value)


def usage(name: str) -> str:
    """The ``--help`` text of node ``name``."""
    lines = [
        f"usage: {name} [-h] [--ros-args -p NAME:=VALUE ... [--params-file FILE]]",
        "",
        DESCRIPTIONS[name],
        "",
        "Exit status: 0 done (also when stopped by SIGINT/SIGTERM), 1 failure while running,",
        "2 invalid argument, parameter or scenario.",
        "",
        "parameters (--ros-args -p NAME:=VALUE):",
    ]
    for pname, default, description in PARAMETERS[name]:
        lines.append(f"  {pname} (default {_format_default(default)})")
        lines += textwrap.wrap(description, 92, initial_indent=" " * 6, subsequent_indent=" " * 6)
    lines += ["", f"example: ros2 run strapdown_ros {name} --ros-args -p "
              "scenario:=config/scenarios/default.yaml"]  # fmt: skip
    return "\n".join(lines)


def _split(args: Sequence[str]) -> tuple[list[str], list[str]]:
    """(non-ROS arguments, ROS arguments) of a command line, as rcl splits them."""
    plain: list[str] = []
    ros: list[str] = []
    in_ros = False
    for arg in args:
        if arg == "--ros-args":
            in_ros = True
        elif in_ros and arg == "--":
            in_ros = False
        elif in_ros:
            ros.append(arg)
        else:
            plain.append(arg)
    return plain, ros


def _fail(name: str, problem: str) -> None:
    print(f"usage: {name} [-h] [--ros-args -p NAME:=VALUE ...]\n{name}: error: {problem}",
          file=sys.stderr)  # fmt: skip
    raise SystemExit(2)


def front(name: str, args: Sequence[str] | None = None) -> None:
    """Handle ``--help`` and bad arguments of node ``name``, then check the Python libraries;
    return to run the node. ``args``: the command line as the node's ``main`` and
    ``rclpy.init`` take it, program name first (default ``sys.argv``).

    Raises SystemExit(0) after printing the help, SystemExit(2) for an argument the node does
    not take, SystemExit(1) for a library older than supported.
    """
    if name in _done:
        return
    plain, ros = _split(list(sys.argv if args is None else args)[1:])
    if any(a in _HELP for a in plain):
        print(usage(name))
        raise SystemExit(0)
    if plain:
        hint = ""
        if any(a in _PARAM_FLAGS or ":=" in a for a in plain):
            hint = "; parameters go after --ros-args: --ros-args -p NAME:=VALUE"
        _fail(name, f"unrecognized arguments: {' '.join(plain)}{hint}")
    known = {p for p, _, _ in PARAMETERS[name]} | set(RCLPY_PARAMETERS)
    for flag, value in zip(ros, ros[1:], strict=False):
        if flag not in _PARAM_FLAGS:
            continue
        pname = value.split(":=", 1)[0]
        if ":=" in value and pname not in known:
            close = difflib.get_close_matches(pname, sorted(known), n=1)
            _fail(name, f"{pname!r} is not a parameter of {name}"
                  + (f" (did you mean {close[0]!r}?)" if close else "")
                  + f"; {name} --help lists them")  # fmt: skip
    from strapdown_ros.requirements_check import exit_if_unsupported

    exit_if_unsupported(name)
    _done.add(name)


def __getattr__(name: str) -> Callable[[], int]:
    """The console script of node ``name`` (the entry points ``strapdown_ros.nodes.usage:NAME``
    of setup.py, one per node of :data:`PARAMETERS`): :func:`front` before the node's module
    (and rclpy) is imported, then the node's ``main``."""
    if name not in PARAMETERS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

    def console_script() -> int:
        front(name)
        return importlib.import_module(f"strapdown_ros.nodes.{name}").main()

    console_script.__name__ = console_script.__qualname__ = name
    console_script.__doc__ = f"Console script ``{name}``."
    return console_script
