"""Where a lost minimum goes: the landing after a located critical point.

The parameters are frozen just past the event; the mechanism steps off along the
critical mode (both sides at a branch point, the lower one at a fold) and slides down
(:mod:`.flows`).  A jump is reported only where the landing is a finite move: where
the landing closes in on the departure as the freezing offset shrinks, the minimum
simply goes on (:func:`continuous`), so no event can land on its own departure.
A supercritical branch point is no jump at all (:mod:`.branch_switching`).
"""
from __future__ import annotations

from typing import NamedTuple

from . import ambiguity, indicators
from .branch_switching import at_the_critical_point, follow_buckled
from .flows import slide
from .normal_form import branch_law, goes_through, is_fold, TURNS_BACK, undecided_below
from .problem import admissible
from .results import Event, FOLD, TrackingError, Undecided
from .run_state import inf_norm


def land(run, kind, s_star, y_star, s_end, reach=1e-3):
    """Where the mechanism goes after the critical point: (state, s, event or None).

    If "just past" lies beyond the end of the command, the landed state is followed
    back along its own branch to the end point.  A fold the branch's law certifies
    (:mod:`.normal_form`) is a jump wherever it lands.  Elsewhere, tried at a fold
    too, the buckled branch: its branch turns back at s*, so no state along its mode lies past s*
    there; where one does, the point was a branch point whose fold test |psi . F_s| is
    ill-conditioned (next to a linkage limit a chord's multiplier amplifies a 1e-5
    asymmetry of the mode ~1e6-fold: 4.9e-6 .. 2.6e-3 against branch_tol 1e-6 at
    config/neck.yaml's mirror-symmetric pitchforks 1e-4 in s before a module folds
    flat; true folds there: >= 4.5e-2)."""
    law = branch_law(run, s_star, y_star, run.critical(y_star, s_star)[1])
    fold = law.law == TURNS_BACK and is_fold(run, s_star, y_star, law)
    release = None
    through = None if fold else goes_through(run, s_star, y_star, law, s_end)
    if through is not None:                 # the branch crosses s* and stays stable
        return (*through, None)
    if not fold:                            # (a fold is a jump, however close it lands)
        passed = len(run.passages)
        buckled = follow_buckled(run, s_star, y_star, s_end)
        if buckled is not None:             # supercritical: no jump, the state goes on
            if len(run.passages) > passed:
                undecided(run, s_star, y_star, law)
            return buckled
        release = released(run, s_star, y_star, s_end)
        if release is not None and release.goes_on:
            return release.rest, release.s, None
    s_land = s_star + landing_offset(run, kind, y_star, s_star)
    if s_land > s_end and not admissible(run.problem, s_land):
        s_land = s_end
    landing, ambiguous, s_land = landing_state(run, kind, s_star, y_star, s_land, s_end, reach)
    event = kind if fold or not continuous(run, kind, s_star, y_star, s_land, landing,
                                           release) else None
    ambiguous = ambiguous or ambiguity.mirror_lands_too(run, y_star, landing, s_land)
    if s_land > s_end:
        back = run.sub_run(s_land, s_end).run(landing)
        if back.status != 'ok' or back.events:
            raise TrackingError(f'the landing after the {kind} at s={float(s_star)!r} does '
                                f'not persist to the end of the command'
                                + at_the_critical_point(s_star, s_end))
        landing, s_land, run.certificate = back.state, s_end, back.certificate
    if event is None:
        return landing, s_land, None
    at_event, s_at = landing_at_event(run, landing, s_land, s_star)
    if (not fold and s_at == s_star
            and run.separation(at_event, y_star) <= run.settings.passage_radius):
        # the landing minimum, followed back to s*, is the departure: one branch of
        # minima runs through the critical point, no jump (the N = 10 paper neck with
        # a 1e-9 asymmetry under a head load: lambda_min dips to 4e-11 of lambda_max on
        # its sharply turning branch, below critical_tol, where the tracker located a
        # 'fold' whose landing led back to 5.5e-8 of it)
        return landing, s_land, None
    return landing, s_land, Event(kind=kind, s=s_star, state=y_star, landing_s=s_at,
                                  landing=at_event, ambiguous=ambiguous)


def undecided(run, s_star, y_star, law):
    """List the passage at (s*, y*) as :class:`Undecided` where its ``ahead`` law held
    down to where doubles resolve it (:func:`.normal_form.undecided_below`): which side
    the state took is then the tracker's rule, not the model's."""
    below = undecided_below(law, s_star)
    if below is not None:
        run.undecided.append(Undecided(s_star, y_star, *below))


#: Where the mechanism released at a critical state is let come to rest (in s past it)
#: to see whether it stays next to it (:func:`released`): a pair, and the
#: next decade out where the nearer offset's rest is lost in the critical state's error.
RELEASE_OFFSETS = (1e-8, 1e-6, 1e-4)
#: A released flow that goes farther than this many step bounds rests nowhere near (the
#: N = 7 neck's went 0.099 out before it came to rest 8.5e-3 from its departure).
RELEASE_LEASH = 4.0
#: Rests this many times farther at an offset 100 times farther: a branch going on (a
#: square root gives 10, a line 100; a jump lands as far at both).
RELEASE_RATIO = 3.0


class Release(NamedTuple):
    """What the mechanism released at a critical state did (:func:`released`): where it
    rests at the farther offset, and whether the branch goes on (closer at the closer)."""

    rest: object
    s: float
    goes_on: bool


def released(run, s_star, y_star, s_end):
    """Where the mechanism released at the critical state, the parameters frozen 1e-8
    and 1e-6 past it, comes to rest (:class:`Release`; None where not next to it, within
    one step bound, at both).  Closer at the closer offset (as a square root, or a line:
    the rests' distances at least 3 times apart), a branch of minima goes on through the
    critical point, no jump (``goes_on``); as far at both, a jump lands there.  The
    critical point is then a degenerate point of the branch, not its end: a module
    passing close to its flat crossing (a random N = 7 neck, all actuators, the
    overdamped flow resting 1.1e-4, 3.5e-4, 1.1e-3 rad from the departure at 1e-8 ..
    1e-6 past by the reference's own model, where a step-off of 1e-2 along the critical
    mode slid 0.02 rad onto the crossing's other arm, a 'fold').

    Where the rests at 1e-8 and 1e-6 are not 3 times apart but the nearer is within
    ``passage_radius`` (the resolution of a state next to a critical point), the pair
    1e-6 and 1e-4 decides: the located critical state may be off along its soft mode by
    as much as the nearer rest's distance (a neck landed from a fold onto a module 0.037
    from flat, Sandybridge kernel: rests 9.3e-6 and 1.2e-5 from y*, whose own error is
    ~1e-5)."""
    offsets = [offset for offset in RELEASE_OFFSETS if s_star + offset <= s_end]
    if len(offsets) < 2:
        return None
    leash = RELEASE_LEASH * run.settings.max_state_step
    # (a flow that goes far: no rest near; its way out from the departure overshoots the
    # rest by up to ~12 times.)  The farther offset first: past a fold, where no rest is
    # near, its flow leaves the fold's ghost ~10 times sooner (the passage time goes as
    # 1 / sqrt(the offset)), and the nearer one is then not needed (the same answer)
    far = s_star + offsets[1]
    rest_far, far_by = _rest_nearby(run, y_star, far, leash)
    if rest_far is None:
        return None
    rest_near, near_by = _rest_nearby(run, y_star, s_star + offsets[0], leash)
    if rest_near is None:
        return None
    if far_by >= RELEASE_RATIO * near_by:
        return Release(rest_far, far, True)
    if len(offsets) < 3 or near_by > run.settings.passage_radius:
        return Release(rest_far, far, False)    # (a move y*'s own error cannot make)
    _, farther_by = _rest_nearby(run, y_star, s_star + offsets[2], leash)
    return Release(rest_far, far, farther_by is not None and farther_by >= RELEASE_RATIO * far_by)


def _rest_nearby(run, y_star, s, leash):
    """(rest, its distance from y_star) of the flow released at y_star frozen at s, where
    it rests within one step bound of it; (None, None) elsewhere."""
    rest = slide(run, y_star, s, leash=leash)
    if rest is None:
        return None, None
    distance = run.separation(rest, y_star)
    if not distance < run.settings.max_state_step:
        return None, None
    return rest, distance


def landing_offset(run, kind, y_star, s_star):
    """How far past the event (in s) the parameters are frozen for landing.

    Fold: far enough that the overdamped flow feels a residual (a short
    command has a small F_s).  Branch point: far enough that a new minimum
    next to the critical point (a supercritical pitchfork: the mechanism
    buckles smoothly) has a resolvable stiffness, ~1e-4 of the scale.
    """
    cfg = run.settings
    if kind == FOLD:
        fs = inf_norm(run.problem.residual_s(y_star, s_star))
        needed = 1e-7 * run.scale / fs if fs > 0 else 0.0
        return max(cfg.landing_offset, min(needed, 1e-3))
    # d lambda_min / ds measured on the approach (the branch is regular up to s*).
    rate = abs(run.last_rate) if run.last_rate else 0.0
    needed = 1e-4 * run.scale / rate if rate > 0 else 1e-3
    return max(cfg.landing_offset, min(needed, 1e-3))


def landing_state(run, kind, s_star, y_star, s_land, s_end=None, reach=1e-3):
    """Step off along the critical mode at frozen s_land and slide: (landing, ambiguous, s_land).

    With ``s_end`` given, a flow that finds no minimum (it rests on saddles near
    the fold's ghost) is retried frozen further past the event, up to ``reach`` in s
    (compared as the s it was set to: (s* + 1e-3) - s* may round below 1e-3, and
    the retries then never ended, e.g. s* = 0.999638580089214).
    """
    last = s_star + max(reach, 1e-3)
    while True:
        try:
            return (*land_once(run, kind, s_star, y_star, s_land), s_land)
        except TrackingError:
            further = s_star + 100.0 * (s_land - s_star)
            if s_end is None or s_land >= last or (
                    further > s_end and not admissible(run.problem, further)):
                raise
            s_land = min(further, last)


def _step_offs(run, s_star, y_star, s_land):
    """The states a step off the critical state along its mode reaches, each side,
    projected, lowest energy first: [(energy, sign, state)]."""
    problem = run.problem
    _, psi = run.critical(y_star, s_star)
    sides = []
    on_constraints = getattr(problem, 'on_constraints', lambda *_: True)
    for sign in (1.0, -1.0):
        start = problem.project(y_star + sign * run.step_off_vector(psi), s_land)
        if not on_constraints(start, s_land):
            # no admissible state next to the step-off (past a linkage limit): a
            # flow from it would start in no configuration of the mechanism
            continue
        sides.append((problem.energy(start, s_land), sign, start))
    sides.sort(key=lambda t: t[0])
    return sides


def land_once(run, kind, s_star, y_star, s_land):
    """(landing, ambiguous) from the critical state frozen at s_land: the lower side
    at a fold, both at a branch point (ambiguous where they land apart)."""
    problem = run.problem
    sides = _step_offs(run, s_star, y_star, s_land)
    if kind == FOLD:
        sides = sides[:1]
    landings, alternatives = [], []
    for _, _, start in sides:
        run.crossing_alternatives = []
        landing = slide(run, start, s_land)
        if landing is not None:
            landings.append(landing)
            alternatives += run.crossing_alternatives
    if not landings:
        raise TrackingError(f'could not land after the {kind} at s={float(s_star)!r}')
    landings.sort(key=lambda y: problem.energy(y, s_land))
    ambiguous = (len(landings) == 2
                 and run.separation(landings[0], landings[1]) > 1e-6)
    return landings[0], ambiguous or ambiguity.lands_elsewhere(run, alternatives, landings[0],
                                                               s_land)


def landing_at_event(run, landing, s_land, s_star):
    """The landing's stable equilibrium at the event's own s: (state, s).

    The mechanism lands with the parameters frozen a little past s* (up to 1e-3
    in s), so the landed minimum is followed back to s*, so that a reported jump
    goes from and to equilibria at one parameter value: by one Newton step where
    the landing hardly moves, else by tracking it back (a soft landing valley, e.g.
    a neck of k = 10 N/m, moves its minimum by up to 0.8 rad over that offset).
    Tracking goes on from the frozen landing.  Only where the landing minimum does
    not persist back to s* is it reported elsewhere, and the jump says so
    (``Event.landing_s != Event.s``): where it is born past s* (or times out on the
    way back), at the s nearest s* it was followed to (a minimum born at s* itself,
    degenerate there: bench_round_commands seed 0, stream 11, head load 0.5 N,
    1e-15 in s short of it); where it buckles on the way, at its own s_land."""
    back = run.newton(landing, s_star)
    if (back is not None and run.separation(back, landing) < run.settings.max_state_step
            and run.definite(run.eigenvalues(back, s_star))):
        return back, s_star
    follower = run.sub_run(s_land, s_star)
    follower.state.stop_at_events = True      # a critical point on the way: not that minimum
    followed = follower.run(landing)
    if followed.events or followed.passages:
        return landing, s_land
    if followed.status != 'ok':         # verified as near s* as it was followed
        return followed.state, s_land + followed.s * (s_star - s_land)
    polished = run.newton(followed.state, s_star)     # the segment ends at s* to rounding
    if (polished is not None
            and run.separation(polished, followed.state) <= run.settings.same_state_tol
            and run.definite(run.eigenvalues(polished, s_star))):
        return polished, s_star
    return followed.state, s_star


def _onward_decides(run, y_star, s_land, landing, distance):
    """What Newton from the departure at s_land says: False where the tracked state
    goes on past s* unstable (it buckled: a jump), True where it is the landing within
    the passage radius (one regular branch through both), else None."""
    cfg = run.settings
    onward = run.newton(y_star, s_land)
    if onward is not None and run.separation(onward, landing) > cfg.same_state_tol:
        if not run.definite(run.eigenvalues(onward, s_land)):
            return False
    elif onward is not None and distance <= cfg.passage_radius:
        return True             # a pitchfork run backwards
    return None


def continuous(run, kind, s_star, y_star, s_land, landing, release=None):
    """Whether the landing is the tracked minimum going on rather than a jump.

    It is when the landing is the departure itself (rounding level), or when
    the tracked branch does not go on past s* as an unstable equilibrium (as it
    does where a minimum buckles) and the landing closes in on the departure
    as the offset shrinks (a jump lands a finite distance away however close
    to s* it is frozen).  So a jump that lands on its own start cannot be made.
    """
    cfg = run.settings
    distance = run.separation(landing, y_star)
    if distance <= cfg.same_state_tol:
        return True
    if minimum_closes_in(run, s_star, y_star, s_land, landing):
        return True
    if distance >= cfg.max_state_step:
        return False
    onward = _onward_decides(run, y_star, s_land, landing, distance)
    if onward is not None:
        return onward
    if release is not None and run.separation(release.rest, landing) <= 0.3 * distance:
        # the mechanism released at the critical state itself rests by the landing, as
        # far at 1e-8 as at 1e-6 past it: the landing does not close in (the closer
        # landing below measures the same; seed 1 path 29 of bench_neck_paths, a 0.0087
        # rad snap at a fold next to a linkage limit: one rigid flow, ~50 ms, saved)
        return False
    try:
        closer, _, _ = landing_state(run, kind, s_star, y_star, s_star + 0.01 * (s_land - s_star))
    except TrackingError:
        # not shown to close in: a landing farther than the critical state is known
        # stands; one within it is no move the tracker can tell from the departure
        # (bench_round_commands seed 0 stream 13, a buckled neck back onto its
        # symmetric branch: landed 3.1e-5 away, Newton from the departure and the
        # closer landing, 1e-8 in s past the pitchfork, both failing; a 'jump' the
        # reference does not make, from a start 2e-15 off one that gave none)
        return distance <= cfg.passage_radius
    if distance <= cfg.passage_radius:          # the same point, as well as it is known
        return run.separation(closer, landing) <= cfg.passage_radius
    return run.separation(closer, y_star) <= 0.3 * distance + cfg.same_state_tol


def minimum_closes_in(run, s_star, y_star, s_land, landing):
    """Whether a verified minimum 100 times closer to s* lies between the departure
    and the landing, at most 0.3 as far from the departure: Newton from the point
    0.1 (a square root's law) or 0.01 (a line's) of the way to the landing.  Then
    one branch of minima runs through the critical point onto the landing.
    (config/neck.yaml, a buckled neck running back onto its symmetric branch 2.3e-4
    in s past a module's flat point, where that branch moves like sqrt(s - s_flat):
    the landing lay 0.017 rad away, Newton from the departure itself does not
    converge and the slide at the closer s did not rest, so a jump was reported that
    the reference does not make.)  Past a fold no equilibrium is near the departure,
    and past a subcritical branch point the branch through it is unstable; and the
    minimum found is followed onto the landing, so the two are one branch."""
    if run.following_onto_landing:
        return False
    s_closer = s_star + 0.01 * (s_land - s_star)
    distance = run.separation(landing, y_star)
    for fraction in (0.1, 0.01):
        closer = run.newton(y_star + fraction * (landing - y_star), s_closer)
        if (closer is not None
                and run.separation(closer, y_star) <= 0.3 * distance
                and run.definite(run.eigenvalues(closer, s_closer))):
            return leads_to(run, closer, s_closer, s_land, landing)
    return False


def leads_to(run, y, s, s_land, landing):
    """Whether the minimum (y, s) is followed to s_land without an event, onto
    ``landing``."""
    follower = run.sub_run(s, s_land)
    follower.state.following_onto_landing = True
    try:
        onward = follower.run(y)
    except TrackingError:
        return False
    return (onward.status == 'ok' and not onward.events
            and run.separation(onward.state, landing) <= run.settings.passage_radius)


def end_at_rounding(run, y, s, s_end):
    """The branch ends within rounding of (y, s): land as from a critical point there,
    (state, s, event or None), or ``None``.

    A fold approached by a command a few 1e-7 long is reached to ~1e-12 of the
    parameter, where lambda_min (a square root of the distance) is still ~1e-6 of
    the scale, above ``critical_tol``; no step of ``min_step`` goes on.  Where
    lambda_min is that small (< ``rounding_critical``) the state is taken as the
    critical point; land() still decides whether the mechanism jumps.  So is a state
    Newton did not resolve (see :data:`.settings.UNRESOLVED_UPDATE`; the start, or where
    a step ended), whatever its lambda_min, where the command moves the mechanism: it
    lies at a fold within what Newton resolves (an independent solve of the fold's own
    equations put that fold 2.5e-9 of the command behind such a start), and no step
    leaves it.  Not at a linkage limit, where Newton does not resolve the state either:
    that is :func:`.linkage_limits.through_linkage_limit`'s to say."""
    lam, psi = run.critical(y, s)
    unresolved = (lam > 0.0 and y is run.unresolved and run.moves(y, s)
                  and not run.linkage_limit(y, s))
    if not 0.0 < lam < run.settings.rounding_critical and not unresolved:
        return None
    kind = indicators.kind(run, y, s, psi)
    try:
        # (from an unresolved state the fold may lie behind it: where a landing just
        # past s finds only the fold's ghost, it is retried up to the command's end)
        return land(run, kind, s, y, s_end, reach=s_end - s if unresolved else 1e-3)
    except TrackingError:
        return None
