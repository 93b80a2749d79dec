"""Exact bifurcation analysis of one module: what the paper did in Maple (sections 4-5).

Three tools, numpy/scipy only (no ROS), each in a file named for it; this module
gathers their public names (the path tools and tests import):

:func:`degenerate_curves` (:mod:`.analysis.degenerate_curves`)
    In the plane of two parameters, the curves where some equilibrium is
    degenerate (``G = 0`` and ``det H = 0``), traced by pseudo-arclength
    continuation of the extended system, not read off pixel edges.  Each point
    carries the degenerate configuration, the Hessian eigenvalues there and
    whether a *minimum* degenerates (``lambda_max > 0``: the stable count
    changes across the curve there) or only a saddle/maximum.
:func:`operation_range` (:mod:`.analysis.operation_range`)
    The rho interval (everything else fixed) over which the stable branch
    through a given configuration stays stable, and what ends it at each side
    (``'fold'``, ``'branch_point'`` or the search ``'limit'``), each end located
    by Newton on a regular extended system to ~1e-12.
:func:`two_stable_limit` (:mod:`.analysis.two_stable_limit`)
    Point C of the paper's fig. 6: the tip of the 2-stable region of the
    (rho, F3, F4) space, where the second stable equilibrium is born out of a
    totally degenerate one (``H = 0``, an umbilic).

Their common ground -- the model in raw form, symmetries, planes, extended systems --
is :mod:`.analysis.bifurcation_model`.

Notation.  ``G = dU/dtheta`` and ``H = d2U/dtheta2`` of :mod:`.module`
(unscaled, SI).  The vertical forces used throughout include the rod weights
(``f3y - m1 g / 2``), exactly as the solver does.

Symmetries and why they are special-cased
-----------------------------------------
The generic extended system ``{G = 0, det H = 0}`` in (theta1, theta2, x, y) is
regular at folds, cusps and at the points where a fold curve crosses a line of
exact symmetry.  It is *singular* along curves of symmetry-breaking pitchforks,
which only exist when a symmetry holds on the whole parameter plane: there the
equilibrium set itself self-intersects (``[H | G_x G_y]`` has rank 1), Newton
converges linearly and continuation stalls.  Three symmetries of the model
occur (docs/model.md section 2):

``'swap'``        (t1, t2) -> (t2, t1); needs L1 = L2, ka = kb, F3 = F4, f3x = -f4x.
                  Fixed set t1 = t2; breaking mode (1, -1).  Curve: eq. (15).
``'swap_mirror'`` (t1, t2) -> (-t2, -t1); needs L1 = L2, ka = kb, F3 = -F4,
                  f3x = -f4x.  Fixed set t1 = -t2; breaking mode (1, 1).
``'mirror'``      (t1, t2) -> (-t1, -t2); needs F3 = F4 = 0 (unloaded).  Fixed
                  points: the four flat configurations, equilibria for every
                  parameter value; their degeneracy is ``det H(flat) = 0``, the
                  three lines of DESIGN section 2 when L1 = 1.

When a symmetry holds on the whole plane (checked exactly on the affine
parameter map) a seed that lies on its fixed set with a breaking critical mode
is traced on the *restricted* system instead: ``{g1(t, +-t) = 0,
psi^T H psi = 0}`` in (t, x, y) for the swap symmetries, ``{det H(flat; x, y) =
0}`` in (x, y) for the mirror one.  Both are regular.  The same restricted
systems locate symmetric branch points in :func:`operation_range`.

Parameters of a plane
---------------------
An axis is a name or a dict of coefficients over the raw parameters
(``{'f3y': 1, 'f4y': 0.5}`` is the ray F4 = F3/2).  Names: ``rho``, ``L1``,
``L2``, ``ka``, ``kb``, ``kc``, ``k`` (all three springs), ``f3x``, ``f4x``,
``F3``/``f3y``, ``F4``/``f4y``, ``F`` (f3y = f4y together).  The value of an axis
*replaces* the components it touches (weights are still subtracted from the
vertical forces); all other parameters come from ``base``.
"""

from .bifurcation_model import AXES, BRANCH_POINT, FOLD, LIMIT
from .degenerate_curves import Curve, degenerate_curves
from .operation_range import operation_range, OperationRange, RangeEnd
from .two_stable_limit import two_stable_limit, TwoStableLimit

__all__ = [
    'Curve', 'degenerate_curves', 'RangeEnd', 'OperationRange', 'operation_range',
    'TwoStableLimit', 'two_stable_limit', 'AXES', 'FOLD', 'BRANCH_POINT', 'LIMIT',
]
