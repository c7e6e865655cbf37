"""ROS 2 nodes of strapdown_ros (the only place, with the CLI and bag I/O, that imports rclpy)."""
