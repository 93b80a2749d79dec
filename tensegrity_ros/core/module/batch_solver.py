"""Equilibria of many parameter points at once, vectorised (numpy), for maps.

The same elimination as :mod:`.module.polynomial_solver`, with the degree-6 polynomial in
w = tan((t1 - PHI0)/2) so that its coefficients are real.  Generic rows are solved
here; every delicate row goes to the scalar solver, so both give the same answer: a
root just off the circle, a candidate that does not converge, solutions crowding
together, a nearly singular equilibrium, or a set that breaks Poincare-Hopf or the
Morse inequalities of the torus (a lost root).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import model as _module
from .angle_polynomial import _horizontal_cosine, _polynomial, _reduced_coefficients, _scale
from .classification import DEGENERACY_TOL, hessian_eigenvalues
from .model import InvalidParameterError, STANDARD_GRAVITY
from .polynomial_solver import (_solve_scalar, _wrap, CANDIDATE_TOL, CONTINUUM_TOL, CONVERGED_TOL,
                                CROWDED_RADIUS, IDENTICAL_TOL, NEWTON_MAX_ITER,
                                SECOND_ROUTE_SEPARATION, UNIT_CIRCLE_TOL)


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
    """:func:`equilibria_batch` on validated, flattened parameter arrays.

    Rows with anything delicate (a candidate that did not converge, solutions crowding
    together, a nearly singular equilibrium, an index sum that breaks Poincare-Hopf) are
    solved again by the scalar path, which is the reference: the batch is a fast path
    for the generic rows, not a second algorithm for the degenerate ones.
    """
    physical, consts, scale = _scaled_constants(v, g)
    laurent = _polynomial(*consts)                                # (n, 7), z^3 .. z^-3
    continuum = np.max(np.abs(laurent), axis=-1) <= CONTINUUM_TOL * scale ** 4
    t1, near_circle = _batch_circle_roots(laurent, continuum)     # (n, 6), nan if off circle
    horizontal = (consts[1] == 0.0) & (consts[3] == 0.0) & ~continuum
    if np.any(horizontal):                     # no vertical load: closed form, see equilibria()
        t1[horizontal] = _batch_horizontal_first_angles(
            *(c[horizontal] for c in (consts[0], consts[2], consts[4], consts[5])))
    theta, hard = _polished(t1, consts, scale, near_circle)
    valid = np.isfinite(theta[..., 0])
    valid[continuum] = False
    cols = [x[:, None] for x in physical]
    eigenvalues = _batch_eigenvalues(theta, valid, cols, v['L1'], v['L2'])
    hard |= _delicate(valid, eigenvalues)
    hard &= ~continuum
    if np.any(hard):
        _solve_scalar_rows(np.nonzero(hard)[0], consts, cols, v, theta, valid, eigenvalues,
                           continuum)
    return EquilibriumBatch(theta=theta, eigenvalues=eigenvalues, valid=valid,
                            continuum=continuum)


def _scaled_constants(v, g):
    """(physical, scaled, scale): the reduced constants, the same divided by the power of
    two nearest their scale (exact, as in polynomial_solver._normalized: the
    solve runs on these) and that scale divided likewise; Hessians need the physical ones."""
    f3y_total = v['f3y'] - 0.5 * v['m1'] * g
    f4y_total = v['f4y'] - 0.5 * v['m2'] * g
    physical = _reduced_coefficients(v['rho'], v['L1'], v['L2'], v['ka'], v['kb'], v['kc'],
                                     v['f3x'], f3y_total, v['f4x'], f4y_total)
    physical_scale = _scale(*physical)
    shift = np.frexp(physical_scale)[1]
    consts = tuple(np.ldexp(c, -shift) for c in physical)
    scale = np.ldexp(physical_scale, -shift)              # exact, as for the constants
    return physical, consts, scale


def _polished(t1, consts, scale, near_circle):
    """(theta (n, 6, 2) packed, hard rows): the first angles ``t1`` (n, 6) completed by
    their second-angle candidates and polished by Newton.  Hard: a root just off the
    circle (``near_circle``), a candidate that did not converge, solutions crowding
    together or more than six of them."""
    # From here on, one entry per real first angle / per candidate (rows ascending).
    n = consts[0].size
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
    return _pack(theta, valid, 6), hard


def _delicate(valid, eigenvalues):
    """Rows with a nearly singular equilibrium, or whose set breaks the Morse counts.

    Without the first, the energy is a Morse function on the torus, so Poincare-Hopf
    (#minima + #maxima - #saddles = 0) and the Morse inequalities (at least one minimum,
    one maximum, two saddles) hold; a lost root breaks one of them."""
    low, high = eigenvalues[..., 0], eigenvalues[..., 1]
    small, big = np.abs(low), np.abs(high)
    singular = (valid & (np.minimum(small, big) <= HARD_TOL * np.maximum(small, big))).any(axis=1)
    minima = (valid & (low > 0.0)).sum(axis=1)
    maxima = (valid & (high < 0.0)).sum(axis=1)
    saddles = valid.sum(axis=1) - minima - maxima
    return singular | (minima + maxima != saddles) | (minima < 1) | (maxima < 1) | (saddles < 2)


def _solve_scalar_rows(index, consts, cols, v, theta, valid, eigenvalues, continuum):
    """Solve rows ``index`` again by the scalar path, in place of theta, valid,
    eigenvalues and continuum."""
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
