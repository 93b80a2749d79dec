"""What a tolerance study asks of each sampled module or neck, and its answer as numbers.

A question evaluates a chunk of samples: ``waypoints``, an array (m, K, N, 12) of
parameter vectors (``PARAMETER_NAMES`` order) of N modules at K points of a command
schedule (K = 1 for the operating range), and returns one float array (m,) per figure
(0/1 for yes/no, NaN where a figure does not apply).  Samples are independent: a
sample's answer never depends on the other rows of its chunk, so a chunked run gives
the same numbers however the chunks are scheduled.

* :class:`OperatingRange` (one module): the stable rho interval through the working
  point, as :func:`.operation_range.operation_range` (``tensegrity range``), and the
  number of stable equilibria at a given rho (bistable or not).
* :class:`PlannedPath` (a module or a neck): the command schedule, leg by leg, as
  ``tensegrity track``: does it jump, where, where does it land, where does it end.
* :class:`HeadLoad` (a neck or a module): a growing head load; the load at which the
  stack first jumps (buckles and snaps), as ``tensegrity track --config ... --to-F``.

The one-module questions solve the generic samples vectorised (:mod:`.branch_batch`)
and every delicate one with the scalar functions above; ``exact=True`` uses the scalar
functions for all (the reference the vectorised path is tested against).
"""
from __future__ import annotations

from dataclasses import dataclass
import functools
import hashlib
import math
import pathlib
import time

import numpy as np

from . import branch_batch as bb
from .classification import DEGENERACY_TOL
from .module import InvalidParameterError, ModuleParams, PARAMETER_NAMES, STANDARD_GRAVITY
from .operation_range import operation_range
from .polynomial_solver import equilibria
from .stack import Stack, track_stack
from .start_state import start_state
from .tolerance_sampling import sample_waypoints
from .tracking import track_module

#: Status codes (the ``status`` figure).
OK, NO_START, TRACKING_FAILED, INVALID = 0, 1, 2, 3
STATUS_NAMES = {OK: 'ok', NO_START: 'no stable start', TRACKING_FAILED: 'tracking failed',
                INVALID: 'invalid parameters'}
#: Kinds of a range end or a jump (the ``*_kind`` figures).
KIND_CODES = {'fold': 0, 'branch_point': 1, 'limit': 2}
KIND_NAMES = {v: k for k, v in KIND_CODES.items()}


def modules_of(vectors, g=STANDARD_GRAVITY):
    """ModuleParams of every row of ``vectors`` (N, 12); InvalidParameterError if any is
    outside the physical domain."""
    return tuple(ModuleParams.from_vector(v, g=g) for v in vectors)


def _wrap(a):
    return (np.asarray(a, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi


def _path_s(start, end, p):
    """Where parameters ``p`` lie on the straight path start -> end (its s)."""
    d = end.vector() - start.vector()
    return float((p.vector() - start.vector()) @ d / (d @ d))


def _empty(names, m):
    return {name: np.full(m, math.nan) for name in names}


def _valid_rows(rows):
    """Rows inside ModuleParams' domain (the others go to the scalar path, which says why)."""
    from .module import MAX_MAGNITUDE, MIN_MAGNITUDE
    finite = np.all(np.isfinite(rows), axis=1) & np.all(np.abs(rows) <= MAX_MAGNITUDE, axis=1)
    positive = np.all(rows[:, :6] >= MIN_MAGNITUDE, axis=1)
    masses = np.all(rows[:, 10:12] >= 0.0, axis=1)
    return finite & positive & masses


def _start(rows, g, guess):
    """(t1, t2, decided, number of stable equilibria) of the start of each row: the
    upper stable equilibrium, or where the mechanism settles from ``guess``."""
    if guess is None:
        t1, t2, count = bb.upper_start(rows, g)
        return t1, t2, count > 0, count
    return bb.settle_start(rows, g, guess)


def _landings(fam, rows, s, t1, t2, g):
    """Where a module jumping off the fold (t1, t2) at ``s`` of rows ``rows`` of ``fam``
    lands: the one stable equilibrium there other than the fold itself (a module has at
    most two stable equilibria).  It is found past the fold (s + 0.01 on the straight
    path, beyond the leg's end if need be: the fold's pair of equilibria has gone there
    and the batch solver sees a generic point), then polished at s by Newton and checked
    stable and away from the fold.  (t1, t2, unique): the rows where that fails (no
    single candidate, parameters past the fold outside the domain, a landing minimum that
    exists only past the jump) go to the scalar tracker."""
    params = fam.p0[rows] + (s + 0.01)[:, None] * fam.dp[rows]
    valid = _valid_rows(params)
    params[~valid] = fam.p0[rows][~valid]               # (answered by the scalar path)
    theta, stable, _ = bb.stable_equilibria(params, g)
    far = np.max(np.abs(_wrap(theta - np.stack([t1, t2], -1)[:, None, :])), axis=-1) > 1e-3
    other = stable & far
    unique = (other.sum(axis=1) == 1) & valid
    slot = np.argmax(other, axis=1)
    pick = np.arange(len(rows))
    l1, l2, ok = bb.newton(fam.at(rows, s), theta[pick, slot, 0], theta[pick, slot, 1])
    away = np.maximum(np.abs(_wrap(l1 - t1)), np.abs(_wrap(l2 - t2))) > 1e-3
    stable_here = _stable_at(fam, rows, s, l1, l2)
    return l1, l2, unique & ok & away & stable_here


def _stable_at(fam, idx, s, t1, t2):
    """lambda_min > DEGENERACY_TOL |lambda_max| (operation_range's start test)."""
    _, _, h11, h12, h22, _, _ = bb.gradient_hessian(fam.at(idx, s), t1, t2)
    lo, hi = bb.eigenvalues_2x2(h11, h12, h22)
    return lo > DEGENERACY_TOL * np.abs(hi)


@dataclass(frozen=True)
class OperatingRange:
    """The operating range of one module around its working point.

    ``guess``: the start guess (t1, t2) (None: the upper stable equilibrium, as
    ``tensegrity range``); ``at_rho``: where to count the stable equilibria (None: at
    the sample's own rho); ``rho_bounds``: the search interval (None: 0 .. 2 (L1 + L2)).
    """

    guess: tuple | None = None
    at_rho: float | None = None
    rho_bounds: tuple | None = None
    exact: bool = False

    name = 'range'
    waypoints = 1
    #: Figures, in report order.
    FIGURES = ('rho_min', 'rho_max', 'width', 'margin_below', 'margin_above',
               'lower_kind', 'upper_kind', 'jumps_below', 'jumps_above',
               'num_stable', 'bistable', 'start_theta1', 'start_theta2', 'scalar', 'status')
    #: 0/1 figures whose probability (with its interval) is reported.
    EVENTS = ('bistable', 'jumps_below', 'jumps_above')
    #: The figure whose smallest values are the worst samples.
    WORST = 'width'
    WORST_ORDER = 'smallest'

    def figures(self, names=None):
        return self.FIGURES

    def evaluate(self, waypoints, g=STANDARD_GRAVITY):
        waypoints = np.asarray(waypoints, dtype=float)
        rows = waypoints[:, 0, 0, :]
        if not self.exact:
            return self._evaluate_batch(rows, g)
        out = _empty(self.FIGURES, len(rows))
        for i, row in enumerate(rows):
            self.evaluate_one(row, g, out, i)
        return out

    def _evaluate_batch(self, rows, g):
        """Generic rows vectorised (:mod:`.branch_batch`), delicate ones by evaluate_one."""
        m = len(rows)
        out = _empty(self.FIGURES, m)
        e_rho = np.zeros_like(rows)
        e_rho[:, 0] = 1.0
        scalar = ~_valid_rows(rows) | bb.symmetric_rows(rows, e_rho, g)
        gen = np.nonzero(~scalar)[0]
        t1, t2, decided, count = _start(rows[gen], g, self.guess)
        base = rows[gen].copy()
        base[:, 0] = 0.0
        fam = bb.PathFamily(base, e_rho[gen], g)
        rho = rows[gen, 0]
        local = np.arange(len(gen))
        p1, p2, ok = bb.newton(fam.at(local, rho), t1, t2)
        stable = _stable_at(fam, local, rho, p1, p2)
        good = decided & ok & stable
        scalar[gen[~good]] = True
        gen, p1, p2, rho, count = gen[good], p1[good], p2[good], rho[good], count[good]
        base = base[good]
        fam = bb.PathFamily(base, e_rho[gen], g)
        L = rows[gen, 1] + rows[gen, 2]
        lo_b = np.zeros(len(gen)) if self.rho_bounds is None else \
            np.full(len(gen), float(self.rho_bounds[0]))
        hi_b = 2.0 * L if self.rho_bounds is None else np.full(len(gen), float(self.rho_bounds[1]))
        n = len(gen)
        both = np.concatenate([np.arange(n), np.arange(n)])
        sigma = np.concatenate([-np.ones(n), np.ones(n)])
        t1w, t2w = _wrap(p1), _wrap(p2)
        end_s, e1, e2, kind, delicate = bb.follow(
            fam, both, np.concatenate([t1w, t1w]), np.concatenate([t2w, t2w]),
            np.concatenate([rho, rho]), sigma, np.concatenate([lo_b, hi_b]),
            np.concatenate([L, L]), True, False)
        fold = kind == bb.FOLD
        if np.any(fold):
            k = np.nonzero(fold)[0]
            branch = bb.fold_is_branch_point(fam, both[k], e1[k], e2[k], end_s[k])
            delicate[k[branch]] = True
        bad = delicate[:n] | delicate[n:]
        keep = ~bad
        scalar[gen[bad]] = True
        rows_ok = gen[keep]
        lower, upper = end_s[:n][keep], end_s[n:][keep]
        out['status'][rows_ok] = OK
        out['scalar'][rows_ok] = 0.0
        out['rho_min'][rows_ok], out['rho_max'][rows_ok] = lower, upper
        out['width'][rows_ok] = upper - lower
        out['margin_below'][rows_ok] = rho[keep] - lower
        out['margin_above'][rows_ok] = upper - rho[keep]
        out['lower_kind'][rows_ok] = kind[:n][keep]
        out['upper_kind'][rows_ok] = kind[n:][keep]
        out['jumps_below'][rows_ok] = (kind[:n][keep] == bb.FOLD).astype(float)
        out['jumps_above'][rows_ok] = (kind[n:][keep] == bb.FOLD).astype(float)
        out['start_theta1'][rows_ok], out['start_theta2'][rows_ok] = t1w[keep], t2w[keep]
        if self.at_rho is None:
            counts = count[keep]
        else:
            at = rows[rows_ok].copy()
            at[:, 0] = self.at_rho
            counts = bb.stable_equilibria(at, g)[1].sum(axis=1)
        out['num_stable'][rows_ok] = counts
        out['bistable'][rows_ok] = (counts == 2).astype(float)
        for i in np.nonzero(scalar)[0]:
            self.evaluate_one(rows[i], g, out, i)
        return out

    def evaluate_one(self, row, g, out, i):
        """The scalar reference for sample ``i`` (``tensegrity range`` and ``solve``)."""
        out['scalar'][i] = 1.0
        try:
            p = ModuleParams.from_vector(row, g=g)
        except InvalidParameterError:
            out['status'][i] = INVALID
            return
        try:
            first = start_state([p], None if self.guess is None else [self.guess])
            result = operation_range(p, first.theta, rho_bounds=self.rho_bounds)
        except (ValueError, RuntimeError):
            out['status'][i] = NO_START
            return
        out['status'][i] = OK
        out['rho_min'][i], out['rho_max'][i] = result.rho_min, result.rho_max
        out['width'][i] = result.width
        out['margin_below'][i] = p.rho - result.rho_min
        out['margin_above'][i] = result.rho_max - p.rho
        out['lower_kind'][i] = KIND_CODES[result.lower.kind]
        out['upper_kind'][i] = KIND_CODES[result.upper.kind]
        out['jumps_below'][i] = float(result.jumps_at(result.lower))
        out['jumps_above'][i] = float(result.jumps_at(result.upper))
        out['start_theta1'][i], out['start_theta2'][i] = result.theta
        at = p if self.at_rho is None else p.with_(rho=self.at_rho)
        count = equilibria(at).num_stable
        out['num_stable'][i] = count
        out['bistable'][i] = float(count == 2)


@dataclass(frozen=True)
class PlannedPath:
    """A command schedule: K - 1 straight legs through the K waypoints of each sample.

    ``guess``: the start guess, N x 2 angles (None: a module's upper stable equilibrium,
    a neck's upright configuration).  ``names``: the module names (for the figures).
    """

    guess: tuple | None = None
    names: tuple = ('m0',)
    exact: bool = False

    name = 'path'
    EVENTS = ('jumped',)
    WORST = 'jump_s_total'
    WORST_ORDER = 'smallest'

    @property
    def modules(self):
        return len(self.names)

    def figures(self, names=None):
        base = ['jumped', 'jumps', 'jump_leg', 'jump_s', 'jump_s_total', 'jump_kind']
        if self.modules == 1:
            base += ['jump_rho', 'jump_F3', 'jump_F4', 'landing_theta1', 'landing_theta2',
                     'final_theta1', 'final_theta2']
        else:
            base += [f'jump_rho_{n}' for n in self.names]
            base += ['jump_F3', 'jump_F4']
            base += [f'landing_{n}_theta{j}' for n in self.names for j in (1, 2)]
            base += ['final_head_x', 'final_head_y', 'final_head_angle']
        return tuple(base) + ('scalar', 'status')

    def evaluate(self, waypoints, g=STANDARD_GRAVITY):
        waypoints = np.asarray(waypoints, dtype=float)
        if self.modules == 1 and not self.exact:
            return self._evaluate_batch(waypoints, g)
        out = _empty(self.figures(), len(waypoints))
        for i, sample in enumerate(waypoints):
            self.evaluate_one(sample, g, out, i)
        return out

    def _evaluate_batch(self, waypoints, g):
        """One module, generic rows vectorised leg by leg (:mod:`.branch_batch`): a fold
        ends the branch and the module lands on the one other stable equilibrium there;
        delicate rows (see branch_batch) by evaluate_one."""
        m, k_stops = waypoints.shape[:2]
        out = _empty(self.figures(), m)
        stops = waypoints[:, :, 0, :]
        scalar = np.zeros(m, bool)
        for k in range(k_stops):
            scalar |= ~_valid_rows(stops[:, k])
        for k in range(k_stops - 1):
            scalar |= bb.symmetric_rows(stops[:, k], stops[:, k + 1] - stops[:, k], g)
        gen = np.nonzero(~scalar)[0]
        guess = None if self.guess is None else self.guess[0]
        t1, t2, decided, _ = _start(stops[gen, 0], g, guess)
        fam = bb.PathFamily(stops[gen, 0], stops[gen, 1] - stops[gen, 0], g)
        local = np.arange(len(gen))
        zero = np.zeros(len(gen))
        t1, t2, ok = bb.newton(fam.at(local, zero), t1, t2)
        fine = decided & ok & _stable_at(fam, local, zero, t1, t2)
        scalar[gen[~fine]] = True
        gen, t1, t2 = gen[fine], t1[fine], t2[fine]
        n = len(gen)
        first = np.full(n, -1)                      # leg of the first jump (-1: none)
        first_s = np.full(n, np.nan)
        first_p = np.full((n, len(PARAMETER_NAMES)), np.nan)
        landing = np.full((n, 2), np.nan)
        jumps = np.zeros(n, int)
        failed = np.zeros(n, bool)
        for leg in range(k_stops - 1):
            p0 = stops[gen, leg]
            dp = stops[gen, leg + 1] - p0
            fam = bb.PathFamily(p0, dp, g)
            live = np.nonzero(~failed)[0]
            s0 = np.zeros(live.size)
            for _ in range(bb.MAX_EVENTS + 1):
                if live.size == 0:
                    break
                end_s, e1, e2, kind, delicate = bb.follow(
                    fam, live, t1[live], t2[live], s0, np.ones(live.size),
                    np.ones(live.size), np.ones(live.size), False, True)
                fold = np.nonzero((kind == bb.FOLD) & ~delicate)[0]
                if fold.size:
                    branch = bb.fold_is_branch_point(fam, live[fold], e1[fold], e2[fold],
                                                     end_s[fold])
                    delicate[fold[branch]] = True
                reached = np.nonzero((kind == bb.LIMIT) & ~delicate)[0]
                if reached.size:            # polished at s = 1 exactly
                    r = live[reached]
                    f1, f2, ok = bb.newton(fam.at(r, np.ones(r.size)), e1[reached],
                                           e2[reached])
                    t1[r], t2[r] = f1, f2
                    delicate[reached[~ok]] = True
                fold = np.nonzero((kind == bb.FOLD) & ~delicate)[0]
                if fold.size:
                    r = live[fold]
                    l1, l2, unique = _landings(fam, r, end_s[fold], e1[fold], e2[fold], g)
                    delicate[fold[~unique]] = True
                    fold, r, l1, l2 = fold[unique], r[unique], l1[unique], l2[unique]
                    new = first[r] < 0
                    first[r[new]] = leg
                    first_s[r[new]] = end_s[fold][new]
                    first_p[r[new]] = p0[r[new]] + end_s[fold][new, None] * dp[r[new]]
                    landing[r[new], 0], landing[r[new], 1] = _wrap(l1[new]), _wrap(l2[new])
                    jumps[r] += 1
                    t1[r], t2[r] = l1, l2
                failed[live[delicate]] = True
                again = (kind == bb.FOLD) & ~delicate
                s0 = end_s[again]
                live = live[again]
            failed[live] = True                     # too many events on one leg
        scalar[gen[failed]] = True
        rows = gen[~failed]
        keep = ~failed
        out['status'][rows] = OK
        out['scalar'][rows] = 0.0
        out['jumped'][rows] = (jumps[keep] > 0).astype(float)
        out['jumps'][rows] = jumps[keep]
        out['final_theta1'][rows], out['final_theta2'][rows] = _wrap(t1[keep]), _wrap(t2[keep])
        hit = keep & (first >= 0)
        rows = gen[hit]
        out['jump_leg'][rows] = first[hit]
        out['jump_s'][rows] = first_s[hit]
        out['jump_s_total'][rows] = first[hit] + first_s[hit]
        out['jump_kind'][rows] = KIND_CODES['fold']
        out['jump_rho'][rows] = first_p[hit, 0]
        out['jump_F3'][rows] = first_p[hit, PARAMETER_NAMES.index('f3y')]
        out['jump_F4'][rows] = first_p[hit, PARAMETER_NAMES.index('f4y')]
        out['landing_theta1'][rows], out['landing_theta2'][rows] = landing[hit, 0], landing[hit, 1]
        for i in np.nonzero(scalar)[0]:
            self.evaluate_one(waypoints[i], g, out, i)
        return out

    def evaluate_one(self, sample, g, out, i):
        """The scalar reference for sample ``i`` (``tensegrity track``, leg by leg)."""
        out['scalar'][i] = 1.0
        try:
            stops = [modules_of(v, g) for v in sample]
        except InvalidParameterError:
            out['status'][i] = INVALID
            return
        try:
            state = start_state(stops[0], None if self.guess is None else self.guess)
        except (ValueError, RuntimeError):
            out['status'][i] = NO_START
            return
        jumps, certificate = [], ''
        for leg, (a, b) in enumerate(zip(stops, stops[1:])):
            if len(a) == 1:
                track = track_module(a[0], b[0], state.theta, certificate=certificate)
                certificate = track.certificate
            else:
                track = track_stack(Stack(a), Stack(b), state)
            jumps += [(leg, j) for j in track.jumps]
            state = track.final
            if track.status != 'ok':
                out['status'][i] = TRACKING_FAILED
                break
        else:
            out['status'][i] = OK
        self._record(out, i, jumps, state)

    def _record(self, out, i, jumps, final):
        out['jumped'][i] = float(bool(jumps))
        out['jumps'][i] = len(jumps)
        if self.modules == 1:
            out['final_theta1'][i], out['final_theta2'][i] = _wrap(final.theta)
        else:
            out['final_head_x'][i], out['final_head_y'][i] = final.head_position
            out['final_head_angle'][i] = final.head_angle
        if not jumps:
            return
        leg, jump = jumps[0]
        out['jump_leg'][i], out['jump_s'][i] = leg, jump.s
        out['jump_s_total'][i] = leg + jump.s
        out['jump_kind'][i] = KIND_CODES[jump.kind]
        if self.modules == 1:
            p = jump.params
            out['jump_rho'][i], out['jump_F3'][i], out['jump_F4'][i] = p.rho, p.f3y, p.f4y
            out['landing_theta1'][i], out['landing_theta2'][i] = _wrap(jump.to_theta)
            return
        for name, m in zip(self.names, jump.stack.modules):
            out[f'jump_rho_{name}'][i] = m.rho
        head = jump.stack.modules[-1]
        out['jump_F3'][i], out['jump_F4'][i] = head.f3y, head.f4y
        for name, t in zip(self.names, _wrap(jump.to_theta)):
            out[f'landing_{name}_theta1'][i], out[f'landing_{name}_theta2'][i] = t


@dataclass(frozen=True)
class HeadLoad(PlannedPath):
    """A head load growing from the sample's start load to its end load (waypoints 0
    and 1): the load at which the module or neck first jumps.  ``critical_load`` is the
    total downward head load there, -(F3 + F4) of the top module (N); NaN where no
    jump happens before the end load.  ``buckled_before``: the neck passed a
    supercritical branch point (a continuous sideways buckling, only in an exactly
    symmetric sample) before it jumped."""

    name = 'head-load'
    EVENTS = ('collapsed', 'buckled_before')
    WORST = 'critical_load'
    WORST_ORDER = 'smallest'

    def figures(self, names=None):
        return ('critical_load', 'critical_F3', 'critical_F4', 'collapse_kind',
                'collapsed', 'buckled_before', 'scalar', 'status')

    def evaluate(self, waypoints, g=STANDARD_GRAVITY):
        waypoints = np.asarray(waypoints, dtype=float)
        if self.modules == 1 and not self.exact:
            return self._evaluate_module_batch(waypoints, g)
        out = _empty(self.figures(), len(waypoints))
        for i, sample in enumerate(waypoints):
            self.evaluate_one(sample, g, out, i)
        return out

    def _evaluate_module_batch(self, waypoints, g):
        """One module: the load path vectorised as a planned path; its first jump is the
        collapse.  (A continuous buckling needs an exact symmetry: such samples, and
        every other delicate one, are answered by evaluate_one.)"""
        path = PlannedPath(guess=self.guess, names=self.names)._evaluate_batch(waypoints, g)
        out = _empty(self.figures(), len(waypoints))
        fast = path['scalar'] == 0.0
        out['status'][fast], out['scalar'][fast] = path['status'][fast], 0.0
        out['collapsed'][fast] = path['jumped'][fast]
        out['buckled_before'][fast] = 0.0
        for name, source in (('critical_F3', 'jump_F3'), ('critical_F4', 'jump_F4'),
                             ('collapse_kind', 'jump_kind')):
            out[name][fast] = path[source][fast]
        out['critical_load'][fast] = -(path['jump_F3'][fast] + path['jump_F4'][fast])
        for i in np.nonzero(~fast)[0]:
            self.evaluate_one(waypoints[i], g, out, i)
        return out

    def evaluate_one(self, sample, g, out, i):
        out['scalar'][i] = 1.0
        try:
            a, b = (modules_of(v, g) for v in sample[:2])
        except InvalidParameterError:
            out['status'][i] = INVALID
            return
        try:
            state = start_state(a, None if self.guess is None else self.guess)
        except (ValueError, RuntimeError):
            out['status'][i] = NO_START
            return
        if len(a) == 1:
            track = track_module(a[0], b[0], state.theta)
            tops = [j.params for j in track.jumps]
            passed = [_path_s(a[0], b[0], p) for p in track.passages]
        else:
            track = track_stack(Stack(a), Stack(b), state)
            tops = [j.stack.modules[-1] for j in track.jumps]
            passed = [p.s for p in track.passages]
        out['status'][i] = OK if track.status == 'ok' else TRACKING_FAILED
        out['collapsed'][i] = float(bool(tops))
        first_s = track.jumps[0].s if tops else math.inf
        out['buckled_before'][i] = float(any(s < first_s for s in passed))
        if not tops:
            return
        first = track.jumps[0]
        out['critical_F3'][i], out['critical_F4'][i] = tops[0].f3y, tops[0].f4y
        out['critical_load'][i] = -(tops[0].f3y + tops[0].f4y)
        out['collapse_kind'][i] = KIND_CODES[first.kind]


@functools.lru_cache(maxsize=1)
def code_fingerprint():
    """A digest of the core's source: the code every sample's answer comes from.  A
    cluster's workers must run the same (else the same seed could answer differently)."""
    digest = hashlib.sha256()
    for path in sorted(pathlib.Path(__file__).parent.glob('*.py')):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def evaluate_chunk(question, nominal, tolerances, unit, g=STANDARD_GRAVITY):
    """One chunk of a study: the samples of the unit-cube points ``unit`` (see
    :func:`.tolerance_sampling.sample_waypoints`) answered by ``question``.  Returns
    (figures, wall seconds, CPU seconds of this thread): the engine's unit of work."""
    t0, c0 = time.perf_counter(), time.thread_time()
    out = question.evaluate(sample_waypoints(nominal, tolerances, unit), g)
    return out, time.perf_counter() - t0, time.thread_time() - c0
