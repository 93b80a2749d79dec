"""What a tolerance study asks of each sampled module or neck, and its answer as numbers.

A question evaluates a chunk of samples: ``waypoints``, an array (m, K, N, 12) of
parameter vectors (``PARAMETER_NAMES`` order) of N modules at K points of a command
schedule (K = 1 for the operating range), and returns one float array (m,) per figure
(0/1 for yes/no, NaN where a figure does not apply).  Samples are independent: a
sample's answer never depends on the other rows of its chunk, so a chunked run gives
the same numbers however the chunks are scheduled.

* :class:`OperatingRange` (one module): the stable rho interval through the working
  point, as :func:`.analysis.operation_range.operation_range` (``tensegrity range``), and the
  number of stable equilibria at a given rho (bistable or not).
* :class:`PlannedPath` (a module or a neck): the command schedule, leg by leg, as
  ``tensegrity track``: does it jump, where, where does it land, where does it end.
* :class:`HeadLoad` (a neck or a module): a growing head load; the load at which the
  stack first jumps (buckles and snaps), as ``tensegrity track --config ... --to-F``.

The one-module questions solve the generic samples vectorised (:mod:`.tolerance.branch_batch`)
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

from . import batch as tb, branch_batch as bb
from .sampling import sample_waypoints
from ..analysis.operation_range import operation_range
from ..continuation import TrackerSettings
from ..module.model import InvalidParameterError, ModuleParams, PARAMETER_NAMES, STANDARD_GRAVITY
from ..module.polynomial_solver import equilibria
from ..module.tracking import track_module
from ..neck.stack import Stack, track_stack
from ..numerics import numba_kernels
from ..simulation.start_state import start_state

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
        """Generic rows vectorised (:mod:`.tolerance.branch_batch`), delicate ones by
        evaluate_one."""
        out = _empty(self.FIGURES, len(rows))
        e_rho = np.zeros_like(rows)
        e_rho[:, 0] = 1.0
        scalar = ~tb.valid_rows(rows) | bb.symmetric_rows(rows, e_rho, g)
        gen = np.nonzero(~scalar)[0]
        base = rows[gen].copy()
        base[:, 0] = 0.0                        # the path rho = s, everything else fixed
        fam = bb.PathFamily(base, e_rho[gen], g)
        t1, t2, count, good = tb.polished_start(fam, rows[gen], rows[gen, 0], g, self.guess)
        scalar[gen[~good]] = True
        idx = np.nonzero(good)[0]
        ends = self._ends(fam, idx, rows[gen[idx]], _wrap(t1[idx]), _wrap(t2[idx]))
        ok = ends[-1]
        scalar[gen[idx[~ok]]] = True
        self._fill(out, rows, gen[idx[ok]], [e[ok] for e in ends[:-1]],
                   _wrap(t1[idx[ok]]), _wrap(t2[idx[ok]]), count[idx[ok]], g)
        for i in np.nonzero(scalar)[0]:
            self.evaluate_one(rows[i], g, out, i)
        return out

    def _ends(self, fam, idx, rows, t1, t2):
        """Both ends of each row's branch: (rho_min, rho_max, lower kind, upper kind, ok);
        not ok where the follower found the row delicate or an end is a branch point."""
        n = len(idx)
        L = rows[:, 1] + rows[:, 2]
        if self.rho_bounds is None:
            lo_b, hi_b = np.zeros(n), 2.0 * L
        else:
            lo_b, hi_b = (np.full(n, float(b)) for b in self.rho_bounds)
        both = np.concatenate([idx, idx])
        end_s, e1, e2, kind, delicate = bb.follow(
            fam, both, np.concatenate([t1, t1]), np.concatenate([t2, t2]),
            np.concatenate([rows[:, 0], rows[:, 0]]), np.repeat([-1.0, 1.0], n),
            np.concatenate([lo_b, hi_b]), np.concatenate([L, L]), True, False)
        fold = np.nonzero(kind == bb.FOLD)[0]
        branch = bb.fold_is_branch_point(fam, both[fold], e1[fold], e2[fold], end_s[fold])
        delicate[fold[branch]] = True
        return end_s[:n], end_s[n:], kind[:n], kind[n:], ~(delicate[:n] | delicate[n:])

    def _fill(self, out, rows, which, ends, t1, t2, count, g):
        """The figures of the vectorised rows ``which``."""
        lower, upper, lower_kind, upper_kind = ends
        rho = rows[which, 0]
        out['status'][which], out['scalar'][which] = OK, 0.0
        out['rho_min'][which], out['rho_max'][which] = lower, upper
        out['width'][which] = upper - lower
        out['margin_below'][which], out['margin_above'][which] = rho - lower, upper - rho
        out['lower_kind'][which], out['upper_kind'][which] = lower_kind, upper_kind
        out['jumps_below'][which] = (lower_kind == bb.FOLD).astype(float)
        out['jumps_above'][which] = (upper_kind == bb.FOLD).astype(float)
        out['start_theta1'][which], out['start_theta2'][which] = t1, t2
        if self.at_rho is not None:
            at = rows[which].copy()
            at[:, 0] = self.at_rho
            count = bb.stable_equilibria(at, g)[1].sum(axis=1)
        out['num_stable'][which] = count
        out['bistable'][which] = (count == 2).astype(float)

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
        """One module, generic rows vectorised leg by leg (:class:`.tolerance_batch.
        ScheduleFollower`: a fold ends the branch, the module lands on the one other
        stable equilibrium there); delicate rows by evaluate_one."""
        m, k_stops = waypoints.shape[:2]
        out = _empty(self.figures(), m)
        stops = waypoints[:, :, 0, :]
        scalar = np.zeros(m, bool)
        for k in range(k_stops):
            scalar |= ~tb.valid_rows(stops[:, k])
        for k in range(k_stops - 1):
            scalar |= bb.symmetric_rows(stops[:, k], stops[:, k + 1] - stops[:, k], g)
        gen = np.nonzero(~scalar)[0]
        fam = bb.PathFamily(stops[gen, 0], stops[gen, 1] - stops[gen, 0], g)
        guess = None if self.guess is None else self.guess[0]
        t1, t2, _, good = tb.polished_start(fam, stops[gen, 0], np.zeros(len(gen)), g, guess)
        scalar[gen[~good]] = True
        gen = gen[good]
        run = tb.ScheduleFollower(stops[gen], t1[good], t2[good], g).run()
        scalar[gen[run.failed]] = True
        self._fill(out, gen[~run.failed], run, ~run.failed)
        for i in np.nonzero(scalar)[0]:
            self.evaluate_one(waypoints[i], g, out, i)
        return out

    def _fill(self, out, rows, run, keep):
        """The figures of the vectorised rows ``rows`` (``keep`` of the follower's)."""
        out['status'][rows], out['scalar'][rows] = OK, 0.0
        out['jumped'][rows] = (run.jumps[keep] > 0).astype(float)
        out['jumps'][rows] = run.jumps[keep]
        out['final_theta1'][rows] = _wrap(run.t1[keep])
        out['final_theta2'][rows] = _wrap(run.t2[keep])
        hit = run.first[keep] >= 0
        rows, keep = rows[hit], np.nonzero(keep)[0][hit]
        out['jump_leg'][rows], out['jump_s'][rows] = run.first[keep], run.first_s[keep]
        out['jump_s_total'][rows] = run.first[keep] + run.first_s[keep]
        out['jump_kind'][rows] = KIND_CODES['fold']
        out['jump_rho'][rows] = run.first_p[keep, 0]
        out['jump_F3'][rows] = run.first_p[keep, PARAMETER_NAMES.index('f3y')]
        out['jump_F4'][rows] = run.first_p[keep, PARAMETER_NAMES.index('f4y')]
        out['landing_theta1'][rows] = run.landing[keep, 0]
        out['landing_theta2'][rows] = run.landing[keep, 1]

    def evaluate_one(self, sample, g, out, i):
        """The scalar reference for sample ``i`` (``tensegrity track``, leg by leg)."""
        out['scalar'][i] = 1.0
        try:
            stops = [modules_of(v, g) for v in sample]
        except InvalidParameterError:
            out['status'][i] = INVALID
            return
        try:
            state = start_state(stops[0], None if self.guess is None else self.guess, NECK)
        except (ValueError, RuntimeError):
            out['status'][i] = NO_START
            return
        jumps, certificate = [], ''
        for leg, (a, b) in enumerate(zip(stops, stops[1:])):
            if len(a) == 1:
                track = track_module(a[0], b[0], state.theta, certificate=certificate)
                certificate = track.certificate
            else:
                track = track_stack(Stack(a), Stack(b), state, NECK)
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


#: A neck sample's tracks (and its start settle) run the compiled gradient flows
#: (:mod:`.neck.flow_kernel`: the same equations to rounding, a third of a head-load
#: sample's time where numpy's ran two thirds of it).
NECK = TrackerSettings(compiled_flows=True)
#: The head-load question needs only where stability is first lost: its tracks end at
#: their first jump (the same event as the full track's, test_tolerance_references).
FIRST_EVENT = TrackerSettings(stop_at_first_event=True, compiled_flows=True)


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
            state = start_state(a, None if self.guess is None else self.guess, FIRST_EVENT)
        except (ValueError, RuntimeError):
            out['status'][i] = NO_START
            return
        if len(a) == 1:
            track = track_module(a[0], b[0], state.theta, FIRST_EVENT)
            tops = [j.params for j in track.jumps]
            passed = [_path_s(a[0], b[0], p) for p in track.passages]
        else:
            track = track_stack(Stack(a), Stack(b), state, FIRST_EVENT)
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
    """A digest of the core's source and of the neck flows' engine (numba's version, or
    numpy): the code every sample's answer comes from.  A cluster's workers must run the
    same (else the same seed could answer differently)."""
    digest = hashlib.sha256(numba_kernels.engine().encode())
    core = pathlib.Path(__file__).parent
    for path in sorted(core.rglob('*.py')):                 # core/continuation/ too
        digest.update(path.relative_to(core).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def evaluate_chunk(question, nominal, tolerances, unit, g=STANDARD_GRAVITY):
    """One chunk of a study: the samples of the unit-cube points ``unit`` (see
    :func:`.tolerance.sampling.sample_waypoints`) answered by ``question``.  Returns
    (figures, wall seconds, CPU seconds of this thread): the engine's unit of work."""
    t0, c0 = time.perf_counter(), time.thread_time()
    out = question.evaluate(sample_waypoints(nominal, tolerances, unit), g)
    return out, time.perf_counter() - t0, time.thread_time() - c0
