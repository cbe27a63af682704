"""The machine's physics as a MuJoCo model (ROS-free); mujoco itself is imported by its users."""
