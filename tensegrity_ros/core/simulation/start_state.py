"""Where a mechanism starts: the stable equilibrium a start guess settles into, or a default.

One rule for every tool (node, simulator, CLI, figures): with a guess (one [t1, t2] per
module) the overdamped mechanism released there slides into a stable equilibrium;
without one, a single module starts on its upper stable equilibrium (largest y3 + y4,
as in the paper's figures) and a neck upright.
"""
from __future__ import annotations

import math

from .mechanisms import mechanism_for
from ..module.polynomial_solver import equilibria


def upper_equilibrium(p):
    """The stable equilibrium of module ``p`` with the largest y3 + y4; ValueError if
    there is none (a degenerate point)."""
    stable = equilibria(p).stable
    if not stable:
        raise ValueError('no stable equilibrium (the point is degenerate; move it slightly)')
    return max(stable, key=lambda e: p.L1 * math.sin(e.theta1) + p.L2 * math.sin(e.theta2))


def upright_guess(modules):
    """The all-upright start guess (N x 2).

    One module: its upper stable equilibrium.  Several: every module symmetric,
    t1 = t2 = acos((rho_i + rho_i+1) / (L1 + L2)), which makes its top chord as long
    as the next module's actuator (the top module uses its own rho, the unloaded
    parallelogram); the neck settles from there.
    """
    modules = tuple(modules)
    if len(modules) == 1:
        return [list(upper_equilibrium(modules[0]).theta)]
    guess = []
    for i, m in enumerate(modules):
        upper = modules[i + 1].rho if i + 1 < len(modules) else m.rho
        c = (m.rho + upper) / (m.L1 + m.L2)
        t = math.acos(min(max(c, -0.95), 0.95))
        guess.append([t, t])
    return guess


def start_state(modules, guess=None, settings=None):
    """The verified stable start state of ``modules`` (an ``Equilibrium`` for one module,
    a ``StackEquilibrium`` for a neck), settled from ``guess`` (N x 2) or the default
    (a neck by the tracker's flows, with ``settings`` where given: compiled flows).

    Raises ValueError (or TrackingError) if no stable equilibrium is reached.
    """
    modules = tuple(modules)
    if guess is None:
        if len(modules) == 1:
            return upper_equilibrium(modules[0])
        guess = upright_guess(modules)
    mechanism, thetas = mechanism_for(len(modules)), [list(t) for t in guess]
    state = (mechanism.settle(modules, thetas) if settings is None
             else mechanism.settle(modules, thetas, settings))
    if not state.stable:
        raise ValueError('settled on a state that is not a stable equilibrium')
    return state
