"""The ROS 2 nodes (collector, identify, replay, bringup): thin wrappers that declare parameters,
convert messages and call the core."""
