"""rosbag2 input/output: bulk CDR codec (:mod:`.cdr`), bag writer (:mod:`.writer`) and reader
(:mod:`.reader`). Uses ``rosbags`` (no rclpy)."""
