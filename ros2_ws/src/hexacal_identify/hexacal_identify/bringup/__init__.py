"""
Start a hexacal system: which nodes (system), how each is spelled (launch_spec), run them.

Modules: launch_spec (NodeLaunch: one node's executable, parameters, remaps),
system (the nodes of a hexacal system from options or launch arguments, used by
launch/hexacal.launch.py), supervisor (NodeGroup: child processes in their own
process groups, stopped with escalation; also used by ``hexacal demo``) and cli
(the ``bringup`` executable). All of them import without numpy, so that
``bringup --help`` and the launch file stay quick.
"""
