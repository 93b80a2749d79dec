"""Morse type of a module's equilibria and the records the solvers return.

An equilibrium is classified by the inertia of its Hessian (eigenvalues scaled by the
largest one), never by the sign of det H alone.  :class:`Equilibrium` is one solution
with eigenvalues, energy and actuator force; :class:`EquilibriumSet` every solution of
one parameter point.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .model import ModuleParams
from ..numerics.tolerances import DEGENERACY_TOL  # (re-exported: equilibria, batch_solver)
from ..numerics.tolerances import verified_minimum

KIND_MINIMUM = 'minimum'
KIND_SADDLE = 'saddle'
KIND_MAXIMUM = 'maximum'
KIND_DEGENERATE = 'degenerate'


@dataclass(frozen=True)
class Equilibrium:
    """One equilibrium of a module: angles (rad), Hessian eigenvalues (ascending).

    ``certificate``: a tracked state's :attr:`.continuation.Track.certificate` (non-empty
    where it ends so close past a passed branch point that it is shown a minimum by the
    normal form; its classification then reads 'degenerate', yet it is ``stable``), or
    :data:`~.numerics.tolerances.MARGIN_CERTIFIED` where the tracker's margin test verified a
    state that classifies as degenerate (also ``stable``)."""

    theta1: float
    theta2: float
    eigenvalues: tuple
    energy: float
    actuator_force: float
    residual: float
    certificate: str = ''

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
        return self.kind == KIND_MINIMUM or (
            bool(self.certificate) and verified_minimum(self.eigenvalues, self.certificate))


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


def hessian_eigenvalues(h11, h12, h22):
    """Ascending eigenvalues of symmetric 2x2 matrices, accurate for the small one."""
    mean = 0.5 * (h11 + h22)
    half_gap = np.hypot(0.5 * (h11 - h22), h12)
    big = mean + np.copysign(half_gap, mean)
    det = h11 * h22 - h12 * h12
    safe = np.where(big == 0.0, 1.0, big)
    small = np.where(big == 0.0, 0.0, det / safe)
    return np.minimum(big, small), np.maximum(big, small)


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
