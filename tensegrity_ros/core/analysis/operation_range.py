"""The operation range of a stable branch: the rho interval over which it stays stable.

:func:`operation_range` follows the stable branch through a configuration in rho
(everything else fixed) and says what ends it on each side: ``'fold'``,
``'branch_point'`` (symmetric pitchforks on the restricted systems of
:mod:`.analysis.bifurcation_model`) or the search ``'limit'``; each end is located by Newton on
a regular extended system to ~1e-12.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .bifurcation_model import (_critical_mode, _FLATS, _gh, _raw, _scale, _symmetries, _wrap,
                                BOUND_TOL, BRANCH_POINT, FOLD, LIMIT, MIRROR, SWAP, SWAP_MIRROR)
from .branch_end_solves import _flat_degenerate_rhos, _fold_newton, _local_terms, _swap_newton
from ..module.classification import DEGENERACY_TOL, hessian_eigenvalues
from ..module.model import ModuleParams
from ..module.polynomial_solver import equilibria

# -- Operation range: continuation of one stable branch in rho ---------------


@dataclass(frozen=True)
class RangeEnd:
    """One end of an operation range.

    ``kind``: ``'fold'`` (the branch merges with a saddle and disappears),
    ``'branch_point'`` (a symmetric branch loses stability to a symmetry-breaking
    mode, or a non-symmetric branch merges into a symmetric one; ``symmetry``
    names the symmetry) or ``'limit'`` (the search bound was reached while still
    stable).  ``theta``: the critical configuration (at a limit: the
    equilibrium there).  ``eigenvalues``: Hessian eigenvalues at the end.
    """

    rho: float
    kind: str
    theta: tuple
    eigenvalues: tuple
    symmetry: str = None


@dataclass(frozen=True)
class OperationRange:
    """The rho interval over which one stable branch exists and stays stable.

    Iterating gives ``(rho_min, rho_max)``.  ``theta`` is the (polished) stable
    equilibrium at ``params.rho`` the branch was followed from; ``branch`` holds
    the accepted continuation points (rho, theta1, theta2), ascending in rho,
    ends included; pass the object back as ``hint`` to later calls.
    """

    params: ModuleParams
    theta: tuple
    lower: RangeEnd
    upper: RangeEnd
    branch: np.ndarray
    bounds: tuple

    @property
    def rho_min(self):
        return self.lower.rho

    @property
    def rho_max(self):
        return self.upper.rho

    @property
    def width(self):
        return self.upper.rho - self.lower.rho

    def __iter__(self):
        yield self.lower.rho
        yield self.upper.rho

    def __contains__(self, rho):
        return self.lower.rho < rho < self.upper.rho

    def jumps_at(self, end):
        """Whether the tracker jumps where this branch reaches ``end`` (one of its ends).

        At a fold, always.  At a branch point, only where this branch is the symmetric
        one losing stability (it buckles) at a subcritical pitchfork (e.g. C1 of fig.
        8a).  A non-symmetric branch ending where it merges into its symmetric one (a
        pitchfork run backwards, e.g. the unloaded module at rho = (L1 + L2) / 2) goes
        on along it, stable, without a jump; so does a symmetric branch losing stability
        at a supercritical pitchfork (the flat state of that module at the same rho): it
        buckles smoothly onto one of the two minima growing out of it.  A branch point
        whose symmetry is not known counts as a jump."""
        if end.kind == FOLD:
            return True
        if end.kind != BRANCH_POINT:
            return False
        if end.symmetry is None:
            return True
        return _invariant(self.theta, end.symmetry) and not self._buckles_smoothly(end)

    def _buckles_smoothly(self, end):
        """A supercritical pitchfork at ``end``: just beyond it (1e-4 (L1 + L2) in rho)
        a stable equilibrium that breaks the symmetry lies next to the critical state
        (the buckled minima are ~ sqrt(rho distance) from it, ~1e-2 rad here; at a
        subcritical one the bifurcated equilibria lie on this side and are unstable)."""
        p = self.params
        step = 1e-4 * (p.L1 + p.L2)
        beyond = end.rho + (step if end is self.upper else -step)
        if beyond <= 0.0:
            return False
        for e in equilibria(p.with_(rho=beyond)).stable:
            near = max(abs(_wrap_float(a - b)) for a, b in zip(e.theta, end.theta))
            if near < 0.2 and not _invariant(e.theta, end.symmetry, 1e-6):
                return True
        return False

    def theta_at(self, rho):
        """The branch's equilibrium at ``rho`` inside the range (interpolated, polished)."""
        if not self.lower.rho <= rho <= self.upper.rho:
            raise ValueError(f'rho {rho} outside the range ({self.lower.rho}, {self.upper.rho})')
        br = self.branch
        guess = (np.interp(rho, br[:, 0], br[:, 1]), np.interp(rho, br[:, 0], br[:, 2]))
        P = _raw(self.params)
        P[0] = rho
        t1, t2, ok = _newton_theta(P, *guess)
        return (t1, t2)


def _invariant(theta, symmetry, tol=1e-9):
    """Whether the configuration ``theta`` is mapped onto itself by ``symmetry``."""
    t1, t2 = (float(v) for v in theta)
    if symmetry == SWAP:
        return abs(_wrap_float(t1 - t2)) <= tol
    if symmetry == SWAP_MIRROR:
        return abs(_wrap_float(t1 + t2)) <= tol
    return all(min(abs(_wrap_float(t)), abs(_wrap_float(t - math.pi))) <= tol for t in (t1, t2))


def _newton_theta(P, t1, t2, max_iter=12):
    """Newton on G = 0 at fixed parameters (scalar, fast).  Returns (t1, t2, converged).

    Converged: the step fell below 1e-13 rad, or the residual is at rounding level
    (|G| <= 1e-13 * scale: needed where H is nearly singular and the last steps
    only shuffle rounding noise)."""
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
    a1 = (ka + kc) * rho + f3x
    a2 = (kb + kc) * rho - f4x
    kl1, kl2 = kc * L1, kc * L2
    tiny = 1e-13 * max(L1, L2) * max(abs(a1), abs(a2), abs(f3y), abs(f4y), kl1, kl2)
    sin, cos = math.sin, math.cos
    residual = math.inf
    for _ in range(max_iter):
        s1, c1, s2, c2 = sin(t1), cos(t1), sin(t2), cos(t2)
        s12 = s1 * c2 + c1 * s2
        c12 = c1 * c2 - s1 * s2
        g1 = L1 * (a1 * s1 - kl2 * s12 - f3y * c1)
        g2 = L2 * (a2 * s2 - kl1 * s12 - f4y * c2)
        residual = max(abs(g1), abs(g2))
        h11 = L1 * (a1 * c1 - kl2 * c12 + f3y * s1)
        h22 = L2 * (a2 * c2 - kl1 * c12 + f4y * s2)
        h12 = -kl1 * L2 * c12
        det = h11 * h22 - h12 * h12
        if det == 0.0 or not math.isfinite(det):
            return t1, t2, residual <= tiny
        d1 = (h22 * g1 - h12 * g2) / det
        d2 = (h11 * g2 - h12 * g1) / det
        if residual <= tiny and abs(d1) + abs(d2) < 1e-6:
            t1 -= d1
            t2 -= d2
            return t1, t2, True
        t1 -= d1
        t2 -= d2
        if abs(d1) + abs(d2) < 1e-13:
            return t1, t2, True
        if abs(d1) + abs(d2) > 1.0:
            return t1, t2, False
    return t1, t2, residual <= 10 * tiny


def _eig2(h11, h12, h22):
    """Ascending eigenvalues of [[h11, h12], [h12, h22]] (pure float; small one accurate)."""
    mean = 0.5 * (h11 + h22)
    big = mean + math.copysign(math.hypot(0.5 * (h11 - h22), h12), mean)
    small = 0.0 if big == 0.0 else (h11 * h22 - h12 * h12) / big
    return (small, big) if small <= big else (big, small)


def _mode(h11, h12, h22, lam):
    """Unit eigenvector of eigenvalue lam."""
    if abs(lam - h11) >= abs(lam - h22):
        a, b = h12, lam - h11
    else:
        a, b = lam - h22, h12
    n = math.hypot(a, b)
    return (a / n, b / n) if n > 0 else (1.0, 0.0)


def _branch_state(P, t1, t2):
    """At an equilibrium: (lambda_min, lambda_max, mode, dtheta/drho, dlambda_min/drho)."""
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
    s1, c1, s2, c2, _, _, h11, h12, h22, k12 = _local_terms(P, t1, t2)
    g1r, g2r = L1 * (ka + kc) * s1, L2 * (kb + kc) * s2
    det = h11 * h22 - h12 * h12
    if det == 0.0:
        # exactly on a degeneracy (e.g. the flat branch on an unloaded boundary line,
        # where the numerators vanish too): lambda_min = 0 makes the caller end here
        dt1 = dt2 = 0.0
    else:
        dt1 = -(h22 * g1r - h12 * g2r) / det
        dt2 = -(h11 * g2r - h12 * g1r) / det
    lo, hi = _eig2(h11, h12, h22)
    v = _mode(h11, h12, h22, lo)
    # total derivative of H along the branch (third derivatives; dh11/dt1 = -g1 = 0)
    dh11 = L1 * (ka + kc) * c1 + k12 * dt2
    dh22 = L2 * (kb + kc) * c2 + k12 * dt1
    dh12 = k12 * (dt1 + dt2)
    dlam = v[0] * v[0] * dh11 + 2 * v[0] * v[1] * dh12 + v[1] * v[1] * dh22
    return lo, hi, v, (dt1, dt2), dlam


def _min_eig(P, t1, t2):
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
    c1, s1, c2, s2 = math.cos(t1), math.sin(t1), math.cos(t2), math.sin(t2)
    c12 = c1 * c2 - s1 * s2
    h11 = L1 * (((ka + kc) * rho + f3x) * c1 - kc * L2 * c12 + f3y * s1)
    h22 = L2 * (((kb + kc) * rho - f4x) * c2 - kc * L1 * c12 + f4y * s2)
    return _eig2(h11, -kc * L1 * L2 * c12, h22)


def _theta_close(a, b, tol):
    return abs(_wrap(a[0] - b[0])) <= tol and abs(_wrap(a[1] - b[1])) <= tol


def _merges_with_flats(P, t1, t2, rho, sigma, est, dtheta):
    """Where a non-flat unloaded branch may merge with a flat one (the flats' degeneracies
    it heads for, sqrt law), and how far the nearest one ahead the law cannot judge yet."""
    candidates, too_far = [], math.inf
    for f in _FLATS:
        for r in _flat_degenerate_rhos(P, f):
            d = r - rho
            pred = (t1 + 2 * d * dtheta[0], t2 + 2 * d * dtheta[1])
            if _theta_close(pred, f, 0.3 * max(abs(_wrap(t1 - f[0])),
                                               abs(_wrap(t2 - f[1]))) + 1e-6):
                candidates.append((r, f, BRANCH_POINT, MIRROR))
            elif 0.0 <= d * sigma <= 3.0 * est:
                too_far = min(too_far, d * sigma)
    return candidates, too_far


def _localise(P, sym, t1, t2, rho, sigma, est, dtheta, v):
    """Try to locate the end of the branch ahead of (t1, t2, rho) (estimated distance est).

    Returns (rho*, theta*, kind, symmetry) or None when no validated end is found (or a
    nearer end ahead is still too far to judge: the branch steps on first)."""
    flat = None
    for f in _FLATS:
        if _theta_close((t1, t2), f, 1e-9):
            flat = f
    candidates, too_far = _end_candidates(P, sym, t1, t2, rho, sigma, est, dtheta, v, flat)
    best = None
    for r, th, kind, symmetry in candidates:
        d = (r - rho) * sigma
        if not (-1e-12 * max(1.0, abs(rho)) <= d <= 3.0 * est + 1e-12):
            continue
        # the end of a stable branch: eigenvalues (0, +); a negative second eigenvalue
        # means the solve landed on another sheet (e.g. beyond an earlier fold)
        Q = list(P)
        Q[0] = r
        if not _min_eig(Q, th[0], th[1])[1] > 0.0:
            continue
        sqrt_law = kind == FOLD or (symmetry == MIRROR and flat is None)
        if not _on_the_branch(t1, t2, rho, dtheta, r, th, sqrt_law):
            if sqrt_law:
                too_far = min(too_far, d)
            continue
        if best is None or d < best[0]:
            best = (d, r, th, kind, symmetry)
    if best is None or too_far < best[0]:     # (unloaded L2 = 1.2539 took rho = 0 for 0.127)
        return None
    _, r, th, kind, symmetry = best
    if kind == FOLD:
        # a generic solve can still land on a non-symmetric branch point: classify
        Q = list(P)
        Q[0] = r
        kind = _kind_at(Q, th[0], th[1])
    return r, th, kind, symmetry


def _end_candidates(P, sym, t1, t2, rho, sigma, est, dtheta, v, flat):
    """([(rho*, theta*, kind, symmetry)], too_far): the ends the branch through (t1, t2,
    rho) may head for, solved on the system its symmetry (``sym``, ``flat`` the flat
    configuration it is on or None) makes regular; too_far as :func:`_merges_with_flats`."""
    candidates, too_far = [], math.inf      # too_far: the nearest end the sqrt law can't judge
    if MIRROR in sym:
        if flat is not None:
            for r in _flat_degenerate_rhos(P, flat):
                candidates.append((r, flat, BRANCH_POINT, MIRROR))
        else:
            candidates, too_far = _merges_with_flats(P, t1, t2, rho, sigma, est, dtheta)
    if not candidates:
        if SWAP in sym and abs(_wrap(t1 - t2)) < 1e-9 and abs(v[0] + v[1]) < 0.2:
            t, r, ok = _swap_newton(P, 0.5 * (t1 + t2), rho, False)
            if ok:
                candidates.append((r, (t, t), BRANCH_POINT, SWAP))
        elif SWAP_MIRROR in sym and abs(_wrap(t1 + t2)) < 1e-9 and abs(v[0] - v[1]) < 0.2:
            t, r, ok = _swap_newton(P, 0.5 * (t1 - t2), rho, True)
            if ok:
                candidates.append((r, (t, -t), BRANCH_POINT, SWAP_MIRROR))
        else:
            a, b, r, ok = _fold_newton(P, t1, t2, rho)
            if ok:
                candidates.append((r, (a, b), FOLD, None))
    return candidates, too_far


def _on_the_branch(t1, t2, rho, dtheta, r, th, sqrt_law):
    """Whether the end (r, th) lies where the branch through (t1, t2, rho) heads: theta -
    theta* ~ sqrt(distance) at a fold or a merge with a flat (``sqrt_law``: theta* ~
    theta + 2 d dtheta/drho), linear at a symmetric branch point."""
    if sqrt_law:
        pred = (t1 + 2 * (r - rho) * dtheta[0], t2 + 2 * (r - rho) * dtheta[1])
        gap = max(abs(_wrap(t1 - th[0])), abs(_wrap(t2 - th[1])))
        return _theta_close(pred, th, 0.35 * gap + 1e-7)
    pred = (t1 + (r - rho) * dtheta[0], t2 + (r - rho) * dtheta[1])
    return _theta_close(pred, th, 0.1 + 1e-3)


def _kind_at(P, t1, t2):
    """'fold' or 'branch_point' for a (nearly) critical equilibrium: is the critical
    mode orthogonal to dG/drho?"""
    _, L1, L2, ka, kb, kc = P[:6]
    _, _, h11, h12, h22 = _gh(P, t1, t2)
    psi = _critical_mode(h11, h12, h22)
    gr = np.array([L1 * (ka + kc) * math.sin(t1), L2 * (kb + kc) * math.sin(t2)])
    norm = np.linalg.norm(gr)
    return BRANCH_POINT if norm == 0 or abs(psi @ gr) <= 1e-7 * norm else FOLD


def _end_record(P, rho, theta, kind, symmetry):
    Q = P.copy()
    Q[0] = rho
    _, _, h11, h12, h22 = _gh(Q, theta[0], theta[1])
    lo, hi = hessian_eigenvalues(h11, h12, h22)
    return RangeEnd(rho=float(rho), kind=kind,
                    theta=(_wrap_float(float(theta[0])), _wrap_float(float(theta[1]))),
                    eigenvalues=(float(lo), float(hi)), symmetry=symmetry)


def _bisect_end(Q, t1, t2, rho, sigma, gap, scale_h):
    """Fallback localisation: bisection on 'the branch continues, stable' between rho
    (stable at (t1, t2)) and rho + sigma * gap (not), each trial a Newton solve from
    the last stable configuration.  Returns (rho_end, theta_end)."""
    a, b = 0.0, gap
    ta = (t1, t2)
    while b - a > 1e-14 * max(1.0, abs(rho)):
        m = 0.5 * (a + b)
        Q[0] = rho + sigma * m
        n1, n2, ok = _newton_theta(Q, *ta)
        if ok and _theta_close((n1, n2), ta, 0.05) and _min_eig(Q, n1, n2)[0] > 0.0:
            a, ta = m, (n1, n2)
        else:
            b = m
    return rho + sigma * a, ta


def _follow(P, sym, t1, t2, sigma, bound, scale_len, scale_h):
    """Follow the stable branch from (t1, t2, P[0]) in direction sigma up to ``bound``."""
    Q = P.copy()
    rho = P[0]
    samples = []
    hmax = 0.1 * scale_len
    shrink = 1.0
    first_fail = None        # smallest failed step since the last accepted one
    tried_here = False       # localisation already attempted from this point
    for _ in range(2000):
        Q[0] = rho
        lo, hi, v, dth, dlam = _branch_state(Q, t1, t2)
        rate = sigma * dlam
        est = lo / -rate if rate < 0 else math.inf
        remaining = sigma * (bound - rho)
        if remaining <= BOUND_TOL * scale_len:
            # at the bound (a degeneracy closer to it than BOUND_TOL counts as the bound)
            return _end_record(Q, bound, (t1, t2), LIMIT, None), samples
        if not tried_here and (est < 0.05 * scale_len or lo < 1e-3 * scale_h):
            tried_here = True
            end = _localise(Q, sym, t1, t2, rho, sigma, est, dth, v)
            if end is not None and sigma * (bound - end[0]) >= 0:
                r, th, kind, symmetry = end
                return _end_record(Q, r, th, kind, symmetry), samples
        speed = math.hypot(*dth)
        # lambda_min is predicted to vanish at or beyond the bound: do not creep up
        # on it, the bound ends the search first
        lam_room = 0.5 * est if est < remaining * (1.0 - 1e-9) else math.inf
        step = min(hmax, lam_room, 0.15 / max(speed, 1e-300)) * shrink
        at_bound = step >= remaining
        if at_bound:
            step = remaining
        if shrink < 1e-3 and first_fail is not None:
            # the corrector keeps failing (e.g. a nearly symmetric branch point, where
            # the fold system is ill-conditioned): bisect on stability instead
            r, th = _bisect_end(Q, t1, t2, rho, sigma, first_fail, scale_h)
            Q[0] = r
            if sigma * (bound - r) <= BOUND_TOL * scale_len:
                return _end_record(Q, bound, th, LIMIT, None), samples
            return _end_record(Q, r, th, _kind_at(Q, *th), None), samples
        r_new = rho + sigma * step
        pred = (t1 + sigma * step * dth[0], t2 + sigma * step * dth[1])
        Q[0] = r_new
        n1, n2, ok = _newton_theta(Q, *pred)
        good = ok and _theta_close((n1, n2), pred, 0.05 + 0.5 * step * speed)
        if good:
            lam_new = _min_eig(Q, n1, n2)[0]
            # on the bound itself a degeneracy (e.g. the continuum at rho = 0) is allowed
            good = lam_new > 0.0 or (at_bound and lam_new > -1e-12 * scale_h)
        if not good:
            first_fail = step if first_fail is None else min(first_fail, step)
            shrink *= 0.25
            continue
        shrink = min(1.0, shrink * 2.0)
        first_fail, tried_here = None, False
        rho, t1, t2 = r_new, n1, n2
        samples.append((rho, t1, t2))
    return _end_record(Q, rho, (t1, t2), LIMIT, None), samples


def operation_range(params: ModuleParams, theta, *, rho_bounds=None, hint=None) -> OperationRange:
    """The rho interval over which the stable branch through ``theta`` stays stable.

    ``params`` fixes everything but rho (``params.rho`` is where the branch is
    entered); ``theta`` is the stable equilibrium there or a close guess (it is
    polished by Newton; ``ValueError`` if that is not a stable equilibrium).
    The branch is followed both ways by continuation in rho (tangent predictor,
    Newton corrector; each step bounded so that lambda_min is predicted to at most
    halve and the angles move at most 0.15 rad).  When lambda_min is about to
    vanish the end is solved for on a regular extended system: a fold on
    ``{G = 0, det H = 0}`` in (theta, rho); a swap-symmetric branch point on the
    restricted system ``{g1(t, +-t) = 0, psi^T H psi = 0}``; for an unloaded
    module, the merge of the non-flat branch with a flat one at ``det H(flat) =
    0`` (a quadratic in rho).  The end is accepted only if it is consistent
    with the branch (ahead, near the predicted configuration).  Ends are exact to
    rounding (~1e-13).

    ``rho_bounds``: search interval (default ``(0, 2 (L1 + L2))``); reaching a
    bound while still stable gives an end of kind ``'limit'``.  ``hint``: a
    previous :class:`OperationRange`; if only rho changed and the new state is on
    the same branch, its ends are reused without any continuation.
    """
    if not isinstance(params, ModuleParams):
        raise TypeError('params must be ModuleParams')
    P = [float(v) for v in _raw(params)]
    L = params.L1 + params.L2
    if rho_bounds is None:
        lo_b, hi_b = 0.0, 2.0 * L
    else:
        lo_b, hi_b = float(rho_bounds[0]), float(rho_bounds[1])
    if not lo_b <= params.rho <= hi_b:
        raise ValueError(f'rho {params.rho} outside rho_bounds ({lo_b}, {hi_b})')
    th = np.asarray(theta, dtype=float)
    if th.shape != (2,) or not np.all(np.isfinite(th)):
        raise ValueError('theta must be two finite angles')
    t1, t2, ok = _newton_theta(P, float(th[0]), float(th[1]))
    if not ok:
        raise ValueError(f'no equilibrium near theta={tuple(th)}')
    lam = _min_eig(P, t1, t2)
    if not lam[0] > DEGENERACY_TOL * abs(lam[1]):
        raise ValueError(f'the equilibrium near theta={tuple(th)} is not stable '
                         f'(eigenvalues {float(lam[0])}, {float(lam[1])})')
    t1, t2 = _wrap_float(t1), _wrap_float(t2)

    if hint is not None and _hint_applies(hint, P, t1, t2, (lo_b, hi_b)):
        return OperationRange(params=params, theta=(t1, t2), lower=hint.lower, upper=hint.upper,
                              branch=hint.branch, bounds=(lo_b, hi_b))

    sym = _symmetries(P)
    scale_h = _scale(P)
    lower, below = _follow(P, sym, t1, t2, -1.0, lo_b, L, scale_h)
    upper, above = _follow(P, sym, t1, t2, +1.0, hi_b, L, scale_h)
    rows = ([(lower.rho, *lower.theta)] + below[::-1] + [(params.rho, t1, t2)] + above
            + [(upper.rho, *upper.theta)])
    branch = np.array(rows)
    branch[:, 1:] = _unwrap_rows(branch[:, 1:])
    return OperationRange(params=params, theta=(t1, t2), lower=lower, upper=upper,
                          branch=branch, bounds=(lo_b, hi_b))


def _wrap_float(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _unwrap_rows(th):
    return np.unwrap(th, axis=0)


def _hint_applies(hint, P, t1, t2, bounds):
    if not isinstance(hint, OperationRange) or tuple(hint.bounds) != tuple(bounds):
        return False
    Ph = _raw(hint.params)
    if not np.array_equal(Ph[1:], P[1:]):
        return False
    rho = P[0]
    if not hint.lower.rho < rho < hint.upper.rho:
        return False
    br = hint.branch
    guess = (np.interp(rho, br[:, 0], br[:, 1]), np.interp(rho, br[:, 0], br[:, 2]))
    a, b, ok = _newton_theta(P, float(guess[0]), float(guess[1]))
    return ok and _theta_close((a, b), (t1, t2), 1e-7)
