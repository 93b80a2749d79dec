"""The vectorised pieces of the one-module tolerance questions (numpy): which rows the
vectorised path may take, where each row starts, where a jump lands, and a command
schedule followed leg by leg for many samples at once (:class:`ScheduleFollower`).
The branch following itself is :mod:`.tolerance.branch_batch`.
"""
from __future__ import annotations

import math

import numpy as np

from . import branch_batch as bb
from ..module.classification import DEGENERACY_TOL
from ..module.model import MAX_MAGNITUDE, MIN_MAGNITUDE, PARAMETER_NAMES


def _wrap(a):
    return (np.asarray(a, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi


def valid_rows(rows):
    """Rows inside ModuleParams' domain (the others go to the scalar path, which says why)."""
    finite = np.all(np.isfinite(rows), axis=1) & np.all(np.abs(rows) <= MAX_MAGNITUDE, axis=1)
    positive = np.all(rows[:, :6] >= MIN_MAGNITUDE, axis=1)
    masses = np.all(rows[:, 10:12] >= 0.0, axis=1)
    return finite & positive & masses


def start_states(rows, g, guess):
    """(t1, t2, decided, number of stable equilibria) of the start of each row: the
    upper stable equilibrium, or where the mechanism settles from ``guess``."""
    if guess is None:
        t1, t2, count = bb.upper_start(rows, g)
        return t1, t2, count > 0, count
    return bb.settle_start(rows, g, guess)


def landings(fam, rows, s, t1, t2, g):
    """Where a module jumping off the fold (t1, t2) at ``s`` of rows ``rows`` of ``fam``
    lands: the one stable equilibrium there other than the fold itself (a module has at
    most two stable equilibria).  It is found past the fold (s + 0.01 on the straight
    path, beyond the leg's end if need be: the fold's pair of equilibria has gone there
    and the batch solver sees a generic point), then polished at s by Newton and checked
    stable and away from the fold.  (t1, t2, unique): the rows where that fails (no
    single candidate, parameters past the fold outside the domain, a landing minimum that
    exists only past the jump) go to the scalar tracker."""
    params = fam.p0[rows] + (s + 0.01)[:, None] * fam.dp[rows]
    valid = valid_rows(params)
    params[~valid] = fam.p0[rows][~valid]               # (answered by the scalar path)
    theta, stable, _ = bb.stable_equilibria(params, g)
    far = np.max(np.abs(_wrap(theta - np.stack([t1, t2], -1)[:, None, :])), axis=-1) > 1e-3
    other = stable & far
    unique = (other.sum(axis=1) == 1) & valid
    slot = np.argmax(other, axis=1)
    pick = np.arange(len(rows))
    l1, l2, ok = bb.newton(fam.at(rows, s), theta[pick, slot, 0], theta[pick, slot, 1])
    away = np.maximum(np.abs(_wrap(l1 - t1)), np.abs(_wrap(l2 - t2))) > 1e-3
    stable_here = stable_at(fam, rows, s, l1, l2)
    return l1, l2, unique & ok & away & stable_here


def polished_start(fam, rows, s, g, guess):
    """Each row's start at ``s`` on its path (``fam``, rows in order): (t1, t2, number of
    stable equilibria, good), polished by Newton; not good (scalar path) where the start
    is undecided, Newton fails or the state is not a verified minimum."""
    t1, t2, decided, count = start_states(rows, g, guess)
    local = np.arange(len(rows))
    t1, t2, ok = bb.newton(fam.at(local, s), t1, t2)
    return t1, t2, count, decided & ok & stable_at(fam, local, s, t1, t2)


def stable_at(fam, idx, s, t1, t2):
    """lambda_min > DEGENERACY_TOL |lambda_max| (operation_range's start test)."""
    _, _, h11, h12, h22, _, _ = bb.gradient_hessian(fam.at(idx, s), t1, t2)
    lo, hi = bb.eigenvalues_2x2(h11, h12, h22)
    return lo > DEGENERACY_TOL * np.abs(hi)


class ScheduleFollower:
    """One module's command schedule for many samples at once: each leg (a straight path
    between waypoints) followed by :func:`.tolerance.branch_batch.follow`; at a fold the module
    lands (:func:`landings`) and goes on from there.  A row that turns out delicate is
    ``failed`` (the caller answers it with the scalar tracker)."""

    def __init__(self, stops, t1, t2, g):
        n = len(stops)
        self.stops, self.g = stops, g
        self.t1, self.t2 = t1.copy(), t2.copy()
        self.first = np.full(n, -1)                 # leg of the first jump (-1: none)
        self.first_s = np.full(n, np.nan)
        self.first_p = np.full((n, len(PARAMETER_NAMES)), np.nan)
        self.landing = np.full((n, 2), np.nan)
        self.jumps = np.zeros(n, int)
        self.failed = np.zeros(n, bool)

    def run(self):
        for leg in range(self.stops.shape[1] - 1):
            self.leg(leg)
        return self

    def leg(self, leg):
        p0 = self.stops[:, leg]
        fam = bb.PathFamily(p0, self.stops[:, leg + 1] - p0, self.g)
        live = np.nonzero(~self.failed)[0]
        s0 = np.zeros(live.size)
        for _ in range(bb.MAX_EVENTS + 1):
            if live.size == 0:
                return
            ones = np.ones(live.size)
            end_s, e1, e2, kind, delicate = bb.follow(fam, live, self.t1[live], self.t2[live],
                                                      s0, ones, ones, ones, False, True)
            fold = np.nonzero((kind == bb.FOLD) & ~delicate)[0]
            branch = bb.fold_is_branch_point(fam, live[fold], e1[fold], e2[fold], end_s[fold])
            delicate[fold[branch]] = True
            self.reached(fam, live, (kind == bb.LIMIT) & ~delicate, e1, e2, delicate)
            fold = np.nonzero((kind == bb.FOLD) & ~delicate)[0]
            self.jumped(fam, leg, live, fold, end_s, e1, e2, delicate)
            self.failed[live[delicate]] = True
            again = (kind == bb.FOLD) & ~delicate
            s0, live = end_s[again], live[again]
        self.failed[live] = True                    # too many events on one leg

    def reached(self, fam, live, reached, e1, e2, delicate):
        """Rows at the leg's end: polished at s = 1 exactly."""
        k = np.nonzero(reached)[0]
        rows = live[k]
        f1, f2, ok = bb.newton(fam.at(rows, np.ones(rows.size)), e1[k], e2[k])
        self.t1[rows], self.t2[rows] = f1, f2
        delicate[k[~ok]] = True

    def jumped(self, fam, leg, live, fold, end_s, e1, e2, delicate):
        """Rows at a fold: they land, and the first jump of each is recorded."""
        rows = live[fold]
        l1, l2, unique = landings(fam, rows, end_s[fold], e1[fold], e2[fold], self.g)
        delicate[fold[~unique]] = True
        fold, rows, l1, l2 = fold[unique], rows[unique], l1[unique], l2[unique]
        new = self.first[rows] < 0
        r = rows[new]
        self.first[r], self.first_s[r] = leg, end_s[fold][new]
        self.first_p[r] = fam.p0[r] + end_s[fold][new, None] * fam.dp[r]
        self.landing[r, 0], self.landing[r, 1] = _wrap(l1[new]), _wrap(l2[new])
        self.jumps[rows] += 1
        self.t1[rows], self.t2[rows] = l1, l2
