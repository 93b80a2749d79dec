"""What RViz and tf draw of the node's state: ``~/head_pose``, ``~/markers`` and ``/tf``.

Each message is pre-built once and updated in place from the core's geometry (the nodes
A1..A4 of each module, the chord frames of :mod:`tensegrity_ros.core.neck.frames`).
"""
from __future__ import annotations

import math

from geometry_msgs.msg import Point, PoseStamped, TransformStamped
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from tensegrity_ros.ros.conversions import ERROR, OK, WARN


class HeadPose:
    """The pre-built ``head_pose`` message (geometry_msgs/PoseStamped), updated in place:
    position = the top chord's midpoint (z = 0), orientation = rotation about z by the
    chord's direction angle, in the frame ``frame_id`` (the stack's base frame)."""

    def __init__(self):
        self.msg = PoseStamped()

    def update(self, position, angle, frame_id, stamp):
        msg = self.msg
        msg.header.frame_id = frame_id
        msg.header.stamp = stamp
        p = msg.pose.position
        p.x, p.y, p.z = float(position[0]), float(position[1]), 0.0
        q = msg.pose.orientation
        q.x, q.y = 0.0, 0.0
        q.z, q.w = math.sin(0.5 * angle), math.cos(0.5 * angle)
        return msg


def _color(r, g, b, a=1.0):
    return ColorRGBA(r=float(r), g=float(g), b=float(b), a=float(a))


#: Rod / node colour by status level: green stable, orange near a jump, red otherwise.
LEVEL_COLORS = {
    OK: _color(0.1, 0.75, 0.2),
    WARN: _color(1.0, 0.55, 0.0),
    ERROR: _color(0.9, 0.1, 0.1),
}
SPRING_COLOR = _color(0.2, 0.45, 0.95, 0.9)
ACTUATOR_COLOR = _color(0.55, 0.55, 0.55)

#: Marker ids within a module's namespace.
MARKER_RODS, MARKER_ACTUATOR, MARKER_SPRINGS, MARKER_NODES = 0, 1, 2, 3


class ModuleMarkers:
    """The four markers of one module (rods, actuator, springs, nodes), updated in place.

    Points are in the module's base frame (origin A1, x along A1->A2, y up, z = 0):
    the ``frame_id`` parameter names that frame.
    """

    def __init__(self, module: str):
        def marker(kind, ident, color):
            m = Marker(ns=module, id=ident, type=kind, action=Marker.ADD)
            m.pose.orientation.w = 1.0
            m.color = color
            return m

        self.rods = marker(Marker.LINE_LIST, MARKER_RODS, LEVEL_COLORS[OK])
        self.actuator = marker(Marker.LINE_LIST, MARKER_ACTUATOR, ACTUATOR_COLOR)
        self.springs = marker(Marker.LINE_LIST, MARKER_SPRINGS, SPRING_COLOR)
        self.nodes = marker(Marker.SPHERE_LIST, MARKER_NODES, LEVEL_COLORS[OK])
        self.markers = [self.rods, self.actuator, self.springs, self.nodes]

    def update(self, positions, level, frame_id, stamp, size):
        """``positions``: A1..A4 as a (4, 2) array; ``size``: a length scale (m)."""
        a1, a2, a3, a4 = (Point(x=float(p[0]), y=float(p[1]), z=0.0) for p in positions)
        color = LEVEL_COLORS.get(level, LEVEL_COLORS[ERROR])
        self.rods.points = [a1, a3, a2, a4]
        self.rods.color = color
        self.rods.scale.x = 0.02 * size
        self.actuator.points = [a1, a2]
        self.actuator.scale.x = 0.03 * size
        self.springs.points = [a2, a3, a1, a4, a3, a4]     # springs a, b, c
        self.springs.scale.x = 0.008 * size
        self.nodes.points = [a1, a2, a3, a4]
        self.nodes.color = color
        self.nodes.scale.x = self.nodes.scale.y = self.nodes.scale.z = 0.05 * size
        for m in self.markers:
            m.header.frame_id = frame_id
            m.header.stamp = stamp
        return self.markers


def marker_array(markers) -> MarkerArray:
    return MarkerArray(markers=list(markers))


class FrameChain:
    """The /tf transforms of the frame chain (``core.frames.chord_frames``), pre-built and
    updated in place: ``parent`` -> ``children[0]`` -> ``children[1]`` ... (each module's
    top chord, then the head)."""

    def __init__(self, parent, children):
        self.transforms = []
        for frame in children:
            t = TransformStamped()
            t.header.frame_id, t.child_frame_id = parent, frame
            self.transforms.append(t)
            parent = frame

    def update(self, links, now_ns):
        """The transforms with the planar ``links`` (x, y, yaw) and the stamp ``now_ns``."""
        sec, nanosec = divmod(now_ns, 1_000_000_000)
        for t, link in zip(self.transforms, links):
            t.header.stamp.sec, t.header.stamp.nanosec = sec, nanosec
            v = t.transform.translation
            v.x, v.y, v.z = float(link.x), float(link.y), 0.0
            q = t.transform.rotation
            q.x, q.y, q.z, q.w = link.quaternion
        return self.transforms
