"""Launch file of the strapdown_ros pipeline (placeholder).

The nodes (trajectory_node, variation_node, navigator_node, bag_recorder) are planned; until
they exist this launch file only declares the ``scenario`` argument and logs a message.
``launch`` / ``launch_ros`` are imported inside :func:`generate_launch_description` so that
this file can be imported (and linted/tested) without a ROS installation.
"""


def generate_launch_description():
    """Return the launch description of the pipeline (placeholder)."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, LogInfo
    from launch.substitutions import LaunchConfiguration

    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "scenario", default_value="", description="path of the scenario YAML file"
            ),
            LogInfo(
                msg=[
                    "strapdown_ros pipeline launch is a placeholder (nodes not implemented yet); "
                    "scenario=",
                    LaunchConfiguration("scenario"),
                ]
            ),
        ]
    )
