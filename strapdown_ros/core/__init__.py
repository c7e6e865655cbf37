"""ROS-free mathematical core of strapdown_ros (numpy/scipy only)."""
