"""
The measuring device during a walk: its inclinometer judged, its turns set (ROS-free).

Used by the walk (``core.walk.execution``) and the executor node.

* ``inclinometer``: settled inclinometer readings for fixed-position corrections.
* ``turns``: turning the device about its link axis during a plan, and telling the nodes.
"""
