"""Maps and bifurcation diagrams of one module (the paper's figures 3-5, 7, 8), by kind:
:mod:`.maps` (the number of stable equilibria over a parameter plane), :mod:`.boundaries`
(the exact curves over a map), :mod:`.diagram` (equilibria against rho, with folds and
branch points), :mod:`.tracked_path` (the quasi-static path over a diagram) and
:mod:`.diagram_plot` (its PNG).

Computation is numpy-only; matplotlib is imported (Agg, no display) only by the
``plot_*`` functions.  The ``tensegrity map`` and ``tensegrity diagram`` commands are
thin wrappers around this package.
"""
from .boundaries import (Boundaries, BOUNDARY_AXES, BOUNDARY_STEP, BOUNDARY_STYLE,
                         compute_boundaries, draw_boundaries, OTHER_CURVE_STYLE,
                         write_boundaries_csv)
from .diagram import Branch, compute_diagram, Diagram, DiagramEvent, write_diagram_csv
from .diagram_plot import plot_diagram, STABLE_STYLE, UNSTABLE_STYLE
from .maps import (AXIS_LABELS, compute_map, COUNT_COLOURS, COUNT_LABELS, MAP_CHUNK,
                   MapResult, PARALLEL_THRESHOLD, plot_map, PROGRESS_THRESHOLD, read_map_csv,
                   write_map_csv)
from .tracked_path import track_path, TrackedPath, TrackLeg

__all__ = ['AXIS_LABELS', 'BOUNDARY_AXES', 'BOUNDARY_STEP', 'BOUNDARY_STYLE', 'Boundaries',
           'Branch', 'COUNT_COLOURS', 'COUNT_LABELS', 'Diagram', 'DiagramEvent', 'MAP_CHUNK',
           'MapResult', 'OTHER_CURVE_STYLE', 'PARALLEL_THRESHOLD', 'PROGRESS_THRESHOLD',
           'STABLE_STYLE', 'TrackLeg', 'TrackedPath', 'UNSTABLE_STYLE', 'compute_boundaries',
           'compute_diagram', 'compute_map', 'draw_boundaries', 'plot_diagram', 'plot_map',
           'read_map_csv', 'track_path', 'write_boundaries_csv', 'write_diagram_csv',
           'write_map_csv']
