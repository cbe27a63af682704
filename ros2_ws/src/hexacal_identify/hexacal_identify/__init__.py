"""hexacal_identify: the calibration core (``hexacal_identify.core``, ROS-free), bag I/O and the
nodes.
"""
