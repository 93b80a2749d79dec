"""Where the overdamped mechanism comes to rest at frozen parameters: gradient flows.

A landing (:mod:`.lander`) and a settle slide down the energy with scipy's LSODA
(stiff-capable: slow near a fold's ghost, fast elsewhere), never with a large-step
optimiser, which can cross into another basin.  Two flows where the problem has
constraints: the elastic one (``descent``, whose constraints may give a little near
a kinematic singularity, to glide through it) and the rigid one (``rigid_descent``,
the constrained model itself), which goes on through a linkage's flat crossings
along one of the half-branches out of them (:func:`through_crossing`).
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import LSODA
from scipy.optimize import minimize_scalar

from .run_state import inf_norm
from .settings import (CROSSING_APPROACH, ELASTIC_FLOW_RTOL, FAR_FROM_FLAT, JACOBIAN_EVALUATIONS,
                       MAX_CROSSING_LEGS, REST_CHECK_MARGIN, RIGID_FLOW_RTOL)
from ..numerics import bounded_work


class FlowBudgetExceeded(Exception):
    """A landing flow used up its evaluation budget (or left its leash)."""


class _Flow:
    """The velocity field a slide integrates (elastic or rigid), with its evaluation
    budget, and whether the elastic flow was damped on its way."""

    def __init__(self, run, s, rigid_first, leash=None):
        problem = run.problem
        self.s = s
        self.run, self.leash, self.start = run, leash, None
        # (not in a tracker that stops at events: its landings, at a critical point
        # reached to rounding, are never kept but where the minimum goes on; there the
        # rigid flows only cost: seed 1, stream 10 of bench_round_commands, 14 in one
        # such run, 40 s)
        self.rigid = None if run.stop_at_events else getattr(problem, 'rigid_descent', None)
        self.field = self.rigid if rigid_first and self.rigid is not None else problem.descent
        # a rigid flow gets an eighth of the budget: stalled at a flat module, where it
        # does not rest, it used it all (16 s on config/neck.yaml; 14000 evaluations the
        # most a landing took there)
        self.rigid_budget = run.settings.flow_evaluations // 8
        self.budget = self.rigid_budget if self.is_rigid else run.settings.flow_evaluations
        self.damped_at = getattr(problem, 'damped', None) if self.rigid is not None else None
        self.was_damped = False

    @property
    def is_rigid(self):
        return self.field is self.rigid

    def to_rigid(self):
        self.field = self.rigid
        self.budget = min(self.budget, self.rigid_budget)

    def velocity(self, _t, v):
        self.budget -= 1
        if self.budget < 0:
            raise FlowBudgetExceeded
        if self.leash is not None and self.run.step_norm(v - self.start) > self.leash:
            raise FlowBudgetExceeded            # it went farther than it was let
        if self.budget % 8 == 0:    # inside a solver step too: a neck's takes ~30
            bounded_work.checkpoint()    # evaluations (scipy >= 1.17's LSODA is re-entrant)
        return self.field(v, self.s)

    def jacobian(self, _t, v):
        """d(velocity)/dv from the problem (LSODA's ``jac``), charged to the budget."""
        self.budget -= JACOBIAN_EVALUATIONS
        if self.budget < 0:
            raise FlowBudgetExceeded
        problem = self.run.problem
        if self.is_rigid:
            return problem.rigid_descent_jacobian(v, self.s)
        return problem.descent_jacobian(v, self.s)

    def watch(self, solver):        # at each solver step of the elastic flow
        if not self.was_damped and self.damped_at(solver.y, self.s):
            self.was_damped = True

    def to_rest(self, run, y, tol):
        """Where this flow from ``y`` comes to rest (None where it does not)."""
        has = hasattr(run.problem, 'rigid_descent_jacobian' if self.is_rigid
                      else 'descent_jacobian')
        jac = self.jacobian if has else None
        if self.is_rigid:
            # a rigid flow near a flat module is integrated as accurately as the
            # reference's: there its way (and its rest) turns on ~1e-7 of it
            return rigid_flow_to_rest(run, self.velocity, y, self.s, tol, jac)
        return flow_to_rest(run, self.velocity, y, tol,
                            stop=None if self.damped_at is None else self.watch, jac=jac)


def slide(run, y, s, rigid_first=False, leash=None):
    """Overdamped gradient flow at fixed s until it comes to rest, then Newton polish.

    Integrated by LSODA, stopping at the first step where the velocity is negligible.
    At rest on a minimum the state is polished; at rest on a saddle it is pushed off
    along the unstable mode.  Where it rests off the constraints (the problem's
    ``descent`` may treat them as slightly elastic, to glide through kinematic
    singularities), it flowed in another model: the flow starts over from the same state
    by the problem's optional ``rigid_descent``, which rests only on equilibria of the
    model itself (``rigid_first``: from the start, as from a flat crossing's
    half-branch).  Where the flow came to rest on a minimum but was damped on the way
    (the problem's optional ``damped``: it passed a module near flat as elastic chords),
    the rigid flow from the same start decides, where it rests on one.  ``leash``: a
    flow that goes farther than this from ``y`` (weighted state norm) rests nowhere.
    """
    problem, start = run.problem, y
    flow = _Flow(run, s, rigid_first, leash)
    flow.start = y
    # Far below any velocity met on the way (near a fold's ghost the landing
    # offset keeps it above ~1e-7 scale), so the flow stops only at rest.
    tol = 1e-10 * run.scale
    for _ in range(5):
        try:
            rest = flow.to_rest(run, y, tol)
        except FlowBudgetExceeded:
            return None
        if rest is None:
            return None
        projected = problem.project(rest, s)
        if (flow.rigid is not None and not flow.is_rigid
                and run.step_norm(projected - rest) > run.settings.same_state_tol):
            flow.to_rigid()             # it rested as elastic chords: the same flow, rigid
            continue
        y = projected
        polished = run.newton(y, s)
        if polished is None or (run.step_norm(polished - y) >= 1e-2
                                and not downhill(run, y, polished, s)):
            continue
        if (run.definite(run.eigenvalues(polished, s))
                and problem.energy(polished, s) <= problem.energy(y, s) + 1e-12 * run.scale):
            return _at_rest(run, flow, start, polished, s)
        _, modes = problem.stability(polished, s)      # a saddle: push off
        y = problem.project(polished + run.step_off_vector(modes[:, 0]), s)
    return None


def _at_rest(run, flow, start, polished, s):
    """The minimum a slide from ``start`` rests on, its flow having reached
    ``polished``: the rigid flow's where the elastic one was damped on its way."""
    if flow.was_damped and not flow.is_rigid:
        rest = rigid_rest(run, start, s)
        return polished if rest is None else rest
    return None if stalled_at_linkage_limit(run, flow.is_rigid, polished, s) else polished


def rigid_rest(run, start, s):
    """The rigid flow's minimum from ``start``, where the elastic flow from there
    was damped on its way to a minimum (its chords gave where a module passed near
    flat, so it may have crossed onto a branch the rigid mechanism does not reach:
    bench_round_commands seed 0, stream 11, head load 0.5 N, a module's flat
    neighbour swung through to (pi/3, 2 pi/3), 2.2 J below where the rigid flow and
    the reference rest).  None where it rests on none (stalled at a flat module, out
    of budget): the elastic flow's minimum stands."""
    alternatives = list(run.crossing_alternatives)
    rest = slide(run, start, s, rigid_first=True)
    if rest is None:
        run.crossing_alternatives = alternatives
    return rest


def stalled_at_linkage_limit(run, rigid, y, s):
    """Whether a rigid flow's rest ``y`` is at a linkage limit (a module flat, at the
    crossing of two branches of its configurations), where it stalls: the projection
    on the constraints is undefined there, the flow goes on along one of the branches
    leaving the crossing (test/reference_paths.py takes the steepest), and the
    reduced Hessian's margin test does not apply.  (config/neck.yaml, bench_round_
    commands seed 0, stream 10, head load -> -10 N: it rested with module 0 flat,
    2e-7 rad, where the reference's flow goes on to 0.26 rad.)"""
    return bool(rigid and run.linkage_limit(y, s))


def downhill(run, a, b, s, samples=16):
    """Whether the energy falls all the way along the straight line from ``a`` to ``b``
    (projected): then Newton's ``b`` is the minimum of the valley the flow came to
    rest in, however far, not one across a ridge.  In a very soft valley (lambda_min
    ~1e-6 of the scale, a neck just past buckling) the flow comes to rest, by its
    velocity, a few 1e-2 short of the minimum."""
    problem = run.problem
    energies = [problem.energy(problem.project(a + t * (b - a), s), s)
                for t in np.linspace(0.0, 1.0, samples + 1)]
    slack = 1e-12 * (abs(energies[0]) + run.scale)
    return all(e1 <= e0 + slack for e0, e1 in zip(energies, energies[1:]))


def flow_to_rest(run, velocity, y, tol, rtol=ELASTIC_FLOW_RTOL, stop=None, jac=None):
    """Integrate dy/dt = velocity until |velocity| <= tol, or until ``stop(solver)``
    (called after each step) returns a state, which is then returned; ``None`` if
    the solver fails."""
    with np.errstate(all='ignore'):
        solver = LSODA(velocity, 0.0, y, 1e7 / run.scale, rtol=rtol, atol=1e-3 * rtol,
                       jac=jac)
        while solver.status == 'running':
            bounded_work.checkpoint()    # between solver steps (and inside: velocity)
            solver.step()
            if (speed_estimate(solver) <= REST_CHECK_MARGIN * tol
                    and inf_norm(velocity(solver.t, solver.y)) <= tol):
                return solver.y
            if stop is not None:
                stopped = stop(solver)
                if stopped is not None:
                    return stopped
    return solver.y if solver.status == 'finished' else None


def speed_estimate(solver):
    """|dy/dt| (inf-norm) at the LSODA ``solver``'s last step from its Nordsieck
    history (scipy's dense output reads the same array), free where a fresh velocity
    costs an evaluation: a third of a landing's evaluations went to checking each
    step for rest.  It is no velocity (it differs from one by up to 40 times the rest
    tolerance, where that is small), only a bound on when to evaluate one; 0 (check
    every step) where this scipy keeps no such array."""
    try:
        rwork = solver._lsoda_solver._integrator.rwork
    except AttributeError:
        return 0.0
    n = solver.n
    return inf_norm(rwork[20 + n:20 + 2 * n]) / abs(rwork[11])


def rigid_flow_to_rest(run, velocity, y, s, tol, jac=None):
    """:func:`flow_to_rest` for the rigid flow, going on through the flat crossings
    of the problem's linkage (its optional ``flatness`` and ``crossing_ways``).

    At a module's flat crossing the projected flow stalls (the projection is
    undefined there) where the mechanism goes on along one of the half-branches
    leaving it: each leg stops once the flattest module is CROSSING_APPROACH flat
    (or ten times flatter than the leg's start), and where a crossing is next to it
    the flow goes on from :func:`through_crossing`'s half-branch; else (a module
    flat at a linkage limit, no crossing) it flows on.  ``None`` where no way leads
    out; after MAX_CROSSING_LEGS legs it flows on without stopping (as before there
    was this rule: a flow creeping onto a linkage limit is not cut short).  Each leg
    at RIGID_FLOW_RTOL, but a first one from a state FAR_FROM_FLAT, at
    ELASTIC_FLOW_RTOL until a module is that flat (or at rest)."""
    flatness = getattr(run.problem, 'flatness', None)
    if flatness is None:
        return flow_to_rest(run, velocity, y, tol, RIGID_FLOW_RTOL, jac=jac)
    rtol = ELASTIC_FLOW_RTOL if flatness(y, s) >= FAR_FROM_FLAT else RIGID_FLOW_RTOL
    for _ in range(MAX_CROSSING_LEGS):
        level = min(CROSSING_APPROACH, 0.1 * flatness(y, s))
        coarse = rtol != RIGID_FLOW_RTOL        # far from flat: until FAR_FROM_FLAT
        rest = flow_to_rest(run, velocity, y, tol, rtol, jac=jac, stop=crossing_stop(
            run, y, s, flatness, FAR_FROM_FLAT if coarse else level))
        rtol = RIGID_FLOW_RTOL
        if rest is None or flatness(rest, s) >= level:
            if coarse and rest is not None:
                y = rest                        # on from there at RIGID_FLOW_RTOL
                continue
            return rest
        onward = through_crossing(run, rest, s)
        if onward is False:
            return None
        y = rest if onward is None else onward
    return flow_to_rest(run, velocity, y, tol, RIGID_FLOW_RTOL, jac=jac)


def crossing_stop(run, y, s, flatness, level):
    """The ``stop`` of a rigid flow's leg from ``y``: the first state it reaches
    ``level`` flat at, after a step or inside one.  A step over a module's flat
    crossing (both its rods turned through its base line, the problem's optional
    ``turned_through_base``) is searched on the step's dense output, as the
    reference's legs are: without, one of two mirror-image flows passed its crossing
    within a step and the other stopped at its own (the upright N = 2 paper neck's
    branch point under a head load, test_stack_formulations)."""
    turned = getattr(run.problem, 'turned_through_base', None)
    previous = [y]

    def stop(solver):
        v = solver.y
        if flatness(v, s) < level:
            return v
        if turned is not None and turned(previous[0], v, s):
            flattest = flattest_in_step(solver, s, flatness)
            if flatness(flattest, s) < level:
                return flattest
        previous[0] = v
        return None
    return stop


def flattest_in_step(solver, s, flatness, samples=32):
    """The flattest state of the solver's last step, on its dense output: sampled,
    then refined by a bounded scalar search next to the flattest sample."""
    dense = solver.dense_output()
    times = np.linspace(dense.t_old, dense.t, samples + 1)
    values = [flatness(dense(t), s) for t in times]
    k = int(np.argmin(values))
    low, high = times[max(k - 1, 0)], times[min(k + 1, samples)]
    found = minimize_scalar(lambda t: flatness(dense(t), s), bounds=(low, high),
                            method='bounded', options={'xatol': 1e-12 * abs(high - low)})
    return dense(found.x) if found.fun < values[k] else dense(times[k])


def through_crossing(run, y, s):
    """The state to flow on from, where the flow reached ``y`` next to a flat
    crossing: out along the half-branch of steepest descent (the energy drop per
    unit length from the crossing, :func:`..flat_crossing.ways_out`) among those the
    mechanism moves away on; the others are kept in ``run.crossing_alternatives``
    (a landing that passed one is ambiguous where they land elsewhere).  None if
    ``y`` is at no crossing; False if no half-branch leads away (it rests there)."""
    ways = run.problem.crossing_ways(y, s)
    if ways is None:
        return None
    if not ways:
        return False
    ways.sort(key=lambda way: way[0], reverse=True)
    run.crossing_alternatives.extend(state for _, state in ways[1:])
    return ways[0][1]
