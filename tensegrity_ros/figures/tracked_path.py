"""The quasi-static path a diagram overlays (``diagram --track``): the tracker's legs
through given rho values, drawn along the stable equilibria between its jumps.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .diagram import _Solver, _torus_sq_dist
from ..core import track_module
from ..core.simulation.start_state import start_state


@dataclass
class TrackLeg:
    rho0: float
    rho1: float
    jumps: tuple
    status: str
    message: str


@dataclass
class TrackedPath:
    """Continuous pieces (rho, theta) of the quasi-static path and its jumps."""

    pieces: list               # list of (rhos (m,), thetas (m, 2))
    jumps: list                # list of (rho, from_theta, to_theta, kind)
    legs: list


def track_path(fixed, rhos, guess, diagram=None):
    """Follow the stable equilibrium through the rho values (``track_module`` per leg),
    from the start state :func:`start_state` settles ``guess`` into (None: the upper one).

    Jumps come from the tracker; between them the path is drawn through the
    stable equilibria nearest to the previous point (at most half the diagram's
    step apart in rho), which is the branch the tracker followed.
    """
    solve = _Solver(fixed)
    step = 0.0025
    if diagram is not None:
        step = 0.5 * (diagram.rho_max - diagram.rho_min) / max(diagram.samples, 2)
    first = start_state([solve.params(rhos[0])], None if guess is None else [guess])
    theta = first.theta
    pieces, jumps, legs = [], [], []
    for r0, r1 in zip(rhos[:-1], rhos[1:]):
        track = track_module(solve.params(r0), solve.params(r1), theta)
        legs.append(TrackLeg(r0, r1, tuple(track.jumps), track.status, track.message))
        rho_a, cur = r0, theta
        for jump in track.jumps:
            pieces.append(_follow(solve, rho_a, jump.params.rho, cur, jump.from_theta, step))
            jumps.append((jump.params.rho, np.asarray(jump.from_theta, float),
                          np.asarray(jump.to_theta, float), jump.kind))
            rho_a, cur = jump.params.rho, np.asarray(jump.to_theta, float)
        r_end = track.end.rho
        pieces.append(_follow(solve, rho_a, r_end, cur, track.final.theta, step))
        theta = track.final.theta
        if track.status != 'ok':
            break
    return TrackedPath(pieces=pieces, jumps=jumps, legs=legs)


def _follow(solve, rho_a, rho_b, theta_a, theta_b, step):
    m = max(2, int(math.ceil(abs(rho_b - rho_a) / step)) + 1)
    rs = np.linspace(rho_a, rho_b, m)
    out = [np.asarray(theta_a, float)]
    for r in rs[1:-1]:
        s = solve(r)
        cand = s.theta[s.stable] if s.stable.any() else s.theta
        if len(cand) == 0:
            out.append(out[-1])
            continue
        d = _torus_sq_dist(out[-1][None], cand)[0]
        out.append(cand[int(np.argmin(d))])
    out.append(np.asarray(theta_b, float))
    return rs, np.array(out)
