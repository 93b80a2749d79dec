"""Linkage limits: constraints whose gradient vanishes (a neck module folded flat onto its
chord), each with its own events.

There two branches of configurations cross, so the equilibrium equations are singular
even where the state is a strict minimum: steps underflow or the branch seems to turn
back, and the landing flow stalls.  What the mechanism does there:

* the minimum goes on along one of the crossing branches (:func:`through_linkage_limit`);
* it is released off a flat crossing onto none of them: a jump
  (:func:`leave_crossing`), or at a command's end on the crossing
  (:func:`end_next_to_crossing`);
* none of these: a stated give-up on the verified state (:func:`underflow_reason`).

The problem describes its linkage with the optional ``linkage_limit``,
``crossing_ways`` and ``crossing_rounding`` (see :mod:`..flat_crossing`).
"""
from __future__ import annotations

import numpy as np

from . import ambiguity
from .flows import slide, through_crossing
from .lander import landing_at_event
from .results import BRANCH_POINT, Event, FOLD
from .run_state import inf_norm, solve
from .settings import EXACT_CROSSING_STALL, SNAP_DISTANCE
from ..numerics import bounded_work


def through_linkage_limit(run, y, s, s_end):
    """Carry the minimum across a linkage limit: (state, s, None) just past it, or
    ``None`` where the state is not at one or does not go on continuously.

    Just past it the minimum lies on one of the crossing branches, ~sqrt(offset) away:
    the nearest verified minimum found by Newton from the state moved along each state
    component and projected on the constraints.  It is the mechanism going on (no
    jump) only if it closes in on the state as the offset shrinks 100-fold (to 0.3 of
    its distance or less, as a square root does)."""
    if s >= s_end or not run.linkage_limit(y, s):
        return None
    if s_end - s < run.settings.linkage_offset:
        # the limit lies at the command's end within rounding: the closing-in test
        # below would compare two states before it (both on the branch coming in)
        ended = end_next_to_crossing(run, y, s_end)
        if ended is not None:
            return ended
    offset = min(run.settings.linkage_offset, s_end - s)
    near = nearest_minimum(run, y, s + offset)
    if near is not None:
        near = at_own_scale(run, near, s + offset)
    if near is None:
        return None
    if not _closes_in(run, y, s, near, s + 0.01 * offset):
        return None
    return near, s + offset, None


def _closes_in(run, y, s, near, s_closer):
    """Whether a minimum at s_closer lies at most 0.3 as far from y as ``near`` does:
    where the minimum goes on, it is ~0.1 as far at 0.01 of the offset (a square root);
    an equilibrium there that is not clearly unstable will do (another module may be at
    its own pitchfork at the same s, e.g. a neck of equal modules)."""
    closer = run.newton(run.problem.project(y + 0.1 * (near - y), s_closer), s_closer)
    if closer is not None and not run.eigenvalues(closer, s_closer)[0] > \
            -run.settings.definiteness_tol * run.scale:
        closer = None
    if closer is None:
        closer = nearest_minimum(run, y, s_closer)
    distance = run.separation(near, y)
    return not (closer is None
                or run.separation(closer, y) > 0.3 * distance + run.settings.same_state_tol)


def leave_crossing(run, y, s, s_end):
    """Where the minimum came onto a module's flat crossing (the problem's optional
    ``crossing_ways``) and goes on continuously along none of its half-branches: the
    mechanism released just past it slides to rest, a jump there (landing, s_land,
    branch point event), as the reference's overdamped flow does; ``None`` where
    ``y`` is at no crossing or no flow rests on a minimum a move away.  Frozen
    1e-9, 1e-7, then ``linkage_offset`` past s (where the minimum is gone, the flow
    from it moves).  (bench_round_commands seed 1, streams 1 and 7, seed 0 stream 8:
    the reference's jumps there, where the tracker gave up at a 'linkage limit'.)"""
    ways = getattr(run.problem, 'crossing_ways', None)
    if (s >= s_end or ways is None or not run.moves(y, s)
            or not run.linkage_limit(y, s)):
        return None     # (a command to the same parameters moves nothing)
    leaving = ways(y, s)
    if leaving is None:
        return None
    stalled = True
    for offset in (1e-9, 1e-7, run.settings.linkage_offset):
        s_land = min(s + offset, s_end)
        run.crossing_alternatives = []
        landing = slide(run, y, s_land, rigid_first=True)
        if landing is not None and run.separation(landing, y) > run.settings.passage_radius:
            return _off_crossing(run, y, s, landing, s_land, leaving)
        stalled = stalled and landing is None
        if s_land >= s_end:
            break
    s_land = min(s + 1e-9, s_end)
    if not stalled or run.newton(y, s_land) is not None:
        # the flow rests next to y, or an equilibrium goes on from it (the steps stopped
        # unresolved next to the flat module: seed 1 stream 12, 2.3e-6 in s before its
        # fold): no jump off the crossing here (H30, e506e01)
        return None
    return _off_the_ways_out(run, y, s, s_land, leaving)


def _off_the_ways_out(run, y, s, s_land, leaving):
    """Where the departure's own flow does not move at all and no equilibrium goes on:
    kept mirror-symmetric to the last bit (the Nehalem kernel's, bench_round_commands seed
    1 stream 1) it stalls where the rigid projection is undefined; the released mechanism
    leaves along the steepest way out (a mirror pair: either, ambiguous), as a flow that
    reaches a crossing does (H30, a7a68a7)."""
    for _, state in sorted(leaving, key=lambda way: -way[0]):
        run.crossing_alternatives = []
        landing = slide(run, state, s_land, rigid_first=True)
        if landing is not None and run.separation(landing, y) > run.settings.passage_radius:
            return _off_crossing(run, y, s, landing, s_land, leaving)
    return None


def _off_crossing(run, y, s, landing, s_land, leaving):
    """The jump off the crossing at (y, s) onto ``landing``: (landing, s_land, branch
    point event).  Which half-branch the released mechanism takes turns on the
    departure's last 1e-7 rad (seed 0 stream 8: the reference's departure, 6e-9 rad from
    flat, took the other): ambiguous where another one lands elsewhere."""
    others = run.crossing_alternatives + [state for _, state in leaving]
    ambiguous = (ambiguity.lands_elsewhere(run, others, landing, s_land)
                 or ambiguity.mirror_lands_too(run, y, landing, s_land))
    at_event, s_at = landing_at_event(run, landing, s_land, s)
    return landing, s_land, Event(kind=BRANCH_POINT, s=s, state=y, landing_s=s_at,
                                  landing=at_event, ambiguous=ambiguous)


def end_next_to_crossing(run, y, s_end):
    """The command's end where the branch coming in (``y``, within ``linkage_offset``
    of s_end) ends next to a module's flat crossing: (minimum, s_end, None) where a
    verified minimum off the crossing ends it (no jump), (landing, s_end, fold event)
    where the state at s_end is at the crossing and the mechanism snaps from it, or
    ``None`` where neither is shown (the closing-in test decides).

    Which it is, Newton at s_end from ``y`` tells (:func:`newton_next_to_crossing`):
    the branch approaches the crossing like the square root of the distance in s, and
    at s_end it either reaches it to rounding (the command ends where rho(i) +
    rho(i+1) = L1 + L2 to within the chord's rounding) or stops short of it, on a
    minimum the chord still resolves (bench_round_commands seed 0, stream 8's
    joint_commands {0: 0.13, 1: 0.12, 2: 0.15}: the sum 5.6e-16 m short, the minimum
    7.8e-8 rad from the crossing, 8 rounding radii, lambda_min 100; snapping there
    reported a jump of 0.08 rad the reference does not make)."""
    found = newton_next_to_crossing(run, y, s_end)
    if found is None:
        return None
    where, state = found
    if where == 'off':
        return state, s_end, None
    return snap_at_end_crossing(run, y, s_end)


def _next_to_crossing(run, start, y, s, delta, f, moving, jacobian):
    """What one Newton iterate ``y`` (after update ``delta``) next to a crossing says:
    ('at', y), ('off', y), 'stop' (None is the answer) or None (iterate on)."""
    found = run.problem.crossing_rounding(y, s)
    if found is None:
        return 'stop'
    distance, radius, exact = found
    stalled = inf_norm(delta[moving]) <= radius
    if exact and (distance <= radius
                  or (stalled and distance <= EXACT_CROSSING_STALL * radius)):
        return 'at', y
    if distance <= radius or not stalled:
        # still moving, or within the radius of a crossing that is not exact:
        # Newton passing on its way (the crossing's arms lie apart, see rounding)
        return None
    if exact:
        # stalled farther from an exact crossing: not a minimum the chord resolves
        # off it (the arms touch there); the closing-in test decides
        return 'stop'
    tol = run.settings.residual_tol * run.scale
    slack = float(np.linalg.norm(jacobian[np.ix_(moving, moving)], 2)) * radius
    if (inf_norm(f) <= tol + slack and run.separation(y, start) <= SNAP_DISTANCE
            and run.definite(run.eigenvalues(y, s))):
        return 'off', y
    return 'stop'


def newton_next_to_crossing(run, y, s):
    """Where Newton at s from ``y`` goes next to a module's flat crossing (the
    problem's optional ``crossing_rounding(y, s)``: (distance, rounding radius,
    exact)): ('at', state) where an iterate comes within the rounding radius of an
    exact crossing or stalls within EXACT_CROSSING_STALL radii of it, ('off', minimum)
    where the updates of the moving components stall below that radius outside a
    crossing that is not exact, on a verified minimum within SNAP_DISTANCE of ``y``,
    else ``None``.

    Next to a crossing the chord's gradient is ~|H| distance, so Newton's steps there
    are fixed only to the chord's rounding over it: they stall at that radius, and the
    residual stays up to |W| times it.  Approaching the crossing itself, whose solution
    Newton converges to only linearly, the iterates halve their distance to it until
    they are within the radius (bench_round_commands seed 0, streams 6 and 8).  An
    iterate within the radius of a crossing that is not exact is only passing (stream
    8b's crossing misses by 5.9e-16 m, and its minimum lies 8 radii out)."""
    if getattr(run.problem, 'crossing_rounding', None) is None:
        return None
    problem, start = run.problem, y
    moving = (np.ones(problem.size, dtype=bool) if run.weights is None
              else run.weights > 0.0)
    f = problem.residual(y, s)
    for _ in range(run.settings.newton_iterations):
        try:
            jacobian = problem.jacobian(y, s)
            delta = solve(jacobian, f)
        except np.linalg.LinAlgError:
            return None
        if not np.all(np.isfinite(delta)):
            return None
        y = y - delta
        f = problem.residual(y, s)
        said = _next_to_crossing(run, start, y, s, delta, f, moving, jacobian)
        if said == 'stop':
            return None
        if said is not None:
            return said
    return None


def snap_at_end_crossing(run, y, s_end):
    """The jump at the command's end where the branch coming in ends on a module's
    flat crossing there (to rounding: :func:`end_next_to_crossing`): (landing, s_end,
    fold event), or ``None`` where no half-branch leads down from it, or the mechanism
    comes to rest within SNAP_DISTANCE of it (it goes on continuously).

    The branch approaches the crossing like the square root of the distance in s
    (config/neck.yaml, bench_round_commands seed 0, stream 6: 4.3e-7 rad at 1e-12
    short of s = 1).  At the crossing two half-branches lead down, and the mechanism
    released there comes to rest 0.015 rad away, 4e-4 J lower: a finite move at fixed s
    with an energy release, a jump.  It lands as a landing flow through a crossing
    does: along the steepest half-branch, ambiguous where another lands elsewhere."""
    problem = run.problem
    if getattr(problem, 'crossing_ways', None) is None:
        return None
    at_end = problem.project(y, s_end)
    run.crossing_alternatives = []
    ways = problem.crossing_ways(at_end, s_end)
    if not ways or max(rate for rate, _ in ways) <= 0.0:
        return None
    onward = through_crossing(run, at_end, s_end)
    alternatives = list(run.crossing_alternatives)
    landing = slide(run, onward, s_end, rigid_first=True)
    if (landing is None or run.separation(landing, at_end) <= SNAP_DISTANCE
            or problem.energy(landing, s_end) >= problem.energy(at_end, s_end)):
        return None
    ambiguous = ambiguity.lands_elsewhere(run, alternatives, landing, s_end)
    return landing, s_end, Event(kind=FOLD, s=s_end, state=at_end, landing_s=s_end,
                                 landing=landing, ambiguous=ambiguous)


def at_own_scale(run, y, s):
    """A minimum found at this run's stiffness scale, polished by Newton and verified
    at its own (the scale :meth:`.run_state.RunState.rescale` sets once the run is
    there), or ``None``.

    At a linkage limit the scale is inflated by the chord force (lambda_max 4.4e10 N/m
    at config/neck.yaml's module 0 flat with no load, 7.3e3 N/m 1e-6 in s past it), and
    so is the residual tolerance: Newton stopped there on a state 0.14 N from
    equilibrium, 9e-5 rad off the minimum, from which every step was 'far'."""
    kept = run.scale
    run.rescale(run.eigenvalues(y, s))
    try:
        polished = run.newton(y, s)
        if polished is None or not run.definite(run.eigenvalues(polished, s)):
            return None
        return polished
    finally:
        run.scale = kept


def _search_directions(run):
    """Each weighted state component alone, then seeded random mixtures (several
    constraints at their limits at once need a combined move), each of unit step norm."""
    problem = run.problem
    weights = np.ones(problem.size) if run.weights is None else run.weights
    moving = np.flatnonzero(weights)
    directions = np.zeros((len(moving), problem.size))
    directions[np.arange(len(moving)), moving] = 1.0 / weights[moving]
    mixed = np.random.default_rng(0).standard_normal((2 * len(moving), len(moving)))
    mixtures = np.zeros((len(mixed), problem.size))
    mixtures[:, moving] = mixed / weights[moving]
    return [d / run.step_norm(d) for d in np.vstack([directions, mixtures])]


def nearest_minimum(run, y, s):
    """The verified minimum at s nearest to ``y`` among those Newton reaches from y
    moved by 1e-5 .. 1e-1 (step norm) along each weighted state component, both
    ways, and projected; ties go to the lower energy.  ``None`` if there is none."""
    problem, best = run.problem, None
    for direction in _search_directions(run):
        for amplitude in (1e-5, 1e-4, 1e-3, 1e-2, 1e-1):
            for sign in (1.0, -1.0):
                bounded_work.checkpoint()
                moved = y + sign * amplitude * direction
                try:
                    found = run.newton(problem.project(moved, s), s)
                except np.linalg.LinAlgError:
                    continue
                if found is None or not run.definite(run.eigenvalues(found, s)):
                    continue
                key = (round(run.separation(found, y), 9), problem.energy(found, s))
                if best is None or key < best[0]:
                    best = key, found
    return None if best is None else best[1]


def underflow_reason(run, y, s, reason):
    """Why the steps underflowed: a linkage limit the minimum does not cross
    continuously (the rigid-chord model does not say where the mechanism goes: its
    chord force grows without bound), or the failed step's reason."""
    limit = run.linkage_limit(y, s)
    if limit:
        return (f'linkage limit at s={float(s)!r}: {limit}; no minimum goes on continuously '
                f'past it, and the rigid-chord model does not say where the mechanism goes')
    return f'step size underflow at s={float(s)!r} ({reason})'
