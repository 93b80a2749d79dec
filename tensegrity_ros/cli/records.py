"""The records (JSON-ready dicts) and text pieces that several commands print: a
module's parameters, a neck equilibrium, the head's pose.
"""
from __future__ import annotations

import math


def params_record(p):
    """JSON-ready dict of one module's parameters (SI)."""
    return {name: getattr(p, name) for name in
            ('rho', 'L1', 'L2', 'ka', 'kb', 'kc', 'f3x', 'f3y', 'f4x', 'f4y', 'm1', 'm2')}


def stack_equilibrium_record(e):
    """JSON-ready dict of a StackEquilibrium (radians, SI; eigenvalues in N/m)."""
    return {
        'theta': [[float(a), float(b)] for a, b in e.theta],
        'stable': bool(e.stable),
        'eigenvalues': [float(v) for v in e.eigenvalues],
        'energy': float(e.energy),
        'actuator_forces': [float(v) for v in e.actuator_forces],
        'head': {'x': float(e.head_position[0]), 'y': float(e.head_position[1]),
                 'angle': float(e.head_angle)},
        'residual': float(e.residual),
        'nodes': [[float(x), float(y)] for x, y in e.nodes],
    }


def head_text(e):
    """The head's position and angle as the neck lines print them."""
    angle = round(math.degrees(e.head_angle), 3) + 0.0          # no '-0.000'
    return (f'head ({e.head_position[0]:.6g}, {e.head_position[1]:.6g}) m, '
            f'{angle:.3f} deg')
