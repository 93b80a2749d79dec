"""Point C of the paper's fig. 6: the tip of the 2-stable region of (rho, F3, F4) space.

There the second stable equilibrium is born out of a totally degenerate one
(``H = 0``, an umbilic); :func:`two_stable_limit` solves for it directly.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.optimize import root

from .bifurcation_model import _CSTEP, _gh, _newton, _raw, _scale, _wrap
from ..module.model import ModuleParams

# ---------------------------------------------------------------------------
# Point C of fig. 6: the tip of the 2-stable region


@dataclass(frozen=True)
class TwoStableLimit:
    """Point C of the paper's fig. 6 for one design.

    ``F3``, ``F4`` (N): the forces of C; ``rho`` and ``theta``: the actuator
    length and the configuration there, an equilibrium whose Hessian vanishes
    entirely (``H = 0``: an umbilic).  ``axis``: unit direction in (rho, F3, F4)
    along which the 2-stable region approaches C (its horn is tangent to it, of
    width O(distance^2)); ``params``: the module at C.
    """

    F3: float
    F4: float
    rho: float
    theta: tuple
    axis: np.ndarray
    params: ModuleParams

    @property
    def forces(self):
        return (self.F3, self.F4)


def _umbilic_guess(L1, L2, ka, kb, kc, sign):
    A, B = ka + kc, kb + kc
    rho = kc * L1 * L2 / math.sqrt(A * A * L1 * L1 + B * B * L2 * L2)
    F3 = math.sqrt(max(kc * kc * L2 * L2 - A * A * rho * rho, 0.0))
    F4 = math.sqrt(max(kc * kc * L1 * L1 - B * B * rho * rho, 0.0))
    t1, t2 = math.atan2(-A * rho, F3), math.atan2(-B * rho, F4)
    return np.array([sign * t1, sign * t2, rho, sign * F3, sign * F4])


def two_stable_limit(L2=1.0, *, L1=1.0, k=100.0, ka=None, kb=None, kc=None,
                     f3x=0.0, f4x=0.0, pushing=False) -> TwoStableLimit:
    """Point C of fig. 6: the largest vertical forces (F3, F4) for which two stable
    equilibria exist for some rho.

    Definition.  The 2-stable region of (rho, F3, F4) space ends, as the forces
    grow, in a thin horn whose tip C is an equilibrium with a totally degenerate
    Hessian, ``G = 0, H = 0`` (5 equations in theta1, theta2, rho, F3, F4: an
    isolated, regular solution).  No point with both F3 > C_F3 and F4 > C_F4 has
    two stable equilibria, and C is a limit of 2-stable points (along ``axis``):
    C is the corner of the 2-stable region's projection on the (F3, F4) plane.
    For L1 = L2 it is on the diagonal and is also the largest F = F3 = F4 with a
    2-stable rho (where the pitchfork curve (15) touches the fold curve (16)).

    Closed form for equal springs and no horizontal forces (derived from H12 = 0,
    H11 = H22 = 0, G = 0):  rho_C = L1 L2 / (2 sqrt(L1^2 + L2^2)),
    C = k (L2^2, L1^2) / sqrt(L1^2 + L2^2); with L1 = L2 = 1, k = 100:
    rho_C = 0.35355..., C = (70.7106..., 70.7106...).  The general case
    (ka, kb, kc, horizontal forces) is solved by Newton from the closed form.

    ``pushing``: the mirror image (negative forces, theta -> -theta).
    """
    ka = k if ka is None else ka
    kb = k if kb is None else kb
    kc = k if kc is None else kc
    sign = -1.0 if pushing else 1.0
    base = ModuleParams(rho=1.0, L1=L1, L2=L2, ka=ka, kb=kb, kc=kc, f3x=f3x, f4x=f4x)
    z = _umbilic(_raw(base), _umbilic_guess(L1, L2, ka, kb, kc, sign))
    t1, t2, rho, F3, F4 = (float(v) for v in z)
    params = ModuleParams(rho=rho, L1=L1, L2=L2, ka=ka, kb=kb, kc=kc, f3x=f3x, f4x=f4x,
                          f3y=F3, f4y=F4)
    return TwoStableLimit(F3=F3, F4=F4, rho=rho, theta=(float(_wrap(t1)), float(_wrap(t2))),
                          axis=_horn_axis(t1, t2, L1, L2, ka, kb, kc), params=params)


def _umbilic(P0, z0):
    """(theta1, theta2, rho, F3, F4) with G = 0 and H = 0 for the raw parameters ``P0``
    (their rho, f3y, f4y replaced), by Newton from ``z0`` (complex-step Jacobian), else
    Levenberg-Marquardt; RuntimeError if neither finds it."""
    s = _scale(P0)

    def residual(z):
        z = np.asarray(z)
        P = np.broadcast_to(P0, z.shape[:-1] + (10,)).astype(z.dtype).copy()
        P[..., 0], P[..., 7], P[..., 9] = z[..., 2], z[..., 3], z[..., 4]
        return np.stack(_gh(P, z[..., 0], z[..., 1]), -1) / s

    def fj(z):
        Z = z[None, :] + (1j * _CSTEP) * np.eye(5)
        R = residual(Z)
        return R[0].real, (R.imag / _CSTEP).T

    z, ok = _newton(fj, z0, tol=1e-15, max_iter=40)
    if not ok:
        sol = root(lambda v: fj(v)[0], z0, jac=lambda v: fj(v)[1], method='lm',
                   options={'xtol': 1e-15})
        z, ok = sol.x, bool(np.max(np.abs(fj(sol.x)[0])) < 1e-10)
    if not ok or z[2] <= 0:
        raise RuntimeError('no totally degenerate equilibrium found for these parameters')
    return z


def _horn_axis(t1, t2, L1, L2, ka, kb, kc):
    """The horn axis at C: the unit kernel of dG/d(rho, F3, F4), on the side where dH is
    positive definite (the degenerate point opens into a minimum)."""
    c1, s1, c2, s2 = math.cos(t1), math.sin(t1), math.cos(t2), math.sin(t2)
    A, B = ka + kc, kb + kc
    row1 = np.array([L1 * A * s1, -L1 * c1, 0.0])
    row2 = np.array([L2 * B * s2, 0.0, -L2 * c2])
    axis = np.cross(row1, row2)
    axis /= np.linalg.norm(axis)
    dh11 = L1 * (A * c1 * axis[0] + s1 * axis[1])
    dh22 = L2 * (B * c2 * axis[0] + s2 * axis[2])
    if dh11 + dh22 < 0:
        axis = -axis
    return axis
