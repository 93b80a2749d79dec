"""The mechanism's frames as a chain of planar transforms (what the node puts on /tf).

Module i+1 sits on module i's top chord: its base frame has its origin at A4(i) and its
x-axis along A4(i) -> A3(i) (the design's section 4).  So one frame per module's top chord
(origin A4, x along A4 -> A3, y to the chord's left, i.e. up when the chord is level) is
at once module i's top and module i+1's base, and the chain

    base (origin A1 of the bottom module) -> top chord of m0 -> ... -> top chord of m(N-1)
    -> head (the midpoint of the top chord, same direction)

holds the whole neck.  Each link is given relative to its parent, as TF wants it:
(x, y, yaw) with the child's origin in the parent's coordinates and yaw the child's
x-axis angle from the parent's.  ROS-free (the node turns the links into
geometry_msgs/TransformStamped); tested against the node positions it is built from.
"""
from __future__ import annotations

from dataclasses import dataclass
import math


@dataclass(frozen=True)
class PlanarTransform:
    """A child frame relative to its parent: origin (x, y) in the parent's coordinates (m)
    and the angle ``yaw`` (rad, in (-pi, pi]) of the child's x-axis from the parent's."""

    x: float
    y: float
    yaw: float

    @property
    def quaternion(self):
        """(x, y, z, w) of the rotation by ``yaw`` about z."""
        return (0.0, 0.0, math.sin(0.5 * self.yaw), math.cos(0.5 * self.yaw))


def _wrapped(angle):
    """``angle`` in (-pi, pi]."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def _relative(parent, origin, angle):
    """(x, y, yaw) of a frame at ``origin`` with x-axis angle ``angle`` (both in the base
    frame) seen from ``parent`` = (origin, angle) in the base frame."""
    (px, py), pangle = parent
    dx, dy = origin[0] - px, origin[1] - py
    c, s = math.cos(pangle), math.sin(pangle)
    return PlanarTransform(c * dx + s * dy, -s * dx + c * dy, _wrapped(angle - pangle))


def chord_frames(module_nodes):
    """The chain of ``len(module_nodes) + 1`` links: every module's top-chord frame
    relative to the frame below it (the base frame for the bottom module), then the head
    relative to the top module's chord frame.

    ``module_nodes``: A1..A4 of every module, bottom to top, each four (x, y) points in
    the base frame of the bottom module (what ``Simulator.module_nodes`` gives).
    """
    links = []
    parent = ((0.0, 0.0), 0.0)
    chord = 0.0
    for nodes in module_nodes:
        a3, a4 = nodes[2], nodes[3]
        dx, dy = float(a3[0] - a4[0]), float(a3[1] - a4[1])
        frame = ((float(a4[0]), float(a4[1])), math.atan2(dy, dx))
        links.append(_relative(parent, *frame))
        parent, chord = frame, math.hypot(dx, dy)
    links.append(PlanarTransform(0.5 * chord, 0.0, 0.0))
    return links
