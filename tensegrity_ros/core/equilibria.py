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
g1 gives t1 + t2 = asin(r / (kc L2)) or pi - asin(...): both candidates are
checked against g2, which also covers the singular case D = 0 (unloaded flat
configurations, where both are solutions).  Candidates are then polished with
Newton on the trigonometric equations, verified and de-duplicated on the torus.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .module import ModuleParams, InvalidParameterError, PARAMETER_NAMES, STANDARD_GRAVITY
from . import module as _module

#: A root z of the polynomial is a real angle candidate if | ln|z| | is below this.
UNIT_CIRCLE_TOL = 1e-3
#: A t2 candidate is kept for polishing if |g2| is below this (relative to the scale).
CANDIDATE_TOL = 1e-2
#: A polished solution is an equilibrium if max |g| is below this (relative).
RESIDUAL_TOL = 1e-10
#: Two solutions closer than this on the torus (rad, max norm) are one.
DUPLICATE_TOL = 1e-7
#: An eigenvalue with |lambda| <= DEGENERACY_TOL * max|lambda| counts as zero.
DEGENERACY_TOL = 1e-8
#: The polynomial vanishes identically (a continuum of equilibria) below this.
CONTINUUM_TOL = 1e-13
NEWTON_MAX_ITER = 12

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
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


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
    """Roots of one polynomial, near-zero leading/trailing coefficients stripped."""
    peak = max(abs(c) for c in coefficients)
    keep = [i for i, c in enumerate(coefficients) if abs(c) > 1e-14 * peak]
    coefficients = coefficients[keep[0]:keep[-1] + 1]
    degree = len(coefficients) - 1
    if degree < 1:
        return []
    companion = np.zeros((degree, degree), dtype=complex)
    companion[0, :] = [-c / coefficients[0] for c in coefficients[1:]]
    companion[np.arange(1, degree), np.arange(degree - 1)] = 1.0
    return np.linalg.eigvals(companion).tolist()


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
    """Newton on (g1, g2) from one candidate; returns (t1, t2, max |g|)."""
    for _ in range(NEWTON_MAX_ITER + 1):
        s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
        s12 = s1 * c2 + c1 * s2
        c12 = c1 * c2 - s1 * s2
        g1 = a1 * s1 - b1 * c1 - kcL2 * s12
        g2 = a2 * s2 - b2 * c2 - kcL1 * s12
        residual = max(abs(g1), abs(g2))
        if residual <= tol:
            break
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
    a1, b1, a2, b2, kcL1, kcL2 = consts
    scale = max(abs(c) for c in consts)
    coefficients = _polynomial_scalar(*consts)
    if max(abs(c) for c in coefficients) <= CONTINUUM_TOL * scale ** 4:
        return EquilibriumSet(params, (), 'continuum')

    found = []
    for z in _polynomial_roots(coefficients):
        modulus = abs(z)
        if modulus == 0.0 or abs(math.log(modulus)) >= UNIT_CIRCLE_TOL:
            continue
        t1 = math.atan2(z.imag, z.real)
        s1, c1 = math.sin(t1), math.cos(t1)
        phi = math.asin(min(1.0, max(-1.0, (a1 * s1 - b1 * c1) / kcL2)))
        for t2 in (phi - t1, math.pi - phi - t1):
            g2 = a2 * math.sin(t2) - b2 * math.cos(t2) - kcL1 * math.sin(t1 + t2)
            if abs(g2) > CANDIDATE_TOL * scale:
                continue
            u1, u2, residual = _polish(t1, t2, *consts, tol=4e-16 * scale)
            if residual <= RESIDUAL_TOL * scale:
                found.append((_wrap_scalar(u1), _wrap_scalar(u2), residual / scale))
    return EquilibriumSet(params, _build(params, _unique(found)))


def _wrap_scalar(angle):
    """Angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _unique(found):
    """Distinct solutions on the torus, the best-polished of each cluster, sorted."""
    two_pi = 2.0 * math.pi
    kept = []
    for candidate in sorted(found, key=lambda c: c[2]):
        t1, t2 = candidate[0], candidate[1]
        for k in kept:
            d1, d2 = abs(t1 - k[0]), abs(t2 - k[1])
            if min(d1, two_pi - d1) <= DUPLICATE_TOL and min(d2, two_pi - d2) <= DUPLICATE_TOL:
                break
        else:
            kept.append(candidate)
    kept.sort()
    return kept


def _build(p, found):
    a1, b1, a2, b2 = ((p.ka + p.kc) * p.rho + p.f3x, p.f3y_total,
                      (p.kb + p.kc) * p.rho - p.f4x, p.f4y_total)
    L1, L2, kc = p.L1, p.L2, p.kc
    out = []
    for t1, t2, residual in found:
        s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
        c12 = c1 * c2 - s1 * s2
        h11 = L1 * (a1 * c1 + b1 * s1 - kc * L2 * c12)
        h22 = L2 * (a2 * c2 + b2 * s2 - kc * L1 * c12)
        h12 = -kc * L1 * L2 * c12
        low, high = _eigenvalues_2x2(h11, h12, h22)
        out.append(Equilibrium(
            theta1=t1, theta2=t2, eigenvalues=(low, high),
            energy=_energy_scalar(p, c1, s1, c2, s2),
            actuator_force=(p.ka * (p.rho - L1 * c1) + p.kb * (p.rho - L2 * c2)
                            + kc * (p.rho - L1 * c1 - L2 * c2) - p.f4x),
            residual=residual))
    return tuple(out)


def _eigenvalues_2x2(h11, h12, h22):
    mean = 0.5 * (h11 + h22)
    big = mean + math.copysign(math.hypot(0.5 * (h11 - h22), h12), mean)
    small = 0.0 if big == 0.0 else (h11 * h22 - h12 * h12) / big
    return (small, big) if small <= big else (big, small)


def _energy_scalar(p, c1, s1, c2, s2):
    x3, y3 = p.L1 * c1, p.L1 * s1
    x4, y4 = p.rho - p.L2 * c2, p.L2 * s2
    springs = 0.5 * (p.ka * ((x3 - p.rho) ** 2 + y3 ** 2) + p.kb * (x4 ** 2 + y4 ** 2)
                     + p.kc * ((x4 - x3) ** 2 + (y4 - y3) ** 2))
    return springs - (p.f3x * x3 + p.f3y_total * y3 + p.f4x * x4 + p.f4y_total * y4)


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
    f3y_total = v['f3y'] - 0.5 * v['m1'] * g
    f4y_total = v['f4y'] - 0.5 * v['m2'] * g
    consts = _reduced_coefficients(v['rho'], v['L1'], v['L2'], v['ka'], v['kb'], v['kc'],
                                   v['f3x'], f3y_total, v['f4x'], f4y_total)
    n = consts[0].size
    scale = _scale(*consts)
    laurent = _polynomial(*consts)                                # (n, 7), z^3 .. z^-3
    continuum = np.max(np.abs(laurent), axis=-1) <= CONTINUUM_TOL * scale ** 4
    t1 = _batch_circle_roots(laurent, continuum)                  # (n, 6), nan if off circle

    cols = [c[:, None] for c in consts]
    t1, t2, g2 = _batch_candidates(t1, *cols)                     # (n, 12)
    rows, slots = np.nonzero(np.abs(g2) <= CANDIDATE_TOL * scale[:, None])   # nan -> False
    c = [x[rows] for x in consts]
    s1, s2 = _newton(t1[rows, slots], t2[rows, slots], *c)
    g1, g2 = _residual(s1, s2, *c)
    residual = np.maximum(np.abs(g1), np.abs(g2)) / scale[rows]
    keep = residual <= RESIDUAL_TOL
    rows, slots = rows[keep], slots[keep]

    theta = np.full((n, 12, 2), np.nan)
    res = np.full((n, 12), np.inf)
    theta[rows, slots, 0] = _wrap(s1[keep])
    theta[rows, slots, 1] = _wrap(s2[keep])
    res[rows, slots] = residual[keep]
    theta, res = _compact(theta, res, np.isfinite(res),
                          max(1, int(np.isfinite(res).sum(axis=1).max(initial=0))))
    valid = _batch_unique(theta, res)
    if theta.shape[1] < 6:
        pad = 6 - theta.shape[1]
        theta = np.concatenate([theta, np.full((n, pad, 2), np.nan)], axis=1)
        res = np.concatenate([res, np.full((n, pad), np.inf)], axis=1)
        valid = np.concatenate([valid, np.zeros((n, pad), dtype=bool)], axis=1)
    theta, res = _compact(theta, res, valid, 6)
    valid = np.isfinite(res)
    valid[continuum] = False
    eigenvalues = _batch_eigenvalues(theta, valid, cols, v['L1'], v['L2'])
    return EquilibriumBatch(theta=theta, eigenvalues=eigenvalues, valid=valid,
                            continuum=continuum)


def _batch_candidates(t1, a1, b1, a2, b2, kcL1, kcL2):
    """Both t2 of g1 = 0 for each t1, and g2 there; no trigonometry beyond t1's.

    With sin(t1 + t2) = r / (kc L2) =: sin(phi), the candidates are t2 = phi - t1
    and t2 = pi - phi - t1, and sin(t1 + t2) is the same for both.
    """
    s1, c1 = np.sin(t1), np.cos(t1)
    sphi = np.clip((a1 * s1 - b1 * c1) / kcL2, -1.0, 1.0)
    cphi = np.sqrt(1.0 - sphi * sphi)
    phi = np.arcsin(sphi)
    s2a, c2a = sphi * c1 - cphi * s1, cphi * c1 + sphi * s1
    s2b, c2b = sphi * c1 + cphi * s1, sphi * s1 - cphi * c1
    g2a = a2 * s2a - b2 * c2a - kcL1 * sphi
    g2b = a2 * s2b - b2 * c2b - kcL1 * sphi
    return (np.concatenate([t1, t1], axis=1),
            np.concatenate([phi - t1, np.pi - phi - t1], axis=1),
            np.concatenate([g2a, g2b], axis=1))


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


def _batch_circle_roots(laurent, continuum):
    """t1 of the unit-circle roots of many polynomials, (n, 6), nan elsewhere."""
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
    return np.where(on_circle, t1, np.nan)


def _batch_arrays(**values):
    arrays = np.broadcast_arrays(*[np.asarray(v, dtype=float) for v in values.values()])
    out = {}
    for (name, _), arr in zip(values.items(), arrays):
        arr = arr.ravel()
        bad = ~np.isfinite(arr)
        if name in ('rho', 'L1', 'L2', 'ka', 'kb', 'kc'):
            bad |= ~(arr > 0)
        elif name in ('m1', 'm2'):
            bad |= ~(arr >= 0)
        if np.any(bad):
            index = int(np.argmax(bad))
            raise InvalidParameterError(
                f'{name} has an invalid value {arr[index]!r} at index {index}')
        out[name] = arr
    return out


def _compact(theta, residual, keep, width):
    """Move kept slots to the front (by residual order) and keep ``width`` of them."""
    order = np.argsort(np.where(keep, residual, np.inf), axis=1, kind='stable')[:, :width]
    theta = np.take_along_axis(theta, order[..., None], axis=1)
    residual = np.take_along_axis(np.where(keep, residual, np.inf), order, axis=1)
    theta[~np.isfinite(residual)] = np.nan
    return theta, residual


def _batch_unique(theta, residual):
    """Mask of the distinct solutions per row; slots are sorted by residual already."""
    finite = np.isfinite(residual)
    keep = finite.copy()
    two_pi = 2.0 * np.pi
    for j in range(1, theta.shape[1]):
        rows = np.nonzero(finite[:, j])[0]
        d1 = np.abs(theta[rows, :j, 0] - theta[rows, j, None, 0])
        d2 = np.abs(theta[rows, :j, 1] - theta[rows, j, None, 1])
        close = ((np.minimum(d1, two_pi - d1) <= DUPLICATE_TOL)
                 & (np.minimum(d2, two_pi - d2) <= DUPLICATE_TOL) & keep[rows, :j])
        keep[rows[close.any(axis=1)], j] = False
    return keep


def _newton(t1, t2, a1, b1, a2, b2, kcL1, kcL2):
    """Newton on (g1, g2) for arrays of candidates, iterating only the unconverged."""
    t1, t2 = t1.copy(), t2.copy()
    active = np.arange(t1.size)
    consts = (a1, b1, a2, b2, kcL1, kcL2)
    for _ in range(NEWTON_MAX_ITER):
        if active.size == 0:
            break
        u1, u2 = t1[active], t2[active]
        a1, b1, a2, b2, kcL1, kcL2 = (np.broadcast_to(c, t1.shape)[active] for c in consts)
        s1, c1, s2, c2 = np.sin(u1), np.cos(u1), np.sin(u2), np.cos(u2)
        s12 = s1 * c2 + c1 * s2
        c12 = c1 * c2 - s1 * s2
        g1 = a1 * s1 - b1 * c1 - kcL2 * s12
        g2 = a2 * s2 - b2 * c2 - kcL1 * s12
        j11 = a1 * c1 + b1 * s1 - kcL2 * c12
        j22 = a2 * c2 + b2 * s2 - kcL1 * c12
        det = j11 * j22 - kcL1 * kcL2 * c12 * c12
        ok = det != 0.0
        det = np.where(ok, det, 1.0)
        d1 = np.where(ok, (j22 * g1 + kcL2 * c12 * g2) / det, 0.0)
        d2 = np.where(ok, (j11 * g2 + kcL1 * c12 * g1) / det, 0.0)
        t1[active] = u1 - d1
        t2[active] = u2 - d2
        active = active[np.abs(d1) + np.abs(d2) > 1e-14]
    return t1, t2


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
