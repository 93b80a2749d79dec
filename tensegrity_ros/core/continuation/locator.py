"""Locate where a test function changes sign between two verified states (scipy's
``solve_ivp`` events, BifurcationKit's bisection of event indicators): a bracket
extended by the secant, narrowed by bracketed secant steps to ~1e-12 in s, and the
root kept only where lambda_min ~ 0 there."""
from __future__ import annotations

import numpy as np

from . import indicators
from .correctors import arc_point, pinned_newton
from .results import BRANCH_POINT


class Lost(Exception):
    """A corrector left the branch (no convergence, or converged too far away)."""


def bracket(test, a, b, tries=8):
    """(a, b, test(a), test(b)) with test(b) < 0 where it can be reached.

    b is a verified indefinite state, so lambda_min there is below a tolerance
    but may still be positive: extend the bracket past it by the secant.
    """
    test_a, test_b = test(a), test(b)
    for _ in range(tries):
        slope = (test_a - test_b) / (b - a)
        if test_b < 0.0 or not slope > 0.0:
            break
        a, test_a, b = b, test_b, b + 2.0 * test_b / slope
        test_b = test(b)
    return a, b, test_a, test_b


def _probe(test, t, a, b, test_a, test_b):
    """One probe of :func:`shrink_bracket`: (a, b, test_a, test_b, probed)."""
    try:
        value = test(t)
    except Lost:
        return a, b, test_a, test_b, False
    if value > 0.0 and t > a:
        a, test_a = t, value
    elif value <= 0.0 and t < b:
        b, test_b = t, value
    return a, b, test_a, test_b, True


def shrink_bracket(test, a, b, test_a, test_b, xtol=1e-12):
    """Narrow [a, b] (test(a) > 0 > test(b)) around the root to about xtol.

    Secant estimates, each bracketed by two probes 2% of the width either side,
    so a test function that is nearly linear there (lambda_min at a simple
    crossing) shrinks the bracket ~25-fold per round.  Probes that cannot be
    solved (a singular Jacobian right at the root) are skipped.  An end kept for
    a second round in a row has its value halved in the secant (the Illinois rule):
    a test function far from linear (7.8e-2 at one end of an arc step, -4.7e-4 at the
    other, on the nearly symmetric N = 5 paper neck) otherwise moved the other end
    ~2.5 % per round, all 60 rounds, 120 probes.
    """
    kept = [0, 0]                           # rounds in a row each end was kept
    for _ in range(60):
        width = b - a
        if width <= xtol * max(1.0, abs(b)):
            break
        weight_a, weight_b = 0.5 ** max(kept[0] - 1, 0), 0.5 ** max(kept[1] - 1, 0)
        guess = a + width * weight_a * test_a / (weight_a * test_a - weight_b * test_b)
        nudge = 0.02 * width
        progress, before = False, (a, b)
        for t in sorted({min(max(guess - nudge, a + nudge), b - nudge),
                         min(max(guess + nudge, a + nudge), b - nudge)}):
            if a < t < b:                   # (the first probe may have moved an end)
                a, b, test_a, test_b, probed = _probe(test, t, a, b, test_a, test_b)
                progress = progress or probed
        if not progress:
            break
        kept = [kept[0] + 1 if a == before[0] else 0, kept[1] + 1 if b == before[1] else 0]
    return a, b, test_a, test_b


def _root(test, point, a, b):
    """(y*, s*) at the located root of ``test`` in [a, b], or None (raises Lost and
    the solvers' errors)."""
    with np.errstate(all='ignore'):
        a, b, test_a, test_b = bracket(test, a, b)
        if not test_a > 0.0:
            return None
        if test_b >= 0.0:           # indefinite by the tolerance only: b is critical
            a, test_a = b, 0.0
        else:
            a, b, test_a, test_b = shrink_bracket(test, a, b, test_a, test_b)
        root_at = a + (b - a) * test_a / (test_a - test_b) if test_a > 0.0 else a
    try:
        return point(root_at)
    except Lost:                   # singular right at the root: its verified neighbour
        y_star, s_star = point(a)
        s_star = s_star + (root_at - a) * (s_star - point(b)[1]) / (a - b) if b != a else s_star
        return y_star, s_star


def critical_point(run, test, point, a, b):
    """Root of a test function bracketed by two verified states, checked to be
    critical (lambda_min ~ 0); returns (kind, s, y) or ``None``."""
    try:
        found = _root(test, point, a, b)
    except (Lost, ValueError, ZeroDivisionError, np.linalg.LinAlgError):
        return None
    if found is None:
        return None
    y_star, s_star = found
    if not run.residual_ok(y_star, s_star):
        # not an equilibrium at s*: the neighbour a lost root fell back on, moved in s
        # only (a module landed 4e-5 in rho past rho = L under a 1e-6 N load: its arc
        # steps back met such a 'fold', the state 1e-6 N out of balance)
        return None
    lam, psi = run.critical(y_star, s_star)
    if abs(lam) > run.settings.critical_tol:
        return None
    return indicators.kind(run, y_star, s_star, psi), s_star, y_star


def crossing_on_path(run, y, s, tangent, s_bad):
    """The critical point where lambda_min crosses zero between the verified (y, s)
    and the verified indefinite state at s_bad (natural parametrisation).

    A probe is Newton from the prediction; where that fails or lands far next to a
    branch point (the critical mode orthogonal to F_s at the start), the bordered
    corrector (:func:`.correctors.pinned_newton`).  There Newton's update along the soft
    mode is rounding over lambda_min: within ~1.5e-9 in s of the perfect N = 3 chord
    ramp's branch point every natural probe was lost, and the event was located on
    arclength points instead, 1.4e-9 .. 3.7e-9 in s off on the Sandybridge and Haswell
    BLAS kernels (H30).  Not next to an imperfect one: its soft mode is not a symmetry's,
    and pinned states there, equilibria to the residual test only because lambda_min is
    ~1e-11 of lambda_max, made false folds (the 1e-9-imperfect N = 5 paper neck)."""
    pinning = []

    def point(t):
        predicted = y + (t - s) * tangent
        near = 0.5 * abs(t - s) * run.step_norm(tangent) + run.settings.same_state_tol
        found = run.newton(predicted, t)
        if found is None or run.step_norm(found - predicted) > near:
            if not pinning:
                pinning.append(indicators.kind(run, y, s, run.critical(y, s)[1]) == BRANCH_POINT)
            # (nor next to a flat module: there the Jacobian's singular direction is its
            # chord's, and the lost probes are unresolved points, which must not bracket
            # a fold: bench_round_commands seed 1 stream 12; H30, e506e01)
            found = (pinned_newton(run, predicted, t)
                     if pinning[0] and not run.linkage_limit(predicted, t) else None)
            if found is None or run.step_norm(found - predicted) > near:
                raise Lost
        return found, t

    return critical_point(run, lambda t: run.margin(*point(t)), point, s, s_bad)


def crossing_on_arc(run, y, s, direction, h, definite_at_end):
    """The critical point on the arclength step of length h from (y, s) along
    ``direction``: where lambda_min crosses zero, or (where the step's end is still
    definite) where the branch turns back in s."""
    def point(hh):
        found = arc_point(run, y, s, direction, hh)
        if found is None:
            raise Lost
        return found

    if not definite_at_end:
        def test(hh):
            return run.margin(*point(hh))
    else:                       # the branch turned back in s while staying stable
        def test(hh):
            return indicators.turning(run, *point(hh), direction)
    return critical_point(run, test, point, 0.0, h)
