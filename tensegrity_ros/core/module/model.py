"""One tensegrity module (docs/model.md section 1): parameters, energy and its derivatives.

Coordinates are the rod angles ``theta = (t1, t2)``.  Base frame: origin at A1,
x along A1->A2, y up.  All quantities are SI (m, N, N/m, rad).  The paper's
eq. (2) force terms are a typo; the force terms used here are
``-f3 . A3 - f4 . A4`` as its eqs. (3)-(4) confirm.

Rod weights enter as nodal forces ``(0, -m1 g / 2)`` at A3 and ``(0, -m2 g / 2)``
at A4, which is exact for uniform rods pinned at their other end.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace
import math

import numpy as np

STANDARD_GRAVITY = 9.80665

#: Order of the parameter vector used by paths and the tracker.
PARAMETER_NAMES = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc',
                   'f3x', 'f3y', 'f4x', 'f4y', 'm1', 'm2')

_POSITIVE = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc')
_NON_NEGATIVE = ('m1', 'm2')

#: Supported range: |x| <= MAX_MAGNITUDE for every parameter, and lengths and
#: stiffnesses >= MIN_MAGNITUDE, so that products such as k L^2 (an energy) stay
#: far inside double precision (1e-308 .. 1e308) instead of overflowing.
MAX_MAGNITUDE = 1e50
MIN_MAGNITUDE = 1e-50


def mirror_symmetric(parameters):
    """Whether modules with these parameter vectors (rows in PARAMETER_NAMES order) are
    each their own mirror image (L1 = L2, ka = kb, m1 = m2, f3y = f4y, f3x = -f4x,
    exactly): then (t1, t2) -> (t2, t1) in every module maps equilibria to equilibria
    of the same energy and stability (the mechanism reflected about the perpendicular
    bisector of its base)."""
    rows = np.reshape(parameters, (-1, len(PARAMETER_NAMES))).T
    _, L1, L2, ka, kb, _, f3x, f3y, f4x, f4y, m1, m2 = rows
    return bool(np.all(L1 == L2) and np.all(ka == kb) and np.all(m1 == m2)
                and np.all(f3y == f4y) and np.all(f3x == -f4x))


class InvalidParameterError(ValueError):
    """A parameter is non-finite or outside its physical range."""


@dataclass(frozen=True)
class ModuleParams:
    """Geometry, stiffness and loads of one module.

    ``f3y``/``f4y`` are the paper's F3/F4: positive pulls up, negative pushes down.
    ``m1``/``m2`` are rod masses (kg); gravity acts along -y of the base frame.
    """

    rho: float
    L1: float = 1.0
    L2: float = 1.0
    ka: float = 100.0
    kb: float = 100.0
    kc: float = 100.0
    f3x: float = 0.0
    f3y: float = 0.0
    f4x: float = 0.0
    f4y: float = 0.0
    m1: float = 0.0
    m2: float = 0.0
    g: float = STANDARD_GRAVITY

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            try:
                if isinstance(value, (str, bytes, bytearray)):
                    raise TypeError('text is not a number')    # float('1.5') would accept it
                value = float(value)
            except (TypeError, ValueError):
                raise InvalidParameterError(
                    f'{f.name} must be a real number, got {value!r}') from None
            if not math.isfinite(value):
                raise InvalidParameterError(f'{f.name} must be finite, got {value!r}')
            if abs(value) > MAX_MAGNITUDE:
                raise InvalidParameterError(
                    f'{f.name} must be at most {MAX_MAGNITUDE:g} in magnitude, got {value!r}')
            object.__setattr__(self, f.name, value)
        for name in _POSITIVE:
            if getattr(self, name) <= 0.0:
                raise InvalidParameterError(
                    f'{name} must be positive, got {getattr(self, name)!r}')
            if getattr(self, name) < MIN_MAGNITUDE:
                raise InvalidParameterError(
                    f'{name} must be at least {MIN_MAGNITUDE:g}, got {getattr(self, name)!r}')
        for name in _NON_NEGATIVE:
            if getattr(self, name) < 0.0:
                raise InvalidParameterError(
                    f'{name} must be non-negative, got {getattr(self, name)!r}')

    @classmethod
    def paper(cls, rho, L2=1.0, F3=0.0, F4=0.0, k=100.0, L1=1.0):
        """The paper's setting: equal springs, vertical forces F3, F4."""
        return cls(rho=rho, L1=L1, L2=L2, ka=k, kb=k, kc=k, f3y=F3, f4y=F4)

    @property
    def f3y_total(self):
        """Vertical force at A3 including half the weight of rod 1."""
        return self.f3y - 0.5 * self.m1 * self.g

    @property
    def f4y_total(self):
        """Vertical force at A4 including half the weight of rod 2."""
        return self.f4y - 0.5 * self.m2 * self.g

    def vector(self):
        """Parameters as an array in ``PARAMETER_NAMES`` order."""
        return np.array([getattr(self, n) for n in PARAMETER_NAMES], dtype=float)

    @classmethod
    def from_vector(cls, values, g=STANDARD_GRAVITY):
        values = np.asarray(values, dtype=float)
        if values.shape != (len(PARAMETER_NAMES),):
            raise InvalidParameterError(
                f'parameter vector must have shape ({len(PARAMETER_NAMES)},), '
                f'got {values.shape}')
        return cls(**dict(zip(PARAMETER_NAMES, values.tolist())), g=g)

    def with_(self, **changes):
        """A copy with some parameters changed (validated)."""
        return replace(self, **changes)

    def with_rho(self, rho):
        """A copy with actuator length ``rho``: only rho is validated (the other values
        were when ``self`` was built), so an actuator command costs a copy, not a
        re-validation of every field.  Same result and errors as ``with_(rho=rho)``."""
        if not (isinstance(rho, float) and MIN_MAGNITUDE <= rho <= MAX_MAGNITUDE):
            return self.with_(rho=rho)          # the full check (and its usual error)
        moved = object.__new__(type(self))
        moved.__dict__.update(self.__dict__)
        moved.__dict__['rho'] = float(rho)
        return moved


def _angles(theta):
    theta = np.asarray(theta, dtype=float)
    if theta.shape[-1:] != (2,):
        raise ValueError(f'theta must have shape (..., 2), got {theta.shape}')
    return theta[..., 0], theta[..., 1]


def _single_angles(theta):
    """(t1, t2) as floats from one angle pair of shape (2,)."""
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (2,):
        raise ValueError(f'theta must have shape (2,), got {theta.shape}')
    return float(theta[0]), float(theta[1])


def node_positions(p: ModuleParams, theta):
    """Positions of A1..A4 as an array of shape (..., 4, 2)."""
    t1, t2 = _angles(theta)
    zero = np.zeros_like(t1)
    a1 = np.stack([zero, zero], -1)
    a2 = np.stack([zero + p.rho, zero], -1)
    a3 = np.stack([p.L1 * np.cos(t1), p.L1 * np.sin(t1)], -1)
    a4 = np.stack([p.rho - p.L2 * np.cos(t2), p.L2 * np.sin(t2)], -1)
    return np.stack([a1, a2, a3, a4], -2)


def energy(p: ModuleParams, theta):
    """Potential energy U (J) of springs and external forces."""
    t1, t2 = _angles(theta)
    c1, s1, c2, s2 = np.cos(t1), np.sin(t1), np.cos(t2), np.sin(t2)
    x3, y3 = p.L1 * c1, p.L1 * s1
    x4, y4 = p.rho - p.L2 * c2, p.L2 * s2
    a2 = (x3 - p.rho) ** 2 + y3 ** 2
    b2 = x4 ** 2 + y4 ** 2
    c2_ = (x4 - x3) ** 2 + (y4 - y3) ** 2
    springs = 0.5 * (p.ka * a2 + p.kb * b2 + p.kc * c2_)
    work = p.f3x * x3 + p.f3y_total * y3 + p.f4x * x4 + p.f4y_total * y4
    return springs - work


def gradient(p: ModuleParams, theta):
    """dU/dtheta, shape (..., 2): zero at an equilibrium."""
    t1, t2 = _angles(theta)
    s1, c1, s2, c2 = np.sin(t1), np.cos(t1), np.sin(t2), np.cos(t2)
    s12 = np.sin(t1 + t2)
    g1 = p.L1 * ((p.ka + p.kc) * p.rho * s1 - p.kc * p.L2 * s12
                 + p.f3x * s1 - p.f3y_total * c1)
    g2 = p.L2 * ((p.kb + p.kc) * p.rho * s2 - p.kc * p.L1 * s12
                 - p.f4x * s2 - p.f4y_total * c2)
    return np.stack([g1, g2], -1)


def hessian(p: ModuleParams, theta):
    """d2U/dtheta2, shape (..., 2, 2)."""
    t1, t2 = _angles(theta)
    s1, c1, s2, c2 = np.sin(t1), np.cos(t1), np.sin(t2), np.cos(t2)
    c12 = np.cos(t1 + t2)
    h11 = p.L1 * ((p.ka + p.kc) * p.rho * c1 - p.kc * p.L2 * c12
                  + p.f3x * c1 + p.f3y_total * s1)
    h22 = p.L2 * ((p.kb + p.kc) * p.rho * c2 - p.kc * p.L1 * c12
                  - p.f4x * c2 + p.f4y_total * s2)
    h12 = -p.kc * p.L1 * p.L2 * c12
    return np.stack([np.stack([h11, h12], -1), np.stack([h12, h22], -1)], -2)


def actuator_force(p: ModuleParams, theta):
    """dU/drho (N): the force the prismatic actuator must exert on A2 along +x to hold rho
    (positive = pushes A2 outward; unloaded at rho = 0.75 it is -75 N: the actuator pulls)."""
    t1, t2 = _angles(theta)
    x3 = p.L1 * np.cos(t1)
    l2c = p.L2 * np.cos(t2)
    return (p.ka * (p.rho - x3) + p.kb * (p.rho - l2c)
            + p.kc * (p.rho - x3 - l2c) - p.f4x)


def parameter_gradient(p: ModuleParams, theta):
    """dU/dp at fixed theta, in ``PARAMETER_NAMES`` order (envelope theorem input)."""
    t1, t2 = _single_angles(theta)
    c1, s1, c2, s2 = math.cos(t1), math.sin(t1), math.cos(t2), math.sin(t2)
    x3, y3 = p.L1 * c1, p.L1 * s1
    x4, y4 = p.rho - p.L2 * c2, p.L2 * s2
    dx, dy = x4 - x3, y4 - y3
    half = 0.5 * p.g
    return np.array([
        float(actuator_force(p, (t1, t2))),
        p.ka * (p.L1 - p.rho * c1) + p.kc * (dx * -c1 + dy * -s1) - p.f3x * c1 - p.f3y_total * s1,
        p.kb * (p.L2 - p.rho * c2) + p.kc * (dx * -c2 + dy * s2) + p.f4x * c2 - p.f4y_total * s2,
        0.5 * ((x3 - p.rho) ** 2 + y3 ** 2),
        0.5 * (x4 ** 2 + y4 ** 2),
        0.5 * (dx ** 2 + dy ** 2),
        -x3, -y3, -x4, -y4,
        half * y3, half * y4,
    ])


def gradient_parameter_jacobian(p: ModuleParams, theta):
    """d(dU/dtheta)/dp, shape (2, len(PARAMETER_NAMES)): how the equilibrium equations move."""
    t1, t2 = _single_angles(theta)
    s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
    s12 = math.sin(t1 + t2)
    inner1 = (p.ka + p.kc) * p.rho * s1 - p.kc * p.L2 * s12 + p.f3x * s1 - p.f3y_total * c1
    inner2 = (p.kb + p.kc) * p.rho * s2 - p.kc * p.L1 * s12 - p.f4x * s2 - p.f4y_total * c2
    L1, L2, half = p.L1, p.L2, 0.5 * p.g
    row1 = [L1 * (p.ka + p.kc) * s1, inner1, -L1 * p.kc * s12,
            L1 * p.rho * s1, 0.0, L1 * (p.rho * s1 - L2 * s12),
            L1 * s1, -L1 * c1, 0.0, 0.0, L1 * half * c1, 0.0]
    row2 = [L2 * (p.kb + p.kc) * s2, -L2 * p.kc * s12, inner2,
            0.0, L2 * p.rho * s2, L2 * (p.rho * s2 - L1 * s12),
            0.0, 0.0, -L2 * s2, -L2 * c2, 0.0, L2 * half * c2]
    return np.array([row1, row2])
