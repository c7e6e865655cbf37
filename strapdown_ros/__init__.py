"""strapdown_ros: exact synthetic strapdown inertial data and navigation for ROS 2."""

__version__ = "0.1.0"
