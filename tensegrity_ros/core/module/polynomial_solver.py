"""Exact enumeration of all equilibria of one module (docs/model.md section 3).

Elimination.  Divide the equilibrium equations by L1, L2 and write
``a1 = (ka+kc) rho + f3x``, ``b1 = f3y``, ``a2 = (kb+kc) rho - f4x``, ``b2 = f4y``
(vertical forces include the rod weights):

    g1 = a1 sin t1 - b1 cos t1 - kc L2 sin(t1+t2) = 0
    g2 = a2 sin t2 - b2 cos t2 - kc L1 sin(t1+t2) = 0

For fixed t1 both are linear in (cos t2, sin t2); the unit-circle condition on
their solution gives one trigonometric polynomial of degree 3 in t1,

    P(t1) = r^2 Q - (kc L2)^2 D^2,  r = a1 s1 - b1 c1,  D = a2 s1 + b2 c1,
    Q = (a2 - kc L1 c1)^2 + (kc L1 s1 + b2)^2,

i.e. a degree-6 polynomial in z = exp(i t1) whose roots on the unit circle are
the t1 of the equilibria (no tan-half singularity at t = pi).  For each root,
g1 gives t1 + t2 = asin(r / (kc L2)) or pi - asin(...), checked against g2,
which also covers the singular case D = 0 (unloaded flat configurations, where
both are solutions); g2 gives the direction of (cos t2, sin t2), checked
against g1, which stays accurate when the loads dwarf kc L2 and the first
route does not.  Candidates are then polished with Newton on the
trigonometric equations, verified and de-duplicated on the torus.

Degenerate parameters:
- no vertical load (b1 = b2 = 0: unloaded, horizontal forces only): P =
  sin(t1)^2 R(t1) with R linear in cos t1, so the four flat configurations
  and the non-flat pair are taken in closed form (root finding cannot separate
  the double roots at 0 and pi from the pair merging into them on the
  boundary lines);
- near a fold the polynomial returns two close roots as a complex pair: a
  candidate whose Newton iteration stalls is analysed along the critical
  direction (a Lyapunov-Schmidt reduction): two roots, or none (a "ghost" just
  past the fold);
- near any multiple root, solutions within each other's error bounds are one
  root (clusters), and a root that is a double root within rounding is
  reported at the singular point, i.e. as degenerate;
- a continuum of equilibria is reported as such.
The batch form is a vectorised fast path for generic points and hands every
delicate row to the scalar solver, so both give the same answer: a root just
off the circle, a candidate that does not converge, solutions crowding
together, a nearly singular equilibrium, or a set that breaks Poincare-Hopf or
the Morse inequalities of the torus (a lost root).
"""
from __future__ import annotations

import math

import numpy as np

from .angle_polynomial import (_horizontal_load_first_angles, _polynomial_roots,
                               _polynomial_scalar, _reduced_coefficients)
from .classification import _build, EquilibriumSet
from .model import ModuleParams

#: A root z of the polynomial is a real angle candidate if | ln|z| | is below this.
UNIT_CIRCLE_TOL = 1e-3
#: A t2 candidate is kept for polishing if |g2| is below this (relative to the scale).
CANDIDATE_TOL = 1e-2
#: A polished solution is an equilibrium if max |g| (relative to the scale) has
#: converged below this (rounding level).  A genuine root, even a multiple one,
#: gets there within NEWTON_MAX_ITER steps; a candidate that does not is analysed
#: as a near-fold (see _solve_from) and otherwise dropped.
CONVERGED_TOL = 1e-14
#: Two solutions closer than this on the torus (rad, max norm) are one.
DUPLICATE_TOL = 1e-7
#: Closer than this they are the same point (merged before any other analysis).
IDENTICAL_TOL = 1e-12
#: Near a multiple root (fold, pitchfork, the unloaded boundary lines) polishing
#: stops anywhere in a small set where |g| is at rounding level.  With the
#: reduced coefficients at hand, two solutions are one if they are closer than
#: CLUSTER_FACTOR times the larger of their error bounds (residual +
#: ROUNDING_NOISE) / sigma_min(Jacobian) (all relative to the scale), capped at
#: CLUSTER_RADIUS (rad); DUPLICATE_TOL applies only without them.
CLUSTER_FACTOR = 4.0
CLUSTER_RADIUS = 1e-2
#: The batch hands rows with two solutions closer than this to the scalar path
#: (rows with a merge at a larger distance have a nearly singular equilibrium,
#: see HARD_TOL, and go there anyway).
CROWDED_RADIUS = 1e-4
ROUNDING_NOISE = 1e-15
#: The polynomial vanishes identically (a continuum of equilibria) below this.
CONTINUUM_TOL = 1e-13
NEWTON_MAX_ITER = 40


def _residual(t1, t2, a1, b1, a2, b2, kcL1, kcL2):
    s1, c1, s2, c2 = np.sin(t1), np.cos(t1), np.sin(t2), np.cos(t2)
    s12 = s1 * c2 + c1 * s2
    return a1 * s1 - b1 * c1 - kcL2 * s12, a2 * s2 - b2 * c2 - kcL1 * s12


def _second_angle_candidates(t1, a1, b1, kcL2):
    """The two t2 with g1(t1, t2) = 0, each shape of t1."""
    ratio = np.clip((a1 * np.sin(t1) - b1 * np.cos(t1)) / kcL2, -1.0, 1.0)
    phi = np.arcsin(ratio)
    return phi - t1, np.pi - phi - t1


def _wrap(angle):
    """Angle in [-pi, pi)."""
    wrapped = (angle + np.pi) % (2.0 * np.pi) - np.pi
    # (-tiny) % (2 pi) rounds to 2 pi: -pi - 4e-16 would come out as +pi
    return np.where(wrapped >= np.pi, wrapped - 2.0 * np.pi, wrapped)


def _polish(t1, t2, a1, b1, a2, b2, kcL1, kcL2, tol):
    """Newton on (g1, g2) from one candidate; returns (t1, t2, max |g|).

    If Newton does not converge, the best iterate seen is returned (with its
    own residual).
    """
    best = (t1, t2, math.inf)
    for _ in range(NEWTON_MAX_ITER + 1):
        s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
        s12 = s1 * c2 + c1 * s2
        c12 = c1 * c2 - s1 * s2
        g1 = a1 * s1 - b1 * c1 - kcL2 * s12
        g2 = a2 * s2 - b2 * c2 - kcL1 * s12
        residual = max(abs(g1), abs(g2))
        if residual <= tol:
            break
        if residual < best[2]:
            best = (t1, t2, residual)
        j11 = a1 * c1 + b1 * s1 - kcL2 * c12
        j22 = a2 * c2 + b2 * s2 - kcL1 * c12
        det = j11 * j22 - kcL1 * kcL2 * c12 * c12
        if det == 0.0:
            break
        d1 = (j22 * g1 + kcL2 * c12 * g2) / det
        d2 = (j11 * g2 + kcL1 * c12 * g1) / det
        t1 -= d1
        t2 -= d2
        if abs(d1) + abs(d2) < 1e-15:
            tol = math.inf           # converged as far as floating point goes
    else:
        return best
    return t1, t2, residual


def equilibria(params: ModuleParams) -> EquilibriumSet:
    """Every equilibrium of one module, with stability, energy and actuator force.

    Raises :class:`InvalidParameterError` only for invalid parameters; a
    continuum of equilibria is reported through ``status``.
    """
    if not isinstance(params, ModuleParams):
        raise TypeError(f'params must be ModuleParams, got {type(params).__name__}')
    p = params
    consts = _reduced_coefficients(p.rho, p.L1, p.L2, p.ka, p.kb, p.kc,
                                   p.f3x, p.f3y_total, p.f4x, p.f4y_total)
    found = _solve_scalar(consts)
    if found is None:
        return EquilibriumSet(params, (), 'continuum')
    return EquilibriumSet(params, _build(params, found))


def _solve_scalar(consts):
    """Every equilibrium [(t1, t2, relative residual)] for one point, None if a continuum."""
    consts = _normalized(consts)
    a1, b1, a2, b2, kcL1, kcL2 = consts
    scale = max(abs(c) for c in consts)
    coefficients = _polynomial_scalar(*consts)
    if max(abs(c) for c in coefficients) <= CONTINUUM_TOL * scale ** 4:
        return None
    if b1 == 0.0 and b2 == 0.0:
        first_angles = _horizontal_load_first_angles(a1, a2, kcL1, kcL2)
    else:
        first_angles = []
        for z in _polynomial_roots(coefficients):
            modulus = abs(z)
            if modulus != 0.0 and abs(math.log(modulus)) < UNIT_CIRCLE_TOL:
                first_angles.append(math.atan2(z.imag, z.real))
    found = []
    regular = set()                  # solutions too far from singular to be double roots
    for t1 in first_angles:
        for t2 in _second_angles(t1, consts, scale):
            for u1, u2, residual, sigma_min in _solve_from(t1, t2, consts, scale):
                solution = (_wrap_scalar(u1), _wrap_scalar(u2), residual / scale)
                found.append(solution)
                if sigma_min > SNAP_SEARCH * scale:
                    regular.add(solution)
    return _snap_double_roots(_unique(found, consts), consts, regular)


def _normalized(consts):
    """The constants divided by the power of two nearest their scale.

    The equations are homogeneous in them, and scaling by a power of two is
    exact: the solutions come out bitwise the same, while the polynomial
    (fourth powers of the constants) can no longer overflow.
    """
    shift = math.frexp(max(abs(c) for c in consts))[1]
    return tuple(math.ldexp(c, -shift) for c in consts)


#: A g2-route candidate for t2 is redundant within this of a g1-route one (rad).
SECOND_ROUTE_SEPARATION = 1e-3


def _second_angles(t1, consts, scale):
    """Candidate t2 for one t1 (see :func:`_batch_candidates` for the two routes)."""
    a1, b1, a2, b2, kcL1, kcL2 = consts
    s1, c1 = math.sin(t1), math.cos(t1)
    r = a1 * s1 - b1 * c1
    tol = CANDIDATE_TOL * scale
    out = []
    phi = math.asin(min(1.0, max(-1.0, r / kcL2)))
    for t2 in (phi - t1, math.pi - phi - t1):
        if abs(a2 * math.sin(t2) - b2 * math.cos(t2) - kcL1 * math.sin(t1 + t2)) <= tol:
            out.append(t2)
    first = list(out)
    psi = math.atan2(b2 + kcL1 * s1, a2 - kcL1 * c1)
    for t2 in (psi, psi + math.pi):
        if abs(r - kcL2 * math.sin(t1 + t2)) > tol:
            continue
        if all(min(abs(t2 - u) % (2 * math.pi), 2 * math.pi - abs(t2 - u) % (2 * math.pi))
               > SECOND_ROUTE_SEPARATION for u in first):
            out.append(t2)
    return out


def _solve_from(t1, t2, consts, scale):
    """Polished equilibria [(t1, t2, max |g|, sigma_min)] from one candidate (usually one);
    sigma_min (of the Jacobian) is 0.0 where it was not computed.

    Near a fold the polynomial cannot separate two close roots (they come out
    as a complex pair, accurate to about the square root of the rounding) and
    Newton from their real part stalls near the singular curve.  A candidate
    that does not converge is therefore analysed along the critical direction
    (:func:`_fold_split`), first from where it started (the real part of the
    pair, near the fold), then from where Newton stalled: two roots there are
    polished separately; none (the "ghost" of a fold just past it) means no
    equilibrium, unless the closest approach is at rounding level (a double
    root).  A candidate that neither converges nor resolves this way is not
    an equilibrium (a genuine root, even a multiple one, converges within
    NEWTON_MAX_ITER steps to rounding level).  A converged root close to
    singular also gets its fold partner looked for (:func:`_fold_partner`).
    """
    u1, u2, residual = _polish(t1, t2, *consts, tol=4e-16 * scale)
    if residual <= CONVERGED_TOL * scale:
        sigma_min = _sigma_min(u1, u2, *consts)
        partner = _fold_partner(u1, u2, consts, scale, sigma_min)
        return [(u1, u2, residual, sigma_min)] + ([partner + (0.0,)] if partner else [])
    for origin in ((t1, t2), (u1, u2)):
        kind, points = _fold_split(*origin, *consts)
        if kind == 'ghost':
            v1, v2 = points[0]
            closest = max(map(abs, _residual(v1, v2, *consts)))
            return [(v1, v2, closest, 0.0)] if closest <= CONVERGED_TOL * scale else []
        split = []
        for v1, v2 in points:
            w1, w2, r = _polish(v1, v2, *consts, tol=4e-16 * scale)
            if r <= CONVERGED_TOL * scale:
                split.append((w1, w2, r, 0.0))
        if split:
            return split
    return []


#: The fold analysis applies only if the predicted roots are this close (rad).
FOLD_SPLIT_RADIUS = 1e-3


#: A converged root this close to singular (sigma_min / scale) gets its fold
#: partner looked for: both candidates of a close pair may converge to one root.
PARTNER_SEARCH = 1e-5
#: A root is a double root within rounding if sigma_min^2 <= 2 SNAP_FACTOR |q| eta.
SNAP_FACTOR = 4.0
#: Roots with sigma_min / scale above this cannot qualify (it bounds the test above).
SNAP_SEARCH = 1e-6


#: The reduced quadratic has fold structure if |q| exceeds this times the scale;
#: below, q is rounding (a pitchfork, where q = 0 by symmetry, or worse).
FOLD_CURVATURE = 1e-8


def _is_fold(q, consts):
    return abs(q) > FOLD_CURVATURE * max(abs(c) for c in consts)


def _reduction(t1, t2, a1, b1, a2, b2, kcL1, kcL2):
    """Lyapunov-Schmidt data at x: g, the SVD of J (left, sing, right) and q = u.D2g(v, v)."""
    s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
    s12 = s1 * c2 + c1 * s2
    c12 = c1 * c2 - s1 * s2
    g = np.array([a1 * s1 - b1 * c1 - kcL2 * s12, a2 * s2 - b2 * c2 - kcL1 * s12])
    jac = np.array([[a1 * c1 + b1 * s1 - kcL2 * c12, -kcL2 * c12],
                    [-kcL1 * c12, a2 * c2 + b2 * s2 - kcL1 * c12]])
    left, sing, right = np.linalg.svd(jac)
    v, u = right[1], left[:, 1]
    d2g = np.array([(-a1 * s1 + b1 * c1) * v[0] ** 2 + kcL2 * s12 * (v[0] + v[1]) ** 2,
                    (-a2 * s2 + b2 * c2) * v[1] ** 2 + kcL1 * s12 * (v[0] + v[1]) ** 2])
    return g, left, sing, right, float(u @ d2g)


def _along(t1, t2, h, left, sing, right, consts):
    """x + h v, corrected in the stiff direction (right[0]), where Newton is safe."""
    v, stiff, u0, big = right[1], right[0], left[:, 0], float(sing[0])
    x1, x2 = t1 + h * v[0], t2 + h * v[1]
    for _ in range(3):
        r1, r2 = _residual(x1, x2, *consts)
        step = (u0[0] * r1 + u0[1] * r2) / big
        x1, x2 = x1 - step * stiff[0], x2 - step * stiff[1]
    return float(x1), float(x2)


def _fold_split(t1, t2, a1, b1, a2, b2, kcL1, kcL2):
    """Roots near a near-singular point x (Lyapunov-Schmidt reduction).

    With J = U diag(S) V^T at x, v = V[:, 1], u = U[:, 1], the equations along
    x + s v reduce to u.g + S[1] s + q s^2 / 2 = 0 with q = u.D2g(v, v).
    Returns ('roots', [two starting points]), ('ghost', [the closest approach])
    when that quadratic has no real root, or ('none', []) when the reduction
    does not apply (q = 0 or the predicted points are not close).
    """
    consts = (a1, b1, a2, b2, kcL1, kcL2)
    g, left, sing, right, q = _reduction(t1, t2, *consts)
    lin, ug = float(sing[1]), float(left[:, 1] @ g)
    if not _is_fold(q, consts):
        return 'none', []
    disc = lin * lin - 2.0 * q * ug
    if disc < 0.0:
        kind, steps = 'ghost', [-lin / q]
    else:
        root = math.sqrt(disc)
        kind, steps = 'roots', [(-lin + root) / q, (-lin - root) / q]
    if max(abs(h) for h in steps) > FOLD_SPLIT_RADIUS:
        return 'none', []
    return kind, [_along(t1, t2, h, left, sing, right, consts) for h in steps]


def _fold_partner(t1, t2, consts, scale, sigma_min):
    """The other root of a fold pair next to a converged near-singular root, or None.

    At a root u.g = 0, so the reduced quadratic S[1] s + q s^2 / 2 has its second
    root at s = -2 S[1] / q.  ``sigma_min`` is that of the Jacobian at the root.
    """
    if sigma_min > PARTNER_SEARCH * scale:                       # the usual case, cheaply
        return None
    g, left, sing, right, q = _reduction(t1, t2, *consts)
    lin = float(sing[1])
    if not _is_fold(q, consts) or lin > PARTNER_SEARCH * scale:
        return None
    h = -2.0 * lin / q
    if abs(h) > FOLD_SPLIT_RADIUS:
        return None
    w1, w2, r = _polish(*_along(t1, t2, h, left, sing, right, consts), *consts, tol=4e-16 * scale)
    return (w1, w2, r) if r <= CONVERGED_TOL * scale else None


def _snap_double_roots(kept, consts, regular=frozenset()):
    """Roots that are double roots within rounding, moved to where J is singular.

    If sigma_min^2 <= 2 SNAP_FACTOR |q| eta (eta the rounding of g), the fold
    pair through the point cannot be told apart from a double root: the point is
    replaced by the vertex of the reduced quadratic, where the Hessian has a
    (numerically) zero eigenvalue, so it is classified as degenerate instead of
    as whichever side of the fold rounding put it on.  Pitchforks (q = 0 by
    symmetry) are not affected.  Solutions in ``regular`` are known to have
    sigma_min above SNAP_SEARCH.
    """
    scale = max(abs(c) for c in consts)
    out, changed = [], False
    for t1, t2, residual in kept:
        if (t1, t2, residual) in regular or _sigma_min(t1, t2, *consts) > SNAP_SEARCH * scale:
            out.append((t1, t2, residual))                          # cannot qualify
            continue
        g, left, sing, right, q = _reduction(t1, t2, *consts)
        lin = float(sing[1])
        if (_is_fold(q, consts)
                and lin * lin <= 2.0 * SNAP_FACTOR * abs(q) * ROUNDING_NOISE * scale):
            h = -lin / q
            if abs(h) <= FOLD_SPLIT_RADIUS:
                x1, x2 = _along(t1, t2, h, left, sing, right, consts)
                r = max(map(abs, _residual(x1, x2, *consts))) / scale
                if r <= CONVERGED_TOL:
                    out.append((_wrap_scalar(x1), _wrap_scalar(x2), r))
                    changed = True
                    continue
        out.append((t1, t2, residual))
    return _unique(out, consts) if changed else out


def _wrap_scalar(angle):
    """Angle in [-pi, pi)."""
    wrapped = (angle + math.pi) % (2.0 * math.pi) - math.pi
    # (-tiny) % (2 pi) rounds to 2 pi: -pi - 4e-16 would come out as +pi
    return wrapped - 2.0 * math.pi if wrapped >= math.pi else wrapped


def _sigma_min(t1, t2, a1, b1, a2, b2, kcL1, kcL2):
    """Smallest singular value of the Jacobian of (g1, g2) at (t1, t2), in closed form."""
    s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
    c12 = c1 * c2 - s1 * s2
    j11 = a1 * c1 + b1 * s1 - kcL2 * c12
    j22 = a2 * c2 + b2 * s2 - kcL1 * c12
    j12, j21 = -kcL2 * c12, -kcL1 * c12
    det = abs(j11 * j22 - j12 * j21)
    frob2 = j11 * j11 + j22 * j22 + j12 * j12 + j21 * j21
    # sigma_max^2 + sigma_min^2 = frob2 and sigma_max sigma_min = det
    sigma_max = math.sqrt(0.5 * (frob2 + math.sqrt(max(frob2 * frob2 - 4.0 * det * det, 0.0))))
    return det / sigma_max if sigma_max > 0.0 else 0.0


def _error_bound(t1, t2, residual, a1, b1, a2, b2, kcL1, kcL2):
    """(residual + rounding) / sigma_min of the scaled Jacobian: how far the true root may be."""
    scale = max(abs(a1), abs(b1), abs(a2), abs(b2), abs(kcL1), abs(kcL2))
    sigma_min = _sigma_min(t1, t2, a1, b1, a2, b2, kcL1, kcL2) / scale
    if sigma_min == 0.0:
        return math.inf
    return (residual + ROUNDING_NOISE) / sigma_min


def _same_root(distance, bound_a, bound_b):
    """Two polished solutions are one root: closer than their error bounds allow.

    Not a fixed DUPLICATE_TOL: two genuine equilibria of a fold pair can be
    well resolved (residuals at rounding level, error bounds 1e-8) and yet only
    8e-8 rad apart; merging them would leave one of a min/saddle pair.
    """
    return distance <= max(IDENTICAL_TOL,
                           min(CLUSTER_RADIUS, CLUSTER_FACTOR * max(bound_a, bound_b)))


def _torus_distance(a, b):
    """Max-norm distance of two (t1, t2, ...) tuples on the torus."""
    two_pi = 2.0 * math.pi
    d1, d2 = abs(a[0] - b[0]) % two_pi, abs(a[1] - b[1]) % two_pi
    return max(min(d1, two_pi - d1), min(d2, two_pi - d2))


def _unique(found, consts=None):
    """Distinct solutions on the torus, the best-polished of each cluster, sorted.

    Without ``consts`` (the reduced coefficients) solutions within DUPLICATE_TOL
    are one.  With them, only identical solutions (IDENTICAL_TOL) are merged
    first; then, where solutions crowd together, those within each other's
    error bounds (:func:`_merge_clusters`): near a multiple root they are one
    root smeared by rounding, while two well-resolved roots of a fold pair
    stay two however close they are.
    """
    two_pi = 2.0 * math.pi
    same = DUPLICATE_TOL if consts is None else IDENTICAL_TOL
    kept = []
    crowded = False                      # two kept solutions within CLUSTER_RADIUS
    for candidate in sorted(found, key=lambda c: c[2]):
        t1, t2 = candidate[0], candidate[1]
        duplicate = near = False
        for k in kept:                   # one torus distance per pair (the hot loop)
            d1, d2 = abs(t1 - k[0]), abs(t2 - k[1])
            d = max(min(d1, two_pi - d1), min(d2, two_pi - d2))
            if d <= same or (consts is not None and d <= DUPLICATE_TOL
                             and _same_type_duplicate(candidate, k, consts)):
                duplicate = True
                break
            near = near or d <= CLUSTER_RADIUS
        if not duplicate:
            kept.append(candidate)
            crowded = crowded or near
    if consts is not None and crowded:
        kept = _merge_clusters(kept, consts, _torus_distance)
    kept.sort()
    return kept


def _inertia(t1, t2, a1, b1, a2, b2, kcL1, kcL2):
    """(sign det, sign of the first diagonal entry) of the Jacobian of (g1, g2): the
    Morse type, since that Jacobian is diag(1/L1, 1/L2) times the Hessian."""
    s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
    c12 = c1 * c2 - s1 * s2
    j11 = a1 * c1 + b1 * s1 - kcL2 * c12
    j22 = a2 * c2 + b2 * s2 - kcL1 * c12
    det = j11 * j22 - kcL1 * kcL2 * c12 * c12
    size = max(abs(j11), abs(j22), abs(kcL1 * c12), abs(kcL2 * c12)) ** 2
    if not abs(det) > NONDEGENERATE_TOL * size:
        return 0, 0                                    # degenerate: no definite type
    return (det > 0) - (det < 0), (j11 > 0) - (j11 < 0)


#: |det J| above this fraction of its entries squared gives a definite Morse type.
NONDEGENERATE_TOL = 1e-6


def _same_type_duplicate(a, b, consts):
    """Two solutions within DUPLICATE_TOL (the caller checks) of the same Morse type are one root.

    Two distinct non-degenerate equilibria that close can only be the two sides
    of a fold (opposite index: a minimum and a saddle, or a saddle and a
    maximum), which must stay two; same-type points are one root polished twice.
    """
    inertia_a, inertia_b = _inertia(a[0], a[1], *consts), _inertia(b[0], b[1], *consts)
    return inertia_a == inertia_b and inertia_a[0] != 0


def _merge_clusters(kept, consts, distance):
    """Merge solutions within each other's error bounds (see :func:`_unique`).

    Clusters grow around their most degenerate member (the largest error
    bound, the one nearest the multiple root); each is represented by the
    member nearest its centroid, so that a symmetric cluster (a flat
    configuration and the mirrored pair 3e-8 rad from it) keeps its centre, or,
    for a merged fold pair, by the vertex of the fold.
    """
    bounds = [_error_bound(k[0], k[1], k[2], *consts) for k in kept]
    clusters = []
    for i in sorted(range(len(kept)), key=lambda i: -bounds[i]):
        for members in clusters:
            leader = members[0]
            if _same_root(distance(kept[i], kept[leader]), bounds[i], bounds[leader]):
                members.append(i)
                break
        else:
            clusters.append([i])
    out = []
    for members in clusters:
        if len(members) == 1:
            out.append(kept[members[0]])
            continue
        base = kept[members[0]]
        offsets = np.array([[_wrap_scalar(kept[m][0] - base[0]),
                             _wrap_scalar(kept[m][1] - base[1])] for m in members])
        centre = offsets.mean(axis=0)
        spread = float(np.max(np.abs(offsets - centre)))
        nearest = kept[members[int(np.argmin(np.max(np.abs(offsets - centre), axis=1)))]]
        # Two roots merged around a fold: a double root, which sits where the
        # Jacobian is singular (the vertex of the reduced quadratic), so that it
        # is classified by a vanishing eigenvalue rather than by whichever side
        # of the fold one of the merged points happened to be on.
        kind, points = _fold_split(base[0] + centre[0], base[1] + centre[1], *consts)
        if kind != 'none':
            vertex = np.mean(points, axis=0)
            r1, r2 = _residual(vertex[0], vertex[1], *consts)
            scale = max(abs(c) for c in consts)
            residual = max(abs(r1), abs(r2)) / scale
            if (_torus_distance(vertex, (base[0] + centre[0], base[1] + centre[1])) <= spread
                    and residual <= CONVERGED_TOL):
                out.append((_wrap_scalar(float(vertex[0])), _wrap_scalar(float(vertex[1])),
                            residual))
                continue
        out.append(nearest)
    return out
