"""Supercritical branch points: the minimum buckles smoothly onto a bifurcated branch.

At a branch point the bifurcated branch leaves along the critical mode psi with
s - s* ~ a^2 at amplitude a (BifurcationKit's ``BranchSwitching``: a step along the
kernel, corrected on the hyperplane psi . (y - y*) = a).  Where it lies past s* and is
stable (supercritical), the mechanism follows it continuously: no jump, the branch
point is a passage (``Track.passages``).  The same rule for one module (the unloaded
paper module at rho = L) and for a neck (an upright neck buckling sideways).

Close to s* the buckled minimum's lambda_min (growing linearly from zero) is below the
margin test: there the end of a command is solved and certified by the pitchfork's
normal form (:mod:`.certificates`), both past the branch point and back towards it.
"""
from __future__ import annotations

from dataclasses import replace
import math

import numpy as np

from . import certificates
from .correctors import arc_point, solve_branch_point
from .problem import admissible
from .results import PITCHFORK_CERTIFIED, TrackingError
from .settings import LOCATION_TOL, PITCHFORK_CONTRACTION, UNRESOLVED
from ..numerics.tolerances import BRANCH_POINT_CERTIFIED


def at_the_critical_point(s_star, s_end):
    """What to add to a failure after the critical point at s* where the command ends
    within its location tolerance of it (e.g. the unloaded paper module commanded to
    rho = L exactly): there the state is degenerate (lambda_min ~ 0), a minimum no
    test can verify, so the last verified state is kept.  '' elsewhere."""
    if not 0.0 <= s_end - s_star <= LOCATION_TOL:
        return ''
    return (f' (the command ends {s_end - s_star:.1e} in s past it, at the critical point '
            f'itself: its state is degenerate, lambda_min ~ 0, not a verifiable minimum; '
            f'the last verified state is kept)')


def _buckled_branch(run, s_star, y_star):
    """A stable state on the bifurcated branch past s*, with a margin (100x the
    definiteness tolerance): (y, s), or None (subcritical, unstable, or lost).

    Of the two mirror sides of a perfect pitchfork the one along +psi is taken, psi
    oriented so that its first clearly non-zero component is positive (a deterministic
    rule: the two sides have the same energy).  The amplitude grows until the buckled
    state is stable with the margin."""
    _, psi = run.critical(y_star, s_star)
    clear = np.flatnonzero(np.abs(psi) > 1e-3 * np.max(np.abs(psi)))
    if clear.size and psi[clear[0]] < 0.0:
        psi = -psi
    direction = np.append(psi, 0.0)
    amplitude = run.settings.step_off / max(run.step_norm(psi), 1e-300)
    for _ in range(5):      # lost there: shorter (config/neck.yaml's buckled branch
        found = arc_point(run, y_star, s_star, direction, amplitude, any_s=True)
        if found is not None:
            break           # 3.6e-4 in s short of two linkage limits: from 3e-4 rad)
        amplitude *= 0.25
    for _ in range(6):
        if found is None or not found[1] > s_star:
            return None                     # not past s*: subcritical (or lost)
        y, s = found
        eigenvalues = run.eigenvalues(y, s)
        if eigenvalues[0] < 0.0:
            return None                     # the bifurcated branch is unstable
        if eigenvalues[0] > 100.0 * run.settings.definiteness_tol * max(
                abs(eigenvalues[-1]), run.scale * 1e-3):
            return y, s
        amplitude *= 2.0
        found = arc_point(run, y_star, s_star, direction, amplitude, any_s=True)
    if on_the_buckled_law(run, eigenvalues, s - s_star):
        run.certificate = PITCHFORK_CERTIFIED
        return y, s
    return None


def on_the_buckled_law(run, eigenvalues, past):
    """Whether a state ``past`` in s beyond a branch point on its bifurcated branch is
    a minimum by the pitchfork's normal form, although its lambda_min is below the
    margin test: lambda_min positive and within 25 % of -2 r (s - s*), r the rate of
    lambda_min on the branch that came in (U = -mu x^2 / 2 + b x^4 / 4: U'' = -mu on
    the unbuckled branch, 2 mu on the buckled one).  A soft buckling mode (the perfect
    N = 10 paper neck under a head load: lambda_min 1.2e-7 at 5.5e-8 in s past, the law
    to 3e-6, where the margin test asks 7.5e-7) is no jump, as one module's is not."""
    rate = run.last_rate
    if rate is None or not rate < 0.0 or not past > 0.0:
        return False
    predicted = -2.0 * rate * past
    return bool(certificates.soft_minimum(run, eigenvalues)
                and abs(eigenvalues[0] - predicted) <= 0.25 * predicted)


def buckled_minimum(run, s_star, y_star, s_end):
    """The stable buckled state just past a supercritical branch point: (state, s,
    passed) or ``None`` (the mechanism jumps: subcritical, e.g. C1 of fig. 8a, or the
    bifurcated branch unstable).

    Past the end of the command the buckled branch is followed back to it; where that
    crosses the branch point back (s* was located a little early, ~1e-8 on the N = 3
    neck, and the command ends before the true one) it ends on the unbuckled branch and
    ``passed`` is False: the branch point was not passed."""
    found = _buckled_branch(run, s_star, y_star)
    if found is None:
        return None
    y, s = found
    if s <= s_end:
        return y, s, True
    # a command ending at the branch point itself: first where no buckled state can
    # be told from it, then where none is found within its location tolerance
    at = at_branch_point(run, s_star, y_star, s_end, UNRESOLVED)
    if at is not None:
        return at, s_end, False
    near = buckled_at(run, s_star, y_star, y, s, s_end)
    if near is not None:
        return near, s_end, True
    if s_end - s_star > UNRESOLVED:         # (closer: tried above)
        at = at_branch_point(run, s_star, y_star, s_end, LOCATION_TOL)
        if at is not None:
            return at, s_end, False
    back = run.sub_run(s, s_end).run(y)
    if back.status != 'ok' or back.events:
        raise TrackingError(f'the buckled state after the branch point at s={float(s_star)!r} '
                            f'could not be followed back to the end of the command'
                            + at_the_critical_point(s_star, s_end))
    run.certificate = back.certificate
    return back.state, s_end, not back.passages


def leave_branch_point(run, y, s, s_end):
    """From a start at a supercritical branch point (certified so), a command into its
    buckling side: the buckled minimum, (state, s, None) with the passage listed, or
    ``None`` (then the command fails: the branch point was found supercritical, so a
    jump from it would be false)."""
    run.certificate = ''           # the buckled state's own, if any (buckled_at)
    try:
        return follow_buckled(run, s, y, s_end)
    except TrackingError:
        return None


def follow_buckled(run, s_star, y_star, s_end):
    """:func:`buckled_minimum` as a move past the branch point: (state, s, None), the
    branch point listed in the passages where it was passed, or ``None``."""
    buckled = buckled_minimum(run, s_star, y_star, s_end)
    if buckled is None:
        return None
    y_end, s_at, passed = buckled
    if passed:
        run.passages.append((s_star, y_star))
    return y_end, s_at, None


def at_branch_point(run, s_star, y_star, s_end, within):
    """The end state of a command that ends at a supercritical branch point itself
    (``within`` in s past s*; e.g. the unloaded paper module commanded to rho = L):
    Newton at s_end from y*, or ``None``.

    lambda_min is zero there to the tracker's resolution, so no margin test can
    verify it, but the buckled branch just found past s* is stable: the normal
    form's quartic term is positive and the branch point is a (degenerate) minimum.
    The state is taken where every other eigenvalue passes the margin test and
    lambda_min is within it of zero (``BRANCH_POINT_CERTIFIED``); the command then ends
    with ``Track.certificate`` saying so, the branch point not passed."""
    if not 0.0 <= s_end - s_star <= within:
        return None
    found = run.newton(y_star, s_end)
    if found is None or run.separation(found, y_star) > run.settings.passage_radius:
        return None
    if not certificates.degenerate_minimum(run, run.eigenvalues(found, s_end)):
        return None
    run.certificate = BRANCH_POINT_CERTIFIED
    return found


def buckled_at(run, s_star, y_star, y, s, s_end):
    """The buckled minimum at s_end in (s*, s), from the one found at s: Newton from
    the parabola through both (amplitude ~ sqrt(s - s*)); ``None`` unless it converges
    on the same side, near the guess, to a verified minimum.

    Verified by the margin test, or, within ~1e-6 in s of s* where the buckled
    branch's lambda_min (growing linearly from zero) is below that margin, by the
    pitchfork's normal form (:func:`.certificates.pitchfork_certified`); the command then
    ends with ``Track.certificate`` saying so."""
    ratio = math.sqrt((s_end - s_star) / (s - s_star))
    guess = y_star + ratio * (y - y_star)
    found = run.newton(guess, s_end)
    if (found is None or (found - y_star) @ (y - y_star) <= 0.0
            or run.separation(found, guess) > 0.5 * run.separation(guess, y_star)):
        return None
    eigenvalues = run.eigenvalues(found, s_end)
    if run.definite(eigenvalues):
        return found
    if certificates.pitchfork_certified(run, eigenvalues, run.eigenvalues(y, s), ratio ** 2):
        run.certificate = PITCHFORK_CERTIFIED
        return found
    return None


def _far_state(run, y, s, s_end, certificate):
    """A state on the branch through y far enough from the branch point to pass the
    margin test 100-fold: ((s, state, eigenvalues), remembered) or (None, False)."""
    far = away_from_branch_point(run, y, s, s_end - s, certificate)
    if far is None and run.clear_of_margin is not None and run.clear_of_margin[0] < s:
        return run.clear_of_margin, True
    return far, False


def toward_branch_point(run, y, s, s_end, near=False):
    """From a state certified by a passed pitchfork's normal form (its buckled branch
    within ~1e-6 in s past the branch point), where the command runs back towards the
    branch point and ends short of it: (state at s_end, s_end); else ``None``.  Tried
    where a step from such a state is rejected, once per state.

    Steps cannot get there: Newton pins such a state along the soft mode only to ~1e-6
    (lambda_min / lambda_max ~ 1e-11 at 1e-9 past on the N = 3 neck), above the
    corrector's slack, so every natural step is 'far'; and [F_y F_s] is rank-deficient
    at a branch point, so arclength steps fail too.  So the branch point is found from
    the normal form: the buckled branch is followed the other way until lambda_min
    passes the margin test 100-fold (or, where no run away leaves the noise, this run's
    last such state, :attr:`.run_state.RunState.clear_of_margin`); lambda_min's linear
    law through both states gives s*, the square root law y*, and :func:`buckled_at`
    solves the end state from the far one.  That far (3e-5 in s on that neck) the linear
    law puts s* within ~1e-11 in s, so an end closer than that is not certified.
    ``near``: tried from a state verified by the margin test too, where a step towards
    the branch point ended below the margin on lambda_min's linear law.  Where it fails,
    it is tried again only from a state whose lambda_min is ten times smaller (nearer the
    branch point by the law): a soft dip of lambda_min that is no branch point (an
    imperfect pitchfork mid-path, the N = 5 paper neck with a 1e-9 asymmetry) had it
    tried from 13 states in a row, 20 s."""
    if not ((run.certificate or near) and run.normal_form_end and s < s_end
            and run.normal_form_tried != s):
        return None
    run.normal_form_tried = s
    lam, found = run.eigenvalues(y, s)[0], None
    if run.normal_form_failed is not None and lam > 0.1 * run.normal_form_failed:
        return None         # no nearer the branch point than where it failed
    certificate, run.certificate = run.certificate, ''
    far, remembered = _far_state(run, y, s, s_end, certificate)
    if far is not None:
        found, s_end = _end_by_the_normal_form(run, y, s, s_end, lam, far, remembered)
    if found is None:
        run.certificate = certificate
        run.normal_form_failed = lam
        return None
    return found, s_end


def _end_by_the_normal_form(run, y, s, s_end, lam, far, remembered):
    """(the end state or None, the s it is at) of :func:`toward_branch_point` from the
    far state: s* on lambda_min's linear law through it and y, refined by the branch
    point's own equations where the command ends short of s*
    (:func:`.correctors.solve_branch_point`:
    y's lambda_min is known to a few per cent only, which put s* 3.5e-11 in s off on the
    Haswell kernel, and the end 6.5e-11 short of it failed the 25 % test: H30), y* on
    the square-root law."""
    s_far, far_state, far_eigenvalues = far
    rate = (far_eigenvalues[0] - lam) / (s_far - s)
    s_star = s - lam / rate if rate < 0.0 else -math.inf
    if not s < s_star:
        return None, s_end
    ratio = math.sqrt((s_star - s) / (s_star - s_far))     # of y's amplitude
    y_star = (y - ratio * far_state) / (1.0 - ratio)
    if abs(s_end - s_star) <= UNRESOLVED:
        # the command ends at the branch point to the law's resolution (2e-16 in s
        # short of it, from the unloaded module's buckled branch at rho 0.51 to rho = 1):
        # its degenerate minimum, as where a step reaches it (a buckled state pinned
        # there by the law, 8e-9 rad off, was a start no command could leave)
        at = at_branch_point(run, min(s_star, s_end), y_star, s_end, UNRESOLVED)
        if at is not None:
            return at, s_end
    if s_end < s_star:
        solved = solve_branch_point(run, y_star, s_star)
        if (solved is not None and s_end < solved[1]
                and abs(solved[1] - s_star) <= 0.5 * (s_star - s)):
            y_star, s_star = solved
        return buckled_at(run, s_star, y_star, far_state, s_far, s_end), s_end
    if remembered:
        return None, s_end
    s_end = min(s_end, 2.0 * s_star - s)       # as far before s* as y was past it
    return unbuckled_at(run, s_star, y_star, rate, s_end), s_end


def unbuckled_at(run, s_star, y_star, rate, s_end):
    """The unbuckled minimum at s_end, just beyond the branch point (s*, y*) that a
    command from the buckled branch crosses back: Newton from y*; ``None`` unless it
    converges near y* to a verified minimum.  The passage is then listed, as one
    crossing the other way lists it.

    Verified by the margin test, or by the pitchfork's normal form: on the unbuckled
    branch lambda_min = -c (s - s*) / 2 where the buckled one's is c (s - s*) (``rate``
    = c, from the far state), so it is certified when positive and within 25 % of
    that prediction; the command then ends with ``Track.certificate`` saying so."""
    found = run.newton(y_star, s_end)
    if found is None or run.separation(found, y_star) > run.settings.passage_radius:
        return None
    eigenvalues = run.eigenvalues(found, s_end)
    predicted = -0.5 * rate * (s_end - s_star)
    if run.definite(eigenvalues):
        run.certificate = ''
    elif (certificates.soft_minimum(run, eigenvalues)
          and abs(eigenvalues[0] - predicted) <= 0.25 * predicted):
        run.certificate = PITCHFORK_CERTIFIED
    else:
        return None
    run.passages.append((s_star, y_star))
    return found


def away_from_branch_point(run, y, s, length, certificate):
    """(s, state, eigenvalues) on the buckled branch through the certified ``y`` at s,
    followed backwards along the path by 1, 10 .. 1e7 times ``length`` until lambda_min
    passes the margin test 100-fold, or ``None``.  A short one may fail: a state that
    close to the branch point is known along the soft mode only to ~1e-6, so steps of
    a few 1e-12 in s are 'far' however short."""
    margin = 100.0 * run.settings.definiteness_tol
    for extent in length * 10.0 ** np.arange(8):
        if not admissible(run.problem, s - extent):
            return None
        # (min_step: where its steps fail, give up after ~20 halvings, not 40)
        away = run.sub_run(s, s - extent, replace(run.settings, min_step=1e-6))
        away.state.normal_form_end = False
        away.state.stop_at_events = True      # a critical point on the way: not this branch
        away.state.contraction = PITCHFORK_CONTRACTION  # its steps are in the cubic valley
        try:
            far = away.run(y, certificate=certificate)
        except TrackingError:
            # its own margin test (scaled to this state's stiffness) may refuse a state
            # this run verified: then there is no far state (must not end the command)
            return None
        stopped = away.state.stopped_at_event
        if stopped is not None and stopped >= 0.1:
            # the branch meets a critical point first, a tenth of the run away or more,
            # where every longer run meets it (the same line in parameter space: an
            # imperfect N = 8 neck ran seven more, each to the same fold, 0.5 s;
            # bench_neck_paths seed 1 path 49).  One closer may be the noise next to the
            # branch point, which a longer run leaves (test_continuous_buckling::
            # test_a_neck_command_from_just_past_its_passage_back_towards_it_ends_ok)
            return None
        if far.status != 'ok' or far.events or far.passages:
            continue                # too short to leave the noise (or the wrong way)
        if far.eigenvalues[0] > margin * max(abs(far.eigenvalues[-1]), run.scale * 1e-3):
            return s - extent, far.state, far.eigenvalues
    return None
