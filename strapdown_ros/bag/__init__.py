"""rosbag2 input/output: bulk CDR codec (:mod:`.cdr`), bag writer (:mod:`.writer`) and reader
(:mod:`.reader`); for live recording and playback (docs/recording.md) the incremental writer
(:mod:`.incremental`), the recorder's bookkeeping (:mod:`.recording`, :mod:`.payload`), the
player's source (:mod:`.playback`) and the repair of interrupted recordings (:mod:`.repair`).
Uses ``rosbags`` (no rclpy)."""
