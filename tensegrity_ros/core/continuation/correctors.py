"""The branch as a curve in (y, s): its tangent and the pseudo-arclength corrector.

The natural corrector (Newton at fixed s) is :meth:`.run_state.RunState.newton`; here
is the one that is regular at folds, on the hyperplane normal to the branch direction
(BifurcationKit's ``PALC``)."""
from __future__ import annotations

import math

import numpy as np

from .run_state import inf_norm
from .settings import ARC_RESOLUTION
from ..numerics import bounded_work


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


def pinned_newton(run, y, s):
    """Newton with the state's component along the Jacobian's softest direction held at
    y's: the bordered system {F(x, s) + beta u = 0, v . (x - y) = 0} (u, v the Jacobian's
    left and right singular vectors of its smallest singular value at y), regular where
    the Jacobian is singular along v (a branch point).  ``None`` unless it converges to a
    residual within the tolerance (beta ~ 0: an equilibrium through that hyperplane
    exists next to y).  (H30, issue 30: within ~1.5e-9 in s of the perfect N = 3 chord
    ramp's branch point Newton's update along the soft mode is rounding over lambda_min
    and every natural probe was lost.)"""
    u, v = null_vectors(run, y, s)
    if u is None:
        return None
    found = bordered_newton(run, y, s, u, v)
    return found[0] if found is not None and run.residual_ok(found[0], s) else None


def null_vectors(run, y, s):
    """(u, v): the Jacobian's left and right singular vectors of its smallest singular
    value at (y, s), or (None, None) where the SVD fails."""
    try:
        u_all, _, vt = np.linalg.svd(run.problem.jacobian(y, s))
    except np.linalg.LinAlgError:
        return None, None
    return u_all[:, -1], vt[-1]


def bordered_newton(run, y, s, u, v, offset=0.0):
    """Newton on the bordered system {F(x, s) + beta u = 0, v . (x - y) = offset} from
    y + offset v, regular where the Jacobian is singular along v: (x, beta, converged)
    where it stops (its update at rounding level: ``converged``; or no longer
    contracting), or None where a solve fails."""
    problem, n = run.problem, y.size
    matrix = np.zeros((n + 1, n + 1))
    matrix[:n, n], matrix[n, :n] = u, v
    x, beta, previous = np.array(y, dtype=float) + offset * v, 0.0, math.inf
    for _ in range(run.settings.newton_iterations):
        matrix[:n, :n] = problem.jacobian(x, s)
        rhs = np.append(problem.residual(x, s) + beta * u, v @ (x - y) - offset)
        try:
            delta = np.linalg.solve(matrix, rhs)
        except np.linalg.LinAlgError:
            return None
        size = inf_norm(delta[:n])
        if not math.isfinite(size) or size > 0.5 * previous + 1e-15:
            return x, beta, False
        x, beta, previous = x - delta[:n], beta - delta[n], size
        if size <= 1e-14 * (1.0 + inf_norm(x)):
            return x, beta, True
    return x, beta, False


def solve_branch_point(run, y, s):
    """(y*, s*) of the branch point next to (y, s), to rounding, or ``None``: Newton
    (finite-difference Jacobian) on the regular extended system of docs/model.md section 3,
    {F(y, s) + beta u0 = 0, lambda_min(y, s) = 0, u(y, s) . F_s(y, s) = 0}, u the
    Jacobian's left singular vector of its smallest singular value (u0, the start's, in
    the unfolding term).  Regular at a simple branch point: lambda_min fixes s*, u . F_s
    the state along the critical mode, beta the unfolding.  Accepted where beta and the
    residual vanish to the tolerance and the solution stays within ``passage_radius`` of
    y.  (H30, issue 30.)"""
    problem, n = run.problem, run.problem.size
    try:
        u0 = np.linalg.svd(problem.jacobian(y, s))[0][:, -1]
    except np.linalg.LinAlgError:
        return None

    def system(z):
        x, t = z[:n], z[n]
        u = np.linalg.svd(problem.jacobian(x, t))[0][:, -1]
        return np.concatenate([problem.residual(x, t) + z[n + 1] * u0,
                               [run.eigenvalues(x, t)[0] / run.scale,
                                u @ problem.residual_s(x, t)]])

    z = _fd_newton(run, system, np.append(np.asarray(y, dtype=float), [s, 0.0]))
    if z is None:
        return None
    x, t = z[:n], float(z[n])
    if (not run.residual_ok(x, t) or run.separation(x, y) > run.settings.passage_radius
            or abs(run.eigenvalues(x, t)[0]) > run.settings.critical_tol * run.scale):
        return None
    return x, t


def _fd_newton(run, system, z, h=1e-7):
    """Newton on ``system`` from z with a forward-difference Jacobian; None where a
    solve fails or an update is not finite."""
    try:
        for _ in range(run.settings.newton_iterations):
            bounded_work.checkpoint()
            f = system(z)
            jac = np.column_stack([(system(z + h * e) - f) / h for e in np.eye(z.size)])
            delta = np.linalg.solve(jac, f)
            if not np.all(np.isfinite(delta)):
                return None
            z = z - delta
            if inf_norm(delta) <= 1e-14 * (1.0 + inf_norm(z)):
                break
    except np.linalg.LinAlgError:
        return None
    return z
