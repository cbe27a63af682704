"""The machine's drawing as RViz markers (the kinematics node's hexacal/machine_markers)."""

from __future__ import annotations

from collections.abc import Mapping

from geometry_msgs.msg import Point
import numpy as np
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

# Marker style per drawing name: RGBA and size (m; sphere diameter or line width).
MARKER_STYLES: dict[str, tuple[tuple[float, float, float, float], float]] = {
    'base_joints': ((0.35, 0.35, 0.35, 1.0), 0.04),
    'rails': ((0.55, 0.55, 0.55, 1.0), 0.012),
    'sliders': ((0.10, 0.40, 0.90, 1.0), 0.045),
    'cylinders': ((0.15, 0.25, 0.70, 1.0), 0.035),
    'legs': ((0.20, 0.60, 0.95, 1.0), 0.014),
    'platform_joints': ((0.95, 0.55, 0.10, 1.0), 0.03),
    'platform': ((0.95, 0.55, 0.10, 1.0), 0.016),
    'device_link': ((0.15, 0.80, 0.25, 1.0), 0.008),
}
DEFAULT_STYLE = ((0.8, 0.8, 0.8, 1.0), 0.01)  # of any other drawing name


def machine_markers(drawing: Mapping[str, np.ndarray], frame_id: str, stamp) -> MarkerArray:
    """
    Return the MarkerArray of an Architecture.drawing.

    One marker per name (namespace = the name, id 0): points as a SPHERE_LIST, segments as a
    LINE_LIST.
    """
    header = Header(stamp=stamp, frame_id=frame_id)
    markers = []
    for name in sorted(drawing):
        array = np.asarray(drawing[name], dtype=float)
        (r, g, b, a), size = MARKER_STYLES.get(name, DEFAULT_STYLE)
        marker = Marker(
            header=header,
            ns=name,
            id=0,
            action=Marker.ADD,
            type=Marker.SPHERE_LIST if array.ndim == 2 else Marker.LINE_LIST,
            color=ColorRGBA(r=r, g=g, b=b, a=a),
        )
        marker.pose.orientation.w = 1.0
        marker.scale.x = marker.scale.y = marker.scale.z = size
        marker.points = [
            Point(x=float(x), y=float(y), z=float(z)) for x, y, z in array.reshape(-1, 3)
        ]
        markers.append(marker)
    return MarkerArray(markers=markers)
