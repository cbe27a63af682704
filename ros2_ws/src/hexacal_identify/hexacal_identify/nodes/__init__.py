"""
The ROS 2 nodes (collector, identify, executor, kinematics, replay): thin ROS wrappers.

They declare parameters, convert messages and call the core; hexacal_identify.bringup starts them.
"""
