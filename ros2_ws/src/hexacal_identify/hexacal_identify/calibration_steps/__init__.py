"""
The steps of a calibration, shared by the identify node and ``hexacal calibrate``: no rclpy.

Start at ``calibration_run.calibrate``, the one calibration call: a bag calibrated offline
gives the same parameters as the node that received the same postures.

* ``machine_files``: a parameters file -> the machine (``load_machine_and_extras``, the one
  loader, and ``load_machine_and_mount`` on it), the device defects and compliances to and
  from its extra keys.
* ``posture_checks``: postures of the right model (``check_model``), within the sensors'
  ranges (``posture_problem`` and its reason codes), stacked into Measurements.
* ``calibration_run``: ``calibrate``, what weighs it, its status fields.
* ``bag_postures``: bag -> postures (``postures_from_bag``): the posture topic, else re-detected.
* ``bag_checks``: a bag's topic types and schemas, decoded messages, the model that recorded it.
* ``redetection``: postures re-detected from the raw input streams by the settled detector.

The modules import what they use only: import the one you need.
"""
