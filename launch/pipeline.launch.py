"""Launch the strapdown_ros live pipeline on a real ROS 2 Jazzy install (``ros2 launch``).

    ros2 launch strapdown_ros pipeline.launch.py \
        scenario:=/path/to/scenario.yaml [out:=DIR] [force:=true] [duration_s:=60.0] \
        [rate_factor:=1.0]

Starts the nodes the scenario needs (``bag_recorder``, ``trajectory_node`` and those of
``navigator_node``, ``aiding_node``, ``aided_node``, ``transfer_node``, ``imu_model_node``,
``variation_node`` the
scenario has sections for) with ``config/params.yaml`` (installed under
``share/strapdown_ros/config``) and, over it, what :mod:`strapdown_ros.launch_logic` derives
from the scenario at launch time: each node's ``subscribers_per_topic`` (the start-up handshake,
so the start order does not matter and no message is lost, for any scenario), the output
directory (default: a new ``strapdown_run_YYYY_MM_DD-HH_MM_SS`` in the current directory; an
existing ``out:=`` is refused before anything starts unless ``force:=true``), flow control above
real time. When any node exits with an error the whole launch shuts down at once, with the
reason, and ``ros2 launch`` exits with status 1.

This is the pipeline of ``strapdown-sim run``. ``launch`` / ``launch_ros`` are imported inside
the functions so that this file imports (and is linted and tested) without them. The process
running this file needs nothing but the standard library and ``strapdown_ros.launch_logic``'s
stdlib part: the plan is computed by the Python the nodes run with.
"""

#: Every node the launch can start (those a scenario needs: strapdown_ros.launch_logic).
NODES = (
    "trajectory_node",
    "variation_node",
    "imu_model_node",
    "navigator_node",
    "aiding_node",
    "aided_node",
    "transfer_node",
    "bag_recorder",
)


def _nodes(context, params):
    """OpaqueFunction: the launch arguments → the Node actions and their exit handlers."""
    from launch.actions import LogInfo, RegisterEventHandler
    from launch.event_handlers import OnProcessExit
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node
    from launch_ros.substitutions import FindPackagePrefix

    from strapdown_ros.launch_logic import (
        NodeFailedError,
        exit_reason,
        node_interpreter,
        plan_launch_with,
    )

    def arg(name):
        return LaunchConfiguration(name).perform(context)

    # Planned by the nodes' own Python (their executables' #! line), which may be a venv that
    # the Python running ros2 launch does not see (the documented system install).
    python = node_interpreter(FindPackagePrefix("strapdown_ros").perform(context))
    plan = plan_launch_with(
        python, arg("scenario"), arg("out"), force=arg("force"), duration_s=arg("duration_s"),
        rate_factor=arg("rate_factor"),
    )  # fmt: skip
    actions = []
    for node in plan.nodes:
        action = Node(
            package="strapdown_ros",
            executable=node.executable,
            name=node.name,
            output="screen",
            parameters=[params.perform(context), node.parameters],
        )

        def on_exit(event, launch_context, name=node.name):
            # An error here takes launch's own error path: the reason logged as an ERROR, the
            # Shutdown event (reason = that message) stops every node at once, and ros2 launch
            # exits with status 1 (a Shutdown action would end it with status 0). The nodes
            # stopped by that shutdown (or by Ctrl-C) exit afterwards: no second reason.
            reason = exit_reason(name, event.returncode, launch_context.is_shutdown)
            if reason:
                raise NodeFailedError(reason)
            return []

        actions += [action, RegisterEventHandler(OnProcessExit(target_action=action,
                                                               on_exit=on_exit))]  # fmt: skip
    started = ", ".join(n.name for n in plan.nodes)
    return [LogInfo(msg=f"strapdown_ros: recording into {plan.out}; nodes {started}"), *actions]


def generate_launch_description():
    """Return the launch description of the pipeline."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import PathJoinSubstitution
    from launch_ros.substitutions import FindPackageShare

    share = FindPackageShare("strapdown_ros")
    params = PathJoinSubstitution([share, "config", "params.yaml"])
    args = [
        DeclareLaunchArgument(
            "scenario",
            default_value=PathJoinSubstitution([share, "config", "scenarios", "default.yaml"]),
            description="scenario YAML file (docs/scenarios.md)",
        ),
        DeclareLaunchArgument(
            "out", default_value="",
            description="bag directory (default: a new strapdown_run_YYYY_MM_DD-HH_MM_SS in "
            "the current directory)",
        ),  # fmt: skip
        DeclareLaunchArgument(
            "force", default_value="false", choices=["true", "false"],
            description="replace an existing out directory",
        ),  # fmt: skip
        DeclareLaunchArgument(
            "duration_s", default_value="0.0", description="duration (s); 0 = the scenario's"
        ),
        DeclareLaunchArgument(
            "rate_factor", default_value="1.0",
            description="speed over real time; above 1 or <= 0 (unpaced): flow-controlled",
        ),  # fmt: skip
    ]
    return LaunchDescription([*args, OpaqueFunction(function=_nodes, args=[params])])
