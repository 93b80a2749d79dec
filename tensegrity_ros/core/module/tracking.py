"""Tracking the stable equilibrium of one module along a parameter path.

``track_module`` moves all parameters of a module together along the straight
path p(s) = start + s (end - start), s in [0, 1], following the stable
equilibrium it starts on with the generic tracker of :mod:`.continuation`, and
reports every jump (fold or branch point) with where it lands.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np

from .classification import _build, _eigenvalues_2x2, Equilibrium
from .model import mirror_symmetric, ModuleParams
from .. import continuation as _continuation
from ..continuation import TrackerSettings
from ..numerics.tolerances import DEGENERACY_TOL, MARGIN_CERTIFIED, verified_minimum


@dataclass(frozen=True)
class ModuleJump:
    """One jump: the branch ended (fold) or lost stability (branch point) at ``params``.

    ``params.rho`` is the critical actuator length; ``from_theta`` the critical
    configuration, ``to_theta`` the stable equilibrium the mechanism lands on.
    ``ambiguous`` is set when the two sides of a branch point land differently.
    ``to_theta`` is an equilibrium of ``params`` except where the landing minimum does
    not exist there (it appears only past the jump): then ``landing_params`` (otherwise
    ``params``) holds the parameters it is an equilibrium of, and ``landed_past`` is true.
    """

    kind: str
    s: float
    params: ModuleParams
    from_theta: np.ndarray
    to_theta: np.ndarray
    ambiguous: bool = False
    landing_params: ModuleParams | None = None

    @property
    def landed_past(self):
        return self.landing_params is not None and self.landing_params != self.params


@dataclass(frozen=True)
class ModuleUndecided:
    """A branch point passed continuously whose side doubles cannot decide (see
    :class:`.continuation.Undecided`): ``params`` there, ``theta`` the critical
    configuration; an imperfection whose branch structure spans less than
    ``s_uncertainty`` of the command (``rho_uncertainty`` m of the actuator) would decide
    which side the module buckles to, and the tracker took one by its rule."""

    s: float
    params: ModuleParams
    theta: np.ndarray
    s_uncertainty: float
    rho_uncertainty: float


@dataclass(frozen=True)
class ModuleTrack:
    """Result of :func:`track_module`.

    ``status`` is ``'ok'`` (``end`` is the commanded end point) or ``'failed'``
    (``end`` is where tracking stopped; ``final`` is still a verified stable
    equilibrium there).  ``final`` is never an unverified state.  ``passages``:
    the parameters of each supercritical branch point passed continuously (the
    module buckled smoothly onto a new minimum: not a jump); ``undecided``: those of
    them whose side doubles cannot decide (:class:`ModuleUndecided`).  ``certificate``: as
    :attr:`.continuation.Track.certificate` (non-empty where ``final`` is so close past
    such a branch point that it is shown a minimum by the normal form; its
    classification, whose tolerance is coarser, may then read 'degenerate').
    """

    final: Equilibrium
    end: ModuleParams
    jumps: tuple
    status: str = 'ok'
    message: str = ''
    steps: int = 0
    passages: tuple = ()
    certificate: str = ''
    undecided: tuple = ()


class ModulePath:
    """One module along p(s) = start + s (end - start), as a :class:`PathProblem`.

    The state is the unwrapped angle pair.  Everything is scalar arithmetic on
    the parameter vector: no :class:`ModuleParams` is built per evaluation.
    """

    size = 2

    def __init__(self, start: ModuleParams, end: ModuleParams):
        if start.g != end.g:
            raise ValueError('start and end must use the same gravity')
        self.start, self.end = start, end
        self.p0 = start.vector()
        self.dp = end.vector() - self.p0
        self.dp_list = self.dp.tolist()
        self.g = start.g
        self._values = {}

    def values(self, s):
        """(rho, L1, L2, ka, kb, kc, f3x, f3y_total, f4x, f4y_total) at s (kept for a few
        s: a step visits s, s + ds and its probe's s + 1e-6 in turn)."""
        found = self._values.get(s)
        if found is None:
            if len(self._values) > 4:
                self._values.clear()
            rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y, m1, m2 = (self.p0 + s * self.dp).tolist()
            found = self._values[s] = (rho, L1, L2, ka, kb, kc, f3x, f3y - 0.5 * m1 * self.g,
                                       f4x, f4y - 0.5 * m2 * self.g)
        return found

    def params(self, s):
        return ModuleParams.from_vector(self.p0 + s * self.dp, g=self.g)

    def admissible(self, s):
        try:
            self.params(s)
        except ValueError:
            return False
        return True

    def residual(self, y, s):
        return np.array(_gradient(self.values(s), y[0], y[1]))

    def jacobian(self, y, s):
        h11, h12, h22 = self._hessian(y, s)
        return np.array([[h11, h12], [h12, h22]])

    def _hessian(self, y, s):
        """(h11, h12, h22) as floats (the eigenvalues need no array)."""
        rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = self.values(s)
        t1, t2 = y[0], y[1]
        s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
        c12 = c1 * c2 - s1 * s2
        return (L1 * ((ka + kc) * rho * c1 - kc * L2 * c12 + f3x * c1 + f3y * s1),
                -kc * L1 * L2 * c12,
                L2 * ((kb + kc) * rho * c2 - kc * L1 * c12 - f4x * c2 + f4y * s2))

    def residual_s(self, y, s):
        """dF/ds = dF/dp . (end - start) at fixed angles."""
        return np.array(self._residual_s(y, s))

    def tangent(self, y, s):
        """The branch's tangent dy/ds = -F_y^-1 F_s, in Python floats (the same arithmetic
        as the tracker's 2 x 2 solve, without building the arrays: a step's end needs one
        for the trapezoid rule)."""
        h11, h12, h22 = self._hessian(y, s)
        r0, r1 = self._residual_s(y, s)
        det = h11 * h22 - h12 * h12
        if det == 0.0 or not math.isfinite(det):
            raise np.linalg.LinAlgError('singular 2x2 matrix')
        return np.array([-((h22 * r0 - h12 * r1) / det), -((h11 * r1 - h12 * r0) / det)])

    def _residual_s(self, y, s):
        """(dF1/ds, dF2/ds) as floats."""
        rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = self.values(s)
        d_rho, d_L1, d_L2, d_ka, d_kb, d_kc, d_f3x, d_f3y, d_f4x, d_f4y, d_m1, d_m2 = self.dp_list
        t1, t2 = y[0], y[1]
        s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
        s12 = s1 * c2 + c1 * s2
        half = 0.5 * self.g
        inner1 = (ka + kc) * rho * s1 - kc * L2 * s12 + f3x * s1 - f3y * c1
        inner2 = (kb + kc) * rho * s2 - kc * L1 * s12 - f4x * s2 - f4y * c2
        r1 = (d_L1 * inner1 + L1 * ((ka + kc) * s1 * d_rho - kc * s12 * d_L2 + rho * s1 * d_ka
                                    + (rho * s1 - L2 * s12) * d_kc + s1 * d_f3x
                                    - c1 * (d_f3y - half * d_m1)))
        r2 = (d_L2 * inner2 + L2 * ((kb + kc) * s2 * d_rho - kc * s12 * d_L1 + rho * s2 * d_kb
                                    + (rho * s2 - L1 * s12) * d_kc - s2 * d_f4x
                                    - c2 * (d_f4y - half * d_m2)))
        return r1, r2

    def energy(self, y, s):
        rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = self.values(s)
        c1, s1, c2, s2 = math.cos(y[0]), math.sin(y[0]), math.cos(y[1]), math.sin(y[1])
        x3, y3 = L1 * c1, L1 * s1
        x4, y4 = rho - L2 * c2, L2 * s2
        springs = 0.5 * (ka * ((x3 - rho) ** 2 + y3 ** 2) + kb * (x4 ** 2 + y4 ** 2)
                         + kc * ((x4 - x3) ** 2 + (y4 - y3) ** 2))
        return springs - (f3x * x3 + f3y * y3 + f4x * x4 + f4y * y4)

    def energy_s(self, y, s):
        """dU/ds at fixed angles (the envelope theorem's side of the energy check)."""
        rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = self.values(s)
        d_rho, d_L1, d_L2, d_ka, d_kb, d_kc, d_f3x, d_f3y, d_f4x, d_f4y, d_m1, d_m2 = self.dp_list
        c1, s1, c2, s2 = math.cos(y[0]), math.sin(y[0]), math.cos(y[1]), math.sin(y[1])
        x3, y3 = L1 * c1, L1 * s1
        x4, y4 = rho - L2 * c2, L2 * s2
        dx, dy = x4 - x3, y4 - y3
        half = 0.5 * self.g
        force = ka * (rho - x3) + kb * (rho - L2 * c2) + kc * (rho - x3 - L2 * c2) - f4x
        return (force * d_rho
                + (ka * (L1 - rho * c1) - kc * (dx * c1 + dy * s1) - f3x * c1 - f3y * s1) * d_L1
                + (kb * (L2 - rho * c2) + kc * (-dx * c2 + dy * s2) + f4x * c2 - f4y * s2) * d_L2
                + 0.5 * ((x3 - rho) ** 2 + y3 ** 2) * d_ka + 0.5 * (x4 ** 2 + y4 ** 2) * d_kb
                + 0.5 * (dx ** 2 + dy ** 2) * d_kc
                - x3 * d_f3x - y3 * d_f3y - x4 * d_f4x - y4 * d_f4y
                + half * (y3 * d_m1 + y4 * d_m2))

    def eigenvalues(self, y, s):
        """Ascending Hessian eigenvalues (the cheap half of :meth:`stability`)."""
        return np.array(_eigenvalues_2x2(*self._hessian(y, s)))

    def stability(self, y, s):
        a, b, c = self._hessian(y, s)
        low, high = _eigenvalues_2x2(a, b, c)
        return np.array([low, high]), np.column_stack([_eigenvector(a, b, c, low),
                                                       _eigenvector(a, b, c, high)])

    def descent(self, y, s):
        return -self.residual(y, s)

    def project(self, y, s):
        return y

    @staticmethod
    def canonical(y):
        return (np.asarray(y) + math.pi) % (2.0 * math.pi) - math.pi

    def mirror(self, y, s):
        """The mirror image (t2, t1) of ``y``, or None where the module is not
        mirror-symmetric at s."""
        return np.asarray(y)[::-1].copy() if mirror_symmetric(self.p0 + s * self.dp) else None


def _gradient(values, t1, t2):
    """dU/dtheta as two floats, from :meth:`ModulePath.values`' tuple (module.gradient
    for one state, without numpy: the tracker and its records call it per command)."""
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = values
    s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
    s12 = s1 * c2 + c1 * s2
    return (L1 * ((ka + kc) * rho * s1 - kc * L2 * s12 + f3x * s1 - f3y * c1),
            L2 * ((kb + kc) * rho * s2 - kc * L1 * s12 - f4x * s2 - f4y * c2))


def _eigenvector(a, b, c, lam):
    """Unit eigenvector of [[a, b], [b, c]] for eigenvalue lam (the better-conditioned row)."""
    u = np.array([b, lam - a])
    v = np.array([lam - c, b])
    w = u if abs(u[0]) + abs(u[1]) >= abs(v[0]) + abs(v[1]) else v
    norm = math.hypot(w[0], w[1])
    if norm == 0.0:
        return np.array([1.0, 0.0]) if abs(a - lam) <= abs(c - lam) else np.array([0.0, 1.0])
    return w / norm


def _wrap(theta):
    return (np.asarray(theta, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi


def _verified_yet_degenerate(eigenvalues):
    """Whether a state the tracker verified by its margin test (lambda_min above
    DEFINITENESS_TOL of lambda_max) classifies as degenerate (below DEGENERACY_TOL):
    then it carries :data:`~.numerics.tolerances.MARGIN_CERTIFIED` (see tolerances.py)."""
    low, high = eigenvalues[0], eigenvalues[-1]
    # (the rare degenerate reading first: every command asks)
    return low <= DEGENERACY_TOL * max(abs(low), abs(high)) and verified_minimum(eigenvalues)


def equilibrium_at(params: ModuleParams, theta) -> Equilibrium:
    """The :class:`Equilibrium` record (eigenvalues, energy, force, residual) at ``theta``."""
    t1, t2 = _wrap(theta).tolist()
    grad = _gradient((params.rho, params.L1, params.L2, params.ka, params.kb, params.kc,
                      params.f3x, params.f3y_total, params.f4x, params.f4y_total), t1, t2)
    scale = max(abs((params.ka + params.kc) * params.rho + params.f3x), abs(params.f3y_total),
                abs((params.kb + params.kc) * params.rho - params.f4x), abs(params.f4y_total),
                params.kc * params.L1, params.kc * params.L2)
    residual = max(abs(grad[0]) / params.L1, abs(grad[1]) / params.L2) / scale
    return _build(params, [(t1, t2, residual)])[0]


def settle(params: ModuleParams, theta_guess) -> Equilibrium:
    """The stable equilibrium whose basin of attraction holds ``theta_guess``.

    The overdamped mechanism released at the guess slides to it.  Raises
    :class:`~tensegrity_ros.core.continuation.TrackingError` if none is reached.
    """
    theta_guess = _checked_theta(theta_guess)
    path = ModulePath(params, params)
    return equilibrium_at(params, _continuation.settle(path, theta_guess))


def _checked_theta(theta):
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (2,):
        raise ValueError(f'theta must have shape (2,), got {theta.shape}')
    if not np.all(np.isfinite(theta)):
        raise ValueError(f'theta must be finite, got {theta.tolist()}')
    return theta


def track_module(start: ModuleParams, end: ModuleParams, theta,
                 settings: TrackerSettings = TrackerSettings(), certificate='') -> ModuleTrack:
    """Follow the stable equilibrium at ``theta`` from ``start`` to ``end``.

    If ``theta`` is not a stable equilibrium at ``start`` the mechanism first
    settles (see :func:`settle`).  Every jump on the way is in ``jumps``.
    ``settings.time_budget`` bounds the whole call, settling included.
    ``certificate``: the previous command's :attr:`ModuleTrack.certificate` where
    ``theta`` is its final state (also on its ``final``).
    """
    theta = _checked_theta(theta)
    path = ModulePath(start, end)
    result = _continuation.track_settled(path, theta, settings, certificate)
    jumps = tuple(ModuleJump(kind=e.kind, s=e.s, params=path.params(e.s),
                             from_theta=_wrap(e.state), to_theta=_wrap(e.landing),
                             ambiguous=e.ambiguous, landing_params=path.params(e.landing_s))
                  for e in result.events)
    reached = end if result.s == 1.0 else path.params(result.s)
    final = equilibrium_at(reached, result.state)
    if result.certificate:              # (rare: a replace costs ~2 us per command)
        final = replace(final, certificate=result.certificate)
    elif _verified_yet_degenerate(final.eigenvalues):
        final = replace(final, certificate=MARGIN_CERTIFIED)
    return ModuleTrack(final=final, end=reached, jumps=jumps,
                       status=result.status, message=result.message, steps=result.steps,
                       passages=tuple(path.params(s) for s, _ in result.passages),
                       certificate=result.certificate,
                       undecided=tuple(ModuleUndecided(
                           u.s, path.params(u.s), _wrap(u.state), u.s_uncertainty,
                           u.s_uncertainty * abs(end.rho - start.rho)) for u in result.undecided))
