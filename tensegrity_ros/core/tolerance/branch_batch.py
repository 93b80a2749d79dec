"""Stable branches of many one-module samples followed at once (numpy), for tolerance
studies: the operating range and a planned path of thousands of samples in one pass.

Each sample moves along its own straight parameter path P(s) = P0 + s dP (the range:
rho = s; a command leg: s from 0 to 1).  The module's gradient and Hessian are linear in
five path coefficients, A1 = L1 ((ka + kc) rho + f3x), A2 = L2 ((kb + kc) rho - f4x),
C1 = L1 F3, C2 = L2 F4 (vertical loads with the rods' weights), K = kc L1 L2:

    g1 = A1 sin t1 - K sin(t1 + t2) - C1 cos t1      h11 = A1 cos t1 - K cos(t1 + t2) + C1 sin t1
    g2 = A2 sin t2 - K sin(t1 + t2) - C2 cos t2      h22 = A2 cos t2 - K cos(t1 + t2) + C2 sin t2
                                                      h12 = -K cos(t1 + t2)

so every row's branch is followed as :func:`.analysis.operation_range.operation_range` follows one
(tangent predictor, Newton corrector, a step bounded so that lambda_min is predicted to
at most halve and the angles move at most 0.15 rad), and an end is solved for on the
regular fold system {G = 0, det H = 0} in (theta, s) by Newton and accepted only where it
lies ahead of the branch, near the predicted configuration.  A jump lands on the one
other stable equilibrium at the fold's parameters (a module has at most two).

The vectorised path takes the generic rows only.  Every delicate row goes to the scalar
reference (``question.evaluate_one``): an exact symmetry (its ends are branch points,
solved on restricted systems there), a step that keeps failing (a nearly symmetric branch
point), an end that is not a fold, a landing that is not the one other minimum, no
unique stable start.  So both give the same answer; test_tolerance_batch checks it.
Each row's arithmetic depends on that row only (finished rows are frozen, never updated
with the others), so a sample's answer does not depend on its chunk.
"""
from __future__ import annotations

import math

import numpy as np

from ..module.batch_solver import equilibria_batch
from ..module.model import PARAMETER_NAMES

#: A row within this fraction of the path's length scale of a bound has reached it
#: (operation_range's BOUND_TOL).
BOUND_TOL = 1e-8
#: Give up on the vectorised path for a row after this many steps (scalar fallback).
MAX_STEPS = 2000
#: Most jumps followed on one leg before the row goes to the scalar path.
MAX_EVENTS = 8
#: Kinds of a branch end.
FOLD, LIMIT = 0, 2

_I = {name: i for i, name in enumerate(PARAMETER_NAMES)}


class PathFamily:
    """The path coefficients of rows moving along P0 + s dP (arrays (m, 12)).

    A1, A2, K are cubic and C1, C2 quadratic in s (products of the parameters, each
    linear in s); their polynomial coefficients are computed once, so that a point of
    the path costs one Horner evaluation."""

    def __init__(self, p0, dp, g):
        self.p0 = np.asarray(p0, dtype=float)
        self.dp = np.asarray(dp, dtype=float)
        self.g = g
        lin = {name: np.stack([self.p0[:, i], self.dp[:, i]]) for name, i in _I.items()}
        half_g = 0.5 * g
        F3 = lin['f3y'] - half_g * lin['m1']
        F4 = lin['f4y'] - half_g * lin['m2']
        a1 = _mul(lin['ka'] + lin['kc'], lin['rho']) + _pad(lin['f3x'], 3)
        a2 = _mul(lin['kb'] + lin['kc'], lin['rho']) - _pad(lin['f4x'], 3)
        polys = [_mul(lin['L1'], a1), _mul(lin['L2'], a2), _pad(_mul(lin['L1'], F3), 4),
                 _pad(_mul(lin['L2'], F4), 4), _mul(_mul(lin['kc'], lin['L1']), lin['L2'])]
        self.poly = np.stack(polys)                                 # (5 quantities, 4, m)

    def at(self, idx, s):
        """(11, k): A1, A2, C1, C2, K, their s-derivatives, and the scale of G and H
        (max |A1|, |A2|, |C1|, |C2|, K) of rows ``idx`` at ``s``."""
        p = self.poly[:, :, idx]
        value = ((p[:, 3] * s + p[:, 2]) * s + p[:, 1]) * s + p[:, 0]
        slope = (3.0 * p[:, 3] * s + 2.0 * p[:, 2]) * s + p[:, 1]
        scale = np.max(np.abs(value), axis=0)
        return np.concatenate([value, slope, scale[None]])


def _mul(a, b):
    """Product of per-row polynomials (coefficients along axis 0, rows along axis 1)."""
    out = np.zeros((a.shape[0] + b.shape[0] - 1, a.shape[1]))
    for i in range(a.shape[0]):
        for j in range(b.shape[0]):
            out[i + j] += a[i] * b[j]
    return out


def _pad(a, n):
    return np.concatenate([a, np.zeros((n - a.shape[0], a.shape[1]))])


def _trig(t1, t2):
    s1, c1, s2, c2 = np.sin(t1), np.cos(t1), np.sin(t2), np.cos(t2)
    return s1, c1, s2, c2, s1 * c2 + c1 * s2, c1 * c2 - s1 * s2


def gradient_hessian(c, t1, t2):
    """(g1, g2, h11, h12, h22, K sin(t1 + t2), trig) for coefficients ``c``."""
    A1, A2, C1, C2, K = c[:5]
    s1, c1, s2, c2, s12, c12 = tr = _trig(t1, t2)
    ks, kc = K * s12, K * c12
    return (A1 * s1 - ks - C1 * c1, A2 * s2 - ks - C2 * c2,
            A1 * c1 - kc + C1 * s1, -kc, A2 * c2 - kc + C2 * s2, ks, tr)


def eigenvalues_2x2(h11, h12, h22):
    """Ascending eigenvalues of the symmetric 2x2 matrices (small one accurate)."""
    mean = 0.5 * (h11 + h22)
    big = mean + np.copysign(np.hypot(0.5 * (h11 - h22), h12), mean)
    with np.errstate(divide='ignore', invalid='ignore'):
        small = np.where(big == 0.0, 0.0, (h11 * h22 - h12 * h12) / big)
    return np.minimum(small, big), np.maximum(small, big)


def _mode(h11, h12, h22, lam):
    """Unit eigenvectors of eigenvalue ``lam``."""
    first = np.abs(lam - h11) >= np.abs(lam - h22)
    a = np.where(first, h12, lam - h22)
    b = np.where(first, lam - h11, h12)
    n = np.hypot(a, b)
    safe = n > 0
    n = np.where(safe, n, 1.0)
    return np.where(safe, a / n, 1.0), np.where(safe, b / n, 0.0)


def _wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _take(c, k):
    return c[:, k]


def newton(c, t1, t2, max_iter=12):
    """Newton on G = 0 at fixed parameters, per row (operation_range's _newton_theta):
    (t1, t2, converged).  A row stops when its step falls below 1e-13 rad or its residual
    is at rounding level; stopped rows are not touched again."""
    t1, t2 = t1.copy(), t2.copy()
    n = len(t1)
    ok = np.zeros(n, bool)
    active = np.arange(n)
    tiny = 1e-13 * c[10]
    residual = np.full(n, np.inf)
    for _ in range(max_iter):
        if active.size == 0:
            break
        ca = _take(c, active)
        a1, a2 = t1[active], t2[active]
        g1, g2, h11, h12, h22, _, _ = gradient_hessian(ca, a1, a2)
        res = np.maximum(np.abs(g1), np.abs(g2))
        residual[active] = res
        det = h11 * h22 - h12 * h12
        bad = (det == 0.0) | ~np.isfinite(det)
        with np.errstate(divide='ignore', invalid='ignore'):
            d1 = np.where(bad, 0.0, (h22 * g1 - h12 * g2) / np.where(bad, 1.0, det))
            d2 = np.where(bad, 0.0, (h11 * g2 - h12 * g1) / np.where(bad, 1.0, det))
        size = np.abs(d1) + np.abs(d2)
        at_rounding = ~bad & (res <= tiny[active]) & (size < 1e-6)
        move = ~bad
        t1[active[move]] = a1[move] - d1[move]
        t2[active[move]] = a2[move] - d2[move]
        converged = at_rounding | (move & (size < 1e-13))
        diverged = move & ~converged & ((size > 1.0) | ~np.isfinite(size))
        ok[active[converged]] = True
        ok[active[bad]] = res[bad] <= tiny[active][bad]
        active = active[~(bad | converged | diverged)]
    if active.size:
        ok[active] = residual[active] <= 10 * tiny[active]
    return t1, t2, ok


def _branch_state(c, t1, t2):
    """At equilibria: (lambda_min, lambda_max, dtheta/ds, dlambda_min/ds)."""
    A1, A2, C1, C2, K, dA1, dA2, dC1, dC2, dK, _ = c
    g1, g2, h11, h12, h22, ks, (s1, c1, s2, c2, s12, c12) = gradient_hessian(c, t1, t2)
    gs1 = dA1 * s1 - dK * s12 - dC1 * c1
    gs2 = dA2 * s2 - dK * s12 - dC2 * c2
    hs11 = dA1 * c1 - dK * c12 + dC1 * s1
    hs22 = dA2 * c2 - dK * c12 + dC2 * s2
    hs12 = -dK * c12
    det = h11 * h22 - h12 * h12
    zero = det == 0.0
    safe = np.where(zero, 1.0, det)
    dt1 = np.where(zero, 0.0, -(h22 * gs1 - h12 * gs2) / safe)
    dt2 = np.where(zero, 0.0, -(h11 * gs2 - h12 * gs1) / safe)
    lo, hi = eigenvalues_2x2(h11, h12, h22)
    v1, v2 = _mode(h11, h12, h22, lo)
    dh11 = hs11 - g1 * dt1 + ks * dt2
    dh22 = hs22 + ks * dt1 - g2 * dt2
    dh12 = hs12 + ks * (dt1 + dt2)
    dlam = v1 * v1 * dh11 + 2 * v1 * v2 * dh12 + v2 * v2 * dh22
    return lo, hi, dt1, dt2, dlam


def _fold_newton(fam, idx, t1, t2, s, relative_s, max_iter=16):
    """Newton on {G = 0, det H = 0} in (t1, t2, s) per row (analytic Jacobian):
    (t1, t2, s, converged)."""
    t1, t2, s = t1.copy(), t2.copy(), s.copy()
    n = len(t1)
    ok = np.zeros(n, bool)
    active = np.arange(n)
    for _ in range(max_iter):
        if active.size == 0:
            break
        a1, a2, sa = t1[active], t2[active], s[active]
        c = fam.at(idx[active], sa)
        dA1, dA2, dC1, dC2, dK = c[5:10]
        g1, g2, h11, h12, h22, ks, (s1, c1, s2, c2, s12, c12) = gradient_hessian(c, a1, a2)
        gs1 = dA1 * s1 - dK * s12 - dC1 * c1
        gs2 = dA2 * s2 - dK * s12 - dC2 * c2
        hs11 = dA1 * c1 - dK * c12 + dC1 * s1
        hs22 = dA2 * c2 - dK * c12 + dC2 * s2
        hs12 = -dK * c12
        scale_h = np.maximum.reduce([np.abs(h11), np.abs(h22), np.abs(h12),
                                     np.full(len(a1), 1e-300)])
        j31 = (-g1 * h22 + h11 * ks - 2 * h12 * ks) / scale_h
        j32 = (ks * h22 - h11 * g2 - 2 * h12 * ks) / scale_h
        j33 = (hs11 * h22 + h11 * hs22 - 2 * h12 * hs12) / scale_h
        f3 = (h11 * h22 - h12 * h12) / scale_h
        # Cramer's rule for [[h11, h12, gs1], [h12, h22, gs2], [j31, j32, j33]] d = -F
        r1, r2, r3 = -g1, -g2, -f3
        m11 = h22 * j33 - gs2 * j32
        m12 = h12 * j33 - gs2 * j31
        m13 = h12 * j32 - h22 * j31
        det = h11 * m11 - h12 * m12 + gs1 * m13
        bad = (det == 0.0) | ~np.isfinite(det)
        safe = np.where(bad, 1.0, det)
        d1 = (r1 * m11 - h12 * (r2 * j33 - gs2 * r3) + gs1 * (r2 * j32 - h22 * r3)) / safe
        d2 = (h11 * (r2 * j33 - gs2 * r3) - r1 * m12 + gs1 * (h12 * r3 - r2 * j31)) / safe
        d3 = (h11 * (h22 * r3 - r2 * j32) - h12 * (h12 * r3 - r2 * j31) + r1 * m13) / safe
        t1[active] = a1 + d1
        t2[active] = a2 + d2
        s[active] = sa + d3
        finite = np.isfinite(d1) & np.isfinite(d2) & np.isfinite(d3)
        diverged = bad | ~finite | (np.abs(d1) + np.abs(d2) > 2.0)
        denom = np.maximum(np.abs(s[active]), 1e-300) if relative_s else 1.0
        size = np.abs(d1) + np.abs(d2) + np.abs(d3) / denom
        s_g = c[10]
        conditioned = (size < 1e-8) & (np.maximum(np.abs(g1), np.abs(g2)) <= 1e-13 * s_g) \
            & (np.abs(f3) <= 1e-11)
        converged = ~diverged & ((size < 1e-14) | conditioned)
        ok[active[converged]] = True
        active = active[~(diverged | converged)]
    return t1, t2, s, ok


def follow(fam, idx, t1, t2, s0, sigma, bound, scale_len, relative_s, stop_at_bound_exactly):
    """Follow the stable branch of rows ``idx`` from (t1, t2) at s0 in direction sigma
    (+1 / -1, per row) up to ``bound`` (per row).

    Returns (s_end, t1_end, t2_end, kind, delicate): kind FOLD (the branch ends at a
    fold: the critical configuration) or LIMIT (the bound reached, still stable);
    ``delicate`` rows need the scalar path (their other outputs are meaningless)."""
    return _Follower(fam, idx, t1, t2, s0, sigma, bound, scale_len, relative_s,
                     stop_at_bound_exactly).run()


class _Follower:
    """:func:`follow`'s rows: their points on the branch, step control and ends."""

    def __init__(self, fam, idx, t1, t2, s0, sigma, bound, scale_len, relative_s,
                 exact_bound):
        m = len(idx)
        self.fam, self.idx, self.sigma, self.bound = fam, idx, sigma, bound
        self.scale_len, self.relative_s, self.exact_bound = scale_len, relative_s, exact_bound
        self.s = s0.astype(float).copy()
        self.t1, self.t2 = t1.astype(float).copy(), t2.astype(float).copy()
        self.shrink = np.ones(m)
        self.first_fail = np.full(m, np.inf)
        self.tried = np.zeros(m, bool)
        self.end_s, self.end_t1, self.end_t2 = (np.full(m, np.nan) for _ in range(3))
        self.kind = np.full(m, -1)
        self.delicate = np.zeros(m, bool)

    def run(self):
        active = np.arange(len(self.idx))
        for _ in range(MAX_STEPS):
            if active.size == 0:
                break
            active = active[~self.step(active)]
        self.delicate[active] = True
        return self.end_s, self.end_t1, self.end_t2, self.kind, self.delicate

    def step(self, active):
        """One predictor-corrector step of rows ``active``; which of them finished."""
        sa, a1, a2 = self.s[active], self.t1[active], self.t2[active]
        sg, bd = self.sigma[active], self.bound[active]
        c = self.fam.at(self.idx[active], sa)
        lo, hi, dt1, dt2, dlam = _branch_state(c, a1, a2)
        rate = sg * dlam
        with np.errstate(divide='ignore', invalid='ignore'):
            est = np.where(rate < 0, lo / -rate, np.inf)
        remaining = sg * (bd - sa)
        scale_h = _hessian_scale(c)
        done = self.ends(active, remaining, est, lo, scale_h, dt1, dt2)
        speed = np.hypot(dt1, dt2)
        lam_room = np.where(est < remaining * (1.0 - 1e-9), 0.5 * est, np.inf)
        with np.errstate(divide='ignore'):
            h = np.minimum(np.minimum(0.1 * self.scale_len[active], lam_room),
                           0.15 / np.maximum(speed, 1e-300)) * self.shrink[active]
        to_bound = h >= remaining
        h = np.where(to_bound, remaining, h)
        stuck = ~done & (self.shrink[active] < 1e-3) & np.isfinite(self.first_fail[active])
        self.delicate[active[stuck]] = True
        done |= stuck
        go = ~done
        if np.any(go):
            self.correct(active[go], h[go], to_bound[go], dt1[go], dt2[go], speed[go],
                         scale_h[go])
        return done

    def ends(self, active, remaining, est, lo, scale_h, dt1, dt2):
        """Rows at their bound (LIMIT) or with a validated fold ahead (FOLD)."""
        done = remaining <= BOUND_TOL * self.scale_len[active]     # a degeneracy this
        k = active[done]                                             # close: the bound
        self.end_s[k], self.end_t1[k], self.end_t2[k] = self.bound[k], self.t1[k], self.t2[k]
        self.kind[k] = LIMIT
        close_to_end = (est < 0.05 * self.scale_len[active]) | (lo < 1e-3 * scale_h)
        near = ~done & ~self.tried[active] & close_to_end
        if np.any(near):
            k = active[near]
            self.tried[k] = True
            found, r, e1, e2 = _localise(self.fam, self.idx[k], self.t1[k], self.t2[k],
                                         self.s[k], self.sigma[k], est[near], dt1[near],
                                         dt2[near], self.relative_s)
            inside = found & (self.sigma[k] * (self.bound[k] - r) >= 0)
            k = k[inside]
            self.end_s[k], self.end_t1[k], self.end_t2[k] = r[inside], e1[inside], e2[inside]
            self.kind[k] = FOLD
            done[np.nonzero(near)[0][inside]] = True
        return done

    def correct(self, rows, h, to_bound, dt1, dt2, speed, scale_h):
        """Predict a step ``h`` along the tangent, correct by Newton, keep it where it
        converged near the prediction onto a stable state; else shrink the step."""
        sg = self.sigma[rows]
        s_new = self.s[rows] + sg * h
        if self.exact_bound:
            s_new = np.where(to_bound, self.bound[rows], s_new)
        p1 = self.t1[rows] + sg * h * dt1
        p2 = self.t2[rows] + sg * h * dt2
        cn = self.fam.at(self.idx[rows], s_new)
        n1, n2, ok = newton(cn, p1, p2)
        good = ok & (np.abs(_wrap(n1 - p1)) <= 0.05 + 0.5 * h * speed) \
            & (np.abs(_wrap(n2 - p2)) <= 0.05 + 0.5 * h * speed)
        if np.any(good):
            close = good.copy()
            _, _, h11, h12, h22, _, _ = gradient_hessian(_take(cn, close), n1[close], n2[close])
            lam_new = eigenvalues_2x2(h11, h12, h22)[0]
            near_bound = to_bound[close] & (lam_new > -1e-12 * scale_h[close])
            good[close] = (lam_new > 0.0) | near_bound
        bad, kept = rows[~good], rows[good]
        self.first_fail[bad] = np.minimum(self.first_fail[bad], h[~good])
        self.shrink[bad] *= 0.25
        self.shrink[kept] = np.minimum(1.0, 2.0 * self.shrink[kept])
        self.first_fail[kept] = np.inf
        self.tried[kept] = False
        self.s[kept], self.t1[kept], self.t2[kept] = s_new[good], n1[good], n2[good]


def _hessian_scale(c):
    """A bound on |lambda| of H (its largest absolute row sum, any angles)."""
    A1, A2, C1, C2, K = c[:5]
    return np.maximum(np.abs(A1) + np.abs(C1), np.abs(A2) + np.abs(C2)) + 2.0 * K


def _localise(fam, rows, t1, t2, s, sigma, est, dt1, dt2, relative_s):
    """The fold ahead of each row, validated as operation_range validates one:
    (found, s*, t1*, t2*)."""
    e1, e2, r, ok = _fold_newton(fam, rows, t1, t2, s, relative_s)
    d = (r - s) * sigma
    ahead = ok & (d >= -1e-12 * np.maximum(1.0, np.abs(s))) & (d <= 3.0 * est + 1e-12)
    found = ahead.copy()
    if np.any(ahead):
        c = fam.at(rows[ahead], r[ahead])
        _, _, h11, h12, h22, _, _ = gradient_hessian(c, e1[ahead], e2[ahead])
        second = eigenvalues_2x2(h11, h12, h22)[1] > 0.0
        pred1 = t1[ahead] + 2 * (r[ahead] - s[ahead]) * dt1[ahead]
        pred2 = t2[ahead] + 2 * (r[ahead] - s[ahead]) * dt2[ahead]
        gap = np.maximum(np.abs(_wrap(t1[ahead] - e1[ahead])),
                         np.abs(_wrap(t2[ahead] - e2[ahead])))
        near = (np.abs(_wrap(pred1 - e1[ahead])) <= 0.35 * gap + 1e-7) \
            & (np.abs(_wrap(pred2 - e2[ahead])) <= 0.35 * gap + 1e-7)
        found[ahead] = second & near
    return found, r, e1, e2


def fold_is_branch_point(fam, rows, t1, t2, s):
    """Whether each located end is a branch point rather than a fold: the critical mode
    orthogonal to dG/ds (operation_range's _kind_at)."""
    c = fam.at(rows, s)
    dA1, dA2, dC1, dC2, dK = c[5:10]
    g1, g2, h11, h12, h22, _, (s1, c1, s2, c2, s12, c12) = gradient_hessian(c, t1, t2)
    gs1 = dA1 * s1 - dK * s12 - dC1 * c1
    gs2 = dA2 * s2 - dK * s12 - dC2 * c2
    lo, hi = eigenvalues_2x2(h11, h12, h22)
    lam = np.where(np.abs(lo) <= np.abs(hi), lo, hi)
    v1, v2 = _mode(h11, h12, h22, lam)
    norm = np.hypot(gs1, gs2)
    return (norm == 0) | (np.abs(v1 * gs1 + v2 * gs2) <= 1e-7 * norm)


def symmetric_rows(p0, dp, g):
    """Rows with an exact symmetry along their whole path (their ends are branch points:
    the scalar path solves them)."""
    def raw(p):
        return (p[:, _I['L1']], p[:, _I['L2']], p[:, _I['ka']], p[:, _I['kb']],
                p[:, _I['f3x']], p[:, _I['f4x']],
                p[:, _I['f3y']] - 0.5 * g * p[:, _I['m1']],
                p[:, _I['f4y']] - 0.5 * g * p[:, _I['m2']])

    out = np.zeros(len(p0), bool)
    swap = np.ones(len(p0), bool)
    swap_mirror = np.ones(len(p0), bool)
    mirror = np.ones(len(p0), bool)
    for p in (p0, p0 + dp):
        L1, L2, ka, kb, f3x, f4x, F3, F4 = raw(p)
        base = (L1 == L2) & (ka == kb) & (f3x == -f4x)
        swap &= base & (F3 == F4)
        swap_mirror &= base & (F3 == -F4)
        mirror &= (F3 == 0.0) & (F4 == 0.0)
    out |= swap | swap_mirror | mirror
    return out


def stable_equilibria(rows, g):
    """(theta (m, 6, 2), stable (m, 6), eigenvalues) of every row (equilibria_batch)."""
    values = {name: rows[:, i] for i, name in enumerate(PARAMETER_NAMES)}
    batch = equilibria_batch(g=g, **values)
    return batch.theta, batch.stable, batch.eigenvalues


def upper_start(rows, g):
    """The upper stable equilibrium of each row (start_state's default: the stable one
    with the largest y3 + y4) and the number of stable equilibria: (t1, t2, count)."""
    theta, stable, _ = stable_equilibria(rows, g)
    L1, L2 = rows[:, _I['L1']], rows[:, _I['L2']]
    height = L1[:, None] * np.sin(theta[..., 0]) + L2[:, None] * np.sin(theta[..., 1])
    height = np.where(stable, height, -np.inf)
    best = np.argmax(height, axis=1)
    pick = np.arange(len(rows))
    return theta[pick, best, 0], theta[pick, best, 1], stable.sum(axis=1)


def settle_start(rows, g, guess):
    """The stable equilibrium each row's mechanism settles into from ``guess``:
    (t1, t2, decided, number of stable equilibria).  Decided where the row has one
    stable equilibrium (every flow ends there), or where the gradient flow from the guess
    (:func:`_flow_to_ball`, Runge-Kutta) enters a ball about one of the two minima on
    which the energy is strongly convex (:func:`_convex_radius`: a flow that enters it
    ends at its minimum), the same with half the step (a guess near the boundary of two
    basins, where the discretisation could decide, lands differently and is not
    decided); the others go to the scalar settle."""
    theta, stable, _ = stable_equilibria(rows, g)
    count = stable.sum(axis=1)
    m = len(rows)
    t1, t2 = np.full(m, np.nan), np.full(m, np.nan)
    decided = np.zeros(m, bool)
    one = count == 1
    if np.any(one):
        slot = np.argmax(stable[one], axis=1)
        t1[one], t2[one] = theta[one, slot, 0], theta[one, slot, 1]
        decided[one] = True
    two = np.nonzero(count == 2)[0]
    if two.size:
        family = PathFamily(rows[two], np.zeros_like(rows[two]), g)
        c = family.at(np.arange(two.size), np.zeros(two.size))
        mins = theta[two][stable[two].nonzero()].reshape(two.size, 2, 2)
        radius = _convex_radius(c, mins)
        clear = np.ones(two.size, bool)
        landed = []
        for step in (2.0, 1.0):         # a landing that holds with half the step
            which = _flow_to_ball(c, np.full(two.size, float(guess[0])),
                                  np.full(two.size, float(guess[1])), mins, radius, step)
            clear &= which >= 0
            landed.append(which)
        clear &= landed[0] == landed[1]
        k = two[clear]
        pick = np.nonzero(clear)[0]
        t1[k], t2[k] = mins[pick, landed[0][clear], 0], mins[pick, landed[0][clear], 1]
        decided[k] = True
    return t1, t2, decided, count


def _convex_radius(c, mins):
    """Per row and minimum (m, 2): a radius within which H stays positive definite
    (lambda_min(H) >= 0.1 lambda_min(H(minimum)), by Weyl's inequality and a bound on
    the third derivatives).  There (theta - m) . G(theta) >= mu |theta - m|^2, so the
    distance to the minimum only shrinks along the flow: a flow entering the ball ends
    at its minimum."""
    third = math.sqrt(2.0) * (np.maximum(np.abs(c[0]) + np.abs(c[2]),
                                         np.abs(c[1]) + np.abs(c[3])) + 3.0 * c[4])
    out = np.zeros(mins.shape[:2])
    for j in range(2):
        _, _, h11, h12, h22, _, _ = gradient_hessian(c, mins[:, j, 0], mins[:, j, 1])
        out[:, j] = 0.9 * np.maximum(eigenvalues_2x2(h11, h12, h22)[0], 0.0) / third
    return out


def _flow_to_ball(c, t1, t2, mins, radius, step, max_steps=3000):
    """The overdamped flow d(theta)/dt = -G from (t1, t2) per row, classical Runge-Kutta
    steps of ``step`` / (a bound on lambda_max) (stable up to 2.78), until it enters the
    ball ``radius`` about one of the two minima ``mins`` (m, 2, 2): that minimum's
    index per row, -1 where it did not within ``max_steps``."""
    h = step / _hessian_scale(c)
    t1, t2 = t1.copy(), t2.copy()
    which = np.full(len(t1), -1)
    active = np.arange(len(t1))
    for it in range(max_steps + 1):
        for j in range(2):
            d = np.hypot(_wrap(t1[active] - mins[active, j, 0]),
                         _wrap(t2[active] - mins[active, j, 1]))
            inside = d < radius[active, j]
            which[active[inside]] = j
            active = active[~inside]
        if active.size == 0 or it == max_steps:
            break
        ca = _take(c, active)
        ha = h[active]
        a1, a2 = t1[active], t2[active]
        k1 = gradient_hessian(ca, a1, a2)
        k2 = gradient_hessian(ca, a1 - 0.5 * ha * k1[0], a2 - 0.5 * ha * k1[1])
        k3 = gradient_hessian(ca, a1 - 0.5 * ha * k2[0], a2 - 0.5 * ha * k2[1])
        k4 = gradient_hessian(ca, a1 - ha * k3[0], a2 - ha * k3[1])
        t1[active] = a1 - ha / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        t2[active] = a2 - ha / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return which
