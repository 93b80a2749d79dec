"""Exact enumeration of all equilibria of one module (DESIGN.md section 3).

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
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg.lapack import zgeev as _zgeev

from .module import ModuleParams, InvalidParameterError, PARAMETER_NAMES, STANDARD_GRAVITY
from . import module as _module

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
#: An eigenvalue with |lambda| <= DEGENERACY_TOL * max|lambda| counts as zero.
DEGENERACY_TOL = 1e-8
#: The polynomial vanishes identically (a continuum of equilibria) below this.
CONTINUUM_TOL = 1e-13
NEWTON_MAX_ITER = 40

KIND_MINIMUM = 'minimum'
KIND_SADDLE = 'saddle'
KIND_MAXIMUM = 'maximum'
KIND_DEGENERATE = 'degenerate'


@dataclass(frozen=True)
class Equilibrium:
    """One equilibrium of a module: angles (rad), Hessian eigenvalues (ascending)."""

    theta1: float
    theta2: float
    eigenvalues: tuple
    energy: float
    actuator_force: float
    residual: float

    @property
    def theta(self):
        return np.array([self.theta1, self.theta2])

    @property
    def stability_margin(self):
        """Smallest Hessian eigenvalue (J/rad^2): positive iff stable."""
        return self.eigenvalues[0]

    @property
    def kind(self):
        return classify(self.eigenvalues)

    @property
    def stable(self):
        return self.kind == KIND_MINIMUM


@dataclass(frozen=True)
class EquilibriumSet:
    """Every equilibrium for one parameter point.

    ``status`` is ``'ok'``, or ``'continuum'`` when the equilibria are not
    isolated (the equations vanish identically in t1); then ``equilibria`` is empty.
    """

    params: ModuleParams
    equilibria: tuple
    status: str = 'ok'

    @property
    def stable(self):
        return tuple(e for e in self.equilibria if e.stable)

    @property
    def num_stable(self):
        return sum(1 for e in self.equilibria if e.stable)

    def __len__(self):
        return len(self.equilibria)

    def __iter__(self):
        return iter(self.equilibria)


def classify(eigenvalues):
    """Morse type of a critical point from its Hessian eigenvalues (by inertia)."""
    ev = np.asarray(eigenvalues, dtype=float)
    scale = float(np.max(np.abs(ev))) if ev.size else 0.0
    tol = DEGENERACY_TOL * scale
    if scale == 0.0 or np.any(np.abs(ev) <= tol):
        return KIND_DEGENERATE
    if np.all(ev > 0):
        return KIND_MINIMUM
    if np.all(ev < 0):
        return KIND_MAXIMUM
    return KIND_SADDLE


def _reduced_coefficients(rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y):
    """(a1, b1, a2, b2, kcL1, kcL2): the constants of the scaled equations."""
    return ((ka + kc) * rho + f3x, f3y, (kb + kc) * rho - f4x, f4y, kc * L1, kc * L2)


def _polynomial(a1, b1, a2, b2, kcL1, kcL2):
    """Coefficients of z^3 P(z), highest power first, shape (..., 7), complex."""
    u = 0.5 * (-b1 + 1j * a1)            # r = u/z + conj(u) z
    v = 0.5 * (b2 + 1j * a2)             # D = v/z + conj(v) z
    w = -kcL1 * (a2 - 1j * b2)           # Q = w/z + q0 + conj(w) z
    q0 = a2 * a2 + b2 * b2 + kcL1 * kcL1
    K = kcL2 * kcL2
    uu = np.abs(u) ** 2
    pm3 = u * u * w
    pm2 = u * u * q0 - K * v * v
    pm1 = u * u * np.conj(w) + 2.0 * uu * w
    p0 = 2.0 * uu * q0 - 2.0 * K * np.abs(v) ** 2 + 0j
    return np.stack([np.conj(pm3), np.conj(pm2), np.conj(pm1), p0, pm1, pm2, pm3], -1)


def _scale(a1, b1, a2, b2, kcL1, kcL2):
    return np.maximum.reduce([np.abs(a1), np.abs(b1), np.abs(a2), np.abs(b2),
                              np.abs(kcL1), np.abs(kcL2)])


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


def hessian_eigenvalues(h11, h12, h22):
    """Ascending eigenvalues of symmetric 2x2 matrices, accurate for the small one."""
    mean = 0.5 * (h11 + h22)
    half_gap = np.hypot(0.5 * (h11 - h22), h12)
    big = mean + np.copysign(half_gap, mean)
    det = h11 * h22 - h12 * h12
    safe = np.where(big == 0.0, 1.0, big)
    small = np.where(big == 0.0, 0.0, det / safe)
    return np.minimum(big, small), np.maximum(big, small)


def _polynomial_roots(coefficients):
    """Roots of one polynomial, near-zero leading/trailing coefficients stripped.

    The eigenvalues of the companion matrix, from LAPACK's zgeev called directly:
    numpy's eigvals runs the same routine behind a wrapper that adds about 40 %
    at this size (17 vs 12 us for 6x6), and this runs on every solve.
    """
    peak = max(abs(c) for c in coefficients)
    keep = [i for i, c in enumerate(coefficients) if abs(c) > 1e-14 * peak]
    coefficients = coefficients[keep[0]:keep[-1] + 1]
    degree = len(coefficients) - 1
    if degree < 1:
        return []
    companion = np.zeros((degree, degree), dtype=complex, order='F')
    lead = coefficients[0]
    companion[0, :] = [-c / lead for c in coefficients[1:]]
    companion.flat[degree::degree + 1] = 1.0                     # the subdiagonal
    roots, _, _, info = _zgeev(companion, compute_vl=0, compute_vr=0, overwrite_a=1)
    if info != 0:                                   # QR did not converge: numpy raises
        return np.linalg.eigvals(companion).tolist()
    return roots.tolist()


def _polynomial_scalar(a1, b1, a2, b2, kcL1, kcL2):
    """:func:`_polynomial` for one point, as a list (no numpy overhead)."""
    u = complex(-0.5 * b1, 0.5 * a1)
    v = complex(0.5 * b2, 0.5 * a2)
    w = complex(-kcL1 * a2, kcL1 * b2)
    q0 = a2 * a2 + b2 * b2 + kcL1 * kcL1
    K = kcL2 * kcL2
    uu = u.real ** 2 + u.imag ** 2
    u2 = u * u
    pm3 = u2 * w
    pm2 = u2 * q0 - K * v * v
    pm1 = u2 * w.conjugate() + 2.0 * uu * w
    p0 = complex(2.0 * uu * q0 - 2.0 * K * (v.real ** 2 + v.imag ** 2))
    return [pm3.conjugate(), pm2.conjugate(), pm1.conjugate(), p0, pm1, pm2, pm3]


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
    w1, w2, r = _polish(*_along(t1, t2, h, left, sing, right, consts), *consts,
                        tol=4e-16 * scale)
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
        if _is_fold(q, consts) and lin * lin <= 2.0 * SNAP_FACTOR * abs(q) * ROUNDING_NOISE * scale:
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


def _horizontal_cosine(a1, a2, kcL1, kcL2):
    """cos t1 of the non-flat equilibria when no vertical load acts (b1 = b2 = 0).

    Then P(t1) = sin(t1)^2 R(t1) with R linear in cos t1, so the equilibria are
    the four flat configurations and the pair t1 = +-acos(C); returns C (nan if
    a1 a2 = 0: no non-flat equilibrium).
    """
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.divide(a1 * a1 * (a2 * a2 + kcL1 * kcL1) - kcL2 * kcL2 * a2 * a2,
                         2.0 * a1 * a1 * a2 * kcL1)


def _horizontal_load_first_angles(a1, a2, kcL1, kcL2):
    """Every t1 of an equilibrium when b1 = b2 = 0, in closed form.

    The polynomial has double roots at t1 = 0 and pi there (the flat
    configurations share them), which merge with the non-flat pair on the
    boundary lines: root finding cannot separate them, the closed form can.
    """
    angles = [0.0, math.pi]
    cosine = float(_horizontal_cosine(a1, a2, kcL1, kcL2))
    if abs(cosine) < 1.0:
        t1 = math.acos(cosine)
        angles += [t1, -t1]
    return angles


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


def _build(p, found):
    """Equilibrium records (Hessian eigenvalues, energy, actuator force) of the
    solutions [(t1, t2, residual)]; parameters are read into locals once, as
    this runs for every solve."""
    rho, L1, L2, ka, kb, kc = p.rho, p.L1, p.L2, p.ka, p.kb, p.kc
    f3x, f3y, f4x, f4y = p.f3x, p.f3y_total, p.f4x, p.f4y_total
    a1, b1, a2, b2 = (ka + kc) * rho + f3x, f3y, (kb + kc) * rho - f4x, f4y
    kcL1, kcL2, kcL1L2 = kc * L1, kc * L2, -kc * L1 * L2
    out = []
    for t1, t2, residual in found:
        s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
        c12 = c1 * c2 - s1 * s2
        h11 = L1 * (a1 * c1 + b1 * s1 - kcL2 * c12)
        h22 = L2 * (a2 * c2 + b2 * s2 - kcL1 * c12)
        h12 = kcL1L2 * c12
        x3, y3 = L1 * c1, L1 * s1
        x4, y4 = rho - L2 * c2, L2 * s2
        springs = 0.5 * (ka * ((x3 - rho) ** 2 + y3 ** 2) + kb * (x4 ** 2 + y4 ** 2)
                         + kc * ((x4 - x3) ** 2 + (y4 - y3) ** 2))
        out.append(Equilibrium(
            theta1=t1, theta2=t2, eigenvalues=_eigenvalues_2x2(h11, h12, h22),
            energy=springs - (f3x * x3 + f3y * y3 + f4x * x4 + f4y * y4),
            actuator_force=(ka * (rho - x3) + kb * (rho - L2 * c2)
                            + kc * (rho - x3 - L2 * c2) - f4x),
            residual=residual))
    return tuple(out)


def _eigenvalues_2x2(h11, h12, h22):
    mean = 0.5 * (h11 + h22)
    big = mean + math.copysign(math.hypot(0.5 * (h11 - h22), h12), mean)
    small = 0.0 if big == 0.0 else (h11 * h22 - h12 * h12) / big
    return (small, big) if small <= big else (big, small)


# ---------------------------------------------------------------------------
# Batch form: many parameter points at once, for maps.

@dataclass(frozen=True)
class EquilibriumBatch:
    """Equilibria of many parameter points, padded to 6 slots per point.

    ``valid[i, j]`` says slot j of point i holds an equilibrium; ``theta`` has
    shape (N, 6, 2), ``eigenvalues`` (N, 6, 2) ascending.  ``continuum[i]``
    marks points whose equilibria are not isolated.
    """

    theta: np.ndarray
    eigenvalues: np.ndarray
    valid: np.ndarray
    continuum: np.ndarray = field(default=None)

    @property
    def stable(self):
        ev = self.eigenvalues
        scale = np.max(np.abs(ev), axis=-1)
        return self.valid & (ev[..., 0] > DEGENERACY_TOL * scale)

    @property
    def num_equilibria(self):
        return self.valid.sum(axis=-1)

    @property
    def num_stable(self):
        return self.stable.sum(axis=-1)


def equilibria_batch(rho, L1=1.0, L2=1.0, ka=100.0, kb=100.0, kc=100.0,
                     f3x=0.0, f3y=0.0, f4x=0.0, f4y=0.0, m1=0.0, m2=0.0,
                     g=STANDARD_GRAVITY) -> EquilibriumBatch:
    """Vectorised :func:`equilibria` over broadcast parameter arrays (flattened).

    Same elimination, but the degree-6 polynomial is taken in w = tan((t1 - PHI0)/2)
    so that its coefficients are real (real companion matrices solve about three
    times faster in batch); the offset PHI0 keeps the common flat solutions
    t1 in {0, pi} away from w = infinity.
    """
    v = _batch_arrays(rho=rho, L1=L1, L2=L2, ka=ka, kb=kb, kc=kc, f3x=f3x, f3y=f3y,
                      f4x=f4x, f4y=f4y, m1=m1, m2=m2)
    n = v['rho'].size
    if n <= BATCH_BLOCK:
        return _batch_block(v, g)
    # Blocks that stay in cache are much faster than one huge set of temporaries.
    blocks = [_batch_block({k: a[i:i + BATCH_BLOCK] for k, a in v.items()}, g)
              for i in range(0, n, BATCH_BLOCK)]
    return EquilibriumBatch(theta=np.concatenate([b.theta for b in blocks]),
                            eigenvalues=np.concatenate([b.eigenvalues for b in blocks]),
                            valid=np.concatenate([b.valid for b in blocks]),
                            continuum=np.concatenate([b.continuum for b in blocks]))


#: Rows per block of :func:`equilibria_batch` (temporaries of a block fit in cache).
BATCH_BLOCK = 8192


def _batch_block(v, g):
    """:func:`equilibria_batch` on validated, flattened parameter arrays."""
    f3y_total = v['f3y'] - 0.5 * v['m1'] * g
    f4y_total = v['f4y'] - 0.5 * v['m2'] * g
    physical = _reduced_coefficients(v['rho'], v['L1'], v['L2'], v['ka'], v['kb'], v['kc'],
                                     v['f3x'], f3y_total, v['f4x'], f4y_total)
    # solved in exactly rescaled constants (see _normalized); Hessians need the physical ones
    physical_scale = _scale(*physical)
    shift = np.frexp(physical_scale)[1]
    consts = tuple(np.ldexp(c, -shift) for c in physical)
    n = consts[0].size
    scale = np.ldexp(physical_scale, -shift)              # exact, as for the constants
    laurent = _polynomial(*consts)                                # (n, 7), z^3 .. z^-3
    continuum = np.max(np.abs(laurent), axis=-1) <= CONTINUUM_TOL * scale ** 4
    t1, near_circle = _batch_circle_roots(laurent, continuum)     # (n, 6), nan if off circle
    horizontal = (consts[1] == 0.0) & (consts[3] == 0.0) & ~continuum
    if np.any(horizontal):                     # no vertical load: closed form, see equilibria()
        t1[horizontal] = _batch_horizontal_first_angles(
            *(c[horizontal] for c in (consts[0], consts[2], consts[4], consts[5])))

    # From here on, one entry per real first angle / per candidate (rows ascending).
    real = np.isfinite(t1)
    isolated = _isolated(t1)[real]
    root_rows = np.nonzero(real)[0]
    roots = t1[real]
    c = [x[root_rows] for x in consts]
    t2, check = _batch_candidates(roots, *c, scale[root_rows])    # (m, 4)
    limit = _candidate_limit(check, scale[root_rows], isolated)
    root_index, route = np.nonzero(check <= limit)
    rows = root_rows[root_index]
    c = [x[root_index] for x in c]
    s1, s2, residual = _newton(roots[root_index], t2[root_index, route], *c, scale[rows])
    converged = residual <= CONVERGED_TOL
    # Rows with anything delicate (a candidate that did not converge, solutions
    # crowding together, a nearly singular equilibrium, an index sum that breaks
    # Poincare-Hopf) are solved again by the scalar path, which is the reference:
    # the batch is a fast path for the generic rows, not a second algorithm for
    # the degenerate ones.
    hard = near_circle.copy()           # a root just off the circle: a pair about to merge
    hard[rows[~converged]] = True
    rows = rows[converged]
    solutions = np.stack([_wrap(s1[converged]), _wrap(s2[converged])], -1)
    slots = _slots(rows, n)
    theta = np.full((n, max(6, int(slots.max(initial=-1)) + 1), 2), np.nan)
    theta[rows, slots] = solutions
    valid, crowded = _batch_unique(theta)
    hard |= crowded
    hard |= valid.sum(axis=1) > 6
    theta = _pack(theta, valid, 6)
    valid = np.isfinite(theta[..., 0])
    valid[continuum] = False
    cols = [x[:, None] for x in physical]
    eigenvalues = _batch_eigenvalues(theta, valid, cols, v['L1'], v['L2'])
    low, high = eigenvalues[..., 0], eigenvalues[..., 1]
    small, big = np.abs(low), np.abs(high)
    hard |= (valid & (np.minimum(small, big) <= HARD_TOL * np.maximum(small, big))).any(axis=1)
    # All non-degenerate now (the line above): the energy is a Morse function on
    # the torus, so Poincare-Hopf (#minima + #maxima - #saddles = 0) and the Morse
    # inequalities (at least one minimum, one maximum, two saddles) hold; a lost
    # root breaks one of them.
    minima = (valid & (low > 0.0)).sum(axis=1)
    maxima = (valid & (high < 0.0)).sum(axis=1)
    saddles = valid.sum(axis=1) - minima - maxima
    hard |= (minima + maxima != saddles) | (minima < 1) | (maxima < 1) | (saddles < 2)
    hard &= ~continuum
    if np.any(hard):
        index = np.nonzero(hard)[0]
        theta[index], valid[index] = np.nan, False
        for row in index.tolist():
            found = _solve_scalar(tuple(float(c[row]) for c in consts))
            continuum[row] = found is None
            for j, (u1, u2, _) in enumerate((found or ())[:6]):
                theta[row, j] = (u1, u2)
                valid[row, j] = True
        eigenvalues[index] = _batch_eigenvalues(theta[index], valid[index],
                                                [c[index] for c in cols],
                                                v['L1'][index], v['L2'][index])
    return EquilibriumBatch(theta=theta, eigenvalues=eigenvalues, valid=valid,
                            continuum=continuum)


#: For a first angle with no other within ROOT_SEPARATION (chord length on the
#: unit circle), a batch candidate whose check residual exceeds CANDIDATE_RATIO
#: times the best one of the same t1 and CANDIDATE_FLOOR (relative to the scale)
#: is not polished.  Such a root is simple and accurate to rounding times a
#: modest condition number, so the check residual of a genuine candidate is far
#: below CANDIDATE_FLOOR; the others passed CANDIDATE_TOL by coincidence (Newton
#: from them wanders, and a candidate that does not converge would send the row
#: to the scalar path).  Clustered roots are inaccurate, and a near miss (say a
#: flat configuration under tiny loads) can then check better than the genuine
#: candidate: there every candidate within CANDIDATE_TOL is polished, as in the
#: scalar path, which never prunes.
CANDIDATE_RATIO = 1e4
CANDIDATE_FLOOR = 1e-9
ROOT_SEPARATION = 1e-3


def _isolated(t1):
    """Which first angles (n, w; nan for none) have no other within ROOT_SEPARATION."""
    c, s = np.cos(t1), np.sin(t1)
    crowded = np.zeros(t1.shape, dtype=bool)
    for i in range(t1.shape[1]):
        for j in range(i + 1, t1.shape[1]):
            near = (c[:, i] - c[:, j]) ** 2 + (s[:, i] - s[:, j]) ** 2 <= ROOT_SEPARATION ** 2
            crowded[:, i] |= near                                  # nan compares False
            crowded[:, j] |= near
    return ~crowded


def _candidate_limit(check, scale, isolated):
    """Acceptance limit (m, 1) for the |check| (m, 4) of each first angle, see CANDIDATE_RATIO."""
    best = np.fmin(np.fmin(check[:, 0], check[:, 1]), np.fmin(check[:, 2], check[:, 3]))
    tol = CANDIDATE_TOL * scale
    limit = np.minimum(tol, np.maximum(CANDIDATE_RATIO * best, CANDIDATE_FLOOR * scale))
    return np.where(isolated, limit, tol)[:, None]


#: Rows with an equilibrium whose |lambda_min| is below this times |lambda_max|
#: are solved by the scalar path.
HARD_TOL = 1e-5


def _batch_candidates(t1, a1, b1, a2, b2, kcL1, kcL2, scale):
    """Candidate t2 for each t1, and the residual of the other equation there.

    From g1 = 0: with sin(t1 + t2) = r / (kc L2) =: sin(phi), t2 = phi - t1 and
    t2 = pi - phi - t1 (checked by g2).  From g2 = 0, (cos t2, sin t2) is
    parallel to (a2 - kc L1 cos t1, b2 + kc L1 sin t1): t2 = psi, psi + pi
    (checked by g1), kept only where no g1 candidate close to it passed.  The
    g1 route is ill-conditioned when the loads dwarf kc L2 (a small error in
    t1 becomes a large one in phi); the g2 route then is not, and conversely.
    All arguments have the shape (m,) of t1; returns (t2, |check|), each
    (m, 4); ``check`` is nan for suppressed candidates.
    """
    s1, c1 = np.sin(t1), np.cos(t1)
    sphi = np.clip((a1 * s1 - b1 * c1) / kcL2, -1.0, 1.0)
    cphi = np.sqrt(1.0 - sphi * sphi)
    phi = np.arcsin(sphi)
    s2a, c2a = sphi * c1 - cphi * s1, cphi * c1 + sphi * s1
    s2b, c2b = sphi * c1 + cphi * s1, sphi * s1 - cphi * c1
    g2a = a2 * s2a - b2 * c2a - kcL1 * sphi
    g2b = a2 * s2b - b2 * c2b - kcL1 * sphi
    x, y = a2 - kcL1 * c1, b2 + kcL1 * s1
    psi = np.arctan2(y, x)
    norm = np.hypot(x, y)
    safe = np.where(norm > 0.0, norm, 1.0)
    cpsi, spsi = np.where(norm > 0.0, x / safe, 1.0), np.where(norm > 0.0, y / safe, 0.0)
    s12 = s1 * cpsi + c1 * spsi                       # sin(t1 + psi)
    r = a1 * s1 - b1 * c1
    g1c, g1d = r - kcL2 * s12, r + kcL2 * s12
    tol = CANDIDATE_TOL * scale
    t2a, t2b, t2c, t2d = phi - t1, np.pi - phi - t1, psi, psi + np.pi

    def near(c, s, cx, sx):                           # chord length of the two angles
        return (c - cx) ** 2 + (s - sx) ** 2 <= SECOND_ROUTE_SEPARATION ** 2

    passed_a, passed_b = np.abs(g2a) <= tol, np.abs(g2b) <= tol
    for sign, g1x in ((1.0, g1c), (-1.0, g1d)):
        cx, sx = sign * cpsi, sign * spsi
        redundant = ((passed_a & near(c2a, s2a, cx, sx)) | (passed_b & near(c2b, s2b, cx, sx)))
        g1x[redundant] = np.nan
    return (np.stack([t2a, t2b, t2c, t2d], axis=-1),
            np.abs(np.stack([g2a, g2b, g1c, g1d], axis=-1)))


#: Offset of the tan-half variable of the batch solver (rad); any value off the
#: special angles 0, pi/2, pi will do.
PHI0 = 0.6180339887498949


def _tan_half_basis():
    """M with R(w) = M @ q: (1+iw)^(3+n) (1-iw)^(3-n) for n = 3..-3, highest power first."""
    basis = np.zeros((7, 7), dtype=complex)
    for col, order in enumerate(range(3, -4, -1)):
        poly = np.poly1d([1.0])
        for _ in range(3 + order):
            poly = poly * np.poly1d([1j, 1.0])
        for _ in range(3 - order):
            poly = poly * np.poly1d([-1j, 1.0])
        basis[:, col] = poly.coeffs
    return basis


_TAN_HALF_BASIS = _tan_half_basis()
_ROTATION = np.exp(1j * PHI0 * np.arange(3, -4, -1))


#: A unit-circle root with | ln|z| | above this is a pair of roots about to
#: merge (or just merged into a complex pair): the row goes to the scalar path.
NEAR_CIRCLE = 1e-9


def _batch_circle_roots(laurent, continuum):
    """t1 of the unit-circle roots of many polynomials, (n, 6), nan elsewhere,
    and which rows have a root near but not on the circle."""
    real = ((laurent * _ROTATION) @ _TAN_HALF_BASIS.T).real     # (n, 7) in w
    peak = np.max(np.abs(real), axis=-1, keepdims=True)
    peak[peak == 0.0] = 1.0
    real = real / peak
    lead = real[:, :1].copy()
    # A vanishing leading coefficient is a root at w = infinity (t1 = PHI0 + pi):
    # a tiny stand-in keeps it as a huge finite root.
    lead[np.abs(lead) < 1e-15] = 1e-15
    companion = np.zeros((real.shape[0], 6, 6))
    companion[:, 0, :] = -real[:, 1:] / lead
    companion[:, np.arange(1, 6), np.arange(0, 5)] = 1.0
    companion[continuum] = np.diag(np.full(5, 1.0), -1)          # harmless stand-in
    w = np.linalg.eigvals(companion)
    z = (1.0 + 1j * w) / (1.0 - 1j * w)
    modulus = np.abs(z)
    on_circle = np.abs(np.log(np.where(modulus > 0, modulus, 1e-300))) < UNIT_CIRCLE_TOL
    on_circle |= ~np.isfinite(modulus) & np.isinf(np.abs(w))
    t1 = PHI0 + np.where(np.isfinite(modulus), np.angle(z), np.pi)
    off = np.abs(np.log(np.where(modulus > 0, modulus, 1e-300)))
    near = (on_circle & (off > NEAR_CIRCLE)).any(axis=1)
    return np.where(on_circle, t1, np.nan), near


def _batch_arrays(**values):
    converted = []
    for name, v in values.items():
        try:
            if isinstance(v, (str, bytes)):
                raise TypeError('text is not a number')
            converted.append(np.asarray(v, dtype=float))
        except (TypeError, ValueError) as error:
            raise InvalidParameterError(f'{name} must be real numbers: {error}') from None
    arrays = np.broadcast_arrays(*converted)
    out = {}
    for (name, _), arr in zip(values.items(), arrays):
        arr = arr.ravel()
        bad = ~(np.abs(arr) <= _module.MAX_MAGNITUDE)              # also nan and inf
        rule = f'finite, at most {_module.MAX_MAGNITUDE:g} in magnitude'
        if name in _module._POSITIVE:
            bad |= ~(arr >= _module.MIN_MAGNITUDE)
            rule += f', at least {_module.MIN_MAGNITUDE:g}'
        elif name in _module._NON_NEGATIVE:
            bad |= ~(arr >= 0)
            rule += ', non-negative'
        if np.any(bad):
            index = int(np.argmax(bad))
            raise InvalidParameterError(
                f'{name} has an invalid value {arr[index]!r} at index {index} ({rule})')
        out[name] = arr
    return out


def _slots(rows, n):
    """Position of each entry within its row, for ascending ``rows`` in range(n)."""
    counts = np.bincount(rows, minlength=n)
    return np.arange(rows.size) - np.repeat(np.cumsum(counts) - counts, counts)


def _pack(theta, keep, width):
    """The kept slots of theta (n, w, 2) moved to the front, in order, ``width`` of them."""
    rows, slots = np.nonzero(keep)
    packed = _slots(rows, keep.shape[0])
    fits = packed < width
    out = np.full((keep.shape[0], width, 2), np.nan)
    out[rows[fits], packed[fits]] = theta[rows[fits], slots[fits]]
    return out


def _batch_horizontal_first_angles(a1, a2, kcL1, kcL2):
    """:func:`_horizontal_load_first_angles` for many points, (m, 6), nan-padded."""
    cosine = _horizontal_cosine(a1, a2, kcL1, kcL2)
    inside = np.abs(cosine) < 1.0
    t1 = np.where(inside, np.arccos(np.where(inside, cosine, 0.0)), np.nan)
    out = np.full((a1.size, 6), np.nan)
    out[:, 0], out[:, 1], out[:, 2], out[:, 3] = 0.0, np.pi, t1, -t1
    return out


def _batch_unique(theta):
    """(mask of the distinct solutions per row, rows where solutions crowd together).

    Empty slots are nan; of identical solutions (IDENTICAL_TOL, both converged
    to rounding level) the first is kept.  Rows with two solutions within
    CROWDED_RADIUS need the cluster analysis of :func:`_unique` (the scalar path).
    """
    finite = np.isfinite(theta[..., 0])
    keep = finite.copy()
    crowded = np.zeros(theta.shape[0], dtype=bool)
    two_pi = 2.0 * np.pi
    for j in range(1, theta.shape[1]):
        rows = np.nonzero(finite[:, j])[0]
        d1 = np.abs(theta[rows, :j, 0] - theta[rows, j, None, 0])
        d2 = np.abs(theta[rows, :j, 1] - theta[rows, j, None, 1])
        distance = np.maximum(np.minimum(d1, two_pi - d1), np.minimum(d2, two_pi - d2))
        earlier = keep[rows, :j]
        keep[rows[((distance <= IDENTICAL_TOL) & earlier).any(axis=1)], j] = False
        crowded[rows[((distance <= CROWDED_RADIUS) & (distance > IDENTICAL_TOL)
                      & earlier).any(axis=1)]] = True
    return keep, crowded


def _newton(t1, t2, a1, b1, a2, b2, kcL1, kcL2, scale):
    """Newton on (g1, g2) for arrays of candidates, iterating only the unconverged.

    Returns (t1, t2, max |g| / scale) at the last point where g was evaluated,
    so the residual certifies the returned point.  A point stops at rounding
    level (|g| <= 4e-16 scale: near a multiple root a step from there only
    amplifies the rounding, as in _polish), after a step below 1e-14 rad
    (converged: g is evaluated once more there), or where g is singular.
    """
    t1, t2 = t1.copy(), t2.copy()
    residual = np.full(t1.shape, np.inf)
    active = np.arange(t1.size)
    u1, u2 = t1, t2
    last = np.zeros(t1.shape, dtype=bool)           # took a tiny step: evaluate and stop
    a1, b1, a2, b2, kcL1, kcL2, scale = (np.broadcast_to(c, t1.shape)
                                         for c in (a1, b1, a2, b2, kcL1, kcL2, scale))
    for iteration in range(NEWTON_MAX_ITER + 1):
        s1, c1, s2, c2 = np.sin(u1), np.cos(u1), np.sin(u2), np.cos(u2)
        s12 = s1 * c2 + c1 * s2
        c12 = c1 * c2 - s1 * s2
        g1 = a1 * s1 - b1 * c1 - kcL2 * s12
        g2 = a2 * s2 - b2 * c2 - kcL1 * s12
        size = np.maximum(np.abs(g1), np.abs(g2))
        residual[active] = size / scale
        j11 = a1 * c1 + b1 * s1 - kcL2 * c12
        j22 = a2 * c2 + b2 * s2 - kcL1 * c12
        det = j11 * j22 - kcL1 * kcL2 * c12 * c12
        going = (det != 0.0) & (size > 4e-16 * scale) & ~last
        if iteration == NEWTON_MAX_ITER or not going.any():
            break
        det = np.where(going, det, 1.0)
        d1 = (j22 * g1 + kcL2 * c12 * g2) / det
        d2 = (j11 * g2 + kcL1 * c12 * g1) / det
        active = active[going]
        last = (np.abs(d1) + np.abs(d2) <= 1e-14)[going]
        u1, u2 = u1[going] - d1[going], u2[going] - d2[going]
        t1[active], t2[active] = u1, u2
        a1, b1, a2, b2, kcL1, kcL2, scale = (c[going] for c in (a1, b1, a2, b2, kcL1, kcL2,
                                                                 scale))
    return t1, t2, residual


def _batch_eigenvalues(theta, valid, cols, L1, L2):
    """Hessian eigenvalues (N, 6, 2) of the valid slots (zeros elsewhere)."""
    a1, b1, a2, b2, kcL1, kcL2 = cols
    t1 = np.where(valid, theta[..., 0], 0.0)
    t2 = np.where(valid, theta[..., 1], 0.0)
    s1, c1, s2, c2 = np.sin(t1), np.cos(t1), np.sin(t2), np.cos(t2)
    c12 = c1 * c2 - s1 * s2
    L1, L2 = L1[:, None], L2[:, None]
    h11 = L1 * (a1 * c1 + b1 * s1 - kcL2 * c12)
    h22 = L2 * (a2 * c2 + b2 * s2 - kcL1 * c12)
    h12 = -kcL1 * L2 * c12
    low, high = hessian_eigenvalues(h11, h12, h22)
    ev = np.stack([low, high], -1)
    ev[~valid] = 0.0
    return ev
