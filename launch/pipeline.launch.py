"""Launch the strapdown_ros live pipeline on a real ROS 2 Jazzy install (``ros2 launch``).

    ros2 launch strapdown_ros pipeline.launch.py \
        scenario:=/path/to/scenario.yaml out:=/tmp/strapdown_run duration_s:=60.0

Starts ``trajectory_node``, ``variation_node``, ``imu_model_node``, ``navigator_node``,
``aiding_node`` and
``bag_recorder`` with
``config/params.yaml`` (installed under ``share/strapdown_ros/config``) and the scenario file;
the nodes' start-up handshake (``subscribers_per_topic``) makes the start order irrelevant.
This is the same pipeline as ``strapdown-sim run`` (which also computes the per-topic
subscription counts for scenarios other than ``default.yaml``). ``launch`` / ``launch_ros`` are
imported inside :func:`generate_launch_description` so that this file imports (and is linted
and tested) without them.
"""

NODES = (
    "trajectory_node",
    "variation_node",
    "imu_model_node",
    "navigator_node",
    "aiding_node",
    "bag_recorder",
)


def generate_launch_description():
    """Return the launch description of the pipeline."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument
    from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
    from launch_ros.actions import Node
    from launch_ros.substitutions import FindPackageShare

    share = FindPackageShare("strapdown_ros")
    scenario = LaunchConfiguration("scenario")
    duration = LaunchConfiguration("duration_s")
    params = PathJoinSubstitution([share, "config", "params.yaml"])
    args = [
        DeclareLaunchArgument(
            "scenario",
            default_value=PathJoinSubstitution([share, "config", "scenarios", "default.yaml"]),
            description="scenario YAML file (docs/interface.md §5)",
        ),
        DeclareLaunchArgument("out", default_value="strapdown_run", description="bag directory"),
        DeclareLaunchArgument(
            "duration_s", default_value="0.0", description="duration (s); 0 = the scenario's"
        ),
        DeclareLaunchArgument(
            "rate_factor", default_value="1.0", description="speed over real time"
        ),
    ]
    common = {"scenario": scenario, "duration_s": duration}
    nodes = [
        Node(
            package="strapdown_ros",
            executable="trajectory_node",
            name="trajectory_node",
            output="screen",
            parameters=[params, common, {"rate_factor": LaunchConfiguration("rate_factor")}],
        ),
        Node(
            package="strapdown_ros",
            executable="variation_node",
            name="variation_node",
            output="screen",
            parameters=[params, common],
        ),
        Node(
            package="strapdown_ros",
            executable="imu_model_node",
            name="imu_model_node",
            output="screen",
            parameters=[params, common],
        ),
        Node(
            package="strapdown_ros",
            executable="navigator_node",
            name="navigator_node",
            output="screen",
            parameters=[params, common],
        ),
        Node(
            package="strapdown_ros",
            executable="aiding_node",
            name="aiding_node",
            output="screen",
            parameters=[params, common],
        ),
        Node(
            package="strapdown_ros",
            executable="bag_recorder",
            name="bag_recorder",
            output="screen",
            parameters=[params, {"scenario": scenario, "output": LaunchConfiguration("out")}],
        ),
    ]
    return LaunchDescription([*args, *nodes])
