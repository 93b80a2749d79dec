"""The branch through a located critical point, measured along its critical mode.

Near a critical point the equilibria on the hyperplane psi . (y - y*) = a lie at

    s - s* = sigma0 + c1 a + c2 a^2 + c3 a^3 + ...

(the reduced equation's solution curve; MATCONT's and BifurcationKit's normal forms).
sigma0 is where the curve crosses the hyperplane through y* itself: not 0 where y* is
not exactly on the branch (next to a fold whose F_s is small the residual test passes
~1e-7 in s past it: the module under a 1e-6 N load next to rho = L).  Both sides +-a at
two amplitudes a factor 4 apart give all three (:func:`_fit`); the fit is taken where
two such pairs predict s - s* at their common amplitude to :data:`LAW_AGREEMENT` of its
size.  Larger amplitudes may reach another branch (the module under a 2e-5 N load next
to rho = L: at 0.014 rad along -psi the corrector landed on the other minimum, past a
fold whose own branch lies 5.8e-5 in s behind).  The curve's vertex (its s-extremum)
lies at a = -c1 / (2 c2); what the law says:

* ``turns_back``: the vertex lies within the amplitudes measured and c2 < 0: the
  branch through the point lies behind its vertex on both sides.  Either a fold (c1,
  sigma0 only y*'s own error) or the bifurcated branch of a branch point lying behind;
* ``ahead``: the vertex within them and c2 > 0: a bifurcated branch past s* (a
  supercritical pitchfork where it is stable; :mod:`.branch_switching` checks that);
* ``through``: the vertex farther out: the branch crosses s* monotonically (a
  transcritical branch point, or a dip of lambda_min that is no critical point);
* ``unresolved``: no two pairs agree before s - s* sinks into rounding, or the
  corrector does not converge (a linkage limit): the caller decides otherwise.

``turns_back`` is a fold only where no other branch runs through the point: at a branch
point the branch across the mode (the unbuckled one) may go on past s* and be stable
(two mirror minima merging into the flat state, a supercritical pitchfork run
backwards: the unloaded module with L2 = 1.5 at rho = 1/4).  :func:`is_fold` tells them
apart by the reduced equation g(xi, sigma) itself (see there).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .correctors import arc_point, bordered_newton, null_vectors
from ..numerics import bounded_work

TURNS_BACK = 'turns_back'
AHEAD = 'ahead'
THROUGH = 'through'
UNRESOLVED_LAW = 'unresolved'

#: Two fits (amplitude pairs a factor 4 apart) agree where their predictions of s - s*
#: at the common amplitude differ by at most this fraction of it: the fits' error
#: shrinks 16-fold per level (the next terms are O(a^2) relative).
LAW_AGREEMENT = 0.1
#: Amplitude levels tried, each a factor 4 below the one before (from the step-off).
LAW_LEVELS = 10
#: A measured s - s* must exceed this (relative to max(1, |s*|)) to count: the
#: locator's bracket and s's rounding are ~1e-12.
LAW_RESOLUTION = 1e-10
#: The fold test's ratio (:func:`is_fold`) is 1 at a fold and 1/3 at a pitchfork: a fold
#: where it lies within this factor of 1.
FOLD_RATIO = 2.0


class BranchLaw(NamedTuple):
    """The branch through a critical point along its mode (see the module's doc):
    s - s* = sigma0 + linear a + quadratic a^2 for amplitudes up to ``amplitude``."""

    law: str
    linear: float = 0.0
    quadratic: float = 0.0
    amplitude: float = 0.0
    sigma0: float = 0.0
    #: The smallest amplitude the law was confirmed at (two fits agreeing there).
    confirmed: float = 0.0


def _sides(run, s_star, y_star, direction, a):
    """(s - s* at +a, at -a), or None where a corrector is lost."""
    plus = arc_point(run, y_star, s_star, direction, a, any_s=True)
    if plus is None:
        return None
    minus = arc_point(run, y_star, s_star, -direction, a, any_s=True)
    if minus is None:
        return None
    return plus[1] - s_star, minus[1] - s_star


def _fit(outer, inner):
    """(sigma0, c1, c2) from the sides at amplitudes a (outer) and a / 4 (inner), each
    (a, s+ - s*, s- - s*): the even parts give sigma0 and c2, the inner odd part c1."""
    (a, p, m), (b, q, n) = outer, inner
    even_a, even_b = 0.5 * (p + m), 0.5 * (q + n)
    c2 = (even_a - even_b) / (a * a - b * b)
    return even_b - c2 * b * b, (q - n) / (2.0 * b), c2


def _agree(coarse, fine, a):
    """Whether two fits predict s - s* at +-a (relative to sigma0) alike."""
    def predicted(fit, side):
        _, c1, c2 = fit
        return c1 * side + c2 * side * side
    sizes = [abs(predicted(fine, side)) for side in (a, -a)]
    return all(abs(predicted(coarse, side) - predicted(fine, side))
               <= LAW_AGREEMENT * max(sizes) for side in (a, -a)) and max(sizes) > 0.0


def branch_law(run, s_star, y_star, psi, amplitude=None):
    """The :class:`BranchLaw` of the branch through (y*, s*) along psi.

    A ``through`` or ``turns_back`` verdict is taken at the first scale where two fits
    agree.  An ``ahead`` one is measured on down to where s - s* sinks into rounding:
    an imperfect pitchfork's law is the perfect one's at amplitudes above the
    imperfection's scale and ``through`` below it (U = x^4/4 - mu x^2/2 - eps x, eps =
    1e-14: ``ahead`` at 0.01 .. 6e-4, the vertex at 3e-5).  The finer scale's verdict
    stands where it is resolved; where it is not (no two fits agree there) the law is
    ``ahead`` with ``confirmed`` the smallest amplitude it held at, and the branch's
    shape below is unknown (:func:`undecided_below`)."""
    a = (run.settings.step_off if amplitude is None else amplitude) / max(
        run.step_norm(psi), 1e-300)
    direction = np.append(psi, 0.0)
    floor = LAW_RESOLUTION * max(1.0, abs(s_star))
    levels, fits, ahead = [], [], None
    for _ in range(LAW_LEVELS):
        bounded_work.checkpoint()       # (a time budget is checked between levels)
        sides = _sides(run, s_star, y_star, direction, a)
        if sides is None:
            levels, fits = [], []
        elif max(map(abs, sides)) <= floor:
            break
        else:
            levels.append((a, *sides))
            if len(levels) >= 2:
                fits.append(_fit(levels[-2], levels[-1]))
            if len(fits) >= 2 and _agree(fits[-2], fits[-1], levels[-2][0]):
                verdict = _verdict(fits[-1], levels[-3][0], levels[-1][0])
                if verdict.law != AHEAD:
                    return verdict
                ahead = verdict if ahead is None else ahead._replace(confirmed=a)
        a *= 0.25
    return BranchLaw(UNRESOLVED_LAW) if ahead is None else ahead


def _verdict(fit, reach, finest):
    """The law of the fit, measured at amplitudes ``finest`` .. ``reach``."""
    sigma0, c1, c2 = fit
    if abs(c1) > 2.0 * abs(c2) * reach:          # the vertex lies farther out
        return BranchLaw(THROUGH, c1, c2, reach, sigma0, finest)
    return BranchLaw(TURNS_BACK if c2 < 0.0 else AHEAD, c1, c2, reach, sigma0, finest)


def _bordered_residual(run, y_star, s, u, v, h):
    """beta of the bordered system {F(y, s) + beta u = 0, v . (y - y*) = h} (the reduced
    equation's value at amplitude h, regular at a simple critical point), or None where
    its Newton does not converge."""
    bounded_work.checkpoint()
    found = bordered_newton(run, y_star, s, u, v, h)
    return found[1] if found is not None and found[2] else None


def is_fold(run, s_star, y_star, law):
    """Whether the ``turns_back`` critical point (y*, s*) is a fold, by the reduced
    equation g on the critical mode: ``beta`` of the bordered system (u, v the
    Jacobian's null vectors at y*), at y*'s hyperplane moved by h = a / 4 either way and
    at s* + sigma, sigma = |c2| h^2 (the law's c2):

        ratio = [g(0, sigma) - g(0, 0)] / [(g(h, 0) + g(-h, 0)) / 2 - g(0, 0)]

    A fold, g = g_s (s - s_f) + g_xx (xi - xi_f)^2 / 2 with c2 = -g_xx / (2 g_s): ratio 1
    exactly, wherever y* lies.  A branch point the law's branch of which turns back,
    g = g_xs xi (s - s_b) + g_xxx xi^3 / 6 with c2 = -g_xxx / (6 g_xs): ratio 1/3 for
    y*'s offset xi0 along the mode below h ((h^2 + xi0^2) / (3 h^2 + xi0^2) in all).
    A fold where the ratio lies within FOLD_RATIO of 1; False (not decided here)
    elsewhere."""
    u, v = null_vectors(run, y_star, s_star)
    if u is None:
        return False
    h = 0.25 * law.amplitude
    s_past = s_star + abs(law.quadratic) * h * h
    if not s_past > s_star:
        return False
    at = _bordered_residual(run, y_star, s_star, u, v, 0.0)
    past = _bordered_residual(run, y_star, s_past, u, v, 0.0)
    sides = [_bordered_residual(run, y_star, s_star, u, v, side) for side in (h, -h)]
    if at is None or past is None or None in sides:
        return False
    curvature = 0.5 * (sides[0] + sides[1]) - at
    if curvature == 0.0:
        return False
    return bool(1.0 / FOLD_RATIO <= (past - at) / curvature <= FOLD_RATIO)


#: A state past a ``through`` point counts as stable where lambda_min exceeds this many
#: definiteness tolerances of lambda_max (as a buckled branch's, :mod:`.branch_switching`).
THROUGH_MARGIN = 100.0
#: Amplitude doublings tried from the law's reach before lambda_min shows that margin.
THROUGH_DOUBLINGS = 12


def goes_through(run, s_star, y_star, law, s_end):
    """The stable state on the branch past a ``through`` point: (y, s) with s* < s <=
    s_end, or None (the caller decides otherwise).

    A ``through`` law says the branch crosses s* monotonically (a dip of lambda_min that
    is no critical point: an imperfect pitchfork's connected branch, lambda_min down to
    ~1e-11 of lambda_max on a nearly symmetric paper neck under a head load).  So does an
    ``ahead`` law whose vertex, resolvable in s, lies below the amplitudes it was
    confirmed at (:func:`resolved_imperfection`).  Where the state on that branch past
    s* is a minimum with a margin, the minimum goes on: no jump, and no flow is needed
    to say so (such a branch moves ~0.1 rad in 1e-6 of s, out of reach of a frozen
    flow's rest test).  The side is the one the law's linear term takes forward in s;
    the amplitude starts where two fits of a ``through`` law were checked to agree (the
    law's reach can be off it by 20 %: a nearly symmetric N = 3 paper neck under a head
    load), its first point checked to lie on the law, or at the vertex of an
    imperfection's; it doubles until the state is clearly stable, s growing all the way."""
    start = _through_start(law, s_star)
    if start is None:
        return None
    a, on_law = start
    _, psi = run.critical(y_star, s_star)
    forward = np.sign(law.linear)
    direction = np.append(forward * psi, 0.0)
    s_before = s_star
    for doubling in range(THROUGH_DOUBLINGS):
        bounded_work.checkpoint()
        found = arc_point(run, y_star, s_star, direction, a, any_s=True)
        if found is None or not found[1] > s_before:
            return None
        y, s_before = found
        if doubling == 0 and on_law and not _on_the_law(law, forward * a, s_before - s_star):
            return None
        eigenvalues = run.eigenvalues(y, s_before)
        if eigenvalues[0] < 0.0 or s_before > s_end:
            return None
        if eigenvalues[0] > THROUGH_MARGIN * run.settings.definiteness_tol * abs(eigenvalues[-1]):
            return y, s_before
        a *= 2.0
    return None


def _through_start(law, s_star):
    """(first amplitude, whether it lies on the law) of :func:`goes_through`, or None."""
    if law.linear == 0.0:
        return None
    if law.law == THROUGH:              # (where two fits were checked to agree)
        return 4.0 * law.confirmed, True
    if resolved_imperfection(law, s_star):
        return vertex(law), False
    return None


def vertex(law):
    """The amplitude of the law's vertex (its s-extremum) from y*: |c1 / (2 c2)|."""
    return abs(law.linear) / (2.0 * abs(law.quadratic)) if law.quadratic else np.inf


def resolved_imperfection(law, s_star):
    """Whether an ``ahead`` law shows an imperfect pitchfork: its vertex lies below the
    amplitudes it was confirmed at (a perfect pitchfork's tracked branch runs through
    the vertex itself, so y* lies there to rounding), and the vertex's own s-size
    c1^2 / (4 |c2|) is above :data:`LAW_RESOLUTION`."""
    if law.law != AHEAD or not vertex(law) < law.confirmed:
        return False
    return law.linear ** 2 / (4.0 * abs(law.quadratic)) > LAW_RESOLUTION * max(1.0, abs(s_star))


def undecided_below(law, s_star):
    """(s-size, amplitude) below which the law of a branch point passed by the rule of
    :func:`.branch_switching.buckled_minimum` (the side along +psi) is not resolved, or
    None (no law measured, or an imperfection resolved).  The side the state takes is
    then decided by an imperfection (if any) doubles cannot see: a nearly symmetric
    N = 3 .. 5 paper neck under a head load, module 0's ka 1e-14 off, buckles to the
    side the 1e-6 .. 1e-12 offs do not.  The amplitude is the smallest the law was
    confirmed at, the s-size the law's s - s* there."""
    if law.law == UNRESOLVED_LAW or not law.confirmed or resolved_imperfection(law, s_star):
        return None
    a = law.confirmed
    return abs(law.quadratic) * a * a + abs(law.linear) * a, a


def _on_the_law(law, a, past):
    """Whether s - s* = ``past`` at amplitude ``a`` is the law's to LAW_AGREEMENT."""
    predicted = law.sigma0 + law.linear * a + law.quadratic * a * a
    return abs(past - predicted) <= LAW_AGREEMENT * abs(predicted - law.sigma0)
