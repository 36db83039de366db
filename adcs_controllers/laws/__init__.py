"""Control laws as pure functions of arrays (leading batch axis allowed). No rclpy here."""
