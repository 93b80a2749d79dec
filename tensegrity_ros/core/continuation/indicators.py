"""Test functions (MATCONT's term; BifurcationKit's event indicators) on the branch.

An event exists only where one of these changes sign between two verified states:

* ``lambda_min`` in scale units (:meth:`.run_state.RunState.margin`): the stability
  matrix loses definiteness (a fold or a branch point of the minimum);
* the branch direction's s-component (:func:`turning`): the branch turns back in s
  while staying stable (a fold seen on an arclength step).

The critical point found is a fold where the critical mode psi is not orthogonal to
F_s (:func:`kind`), else a branch point.  Linkage limits have their own descriptions
(:mod:`.linkage_limits`).
"""
from __future__ import annotations

import numpy as np

from .correctors import curve_tangent
from .results import BRANCH_POINT, FOLD


def turning(run, y, s, direction):
    """The s-component of the branch direction at (y, s), oriented along ``direction``."""
    return curve_tangent(run, y, s, direction)[-1]


def orthogonality(run, y, s, psi):
    """|psi . F_s| / |F_s|: zero at a branch point, where the path does not move the
    equilibrium conditions along the critical mode."""
    fs = run.problem.residual_s(y, s)
    norm = np.linalg.norm(fs)
    return abs(psi @ fs) / norm if norm > 0 else 0.0


def kind(run, y, s, psi):
    """``fold`` or ``branch_point``, by :func:`orthogonality` against ``branch_tol``."""
    return FOLD if orthogonality(run, y, s, psi) > run.settings.branch_tol else BRANCH_POINT
