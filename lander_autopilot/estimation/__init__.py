"""Navigation: the error-state Kalman filter that flies on the sensors (core, no rclpy)."""
