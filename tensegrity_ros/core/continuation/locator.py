"""Locate where a test function changes sign between two verified states (scipy's
``solve_ivp`` events, BifurcationKit's bisection of event indicators): a bracket
extended by the secant, narrowed by bracketed secant steps to ~1e-12 in s, and the
root kept only where lambda_min ~ 0 there."""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from . import indicators
from .correctors import arc_point


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
    solved (a singular Jacobian right at the root) are skipped.
    """
    for _ in range(60):
        width = b - a
        if width <= xtol * max(1.0, abs(b)):
            break
        guess = a + width * test_a / (test_a - test_b)
        nudge = 0.02 * width
        progress = False
        for t in sorted({min(max(guess - nudge, a + nudge), b - nudge),
                         min(max(guess + nudge, a + nudge), b - nudge)}):
            a, b, test_a, test_b, probed = _probe(test, t, a, b, test_a, test_b)
            progress = progress or probed
        if not progress:
            break
    return a, b, test_a, test_b


def _brent(test, a, b, test_a, test_b, xtol=1e-12):
    """The root of ``test`` in [a, b] (test(a) > 0 > test(b)) by scipy's brentq, to
    about xtol: (a, b, test_a, test_b) with a = b = the root, test_a = 0; where a probe
    cannot be solved (a singular Jacobian right at the root), :func:`shrink_bracket`,
    which skips such probes.  (Brent's bisection steps bound the work where the test
    function is far from linear, e.g. where the corrector's points leave the branch:
    the secant with its 2 % probes then moved one end 2 % a round, 120 probes a root.)"""
    try:
        root = brentq(test, a, b, xtol=xtol * max(1.0, abs(b)), rtol=4.0 * np.finfo(float).eps)
    except Lost:
        return shrink_bracket(test, a, b, test_a, test_b, xtol)
    return root, root, 0.0, test_b


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
            a, b, test_a, test_b = _brent(test, a, b, test_a, test_b)
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
    lam, psi = run.critical(y_star, s_star)
    if abs(lam) > run.settings.critical_tol:
        return None
    return indicators.kind(run, y_star, s_star, psi), s_star, y_star


def crossing_on_path(run, y, s, tangent, s_bad):
    """The critical point where lambda_min crosses zero between the verified (y, s)
    and the verified indefinite state at s_bad (natural parametrisation)."""
    def point(t):
        found = run.newton(y + (t - s) * tangent, t)
        if found is None or run.step_norm(found - y - (t - s) * tangent) > \
                0.5 * abs(t - s) * run.step_norm(tangent) + run.settings.same_state_tol:
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
