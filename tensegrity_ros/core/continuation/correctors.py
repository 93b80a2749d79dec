"""The branch as a curve in (y, s): its tangent and the pseudo-arclength corrector.

The natural corrector (Newton at fixed s) is :meth:`.run_state.RunState.newton`; here
is the one that is regular at folds, on the hyperplane normal to the branch direction
(BifurcationKit's ``PALC``)."""
from __future__ import annotations

import math

import numpy as np

from .run_state import inf_norm
from .settings import ARC_RESOLUTION


def curve_tangent(run, y, s, reference=None):
    """Unit null vector of [F_y F_s] (the branch's direction in (y, s)), oriented
    along ``reference`` (or towards growing s); regular at folds, unlike dy/ds."""
    problem = run.problem
    matrix = np.column_stack([problem.jacobian(y, s), problem.residual_s(y, s)])
    direction = np.linalg.svd(matrix)[2][-1]
    along = direction @ reference if reference is not None else direction[-1]
    return -direction if along < 0.0 else direction


def _extended_newton(run, z0, direction, h):
    """Newton on {F(y, s) = 0, direction . (z - z0 - h direction) = 0}: (z, predicted,
    last applied update or None), or None where a solve fails."""
    problem, n = run.problem, run.problem.size
    predicted = z0 + h * direction
    z = predicted.copy()
    matrix = np.empty((n + 1, n + 1))
    matrix[n] = direction
    previous, applied = math.inf, None
    for _ in range(run.settings.newton_iterations):
        y, s = z[:n], z[n]
        matrix[:n, :n] = problem.jacobian(y, s)
        matrix[:n, n] = problem.residual_s(y, s)
        rhs = np.append(problem.residual(y, s), direction @ (z - predicted))
        try:
            delta = np.linalg.solve(matrix, rhs)
        except np.linalg.LinAlgError:
            return None
        size = inf_norm(delta)
        if not math.isfinite(size) or size > 0.5 * previous + 1e-15:
            break
        z, previous, applied = z - delta, size, delta
        if size <= 1e-14 * (1.0 + inf_norm(z)):
            break
    return z, predicted, applied


def arc_point(run, y0, s0, direction, h, any_s=False):
    """Pseudo-arclength corrector: the branch point on the hyperplane through
    (y0, s0) + h direction normal to direction; ``None`` unless it converges near it.

    ``any_s``: near it in the state only, at whatever s (a bifurcated branch off a
    branch point, ``direction`` the critical mode: its s - s* ~ h^2 / c is in the
    path's own units, 1e6 commands away for a command 1e-9 in rho long)."""
    n = run.problem.size
    found = _extended_newton(run, np.append(y0, s0), direction, h)
    if found is None:
        return None
    z, predicted, applied = found
    y, s = z[:n], float(z[n])
    # the extended system is regular at folds, so it converges to rounding level;
    # where it does not (a singular linkage limit), the step is refused
    miss = z - predicted
    if (applied is None or not run.step_norm(applied[:n]) <= ARC_RESOLUTION
            or not run.residual_ok(y, s, 1e-3)
            or inf_norm(miss[:n] if any_s else miss) > 0.5 * h + run.settings.same_state_tol):
        return None
    if not run.energy_consistent(y0, s0, y, s):
        return None
    return y, s
