"""The exact boundaries over a map: the curves where an equilibrium is degenerate
(G = 0, det H = 0), traced by continuation, their CSV and their overlay on a map.
"""
from __future__ import annotations

from dataclasses import dataclass
import time

import numpy as np

from ..core import ModuleParams
from ..problem import resolve_fields

#: CLI axis names that the exact curves support, and the analysis axis each one is.
#: (Mass axes are not affine in the raw parameters the curves are traced in.)
BOUNDARY_AXES = {'rho': 'rho', 'L1': 'L1', 'L2': 'L2', 'k': 'k', 'ka': 'ka', 'kb': 'kb',
                 'kc': 'kc', 'F': 'F', 'F3': 'F3', 'F4': 'F4', 'F3x': 'f3x', 'F4x': 'f4x'}
#: Styles of the overlay: where the stable count changes, and elsewhere.
#: Continuation step along the curves (arclength in the box scaled to the unit square):
#: at least 200 points per box side, smooth at figure resolution (~0.2-0.7 s per map).
BOUNDARY_STEP = 0.005
BOUNDARY_STYLE = {'color': 'k', 'linestyle': '-', 'linewidth': 1.6}
OTHER_CURVE_STYLE = {'color': '#7a7a7a', 'linestyle': (0, (4, 3)), 'linewidth': 0.8}


@dataclass
class Boundaries:
    """Curves of degenerate equilibria over a map box (``degenerate_curves``)."""

    xname: str
    yname: str
    box: tuple                 # ((xmin, xmax), (ymin, ymax))
    curves: list
    seconds: float = 0.0

    @property
    def points(self):
        return sum(len(c) for c in self.curves)

    def summary(self):
        kinds = {}
        for c in self.curves:
            kinds[c.kind] = kinds.get(c.kind, 0) + 1
        text = ', '.join(f'{n} {k}' for k, n in sorted(kinds.items())) or 'none'
        stable = sum(c.changes_stable_count for c in self.curves)
        n = len(self.curves)
        return (f'boundaries: {n} curve{"" if n == 1 else "s"} ({text}; {stable} change'
                f'{"s" if stable == 1 else ""} the stable count), {self.points} points traced '
                f'by continuation; {self.seconds:.2f} s')


def compute_boundaries(fixed, xaxis, yaxis):
    """Exact curves where an equilibrium is degenerate (G = 0, det H = 0) over a map box.

    ``fixed`` and the axes as for :func:`compute_map` (only the names and ranges of
    the axes are used: the curves are traced by continuation, not sampled).
    """
    from ..core.analysis import degenerate_curves
    xname, xlo, xhi, _ = xaxis
    yname, ylo, yhi, _ = yaxis
    for name in (xname, yname):
        if name not in BOUNDARY_AXES:
            raise ValueError(f'{name} is not an axis of degenerate_curves')
    values = dict(fixed)
    values[xname], values[yname] = xhi, yhi          # replaced along the axes anyway
    base = ModuleParams(**resolve_fields(values))
    t0 = time.perf_counter()
    curves = degenerate_curves(base, BOUNDARY_AXES[xname], (xlo, xhi),
                               BOUNDARY_AXES[yname], (ylo, yhi),
                               step=BOUNDARY_STEP, max_step=BOUNDARY_STEP)
    return Boundaries(xname=xname, yname=yname, box=((xlo, xhi), (ylo, yhi)), curves=curves,
                      seconds=time.perf_counter() - t0)


def write_boundaries_csv(boundaries, stream):
    """Header ``curve,x,y,stable_boundary,kind``, one row per traced point (curves in order)."""
    stream.write('curve,x,y,stable_boundary,kind\n')
    for i, c in enumerate(boundaries.curves):
        for (x, y), flag in zip(c.points, c.stable_boundary):
            stream.write(f'{i},{x:.12g},{y:.12g},{int(bool(flag))},{c.kind}\n')


def _flag_runs(flags):
    """Maximal runs [(flag, start, stop)] of a boolean sequence; neighbouring runs share
    their boundary point so that the drawn curve has no gaps."""
    runs = []
    start = 0
    for i in range(1, len(flags) + 1):
        if i == len(flags) or flags[i] != flags[start]:
            runs.append((bool(flags[start]), start, min(i + 1, len(flags))))
            start = i
    return runs


def draw_boundaries(ax, curves):
    """Overlay the curves: solid black where the stable count changes, thin grey dashed
    elsewhere; returns the legend handles of the styles drawn."""
    from matplotlib.lines import Line2D
    used = set()
    for c in curves:
        pts = np.asarray(c.points)
        if c.closed and len(pts) > 2:
            pts = np.vstack([pts, pts[:1]])
            flags = np.append(c.stable_boundary, c.stable_boundary[:1])
        else:
            flags = np.asarray(c.stable_boundary)
        for flag, a, b in _flag_runs(flags):
            style = BOUNDARY_STYLE if flag else OTHER_CURVE_STYLE
            ax.plot(pts[a:b, 0], pts[a:b, 1], zorder=4, solid_capstyle='round', **style)
            used.add(flag)
    handles = []
    if True in used:
        handles.append(Line2D([], [], **BOUNDARY_STYLE, label='stable count changes (exact)'))
    if False in used:
        handles.append(Line2D([], [], **OTHER_CURVE_STYLE, label='only unstable ones degenerate'))
    return handles
