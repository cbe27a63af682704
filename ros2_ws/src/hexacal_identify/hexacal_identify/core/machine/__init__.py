"""
The machine model: parameters, kinematics, the measuring device and its readings.

Start here to know what a machine is to hexacal.

* ``model``: kinematic parameters, the generic parts and the nominal sets.
* ``kinematics``: inverse and forward kinematics of any architecture, batched.
* ``device``: the measuring link, its U joints, inclinometer and rotary sensor (eq. 4).
* ``measurements``: measured postures and their simulation.
* ``postures``: measurement postures over a workspace.
* ``angle_conventions``: hexacal's angles <-> LinuxCNC genhexkins' and ROS's.
* ``live``: the calibrated model at work (pose of readings, targets of a pose).

The architectures themselves live in ``core.architectures``.
"""
