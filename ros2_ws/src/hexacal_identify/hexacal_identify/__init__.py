"""The calibration core (``hexacal_identify.core``, ROS-free), bag I/O, the nodes and the CLI."""
