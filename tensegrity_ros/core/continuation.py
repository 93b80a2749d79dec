"""Follow a stable equilibrium along a parameter path, with jump detection (DESIGN.md section 3).

The tracker knows nothing about tensegrity: it works on a :class:`PathProblem`,
a family of equilibrium equations ``F(y, s) = 0`` along a path ``s in [0, 1]``
with an energy and a stability matrix.  One module (2 angles) and the neck
stack (angles and Lagrange multipliers) both implement it.

Per step: a tangent predictor and a Newton corrector.  The step is bounded so
that the smallest stability eigenvalue is predicted to at most halve and the
state moves at most ``max_state_step``.  A step is accepted only if Newton
contracts, lands near the prediction, the stability matrix is still positive
definite (by eigenvalues) and the energy change matches the envelope theorem
``dE/ds = dU/ds``.  A rejected step is not an event: it is retried as a
pseudo-arclength step (which follows a sharply turning branch, e.g. near an
imperfect branch point, and goes round a fold), then shrunk.  An event exists
only between two verified states of the branch where the test function
lambda_min changes sign, or where the branch turns back in s; it is located
there by a bracketed secant (to ~1e-12 in s) and kept only if lambda_min ~ 0.
It is a fold where the critical mode ``psi`` is not orthogonal to ``F_s``, else
a branch point.  At a supercritical branch point (the bifurcated branch lies past
s* and is stable) the state follows the buckled minimum: no event, the branch point
is listed in ``Track.passages``.  Otherwise the mechanism lands where an
overdamped gradient flow with the parameters frozen just past the event takes it;
where the landing closes in on the departure as that offset shrinks, the minimum
simply goes on (no event).
Tolerances follow the local stiffness scale, so every magnitude works.
A reported jump lands on a minimum at the event's own s (the frozen landing followed
back to s*).  A command ending within ~1e-6 in s past a passed branch point, where
the buckled minimum's lambda_min is below the margin test, ends on a state certified
by the pitchfork's normal form instead (``Track.certificate``); from such a state a
command back towards the branch point is solved by that normal form too.
``TrackerSettings.time_budget`` bounds a whole command, nested work included.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Protocol

import numpy as np
from scipy.integrate import LSODA
from scipy.optimize import minimize_scalar

from .bounded_work import Budget, checkpoint
from .tolerances import BRANCH_POINT_CERTIFIED, DEFINITENESS_TOL, verified_minimum

FOLD = 'fold'
BRANCH_POINT = 'branch_point'
#: A final state certified by a passed pitchfork's normal form (see ``_Tracker.buckled_at``).
PITCHFORK_CERTIFIED = 'pitchfork_normal_form'
#: Newton's contraction test on a buckled branch followed away from its branch point
#: (``_Tracker.away_from_branch_point``): in that nearly cubic valley Newton converges
#: linearly, by 2/3 an iterate (x - x^3 / (3 x^2)), so the usual 1/2 stops it at a state
#: up to 2x off the minimum whose residual already passes the tolerance (the unloaded
#: module 1.5e-8 in rho past its branch point: 3.5e-4 rad for 1.76e-4; then 180 false
#: jumps).  Not everywhere: it made the N = 3 neck's command up to 1e-10 before its
#: branch point list a false passage 7e-8 early.
PITCHFORK_CONTRACTION = 0.75
#: A critical point is located to this in s (DESIGN.md): a command that ends closer than
#: this past one ends at the critical point itself (see ``_Tracker.at_the_critical_point``).
LOCATION_TOL = 1e-9
#: A command ending closer than this in s past a supercritical branch point ends at the
#: branch point itself: a buckled state that close is not told from it (the normal form's
#: linear law of lambda_min puts s* within ~1e-11 from a state 3e-5 in s away on the
#: N = 3 neck: see ``_Tracker.toward_branch_point``).  The unloaded paper module
#: commanded to rho = 1.0 from below met its branch point 4.4e-13 in s before the end,
#: rho's rounding, and ended 'past' it 8e-9 rad out, a state the next command back up
#: could not leave (the time budget ran out).
UNRESOLVED = 1e-11
#: A Newton update (relative to 1 + |y|) left above this where Newton stopped converging:
#: the state is not resolved to what its eigenvalues need.  Newton from an equilibrium
#: stops at updates of ~1e-14 (rounding); next to a fold it converges only linearly (by
#: 1/2 an iterate, the Jacobian singular at the double root), and stops at the first
#: update that does not halve: 1.4e-5 rad from a state config/neck.yaml was left on
#: after a failed landing (residual 1.9e-8, within the 1.1e-7 tolerance; lambda_min
#: 0.013 N/m there, ~0 at the fold).
UNRESOLVED_UPDATE = 1e-9
#: A rigid landing flow leg stops to look for a flat crossing once the flattest module's
#: chord gradient (over l_ref) is below this (see ``_Tracker.rigid_flow_to_rest``); it
#: goes on through at most MAX_CROSSING_LEGS such stops per flow.
CROSSING_APPROACH = 1e-3
#: Where a command ends on a module's flat crossing, a mechanism released there that
#: comes to rest farther than this (weighted state norm) has jumped (see
#: ``_Tracker.snap_at_end_crossing``): ten times the passage radius; a minimum going on
#: through the crossing stays ~sqrt(the step in s) of it, ~1e-6 at the last steps.
SNAP_DISTANCE = 1e-3
#: Next to an exact crossing (see ``flat_crossing.rounding``), Newton's iterates that
#: stall within this many rounding radii of it are at it: the radius is an
#: order-of-magnitude estimate of the chord's rounding (bench_round_commands seed 2,
#: stream 11: stalled at 1.015 radii, the residual 0.26, 1e7 times the tolerance, since
#: no state there is resolved better).
EXACT_CROSSING_STALL = 4.0
MAX_CROSSING_LEGS = 16
#: An arclength point is kept only where its Newton's last update moved the state by
#: less than this (weighted state norm): Newton stopped after an update that no longer
#: contracts leaves the point off the branch by about that update, and its residual may
#: still pass a tolerance relative to the stiffness scale, which a module folded flat
#: inflates (config/neck.yaml, bench_round_commands seed 1, stream 12: points kept
#: after one update of 7.9e-4, residual 3.4e-6 against 1.3e-5, lambda_max 4.5e8; the
#: fold was located on them, 4.9e-7 in s past the one the reference's fold equations
#: give, and the landing failed).  Next to that flat module, whose angles the chord
#: fixes only to ~sqrt(rounding), resolved points still move by up to 1.2e-7.
ARC_RESOLUTION = 1e-6


class PathProblem(Protocol):
    """Equilibrium equations along a parameter path, as the tracker needs them.

    ``y`` is the state (angles, and multipliers for constrained systems); ``s``
    the path parameter.  ``stability`` returns the ascending eigenvalues of the
    stability matrix (Hessian, or reduced Hessian) and the matching modes
    expressed as state-space directions (columns).  ``descent`` is the velocity
    of the overdamped mechanism (minus the gradient, projected if constrained);
    ``project`` returns a nearby admissible state (identity if unconstrained).
    ``admissible(s)`` (optional) says whether the parameters at s (possibly
    slightly beyond [0, 1], for landing) are physically valid.  ``on_constraints(y, s)``
    (optional) says whether a state meets the constraints (``project`` may find none
    near it).

    Optional: ``eigenvalues(y, s)`` (the stability eigenvalues alone, if cheaper),
    ``state_weights`` (per-component weights of the step-size norm, e.g. 1/length
    for positions and 0 for multipliers; default all ones) and ``canonical(y)``
    (a representative for comparing states, e.g. angles wrapped to [-pi, pi)).
    Landing flows use, where given: ``rigid_descent`` (the flow of the constrained model
    itself, where ``descent`` lets the constraints give), ``damped(y, s)`` (whether
    ``descent`` does so at y), ``flatness``, ``turned_through_base`` and
    ``crossing_ways`` (a linkage's crossings, see :meth:`_Tracker.rigid_flow_to_rest`)
    and ``mirror(y, s)`` (the state's mirror image, or None where the problem has no
    mirror symmetry at s).
    """

    size: int

    def residual(self, y, s): ...
    def jacobian(self, y, s): ...
    def residual_s(self, y, s): ...
    def energy(self, y, s): ...
    def energy_s(self, y, s): ...
    def stability(self, y, s): ...
    def descent(self, y, s): ...
    def project(self, y, s): ...


@dataclass(frozen=True)
class TrackerSettings:
    """Tolerances and step limits of :func:`track` (named, so they can be tuned and cited)."""

    #: Largest predicted change of any state component in one step (rad).
    max_state_step: float = 0.05
    #: The smallest eigenvalue may be predicted to shrink to this fraction per step.
    eigenvalue_shrink: float = 0.5
    #: Residual accepted as an equilibrium, relative to the stability scale.
    residual_tol: float = 1e-10
    #: Positive definite means lambda_min > this * |lambda_max| (see :mod:`.tolerances`).
    definiteness_tol: float = DEFINITENESS_TOL
    #: Newton iterations per corrector.
    newton_iterations: int = 12
    #: Below this |psi . F_s| / |F_s| the critical point is a branch point.
    branch_tol: float = 1e-6
    #: The mechanism lands with the parameters frozen this far past the event (in s,
    #: at least; made larger where the command is short, see ``_landing_offset``).
    landing_offset: float = 1e-7
    #: Step-off distance along the critical mode before sliding down (state units).
    step_off: float = 1e-2
    #: Give up after this many steps (a guard, never reached in practice).
    max_steps: int = 100000
    #: Smallest step in s before the tracker localises or gives up.
    min_step: float = 1e-13
    #: Velocity evaluations one landing flow may spend before it is abandoned.
    flow_evaluations: int = 200000
    #: Two states closer than this (weighted state norm) are the same state; also the
    #: corrector's slack near a critical point, where rounding is amplified by 1/lambda_min.
    same_state_tol: float = 1e-7
    #: Near a pitchfork |lambda_min| <= critical_tol pins the critical state only to
    #: ~sqrt(critical_tol): a landing this close to it (weighted state norm) that does
    #: not move with the freezing offset is the minimum going on, not a jump.
    passage_radius: float = 1e-4
    #: A located critical point must have |lambda_min| below this, relative to the scale.
    critical_tol: float = 1e-9
    #: An arclength step is kept only if the branch direction turns less than this
    #: (cosine) over it: a sharper turn means the corrector reached another branch.
    arc_alignment: float = 0.9
    #: Where steps underflow, a state with lambda_min below this (relative to the scale)
    #: is a critical point reached to rounding (see ``_Tracker.end_at_rounding``).
    rounding_critical: float = 1e-5
    #: Past a linkage limit the minimum is looked for this far on (in s, and 100 times
    #: closer, to see that it closes in: see ``_Tracker.through_linkage_limit``).
    linkage_offset: float = 1e-6
    #: Seconds one command may take before it gives up (None: no limit): checked at every
    #: check point (:func:`.bounded_work.checkpoint`), nested landings, followers and
    #: bisections included, so a command ends at most one check point's work past it,
    #: on its last verified state (status 'failed').
    time_budget: float | None = None
    #: The clock ``time_budget`` is read on (tests inject a counting clock).
    clock: Callable[[], float] = time.perf_counter


@dataclass(frozen=True)
class Event:
    """A jump: the stable branch ended (``fold``) or lost stability (``branch_point``) at ``s``.

    ``landing`` is a verified stable equilibrium at ``landing_s``, which is ``s`` unless
    that minimum does not exist back at ``s`` (see ``_Tracker.landing_at_event``)."""

    kind: str
    s: float
    state: np.ndarray
    landing_s: float
    landing: np.ndarray
    ambiguous: bool = False


@dataclass(frozen=True)
class Track:
    """Result of :func:`track`: the last verified stable state, where it is, and the events.

    ``status`` is ``'ok'`` when ``s == 1``, else ``'failed'`` with a ``message``;
    ``state`` has always passed the residual and positive-definiteness checks.
    ``passages``: (s, critical state) of each supercritical branch point the state
    passed continuously (it buckled smoothly onto a new minimum: not a jump, no event).
    ``certificate`` says how ``state`` was shown positive definite: ``''`` by the margin
    test (lambda_min > definiteness_tol * lambda_max), or :data:`PITCHFORK_CERTIFIED`:
    the command ended so close past a passed branch point (~1e-6 in s) that the
    buckled minimum's lambda_min is below that margin, and it is shown positive by the
    branch point's normal form instead (``_Tracker.buckled_at``).
    """

    state: np.ndarray
    s: float
    eigenvalues: np.ndarray
    events: tuple = ()
    status: str = 'ok'
    message: str = ''
    steps: int = 0
    passages: tuple = ()
    certificate: str = ''


class _FlowBudgetExceeded(Exception):
    """A landing flow used up its evaluation budget."""


class _Lost(Exception):
    """A corrector left the branch (no convergence, or converged too far away)."""


class TrackingError(RuntimeError):
    """The start state is not a stable equilibrium and cannot be made one."""


def _solve(matrix, rhs):
    if matrix.shape == (2, 2):                  # (in Python floats: no numpy scalars)
        (a, b), (c, d) = matrix.tolist()
        r0, r1 = rhs.tolist()
        det = a * d - b * c
        if det == 0.0 or not math.isfinite(det):
            raise np.linalg.LinAlgError('singular 2x2 matrix')
        return np.array([(d * r0 - b * r1) / det, (a * r1 - c * r0) / det])
    return np.linalg.solve(matrix, rhs)


def _inf_norm(v):
    return max(map(abs, v.tolist()), default=0.0)


# -- the acceptance rules of one step (public: a problem's own fast path uses these) --

def positive_definite(eigenvalues, scale, settings):
    """A verified minimum: lambda_min > definiteness_tol * max(|lambda_max|, scale / 1000)."""
    return eigenvalues[0] > settings.definiteness_tol * max(abs(eigenvalues[-1]), scale * 1e-3)


def step_bound(reach, lam, rate, settings):
    """The largest step in s the step rules allow from a state whose tangent has step
    norm ``reach`` and smallest eigenvalue ``lam`` changing at ``rate`` = d lambda / ds:
    the state moves by at most max_state_step, lambda_min is predicted to shrink to no
    less than eigenvalue_shrink of itself."""
    ds = settings.max_state_step / max(reach, 1e-300)
    if rate < 0.0:
        ds = min(ds, (1.0 - settings.eigenvalue_shrink) * lam / -rate)
    return ds


def forward_rate(eigenvalues, y, s, tangent, lam):
    """d lambda_min / ds along the branch, by a forward difference of ``eigenvalues(y, s)``."""
    h = 1e-6
    return (eigenvalues(y + h * tangent, s + h)[0] - lam) / h


def near_prediction(miss, reach, ds, settings):
    """The corrector stayed on the branch: it moved the prediction by at most half the
    predicted step (``miss`` and ``reach`` are step norms of the correction and tangent)."""
    return miss <= 0.5 * ds * reach + settings.same_state_tol


def energy_consistent(energy0, energy1, energy_s0, energy_s1, ds, scale):
    """The envelope theorem: along one branch dE/ds = U_s (a jump to another breaks it)."""
    expected = 0.5 * (energy_s0 + energy_s1) * ds
    slack = 1e-9 * (abs(energy0) + abs(energy1) + scale) + 0.5 * abs((energy_s1 - energy_s0) * ds)
    return abs((energy1 - energy0) - expected) <= slack


class _Tracker:
    """One tracking run; holds the problem, the scales and the settings."""

    #: Set on the run that follows a minimum onto a landing (:meth:`leads_to`): its own
    #: landings are not checked that way again (each check would nest another run).
    following_onto_landing = False

    def __init__(self, problem, settings):
        self.problem = problem
        self.settings = settings
        self.scale = 1.0          # stability scale, set from the start state
        self.steps = 0
        self.last_rate = None     # d lambda_min / ds over the last accepted step
        self.base_scale = None    # the stability scale at the start
        self.passages = []        # (s, state) of the branch points passed continuously
        self.certificate = ''     # how the final state's definiteness was shown (Track)
        #: Newton's contraction test (see :meth:`newton`)
        self.contraction = 0.5
        #: Stop (failed) at a critical point instead of landing: a landing's own
        #: minimum followed back to its event (nested landings there could recurse).
        self.stop_at_events = False
        #: From a pitchfork-certified state, solve a command's end short of its branch
        #: point by the normal form (off in the tracker that follows the branch away for it).
        self.normal_form_end = True
        self.normal_form_tried = None   # the s it was tried at (once per state)
        #: The last verified state of :meth:`run` (what a spent time budget returns).
        self.kept = None
        self.newton_unresolved = False  # the last newton() stopped short of rounding level
        #: The start, or the state a step ended on, where Newton did not resolve it (see
        #: :meth:`end_at_rounding`).
        self.unresolved = None
        #: (s, state, eigenvalues) of the last state of :meth:`run` whose lambda_min passed
        #: the margin test 100-fold, on the branch tracked since (see :meth:`toward_branch_point`).
        self.clear_of_margin = None
        #: States out along the other half-branches of the flat crossings a landing flow
        #: passed (see :meth:`through_crossing`).
        self.crossing_alternatives = []
        weights = getattr(problem, 'state_weights', None)
        self.weights = None if weights is None else np.asarray(weights, dtype=float)

    def step_norm(self, v):
        """Size of a state change for the step limits (weighted max norm)."""
        return _inf_norm(v if self.weights is None else self.weights * v)

    # -- verification -------------------------------------------------------
    def residual_ok(self, y, s, factor=1.0):
        return _inf_norm(self.problem.residual(y, s)) <= factor * self.settings.residual_tol * self.scale

    def definite(self, eigenvalues):
        return positive_definite(eigenvalues, self.scale, self.settings)

    def newton(self, y, s):
        """Newton corrector; ``None`` unless it contracts and converges.

        It iterates to rounding level, not just below the acceptance tolerance:
        near a critical point a residual r leaves an error r / lambda_min along
        the soft mode, which is what the stability margin is computed from.
        Contracting: each update at most ``self.contraction`` of the one before (1/2;
        the tracker that follows a buckled branch away from its branch point allows
        :data:`PITCHFORK_CONTRACTION`).
        """
        tol = self.settings.residual_tol * self.scale
        contraction = self.contraction
        previous = size = math.inf
        f = self.problem.residual(y, s)
        for _ in range(self.settings.newton_iterations):
            try:
                delta = _solve(self.problem.jacobian(y, s), f)
            except np.linalg.LinAlgError:
                break
            size = _inf_norm(delta)
            if not math.isfinite(size) or size > contraction * previous + 1e-15:
                break                                   # no longer contracting
            y = y - delta
            f = self.problem.residual(y, s)
            previous = size
            if size <= 1e-14 * (1.0 + _inf_norm(y)):
                break
        self.newton_unresolved = not size <= UNRESOLVED_UPDATE * (1.0 + _inf_norm(y))
        return y if _inf_norm(f) <= tol else None

    def pinned_newton(self, y, s):
        """Newton with the state's component along the Jacobian's softest direction held
        at y's: the bordered system {F(x, s) + beta u = 0, v . (x - y) = 0} (u, v the
        Jacobian's left and right singular vectors of its smallest singular value at y),
        regular where the Jacobian is singular along v (a branch point).  ``None`` unless
        it converges to a residual within the tolerance (beta ~ 0: an equilibrium through
        that hyperplane exists next to y)."""
        try:
            u_all, _, vt = np.linalg.svd(self.problem.jacobian(y, s))
        except np.linalg.LinAlgError:
            return None
        u, v, n = u_all[:, -1], vt[-1], y.size
        matrix = np.zeros((n + 1, n + 1))
        matrix[:n, n], matrix[n, :n] = u, v
        x, beta, previous = np.array(y, dtype=float), 0.0, math.inf
        for _ in range(self.settings.newton_iterations):
            matrix[:n, :n] = self.problem.jacobian(x, s)
            rhs = np.append(self.problem.residual(x, s) + beta * u, v @ (x - y))
            try:
                delta = np.linalg.solve(matrix, rhs)
            except np.linalg.LinAlgError:
                return None
            size = _inf_norm(delta[:n])
            if not math.isfinite(size) or size > 0.5 * previous + 1e-15:
                break
            x, beta, previous = x - delta[:n], beta - delta[n], size
            if size <= 1e-14 * (1.0 + _inf_norm(x)):
                break
        return x if self.residual_ok(x, s) else None

    # -- one continuation step ----------------------------------------------
    def tangent(self, y, s):
        return -_solve(self.problem.jacobian(y, s), self.problem.residual_s(y, s))

    def energy_consistent(self, y0, s0, y1, s1):
        """:func:`energy_consistent` between two states."""
        problem = self.problem
        return energy_consistent(problem.energy(y0, s0), problem.energy(y1, s1),
                                 problem.energy_s(y0, s0), problem.energy_s(y1, s1),
                                 s1 - s0, self.scale)

    def try_step(self, y, s, tangent, ds):
        """Corrector at s + ds; returns (state, eigenvalues, reason) with reason '' if accepted."""
        s1 = s + ds
        predicted = y + ds * tangent
        y1 = self.newton(predicted, s1)
        if y1 is None:
            return None, None, 'newton'
        if not near_prediction(self.step_norm(y1 - predicted), self.step_norm(tangent), ds,
                               self.settings):
            return None, None, 'far'
        if not self.energy_consistent(y, s, y1, s1):
            return None, None, 'energy'
        eigenvalues = self.eigenvalues(y1, s1)
        if not self.definite(eigenvalues):
            return y1, eigenvalues, 'indefinite'
        return y1, eigenvalues, ''

    def run(self, y, s_end=1.0, certificate=''):
        """The main loop: natural steps; an arclength step where one is rejected; events
        only where a test function changes sign (or the branch turns) between verified states.

        ``certificate`` (a previous :class:`Track`'s, for its final state as the start)
        lets a start certified by a pitchfork's normal form be taken: its steps are
        accepted while lambda_min stays positive and grows (:meth:`still_certified`),
        until one passes the margin test."""
        cfg = self.settings
        self.certificate = certificate
        s = 0.0
        eigenvalues = self.eigenvalues(y, s)
        self.rescale(eigenvalues)
        y = np.asarray(y, dtype=float)
        polished = self.newton(y, s)
        if self.newton_unresolved and self.residual_ok(y, s):
            # a verified start at a singular point (a fold, a flat module): Newton does
            # not converge from it and may go astray (13.9 in the state from one kept at
            # a linkage limit, bench_round_commands seed 3, stream 15): keep the start
            polished = None
        if polished is None and not self.residual_ok(y, s):
            raise TrackingError('the start state is not an equilibrium')
        if polished is not None and self.step_norm(polished - y) > cfg.passage_radius:
            # Newton from a rough guess may converge to a minimum whose basin does not
            # hold the guess: where the mechanism comes to rest is settle()'s to decide
            raise TrackingError('the start state is not an equilibrium')
        y = y if polished is None else polished
        self.unresolved = y if polished is None or self.newton_unresolved else None
        eigenvalues = self.eigenvalues(y, s)
        if self.definite(eigenvalues):
            self.certificate = ''
        elif not self.certified_start(eigenvalues):
            raise TrackingError('the start state is not a stable equilibrium')
        events = []
        self.keep(y, s, eigenvalues, events)
        ds, rate = 1.0, None
        while s < s_end:
            self.steps += 1
            checkpoint()                # a bounded caller may pause (or give up) here
            if self.steps > cfg.max_steps:
                return self.result(y, s, eigenvalues, events, 'failed', 'too many steps')
            try:
                tangent = self.tangent(y, s)
            except np.linalg.LinAlgError:
                tangent = np.zeros_like(y)
            if rate is None:
                rate = self.eigenvalue_rate(y, s, tangent, eigenvalues[0])
            ds = min(ds, s_end - s,
                     step_bound(self.step_norm(tangent), eigenvalues[0], rate, cfg))
            y1, eig1, reason = self.try_step(y, s, tangent, ds)
            certified = reason == 'indefinite' and (
                self.still_certified(eigenvalues, eig1)
                or self.linear_approach(eigenvalues, eig1, rate, ds, s_end - s))
            if not reason or certified:
                self.certificate = PITCHFORK_CERTIFIED if certified else ''
                rate = self.last_rate = (eig1[0] - eigenvalues[0]) / ds
                y, s, eigenvalues = y1, s + ds, eig1
                if self.newton_unresolved:          # (try_step's Newton: the last one run)
                    self.unresolved = y
                self.keep(y, s, eigenvalues, events)
                self.note_margin(y, s, eigenvalues)
                self.rescale(eigenvalues)
                ds *= 2.0
                continue
            ended = self.toward_branch_point(y, s, s_end)      # certified y only
            if ended is not None:
                y, s = ended
                eigenvalues = self.eigenvalues(y, s)
                self.keep(y, s, eigenvalues, events)
                continue
            found = None
            if reason == 'indefinite' and self.certificate == BRANCH_POINT_CERTIFIED:
                # at the branch point itself, the command leading into its buckling side
                moved = self.leave_branch_point(y, s, s_end)
                if moved is None:
                    return self.result(y, s, eigenvalues, events, 'failed',
                                       f'no stable buckled state found leaving the branch '
                                       f'point at s={s!r}')
                y, s, _ = moved
                eigenvalues = self.eigenvalues(y, s)
                self.keep(y, s, eigenvalues, events)
                self.rescale(eigenvalues)
                ds, rate = 1.0, None
                continue
            if reason == 'indefinite':
                found = self.crossing_on_path(y, s, tangent, s + ds)
                if ((found is None or found[1] > s_end)
                        and self.on_linear_law(eigenvalues, eig1, rate, ds)):
                    # lambda_min falls linearly to a branch point the command runs
                    # through, and no crossing is found on the path: the buckled branch
                    # ends there (a verified state not yet certified, e.g. the module
                    # 1e-9 .. 5e-10 in rho past rho = L going back up)
                    ended = self.toward_branch_point(y, s, s_end, near=True)
                    if ended is not None:
                        y, s = ended
                        eigenvalues = self.eigenvalues(y, s)
                        self.keep(y, s, eigenvalues, events)
                        ds, rate = 1.0, None
                        continue
            if found is None:           # rejected, or no crossing on the natural path
                arc = self.arc_step(y, s, tangent, ds)
                if arc is not None and arc[0] == 'regular' and arc[2] > s_end:
                    arc = self.back_to_end(*arc[1:3], s_end)
                if arc is not None and arc[0] == 'regular':
                    _, y1, s1, eig1 = arc
                    self.last_rate = (eig1[0] - eigenvalues[0]) / (s1 - s)
                    y, s, eigenvalues, rate = y1, s1, eig1, None
                    self.keep(y, s, eigenvalues, events)
                    self.note_margin(y, s, eigenvalues)
                    self.rescale(eigenvalues)
                    continue
                if arc is not None:
                    found = arc[1]
            moved = None
            if found is not None and found[1] <= s_end and self.stop_at_events:
                return self.result(y, s, eigenvalues, events, 'failed',
                                   f'a critical point at s={found[1]!r} (not landed: '
                                   f'stop_at_events)')
            if found is not None and found[1] <= s_end:
                # at a linkage limit the flow of land() stalls: cross it first
                moved = self.through_linkage_limit(found[2], found[1], s_end)
                try:
                    moved = moved or self.land(*found, s_end)
                except TrackingError as error:
                    return self.result(y, s, eigenvalues, events, 'failed', str(error))
            elif ds <= cfg.min_step:
                moved = (self.through_linkage_limit(y, s, s_end)
                         or self.end_at_rounding(y, s, s_end)
                         or self.leave_crossing(y, s, s_end))
                if moved is None:
                    return self.result(y, s, eigenvalues, events, 'failed',
                                       self.underflow_reason(y, s, reason))
            if moved is not None:       # past the event (or limit): go on from the landing
                y, s, event = moved
                if event is not None:
                    events.append(event)
                self.clear_of_margin = None     # another branch (or across a limit)
                eigenvalues = self.eigenvalues(y, s)
                self.keep(y, s, eigenvalues, events)
                self.rescale(eigenvalues)
                ds, rate = 1.0, None
                continue
            ds *= 0.25 if reason == 'indefinite' else 0.5
        return self.result(y, s, eigenvalues, events)

    def back_to_end(self, y1, s1, s_end):
        """An arclength step that went past the end of the command, brought back to it
        (a natural step back on the regular branch): ('regular', y, s_end, eigenvalues),
        or ``None`` (the step is then refused and retried shorter)."""
        try:
            y = self.newton(y1 + (s_end - s1) * self.tangent(y1, s1), s_end)
        except np.linalg.LinAlgError:
            return None
        if y is None or self.step_norm(y - y1) > self.settings.max_state_step:
            return None
        eigenvalues = self.eigenvalues(y, s_end)
        return ('regular', y, s_end, eigenvalues) if self.definite(eigenvalues) else None

    def certified_start(self, eigenvalues):
        """A start below the margin test that ``self.certificate`` verifies: a soft
        minimum (lambda_min positive) next to a passed pitchfork, or a supercritical
        branch point itself (:meth:`at_branch_point`)."""
        if self.certificate == BRANCH_POINT_CERTIFIED:
            return self.degenerate_minimum(eigenvalues)
        return bool(self.certificate and self.soft_minimum(eigenvalues))

    def degenerate_minimum(self, eigenvalues):
        """Every eigenvalue but lambda_min passes the margin test and lambda_min is zero
        to within it, either sign (a supercritical branch point itself: see
        :meth:`at_branch_point`)."""
        return bool(self.definite(eigenvalues[1:])
                    and verified_minimum(eigenvalues, BRANCH_POINT_CERTIFIED))

    def soft_minimum(self, eigenvalues):
        """lambda_min positive and every other eigenvalue passes the margin test."""
        return bool(eigenvalues[0] > 0.0
                    and (len(eigenvalues) == 1 or self.definite(eigenvalues[1:])))

    def still_certified(self, previous, eigenvalues):
        """A step from a pitchfork-certified state (``self.certificate``) to one still
        below the margin test keeps the certificate where lambda_min grew (and the step
        passed every other check): on the buckled branch lambda_min grows linearly away
        from the branch point, so the new state lies further along it."""
        return bool(self.certificate and eigenvalues[0] > previous[0]
                    and self.soft_minimum(eigenvalues))

    def linear_approach(self, previous, eigenvalues, rate, ds, remaining):
        """A step towards a branch point that ends below the margin test is still on a
        minimum where lambda_min is positive and where the linear law predicts it (within
        25 %) from the verified state before and the rate over the step before that: near
        a simple branch point lambda_min = c (s* - s), so a command ending within ~1e-6
        before one (e.g. on the buckled branch going back) ends on a minimum, while
        rounding noise, ~1e-16 of lambda_max, cannot match the law.  Only where the law
        keeps lambda_min positive up to the command's end (``remaining`` in s): a command
        through the branch point is left to the event's localisation, as before."""
        return bool(rate is not None and previous[0] + rate * remaining > 0.0
                    and self.on_linear_law(previous, eigenvalues, rate, ds))

    def on_linear_law(self, previous, eigenvalues, rate, ds):
        """A step's end is a minimum whose lambda_min, positive, falls as the linear law
        of a simple branch point predicts it (within 25 %) from the verified state before
        (eigenvalues ``previous``) and the rate over the step before that (see
        :meth:`linear_approach`)."""
        if not (rate is not None and rate < 0.0 and eigenvalues is not None
                and self.soft_minimum(eigenvalues)):
            return False
        predicted = previous[0] + rate * ds
        return bool(predicted > 0.0 and abs(eigenvalues[0] - predicted) <= 0.25 * predicted)

    def rescale(self, eigenvalues):
        """Tolerances follow the stiffness scale: the start's, or the local one where
        the branch has softened (relative, so every magnitude works; never looser
        than at the start, so a stiffening branch keeps the start's accuracy)."""
        local = abs(float(eigenvalues[-1]))
        if self.base_scale is None:
            self.base_scale = max(local, 1e-300)
        self.scale = local if 0.0 < local < self.base_scale else self.base_scale

    def note_margin(self, y, s, eigenvalues):
        """Remember an accepted state whose lambda_min passes the margin test 100-fold."""
        if eigenvalues[0] > 100.0 * self.settings.definiteness_tol * max(
                abs(eigenvalues[-1]), self.scale * 1e-3):
            self.clear_of_margin = (s, y, eigenvalues)

    def keep(self, y, s, eigenvalues, events):
        """Note a verified state of :meth:`run` (with its certificate and the events
        before it): where the time budget runs out, the command ends there.  (Without a
        budget nothing reads it: no copy on the small-step path.)"""
        if self.settings.time_budget is not None:
            self.kept = (y, s, eigenvalues, tuple(events), self.certificate)

    def out_of_budget(self):
        """The result of a run whose time budget ran out: its last verified state."""
        y, s, eigenvalues, events, self.certificate = self.kept
        return self.result(y, s, eigenvalues, events, 'failed',
                           f'time budget of {self.settings.time_budget:g} s used up '
                           f'(last verified state at s={float(s)!r})')

    def result(self, y, s, eigenvalues, events, status='ok', message=''):
        return Track(state=y, s=s, eigenvalues=np.asarray(eigenvalues), events=tuple(events),
                     status=status, message=message, steps=self.steps,
                     passages=tuple(self.passages), certificate=self.certificate)

    def eigenvalue_rate(self, y, s, tangent, lam):
        """d lambda_min / ds along the branch, by a small forward difference."""
        return forward_rate(self.eigenvalues, y, s, tangent, lam)

    def eigenvalues(self, y, s):
        """Ascending stability eigenvalues (without modes where the problem can)."""
        cheap = getattr(self.problem, 'eigenvalues', None)
        return cheap(y, s) if cheap is not None else self.problem.stability(y, s)[0]

    def margin(self, y, s):
        """The test function lambda_min in scale units (its root is the critical point)."""
        checkpoint()                    # every probe of a localisation
        return self.eigenvalues(y, s)[0] / self.scale

    # -- the branch as a curve in (y, s): arclength steps ----------------------
    def curve_tangent(self, y, s, reference=None):
        """Unit null vector of [F_y F_s] (the branch's direction in (y, s)), oriented
        along ``reference`` (or towards growing s); regular at folds, unlike dy/ds."""
        matrix = np.column_stack([self.problem.jacobian(y, s), self.problem.residual_s(y, s)])
        direction = np.linalg.svd(matrix)[2][-1]
        along = direction @ reference if reference is not None else direction[-1]
        return -direction if along < 0.0 else direction

    def arc_point(self, y0, s0, direction, h, any_s=False):
        """Pseudo-arclength corrector: the branch point on the hyperplane through
        (y0, s0) + h direction normal to direction; ``None`` unless it converges near it.

        ``any_s``: near it in the state only, at whatever s (a bifurcated branch off a
        branch point, ``direction`` the critical mode: its s - s* ~ h^2 / c is in the
        path's own units, 1e6 commands away for a command 1e-9 in rho long)."""
        problem, n = self.problem, self.problem.size
        z0 = np.append(y0, s0)
        predicted = z0 + h * direction
        z = predicted.copy()
        matrix = np.empty((n + 1, n + 1))
        matrix[n] = direction
        previous, applied = math.inf, None
        for _ in range(self.settings.newton_iterations):
            y, s = z[:n], z[n]
            matrix[:n, :n] = problem.jacobian(y, s)
            matrix[:n, n] = problem.residual_s(y, s)
            rhs = np.append(problem.residual(y, s), direction @ (z - predicted))
            try:
                delta = np.linalg.solve(matrix, rhs)
            except np.linalg.LinAlgError:
                return None
            size = _inf_norm(delta)
            if not math.isfinite(size) or size > 0.5 * previous + 1e-15:
                break
            z, previous, applied = z - delta, size, delta
            if size <= 1e-14 * (1.0 + _inf_norm(z)):
                break
        y, s = z[:n], float(z[n])
        # the extended system is regular at folds, so it converges to rounding level;
        # where it does not (a singular linkage limit), the step is refused
        miss = z - predicted
        if (applied is None or not self.step_norm(applied[:n]) <= ARC_RESOLUTION
                or not self.residual_ok(y, s, 1e-3)
                or _inf_norm(miss[:n] if any_s else miss) > 0.5 * h + self.settings.same_state_tol):
            return None
        if not self.energy_consistent(y0, s0, y, s):
            return None
        return y, s

    def arc_step(self, y, s, tangent, ds):
        """One arclength step as long as the rejected natural step.

        Returns ('regular', y1, s1, eigenvalues) where the branch goes on stable and
        forward, ('event', found) where a test function changed sign on the arc
        (found as from :meth:`critical_point`), or ``None`` if the step failed.
        """
        direction = self.curve_tangent(y, s)
        h = ds * math.sqrt(1.0 + float(tangent @ tangent))
        end = self.arc_point(y, s, direction, h)
        if end is None:
            return None
        y1, s1 = end
        direction1 = self.curve_tangent(y1, s1, direction)
        if direction1 @ direction < self.settings.arc_alignment:
            return None             # turned too much for one step: another branch, or too long
        eigenvalues = self.eigenvalues(y1, s1)
        forward = direction1[-1] > 0.0
        if self.definite(eigenvalues) and forward and s1 > s:
            return 'regular', y1, s1, eigenvalues

        def point(hh):
            found = self.arc_point(y, s, direction, hh)
            if found is None:
                raise _Lost
            return found

        if not self.definite(eigenvalues):
            test = lambda hh: self.margin(*point(hh))                          # noqa: E731
        else:                       # the branch turned back in s while staying stable
            test = lambda hh: self.curve_tangent(*point(hh), direction)[-1]   # noqa: E731
        found = self.critical_point(test, point, 0.0, h)
        if found is not None and found[1] < s:
            # the arc went back in s before its critical point: that one is not ahead of
            # (y, s) on the command (a start within rounding of a fold: the Haswell
            # kernel's arc from bench_round_commands seed 3 stream 10's mirror-symmetric
            # start put a branch point at s = -6.2e-4 and went on from there silently;
            # SkylakeX's stepped 1e-13 forward first and found the fold there).  Shorter
            # steps decide, down to the state itself (end_at_rounding).
            return None
        return 'event', found

    def crossing_on_path(self, y, s, tangent, s_bad):
        """The critical point where lambda_min crosses zero between the verified (y, s)
        and the verified indefinite state at s_bad (natural parametrisation).

        A probe is Newton from the prediction; where that fails or lands far, the
        bordered corrector (:meth:`pinned_newton`).  Next to a branch point Newton's
        update along the soft mode is rounding over lambda_min: within ~1.5e-9 in s of
        the perfect N = 3 chord ramp's branch point it moved the state 2e-7 .. 1e-5 off
        the prediction, every probe there was lost, and the event was located on the
        arclength steps instead, whose extended system is singular there too: 1.4e-9 ..
        3.7e-9 in s off on the Sandybridge and Haswell BLAS kernels, 2e-12 on SkylakeX."""
        def point(t):
            predicted = y + (t - s) * tangent
            near = 0.5 * abs(t - s) * self.step_norm(tangent) + self.settings.same_state_tol
            found = self.newton(predicted, t)
            if found is None or self.step_norm(found - predicted) > near:
                # (not next to a flat module: there the Jacobian's singular direction is
                # its chord's, and Newton's lost probes are unresolved points, which must
                # not bracket a fold: bench_round_commands seed 1 stream 12)
                found = None if self.linkage_limit(predicted, t) else \
                    self.pinned_newton(predicted, t)
                if found is None or self.step_norm(found - predicted) > near:
                    raise _Lost
            return found, t

        return self.critical_point(lambda t: self.margin(*point(t)), point, s, s_bad)

    def critical_point(self, test, point, a, b):
        """Root of a test function bracketed by two verified states, checked to be
        critical (lambda_min ~ 0); returns (kind, s, y) or ``None``."""
        try:
            with np.errstate(all='ignore'):
                a, b, test_a, test_b = _bracket(test, a, b)
                if not test_a > 0.0:
                    return None
                if test_b >= 0.0:           # indefinite by the tolerance only: b is critical
                    a, test_a = b, 0.0
                else:
                    a, b, test_a, test_b = _shrink_bracket(test, a, b, test_a, test_b)
                root_at = a + (b - a) * test_a / (test_a - test_b) if test_a > 0.0 else a
            try:
                y_star, s_star = point(root_at)
            except _Lost:                   # singular right at the root: its verified neighbour
                y_star, s_star = point(a)
                s_star = s_star + (root_at - a) * (s_star - point(b)[1]) / (a - b) if b != a else s_star
        except (_Lost, ValueError, ZeroDivisionError, np.linalg.LinAlgError):
            return None
        lam, psi = self.critical(y_star, s_star)
        if abs(lam) > self.settings.critical_tol:
            return None
        ratio = self.orthogonality(y_star, s_star, psi)
        kind = FOLD if ratio > self.settings.branch_tol else BRANCH_POINT
        return kind, s_star, y_star

    # -- linkage limits (constrained problems) ------------------------------------
    def through_linkage_limit(self, y, s, s_end):
        """Carry the minimum across a linkage limit: (state, s, None) just past it, or
        ``None`` where the state is not at one or does not go on continuously.

        At a linkage limit (the problem's optional ``linkage_limit(y, s)``: a constraint
        whose gradient vanishes, e.g. a module folded flat onto its chord) two branches
        of configurations cross, so the equilibrium equations are singular there even
        where the state is a strict minimum: steps underflow or the branch seems to turn
        back, and the landing flow stalls (its pull onto the constraints vanishes with
        that gradient).  Just past it the minimum lies on one of the crossing branches,
        ~sqrt(offset) away: the nearest verified minimum found by Newton from the state
        moved along each state component and projected on the constraints.  It is the
        mechanism going on (no jump) only if it closes in on the state as the offset
        shrinks 100-fold (to 0.3 of its distance or less, as a square root does)."""
        if s >= s_end or not self.linkage_limit(y, s):
            return None
        if s_end - s < self.settings.linkage_offset:
            # the limit lies at the command's end within rounding: the closing-in test
            # below would compare two states before it (both on the branch coming in)
            ended = self.end_next_to_crossing(y, s_end)
            if ended is not None:
                return ended
        offset = min(self.settings.linkage_offset, s_end - s)
        near = self.nearest_minimum(y, s + offset)
        if near is not None:
            near = self.at_own_scale(near, s + offset)
        if near is None:
            return None
        # where the minimum goes on, it is ~0.1 as far at 0.01 of the offset (a square
        # root); an equilibrium there that is not clearly unstable will do (another
        # module may be at its own pitchfork at the same s, e.g. a neck of equal modules)
        s_closer = s + 0.01 * offset
        closer = self.newton(self.problem.project(y + 0.1 * (near - y), s_closer), s_closer)
        if closer is not None and not self.eigenvalues(closer, s_closer)[0] > \
                -self.settings.definiteness_tol * self.scale:
            closer = None
        if closer is None:
            closer = self.nearest_minimum(y, s_closer)
        distance = self.separation(near, y)
        if (closer is None
                or self.separation(closer, y) > 0.3 * distance + self.settings.same_state_tol):
            return None
        return near, s + offset, None

    def leave_crossing(self, y, s, s_end):
        """Where the minimum came onto a module's flat crossing (the problem's optional
        ``crossing_ways``) and goes on continuously along none of its half-branches: the
        mechanism released just past it slides to rest, a jump there (landing, s_land,
        branch point event), as the reference's overdamped flow does; ``None`` where
        ``y`` is at no crossing or no flow rests on a minimum a move away.  Frozen
        1e-9, 1e-7, then ``linkage_offset`` past s (where the minimum is gone, the flow
        from it moves).  (bench_round_commands seed 1, streams 1 and 7, seed 0 stream 8:
        the reference's jumps there, where the tracker gave up at a 'linkage limit'.
        Leaving along the steepest half-branch, the rule of a flow that reaches a
        crossing, took another half-branch than the flow from the departure itself,
        6e-9 rad from flat, in seed 0 stream 8.)"""
        ways = getattr(self.problem, 'crossing_ways', None)
        if (s >= s_end or ways is None or not self.moves(y, s)
                or not self.linkage_limit(y, s)):
            return None     # (a command to the same parameters moves nothing)
        leaving = ways(y, s)
        if leaving is None:
            return None
        stalled = True
        for offset in (1e-9, 1e-7, self.settings.linkage_offset):
            s_land = min(s + offset, s_end)
            self.crossing_alternatives = []
            landing = self.slide(y, s_land, rigid_first=True)
            if landing is not None and self.separation(landing, y) > self.settings.passage_radius:
                return self.off_crossing(y, s, landing, s_land, leaving)
            stalled = stalled and landing is None
            if s_land >= s_end:
                break
        s_land = min(s + 1e-9, s_end)
        if not stalled or self.newton(y, s_land) is not None:
            # the flow rests next to y, or an equilibrium goes on from it (the steps
            # stopped unresolved next to the flat module: seed 1 stream 12, 2.3e-6 in s
            # before its fold): no jump off the crossing here
            return None
        # the departure's own flow does not move at all and no equilibrium goes on: kept
        # mirror-symmetric to the last bit (the Nehalem kernel's, seed 1 stream 1), the flow
        # stalls where the rigid projection is undefined; the released mechanism leaves
        # along the steepest way out (a mirror pair: either, ambiguous), as a flow that
        # reaches a crossing does
        for _, state in sorted(leaving, key=lambda way: -way[0]):
            self.crossing_alternatives = []
            landing = self.slide(state, s_land, rigid_first=True)
            if landing is not None and self.separation(landing, y) > self.settings.passage_radius:
                return self.off_crossing(y, s, landing, s_land, leaving)
        return None

    def off_crossing(self, y, s, landing, s_land, leaving):
        """The jump off the crossing at (y, s) onto ``landing``: (landing, s_land, branch
        point event).  Which half-branch the released mechanism takes turns on the
        departure's last 1e-7 rad (seed 0 stream 8: the reference's departure, 6e-9 rad
        from flat, took the other): ambiguous where another one lands elsewhere."""
        others = self.crossing_alternatives + [state for _, state in leaving]
        ambiguous = (self.lands_elsewhere(others, landing, s_land)
                     or self.mirror_lands_too(y, landing, s_land))
        at_event, s_at = self.landing_at_event(landing, s_land, s)
        return landing, s_land, Event(kind=BRANCH_POINT, s=s, state=y, landing_s=s_at,
                                      landing=at_event, ambiguous=ambiguous)

    def end_next_to_crossing(self, y, s_end):
        """The command's end where the branch coming in (``y``, within ``linkage_offset``
        of s_end) ends next to a module's flat crossing: (minimum, s_end, None) where a
        verified minimum off the crossing ends it (no jump), (landing, s_end, fold event)
        where the state at s_end is at the crossing and the mechanism snaps from it, or
        ``None`` where neither is shown (the closing-in test decides).

        Which it is, Newton at s_end from ``y`` tells (:meth:`newton_next_to_crossing`):
        the branch approaches the crossing like the square root of the distance in s, and
        at s_end it either reaches it to rounding (the command ends where rho(i) +
        rho(i+1) = L1 + L2 to within the chord's rounding: there the model does not tell
        the state from the crossing) or stops short of it, on a minimum the chord still
        resolves (bench_round_commands seed 0, stream 8's joint_commands {0: 0.13, 1: 0.12,
        2: 0.15}: the sum 5.6e-16 m short, the minimum 7.8e-8 rad from the crossing,
        8 rounding radii, lambda_min 100; snapping there reported a jump of 0.08 rad the
        reference does not make)."""
        found = self.newton_next_to_crossing(y, s_end)
        if found is None:
            return None
        where, state = found
        if where == 'off':
            return state, s_end, None
        return self.snap_at_end_crossing(y, s_end)

    def newton_next_to_crossing(self, y, s):
        """Where Newton at s from ``y`` goes next to a module's flat crossing (the
        problem's optional ``crossing_rounding(y, s)``: (distance, rounding radius,
        exact) of a state, the crossing next to it and whether that crossing is exact to
        rounding): ('at', state) where an iterate comes within the rounding radius of an
        exact crossing or stalls within EXACT_CROSSING_STALL radii of it, ('off', minimum)
        where the updates of the moving components stall below that radius outside a
        crossing that is not exact, on a verified minimum within SNAP_DISTANCE of ``y``,
        else ``None``.

        Next to a crossing the chord's gradient is ~|H| distance, so Newton's steps there
        are fixed only to the chord's rounding over it: they stall at that radius (the
        multipliers, ~1e7 N, cycling by a few per cent), and the residual stays up to
        |W| times it (1.7e-3 where the tracker's own tolerance is 7e-8; as the
        reference's critical_point allows).  Approaching the crossing itself, whose
        solution Newton converges to only linearly (the equations are singular there),
        the iterates halve their distance to it until they are within the radius
        (bench_round_commands seed 0, streams 6 and 8: within it after 2 and 4 updates,
        at 0.86 and 0.77 of it; the crossings miss their chords by 2.9e-17 and 1.4e-17 m,
        below the 6e-17 m of an exact one).  An iterate within the radius of a crossing
        that is not exact is only passing (stream 8b's crossing misses by 5.9e-16 m, and
        its minimum lies 8 radii out: Newton from its incoming state moved at random by
        1e-7 or 1e-6 rad passed within the radius on its way there from 2 of 16 starts)."""
        rounding = getattr(self.problem, 'crossing_rounding', None)
        if rounding is None:
            return None
        problem, start = self.problem, y
        moving = (np.ones(problem.size, dtype=bool) if self.weights is None
                  else self.weights > 0.0)
        tol = self.settings.residual_tol * self.scale
        f = problem.residual(y, s)
        for _ in range(self.settings.newton_iterations):
            try:
                jacobian = problem.jacobian(y, s)
                delta = _solve(jacobian, f)
            except np.linalg.LinAlgError:
                return None
            if not np.all(np.isfinite(delta)):
                return None
            y = y - delta
            f = problem.residual(y, s)
            found = rounding(y, s)
            if found is None:
                return None
            distance, radius, exact = found
            stalled = _inf_norm(delta[moving]) <= radius
            if exact and (distance <= radius
                          or (stalled and distance <= EXACT_CROSSING_STALL * radius)):
                return 'at', y
            if distance <= radius or not stalled:
                # still moving, or within the radius of a crossing that is not exact:
                # Newton passing on its way (the crossing's arms lie apart, see rounding)
                continue
            if exact:
                # stalled farther from an exact crossing: not a minimum the chord resolves
                # off it (the arms touch there); the closing-in test decides
                return None
            slack = float(np.linalg.norm(jacobian[np.ix_(moving, moving)], 2)) * radius
            if (_inf_norm(f) <= tol + slack and self.separation(y, start) <= SNAP_DISTANCE
                    and self.definite(self.eigenvalues(y, s))):
                return 'off', y
            return None
        return None

    def snap_at_end_crossing(self, y, s_end):
        """The jump at the command's end where the branch coming in ends on a module's
        flat crossing there (to rounding: :meth:`end_next_to_crossing`): (landing, s_end,
        fold event), or ``None`` where no half-branch leads down from it, or the mechanism
        comes to rest within SNAP_DISTANCE of it (it goes on continuously).

        The branch approaches the crossing like the square root of the distance in s
        (config/neck.yaml, bench_round_commands seed 0, stream 6: 4.3e-7 rad at 1e-12
        short of s = 1, where rho0 + rho1 = L1 + L2 to 3e-17 m).  At the crossing two
        half-branches lead down (0.27 per unit node length), and the mechanism released
        there comes to rest 0.015 rad away, 4e-4 J lower: a finite move at fixed s with
        an energy release, a jump.  (It was made silently, as 'just past the limit':
        :meth:`through_linkage_limit`'s closing-in test, with its offset capped by the
        command's end, compared two states before the crossing.)  It lands as a landing
        flow through a crossing does: along the steepest half-branch, ambiguous where
        another lands elsewhere (there: on the mirror image)."""
        problem = self.problem
        if getattr(problem, 'crossing_ways', None) is None:
            return None
        at_end = problem.project(y, s_end)
        self.crossing_alternatives = []
        ways = problem.crossing_ways(at_end, s_end)
        if not ways or max(rate for rate, _ in ways) <= 0.0:
            return None
        onward = self.through_crossing(at_end, s_end)
        alternatives = list(self.crossing_alternatives)
        landing = self.slide(onward, s_end, rigid_first=True)
        if (landing is None or self.separation(landing, at_end) <= SNAP_DISTANCE
                or problem.energy(landing, s_end) >= problem.energy(at_end, s_end)):
            return None
        ambiguous = self.lands_elsewhere(alternatives, landing, s_end)
        return landing, s_end, Event(kind=FOLD, s=s_end, state=at_end, landing_s=s_end,
                                     landing=landing, ambiguous=ambiguous)

    def at_own_scale(self, y, s):
        """A minimum found at this run's stiffness scale, polished by Newton and verified
        at its own (the scale :meth:`rescale` sets once the run is there), or ``None``.

        At a linkage limit the scale is inflated by the chord force (lambda_max 4.4e10 N/m
        at config/neck.yaml's module 0 flat with no load, 7.3e3 N/m 1e-6 in s past it), and
        so is the residual tolerance: Newton stopped there on a state 0.14 N from
        equilibrium, 9e-5 rad off the minimum, from which every step was 'far'."""
        kept = self.scale
        self.rescale(self.eigenvalues(y, s))
        try:
            polished = self.newton(y, s)
            if polished is None or not self.definite(self.eigenvalues(polished, s)):
                return None
            return polished
        finally:
            self.scale = kept

    def end_at_rounding(self, y, s, s_end):
        """The branch ends within rounding of (y, s): land as from a critical point there,
        (state, s, event or None), or ``None``.

        A fold approached by a command a few 1e-7 long is reached to ~1e-12 of the
        parameter, where lambda_min (a square root of the distance) is still ~1e-6 of
        the scale, above ``critical_tol``; no step of ``min_step`` goes on.  Where
        lambda_min is that small (< ``rounding_critical``) the state is taken as the
        critical point; land() still decides whether the mechanism jumps.  So is a state
        Newton did not resolve (see :data:`UNRESOLVED_UPDATE`; the start, or where a step
        ended), whatever its lambda_min, where the command moves the mechanism: it lies at
        a fold within what Newton resolves (lambda_min is 0 at the fold, and 0.013 N/m at
        such a start 1.4e-5 rad off; an independent solve of the fold's own equations put
        that fold 2.5e-9 of the command behind it), and no step leaves it.  Not at a linkage
        limit, where Newton does not resolve the state either: what happens there is
        :meth:`through_linkage_limit`'s to say (the rigid-chord model does not say where
        the mechanism goes)."""
        lam, psi = self.critical(y, s)
        unresolved = (lam > 0.0 and y is self.unresolved and self.moves(y, s)
                      and not self.linkage_limit(y, s))
        if not 0.0 < lam < self.settings.rounding_critical and not unresolved:
            return None
        kind = FOLD if self.orthogonality(y, s, psi) > self.settings.branch_tol else BRANCH_POINT
        try:
            # (from an unresolved state the fold may lie behind it: where a landing just
            # past s finds only the fold's ghost, it is retried up to the command's end)
            return self.land(kind, s, y, s_end, reach=s_end - s if unresolved else 1e-3)
        except TrackingError:
            return None

    def linkage_limit(self, y, s):
        """The problem's description of the linkage limit at (y, s) ('' where none)."""
        return getattr(self.problem, 'linkage_limit', lambda *_: '')(y, s)

    def moves(self, y, s):
        """Whether the path moves the equilibrium conditions at (y, s) (not a command to
        the same parameters)."""
        return _inf_norm(self.problem.residual_s(y, s)) > 0.0

    def underflow_reason(self, y, s, reason):
        """Why the steps underflowed: a linkage limit the minimum does not cross
        continuously (the rigid-chord model does not say where the mechanism goes: its
        chord force grows without bound), or the failed step's reason."""
        limit = self.linkage_limit(y, s)
        if limit:
            return (f'linkage limit at s={float(s)!r}: {limit}; no minimum goes on continuously '
                    f'past it, and the rigid-chord model does not say where the mechanism goes')
        return f'step size underflow at s={float(s)!r} ({reason})'

    def nearest_minimum(self, y, s):
        """The verified minimum at s nearest to ``y`` among those Newton reaches from y
        moved by 1e-5 .. 1e-1 (step norm) along each weighted state component, both
        ways, and projected; ties go to the lower energy.  ``None`` if there is none."""
        problem, best = self.problem, None
        weights = np.ones(problem.size) if self.weights is None else self.weights
        moving = np.flatnonzero(weights)
        # each component alone, then seeded random mixtures (several constraints at
        # their limits at once need a combined move)
        directions = np.zeros((len(moving), problem.size))
        directions[np.arange(len(moving)), moving] = 1.0 / weights[moving]
        mixed = np.random.default_rng(0).standard_normal((2 * len(moving), len(moving)))
        mixtures = np.zeros((len(mixed), problem.size))
        mixtures[:, moving] = mixed / weights[moving]
        directions = np.vstack([directions, mixtures])
        for direction in directions:
            direction = direction / self.step_norm(direction)
            for amplitude in (1e-5, 1e-4, 1e-3, 1e-2, 1e-1):
                for sign in (1.0, -1.0):
                    checkpoint()
                    moved = y + sign * amplitude * direction
                    try:
                        found = self.newton(problem.project(moved, s), s)
                    except np.linalg.LinAlgError:
                        continue
                    if found is None or not self.definite(self.eigenvalues(found, s)):
                        continue
                    key = (round(self.separation(found, y), 9), problem.energy(found, s))
                    if best is None or key < best[0]:
                        best = key, found
        return None if best is None else best[1]

    # -- events ---------------------------------------------------------------
    def critical(self, y, s, reference=None):
        """(lambda_min / scale, psi) with psi's sign aligned to ``reference``."""
        eigenvalues, modes = self.problem.stability(y, s)
        psi = modes[:, 0] / np.linalg.norm(modes[:, 0])
        if reference is not None and psi @ reference < 0.0:
            psi = -psi
        return eigenvalues[0] / self.scale, psi

    def orthogonality(self, y, s, psi):
        fs = self.problem.residual_s(y, s)
        norm = np.linalg.norm(fs)
        return abs(psi @ fs) / norm if norm > 0 else 0.0

    def land(self, kind, s_star, y_star, s_end, reach=1e-3):
        """Where the mechanism goes after the critical point: (state, s, event or None).

        The parameters are frozen just past the event; the mechanism steps off along
        the critical mode and slides down.  Where the tracked branch ends at s* and
        the landing closes in on the critical point as the offset shrinks (a minimum
        crossing onto another branch, e.g. a supercritical pitchfork run backwards),
        the state simply follows (see :meth:`continuous`): no event (so no event can land on its own
        departure).  If "just past" lies beyond the end of the command,
        the landed state is followed back along its own branch to the end point.
        """
        problem = self.problem
        # Tried at a fold too: its branch turns back at s*, so no state along its mode
        # lies past s* there; where one does, the point was a branch point whose fold
        # test |psi . F_s| is ill-conditioned (next to a linkage limit a chord's multiplier
        # amplifies a 1e-5 asymmetry of the mode ~1e6-fold: 4.9e-6 .. 2.6e-3 against
        # branch_tol 1e-6 at config/neck.yaml's mirror-symmetric pitchforks 1e-4 in s
        # before a module folds flat; true folds there: >= 4.5e-2).
        buckled = self.follow_buckled(s_star, y_star, s_end)
        if buckled is not None:                 # supercritical: no jump, the state goes on
            return buckled
        offset = self.landing_offset(kind, y_star, s_star)
        s_land = s_star + offset
        if s_land > s_end and not _admissible(problem, s_land):
            s_land = s_end
        landing, ambiguous, s_land = self.landing_state(kind, s_star, y_star, s_land, s_end,
                                                        reach)
        event = None if self.continuous(kind, s_star, y_star, s_land, landing) else kind
        ambiguous = ambiguous or self.mirror_lands_too(y_star, landing, s_land)
        if s_land > s_end:
            back = _Tracker(_Segment(problem, s_land, s_end), self.settings).run(landing)
            if back.status != 'ok' or back.events:
                raise TrackingError(f'the landing after the {kind} at s={float(s_star)!r} does '
                                    f'not persist to the end of the command'
                                    + self.at_the_critical_point(s_star, s_end))
            landing, s_land, self.certificate = back.state, s_end, back.certificate
        if event is None:
            return landing, s_land, None
        at_event, s_at = self.landing_at_event(landing, s_land, s_star)
        return landing, s_land, Event(kind=kind, s=s_star, state=y_star, landing_s=s_at,
                                      landing=at_event, ambiguous=ambiguous)

    def at_the_critical_point(self, s_star, s_end):
        """What to add to a failure after the critical point at s* where the command ends
        within its location tolerance of it (e.g. the unloaded paper module commanded to
        rho = L exactly): there the state is degenerate (lambda_min ~ 0), a minimum no
        test can verify, so the last verified state is kept.  '' elsewhere."""
        if not 0.0 <= s_end - s_star <= LOCATION_TOL:
            return ''
        return (f' (the command ends {s_end - s_star:.1e} in s past it, at the critical point '
                f'itself: its state is degenerate, lambda_min ~ 0, not a verifiable minimum; '
                f'the last verified state is kept)')

    def buckled_minimum(self, s_star, y_star, s_end):
        """The stable buckled state just past a supercritical branch point: (state, s,
        passed) or ``None``.

        At a branch point the bifurcated branch leaves along the critical mode psi
        with s - s* ~ a^2 at amplitude a.  It is found on the hyperplane
        psi . (y - y*) = a (the arclength corrector, regular off the trivial branch).
        Where it lies past s* and is stable (supercritical: the minimum turns into
        a saddle and two minima grow out of it like sqrt(s - s*)), the mechanism
        follows it continuously, no jump.  Where it lies before s* (subcritical,
        e.g. C1 of fig. 8a) or is unstable, ``None``: the mechanism jumps.
        The amplitude grows until the buckled state is stable with a margin (100x
        the definiteness tolerance).  Of the two mirror sides of a perfect
        pitchfork the one along +psi is taken, psi oriented so that its first
        clearly non-zero component is positive (a deterministic rule: the two
        sides have the same energy).  Past the end of the command the buckled
        branch is followed back to it; where that crosses the branch point back (s* was
        located a little early, ~1e-8 on the N = 3 neck, and the command ends before
        the true one) it ends on the unbuckled branch and ``passed`` is False: the
        branch point was not passed.
        """
        _, psi = self.critical(y_star, s_star)
        clear = np.flatnonzero(np.abs(psi) > 1e-3 * np.max(np.abs(psi)))
        if clear.size and psi[clear[0]] < 0.0:
            psi = -psi
        direction = np.append(psi, 0.0)
        amplitude = self.settings.step_off / max(self.step_norm(psi), 1e-300)
        for _ in range(5):      # lost there: shorter (config/neck.yaml's buckled branch
            found = self.arc_point(y_star, s_star, direction, amplitude, any_s=True)
            if found is not None:
                break           # 3.6e-4 in s short of two linkage limits: from 3e-4 rad)
            amplitude *= 0.25
        for _ in range(6):
            if found is None or not found[1] > s_star:
                return None                     # not past s*: subcritical (or lost)
            y, s = found
            eigenvalues = self.eigenvalues(y, s)
            if eigenvalues[0] < 0.0:
                return None                     # the bifurcated branch is unstable
            if eigenvalues[0] > 100.0 * self.settings.definiteness_tol * max(
                    abs(eigenvalues[-1]), self.scale * 1e-3):
                break
            amplitude *= 2.0
            found = self.arc_point(y_star, s_star, direction, amplitude, any_s=True)
        else:
            return None
        if s <= s_end:
            return y, s, True
        # a command ending at the branch point itself: first where no buckled state can
        # be told from it, then where none is found within its location tolerance
        at = self.at_branch_point(s_star, y_star, s_end, UNRESOLVED)
        if at is not None:
            return at, s_end, False
        near = self.buckled_at(s_star, y_star, y, s, s_end)
        if near is not None:
            return near, s_end, True
        if s_end - s_star > UNRESOLVED:         # (closer: tried above)
            at = self.at_branch_point(s_star, y_star, s_end, LOCATION_TOL)
            if at is not None:
                return at, s_end, False
        back = _Tracker(_Segment(self.problem, s, s_end), self.settings).run(y)
        if back.status != 'ok' or back.events:
            raise TrackingError(f'the buckled state after the branch point at s={float(s_star)!r} '
                                f'could not be followed back to the end of the command'
                                + self.at_the_critical_point(s_star, s_end))
        self.certificate = back.certificate
        return back.state, s_end, not back.passages

    def leave_branch_point(self, y, s, s_end):
        """From a start at a supercritical branch point (certified so), a command into its
        buckling side: the buckled minimum, (state, s, None) with the passage listed, or
        ``None`` (then the command fails: the branch point was found supercritical, so a
        jump from it would be false)."""
        self.certificate = ''           # the buckled state's own, if any (buckled_at)
        try:
            return self.follow_buckled(s, y, s_end)
        except TrackingError:
            return None

    def follow_buckled(self, s_star, y_star, s_end):
        """:meth:`buckled_minimum` as a move past the branch point: (state, s, None), the
        branch point listed in the passages where it was passed, or ``None``."""
        buckled = self.buckled_minimum(s_star, y_star, s_end)
        if buckled is None:
            return None
        y_end, s_at, passed = buckled
        if passed:
            self.passages.append((s_star, y_star))
        return y_end, s_at, None

    def at_branch_point(self, s_star, y_star, s_end, within):
        """The end state of a command that ends at a supercritical branch point itself
        (``within`` in s past s*; e.g. the unloaded paper module commanded to rho = L):
        Newton at s_end from y*, or ``None``.

        lambda_min is zero there to the tracker's resolution, so no margin test can
        verify it, but the buckled branch just found past s* is stable: the normal
        form's quartic term is positive and the branch point is a (degenerate) minimum.
        The state is taken where every other eigenvalue passes the margin test and
        lambda_min is within it of zero (:func:`~.tolerances.verified_minimum` with
        ``BRANCH_POINT_CERTIFIED``); the command then ends with ``Track.certificate``
        saying so, the branch point not passed."""
        if not 0.0 <= s_end - s_star <= within:
            return None
        found = self.newton(y_star, s_end)
        if found is None or self.separation(found, y_star) > self.settings.passage_radius:
            return None
        if not self.degenerate_minimum(self.eigenvalues(found, s_end)):
            return None
        self.certificate = BRANCH_POINT_CERTIFIED
        return found

    def buckled_at(self, s_star, y_star, y, s, s_end):
        """The buckled minimum at s_end in (s*, s), from the one found at s: Newton from
        the parabola through both (amplitude ~ sqrt(s - s*)); ``None`` unless it converges
        on the same side, near the guess, to a verified minimum.

        Verified by the margin test, or, within ~1e-6 in s of s* where the buckled
        branch's lambda_min (growing linearly from zero) is below that margin, by the
        pitchfork's normal form (:meth:`pitchfork_certified`); the command then ends
        with ``Track.certificate`` saying so."""
        ratio = math.sqrt((s_end - s_star) / (s - s_star))
        guess = y_star + ratio * (y - y_star)
        found = self.newton(guess, s_end)
        if (found is None or (found - y_star) @ (y - y_star) <= 0.0
                or self.separation(found, guess) > 0.5 * self.separation(guess, y_star)):
            return None
        eigenvalues = self.eigenvalues(found, s_end)
        if self.definite(eigenvalues):
            return found
        if self.pitchfork_certified(eigenvalues, self.eigenvalues(y, s), ratio ** 2):
            self.certificate = PITCHFORK_CERTIFIED
            return found
        return None

    def toward_branch_point(self, y, s, s_end, near=False):
        """From a state certified by a passed pitchfork's normal form (its buckled branch
        within ~1e-6 in s past the branch point), where the command runs back towards the
        branch point and ends short of it: (state at s_end, s_end); else ``None``.  Tried
        where a step from such a state is rejected, once per state.

        Steps cannot get there: Newton pins such a state along the soft mode only to ~1e-6
        (lambda_min / lambda_max ~ 1e-11 at 1e-9 past on the N = 3 neck), above the
        corrector's slack, so every natural step is 'far'; and [F_y F_s] is rank-deficient
        at a branch point, so arclength steps fail too.  So the branch point is found from
        the normal form instead: the buckled branch is followed the other way (away from
        the branch point, the path extended backwards) until lambda_min passes the margin
        test 100-fold; lambda_min's linear law through both states gives s*, the square
        root law y*, and :meth:`buckled_at` solves the end state from the far one.  (Two
        far states would avoid y's noise, but lambda_min's law is linear only to ~1e-4
        that far, which puts s* off by more.)  Where no run away leaves the noise (every
        step 'far': the N = 3 neck 1.8e-10 in s past it) and the command ends short of
        the branch point, the far state is this run's last one that passed the margin test
        100-fold (:attr:`clear_of_margin`, the branch followed since: no event between).
        That far (3e-5 in s on that neck) the linear law puts s* within ~1e-11 in s, so
        an end closer than that is not resolved: it is not certified, and the command
        fails on the last verified state.  ``near``: tried from a state verified by
        the margin test too, where a step towards the branch point ended below the margin
        on lambda_min's linear law (see where :meth:`run` calls it so)."""
        if not ((self.certificate or near) and self.normal_form_end and s < s_end
                and self.normal_form_tried != s):
            return None
        self.normal_form_tried = s
        certificate, self.certificate = self.certificate, ''
        lam, found = self.eigenvalues(y, s)[0], None
        far, remembered = self.away_from_branch_point(y, s, s_end - s, certificate), False
        if far is None and self.clear_of_margin is not None and self.clear_of_margin[0] < s:
            far, remembered = self.clear_of_margin, True
        if far is not None:
            s_far, far_state, far_eigenvalues = far
            rate = (far_eigenvalues[0] - lam) / (s_far - s)
            s_star = s - lam / rate if rate < 0.0 else -math.inf
            if s < s_star:
                ratio = math.sqrt((s_star - s) / (s_star - s_far))     # of y's amplitude
                y_star = (y - ratio * far_state) / (1.0 - ratio)
            if s < s_star and s_end < s_star:
                # lam is y's, whose soft component Newton pins only to ~1e-6, so the linear
                # law put s* 3.5e-11 in s off on the Haswell kernel (6e-11 .. 1e-10 from
                # other states), 2e-12 on SkylakeX: a command ending 6.5e-11 short of it
                # was not certified there; the branch point's own equations put it to ~1e-14
                solved = self.branch_point(y_star, s_star)
                if solved is not None and s_end < solved[1] \
                        and abs(solved[1] - s_star) <= 0.5 * (s_star - s):
                    y_star, s_star = solved
                found = self.buckled_at(s_star, y_star, far_state, s_far, s_end)
            elif s < s_star and not remembered:
                s_end = min(s_end, 2.0 * s_star - s)   # as far before s* as y was past it
                found = self.unbuckled_at(s_star, y_star, rate, s_end)
        if found is None:
            self.certificate = certificate
            return None
        return found, s_end

    def branch_point(self, y, s):
        """(y*, s*) of the branch point next to (y, s), to rounding, or ``None``: Newton
        (finite-difference Jacobian) on the regular extended system of DESIGN.md section
        3, {F(y, s) + beta u = 0, lambda_min(y, s) = 0, u(y, s) . F_s(y, s) = 0}, u the
        Jacobian's left singular vector of its smallest singular value (u0, the start's,
        in the unfolding term).  Regular at a simple branch point: lambda_min fixes s*,
        u . F_s the state along the critical mode (along which lambda_min is flat at a
        pitchfork), beta the unfolding.  Accepted where beta and the residual vanish to
        the tolerance and the solution stays within ``passage_radius`` of y."""
        problem, n = self.problem, self.problem.size
        try:
            u0 = np.linalg.svd(problem.jacobian(y, s))[0][:, -1]
        except np.linalg.LinAlgError:
            return None

        def system(z):
            x, t = z[:n], z[n]
            u = np.linalg.svd(problem.jacobian(x, t))[0][:, -1]
            return np.concatenate([problem.residual(x, t) + z[n + 1] * u0,
                                   [self.eigenvalues(x, t)[0] / self.scale,
                                    u @ problem.residual_s(x, t)]])

        z = np.append(np.asarray(y, dtype=float), [s, 0.0])
        h = 1e-7
        try:
            for _ in range(self.settings.newton_iterations):
                checkpoint()
                f = system(z)
                jac = np.column_stack([(system(z + h * e) - f) / h for e in np.eye(n + 2)])
                delta = np.linalg.solve(jac, f)
                if not np.all(np.isfinite(delta)):
                    return None
                z = z - delta
                if _inf_norm(delta) <= 1e-14 * (1.0 + _inf_norm(z)):
                    break
        except np.linalg.LinAlgError:
            return None
        x, t = z[:n], float(z[n])
        if (not self.residual_ok(x, t) or self.separation(x, y) > self.settings.passage_radius
                or abs(self.eigenvalues(x, t)[0]) > self.settings.critical_tol * self.scale):
            return None
        return x, t

    def unbuckled_at(self, s_star, y_star, rate, s_end):
        """The unbuckled minimum at s_end, just beyond the branch point (s*, y*) that a
        command from the buckled branch crosses back: Newton from y*; ``None`` unless it
        converges near y* to a verified minimum.  The passage is then listed, as one
        crossing the other way lists it.

        Verified by the margin test, or by the pitchfork's normal form: on the unbuckled
        branch lambda_min = -c (s - s*) / 2 where the buckled one's is c (s - s*) (``rate``
        = c, from the far state), so it is certified when positive and within 25 % of
        that prediction, as in :meth:`pitchfork_certified`; the command then ends with
        ``Track.certificate`` saying so (its steps away from s* see lambda_min grow)."""
        found = self.newton(y_star, s_end)
        if found is None or self.separation(found, y_star) > self.settings.passage_radius:
            return None
        eigenvalues = self.eigenvalues(found, s_end)
        predicted = -0.5 * rate * (s_end - s_star)
        if self.definite(eigenvalues):
            self.certificate = ''
        elif (self.soft_minimum(eigenvalues)
              and abs(eigenvalues[0] - predicted) <= 0.25 * predicted):
            self.certificate = PITCHFORK_CERTIFIED
        else:
            return None
        self.passages.append((s_star, y_star))
        return found

    def away_from_branch_point(self, y, s, length, certificate):
        """(s, state, eigenvalues) on the buckled branch through the certified ``y`` at s,
        followed backwards along the path by 1, 10 .. 1e7 times ``length`` until lambda_min
        passes the margin test 100-fold, or ``None``.  A short one may fail: a state that
        close to the branch point is known along the soft mode only to ~1e-6, so steps of
        a few 1e-12 in s are 'far' however short."""
        margin = 100.0 * self.settings.definiteness_tol
        for extent in length * 10.0 ** np.arange(8):
            if not _admissible(self.problem, s - extent):
                return None
            # (min_step: where its steps fail, give up after ~20 halvings, not 40)
            away = _Tracker(_Segment(self.problem, s, s - extent),
                            replace(self.settings, min_step=1e-6))
            away.normal_form_end = False
            away.stop_at_events = True      # a critical point on the way: not this branch
            away.contraction = PITCHFORK_CONTRACTION    # its steps are in the cubic valley
            try:
                far = away.run(y, certificate=certificate)
            except TrackingError:
                # its own margin test (scaled to this state's stiffness, not to the
                # command start's as this run's is) may refuse a state this run verified:
                # then there is no far state (the error must not end the command)
                return None
            if far.status != 'ok' or far.events or far.passages:
                continue                # too short to leave the noise (or the wrong way)
            if far.eigenvalues[0] > margin * max(abs(far.eigenvalues[-1]), self.scale * 1e-3):
                return s - extent, far.state, far.eigenvalues
        return None

    def pitchfork_certified(self, eigenvalues, far, fraction):
        """Whether a buckled state a ``fraction`` of the way (in s) from a supercritical
        branch point to a verified buckled minimum (eigenvalues ``far``, with a 100x
        margin) is a minimum although its lambda_min is below the margin test.

        On the buckled branch lambda_min = c (s - s*) (1 + O(s - s*)) (the normal form
        of a pitchfork), so it is predicted as ``fraction * far[0]``.  Certified when
        the computed lambda_min is positive and within 25 % of that prediction (rounding
        noise, ~1e-16 of lambda_max, cannot match a prediction 1e-12 of it: on the N = 3
        neck 1e-9 in s past, lambda_min / lambda_max = 9.4e-12 matched it to 2e-4) and
        every other eigenvalue passes the margin test (one soft mode only)."""
        predicted = fraction * far[0]
        return self.soft_minimum(eigenvalues) and abs(eigenvalues[0] - predicted) <= 0.25 * predicted

    def landing_at_event(self, landing, s_land, s_star):
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
        back = self.newton(landing, s_star)
        if (back is not None and self.separation(back, landing) < self.settings.max_state_step
                and self.definite(self.eigenvalues(back, s_star))):
            return back, s_star
        follower = _Tracker(_Segment(self.problem, s_land, s_star), self.settings)
        follower.stop_at_events = True      # a critical point on the way: not that minimum
        followed = follower.run(landing)
        if followed.events or followed.passages:
            return landing, s_land
        if followed.status != 'ok':         # verified as near s* as it was followed
            return followed.state, s_land + followed.s * (s_star - s_land)
        polished = self.newton(followed.state, s_star)     # the segment ends at s* to rounding
        if (polished is not None
                and self.separation(polished, followed.state) <= self.settings.same_state_tol
                and self.definite(self.eigenvalues(polished, s_star))):
            return polished, s_star
        return followed.state, s_star

    def continuous(self, kind, s_star, y_star, s_land, landing):
        """Whether the landing is the tracked minimum going on rather than a jump.

        It is when the landing is the departure itself (rounding level), or when
        the tracked branch does not go on past s* as an unstable equilibrium (as it
        does where a minimum buckles) and the landing closes in on the departure
        as the offset shrinks (a jump lands a finite distance away however close
        to s* it is frozen).  So a jump that lands on its own start cannot be made.
        """
        cfg = self.settings
        distance = self.separation(landing, y_star)
        if distance <= cfg.same_state_tol:
            return True
        if self.minimum_closes_in(s_star, y_star, s_land, landing):
            return True
        if distance >= cfg.max_state_step:
            return False
        onward = self.newton(y_star, s_land)
        if onward is not None and self.separation(onward, landing) > cfg.same_state_tol:
            if not self.definite(self.eigenvalues(onward, s_land)):
                return False        # the tracked state goes on, unstable: it buckled
        elif onward is not None and distance <= cfg.passage_radius:
            return True             # Newton from the departure is the landing: one regular
            #                         branch through both (a pitchfork run backwards)
        try:
            closer, _, _ = self.landing_state(kind, s_star, y_star, s_star + 0.01 * (s_land - s_star))
        except TrackingError:
            # not shown to close in: a landing farther than the critical state is known
            # stands; one within it is no move the tracker can tell from the departure
            # (bench_round_commands seed 0 stream 13, a buckled neck back onto its
            # symmetric branch: landed 3.1e-5 away, Newton from the departure and the
            # closer landing, 1e-8 in s past the pitchfork, both failing; a 'jump' the
            # reference does not make, from a start 2e-15 off one that gave none)
            return distance <= cfg.passage_radius
        if distance <= cfg.passage_radius:          # the same point, as well as it is known
            return self.separation(closer, landing) <= cfg.passage_radius
        return self.separation(closer, y_star) <= 0.3 * distance + cfg.same_state_tol

    def minimum_closes_in(self, s_star, y_star, s_land, landing):
        """Whether a verified minimum 100 times closer to s* lies between the departure
        and the landing, at most 0.3 as far from the departure: Newton from the point
        0.1 (a square root's law) or 0.01 (a line's) of the way to the landing.  Then
        one branch of minima runs through the critical point onto the landing.
        (config/neck.yaml, a buckled neck running back onto its symmetric branch 2.3e-4
        in s past a module's flat point, where that branch moves like sqrt(s - s_flat):
        the landing lay 0.017 rad away, Newton from the departure itself does not
        converge (its Jacobian is singular there) and the slide at the closer s, a flow
        with lambda_min ~ 1 N/m, did not rest, so a jump was reported that the reference
        does not make.)  Past a fold no equilibrium is near the departure, and past a
        subcritical branch point the branch through it is unstable; and the minimum found
        is followed onto the landing, so the two are one branch."""
        if self.following_onto_landing:
            return False
        s_closer = s_star + 0.01 * (s_land - s_star)
        distance = self.separation(landing, y_star)
        for fraction in (0.1, 0.01):
            closer = self.newton(y_star + fraction * (landing - y_star), s_closer)
            if (closer is not None
                    and self.separation(closer, y_star) <= 0.3 * distance
                    and self.definite(self.eigenvalues(closer, s_closer))):
                return self.leads_to(closer, s_closer, s_land, landing)
        return False

    def leads_to(self, y, s, s_land, landing):
        """Whether the minimum (y, s) is followed to s_land without an event, onto
        ``landing``."""
        follower = _Tracker(_Segment(self.problem, s, s_land), self.settings)
        follower.following_onto_landing = True
        try:
            onward = follower.run(y)
        except TrackingError:
            return False
        return (onward.status == 'ok' and not onward.events
                and self.separation(onward.state, landing) <= self.settings.passage_radius)

    def landing_state(self, kind, s_star, y_star, s_land, s_end=None, reach=1e-3):
        """Step off along the critical mode at frozen s_land and slide: (landing, ambiguous, s_land).

        With ``s_end`` given, a flow that finds no minimum (it rests on saddles near
        the fold's ghost) is retried frozen further past the event, up to ``reach`` in s
        (compared as the s it was set to: (s* + 1e-3) - s* may round below 1e-3, and
        the retries then never ended, e.g. s* = 0.999638580089214).
        """
        last = s_star + max(reach, 1e-3)
        while True:
            try:
                return (*self._land_once(kind, s_star, y_star, s_land), s_land)
            except TrackingError:
                further = s_star + 100.0 * (s_land - s_star)
                if s_end is None or s_land >= last or (
                        further > s_end and not _admissible(self.problem, further)):
                    raise
                s_land = min(further, last)

    def _land_once(self, kind, s_star, y_star, s_land):
        problem = self.problem
        _, psi = self.critical(y_star, s_star)
        sides = []
        on_constraints = getattr(problem, 'on_constraints', lambda *_: True)
        for sign in (1.0, -1.0):
            start = problem.project(y_star + sign * self.step_off_vector(psi), s_land)
            if not on_constraints(start, s_land):
                # no admissible state next to the step-off (past a linkage limit): a
                # flow from it would start in no configuration of the mechanism
                continue
            sides.append((problem.energy(start, s_land), sign, start))
        sides.sort(key=lambda t: t[0])
        if kind == FOLD:
            sides = sides[:1]
        landings, alternatives = [], []
        for _, _, start in sides:
            self.crossing_alternatives = []
            landing = self.slide(start, s_land)
            if landing is not None:
                landings.append(landing)
                alternatives += self.crossing_alternatives
        if not landings:
            raise TrackingError(f'could not land after the {kind} at s={float(s_star)!r}')
        landings.sort(key=lambda y: problem.energy(y, s_land))
        ambiguous = (len(landings) == 2
                     and self.separation(landings[0], landings[1]) > 1e-6)
        return landings[0], ambiguous or self.lands_elsewhere(alternatives, landings[0], s_land)

    def lands_elsewhere(self, alternatives, landing, s):
        """Whether a rigid flow from one of the ``alternatives`` (states out along the
        other half-branches of a flat crossing the landing flow passed) rests more than
        1e-6 from ``landing``: then the landing is ambiguous, as where the two sides of a
        branch point land differently (e.g. the mirror images of a symmetric neck, when
        the steepest half-branch wins by 3e-4 of its descent rate: config/neck.yaml,
        bench_round_commands seed 0, stream 16).  Their own crossings are not followed up."""
        for state in alternatives:
            other = self.slide(state, s, rigid_first=True)
            if other is not None and self.separation(other, landing) > 1e-6:
                return True
        return False

    def mirror_lands_too(self, y_star, landing, s):
        """Whether the landing's mirror image is as good a landing: the problem is
        mirror-symmetric at s (its optional ``mirror``), the departure its own mirror
        image (to ARC_RESOLUTION) and the landing not (by more than 1e-6).  Nothing in
        the model then chooses between the two; rounding does (bench_round_commands
        seed 3, streams 1, 10 and 19: folds off a flat module of a mirror-symmetric
        neck, the lower side of the critical mode landing on one image or the other as
        the departure's last bits went)."""
        mirror = getattr(self.problem, 'mirror', None)
        image = None if mirror is None else mirror(y_star, s)
        return (image is not None and self.separation(image, y_star) <= ARC_RESOLUTION
                and self.separation(mirror(landing, s), landing) > 1e-6)

    def separation(self, a, b):
        """Distance of two states (weighted), with angles compared modulo 2 pi."""
        return self.step_norm(self.canonical(a - b))

    def canonical(self, y):
        return getattr(self.problem, 'canonical', lambda v: v)(y)

    def landing_offset(self, kind, y_star, s_star):
        """How far past the event (in s) the parameters are frozen for landing.

        Fold: far enough that the overdamped flow feels a residual (a short
        command has a small F_s).  Branch point: far enough that a new minimum
        next to the critical point (a supercritical pitchfork: the mechanism
        buckles smoothly) has a resolvable stiffness, ~1e-4 of the scale.
        """
        cfg = self.settings
        if kind == FOLD:
            fs = _inf_norm(self.problem.residual_s(y_star, s_star))
            needed = 1e-7 * self.scale / fs if fs > 0 else 0.0
            return max(cfg.landing_offset, min(needed, 1e-3))
        # d lambda_min / ds measured on the approach (the branch is regular up to s*).
        rate = abs(self.last_rate) if self.last_rate else 0.0
        needed = 1e-4 * self.scale / rate if rate > 0 else 1e-3
        return max(cfg.landing_offset, min(needed, 1e-3))

    def slide(self, y, s, rigid_first=False):
        """Overdamped gradient flow at fixed s until it comes to rest, then Newton polish.

        Integrated by scipy's LSODA stepper (stiff-capable: the flow is slow near
        the ghost of a fold and fast elsewhere), stopping at the first step where
        the velocity is negligible.  At rest on a minimum the state is polished;
        at rest on a saddle it is pushed off along the unstable mode.  Where it rests
        off the constraints (the problem's ``descent`` may treat them as slightly
        elastic, to glide through kinematic singularities), it flowed in another model:
        the flow starts over from the same state by the problem's optional
        ``rigid_descent``, which rests only on equilibria of the model itself
        (``rigid_first``: from the start, as from a flat crossing's half-branch).
        Where the flow came to rest on a minimum but was damped on the way (the
        problem's optional ``damped``: it passed a module near flat as elastic
        chords), the rigid flow from the same start decides, where it rests on one.
        """
        problem = self.problem
        start = y
        flow = [problem.descent]
        # (not in a tracker that stops at events: its landings, at a critical point reached
        # to rounding, are never kept but where the minimum goes on; there the rigid flows
        # only cost: seed 1, stream 10 of bench_round_commands, 14 in one such run, 40 s)
        rigid = None if self.stop_at_events else getattr(problem, 'rigid_descent', None)
        if rigid_first and rigid is not None:
            flow[0] = rigid
        # Far below any velocity met on the way (near a fold's ghost the landing
        # offset keeps it above ~1e-7 scale), so the flow stops only at rest.
        tol = 1e-10 * self.scale
        # a rigid flow gets an eighth of the budget: stalled at a flat module, where it
        # does not rest, it used it all (16 s on config/neck.yaml; 14000 evaluations the
        # most a landing took there)
        rigid_budget = self.settings.flow_evaluations // 8
        budget = [rigid_budget if flow[0] is rigid else self.settings.flow_evaluations]
        damped_at = getattr(problem, 'damped', None) if rigid is not None else None
        was_damped = [False]

        def watch(solver):              # at each solver step of the elastic flow
            if not was_damped[0] and damped_at(solver.y, s):
                was_damped[0] = True

        def velocity(_t, v):
            budget[0] -= 1
            if budget[0] < 0:
                raise _FlowBudgetExceeded
            if budget[0] % 8 == 0:  # inside a solver step too: a neck's takes ~30
                checkpoint()        # evaluations (scipy >= 1.17's LSODA is re-entrant)
            return flow[0](v, s)

        for _ in range(5):
            try:
                # a rigid flow near a flat module is integrated as accurately as the
                # reference's: there its way (and its rest) turns on ~1e-7 of it (it rested
                # at the crossing of two branches, or crossed onto the other one)
                rest = (self.rigid_flow_to_rest(velocity, y, s, tol) if flow[0] is rigid
                        else self.flow_to_rest(velocity, y, tol,
                                               stop=None if damped_at is None else watch))
            except _FlowBudgetExceeded:
                return None
            if rest is None:
                return None
            projected = problem.project(rest, s)
            if (rigid is not None and flow[0] is not rigid
                    and self.step_norm(projected - rest) > self.settings.same_state_tol):
                flow[0] = rigid             # it rested as elastic chords: the same flow, rigid
                budget[0] = min(budget[0], rigid_budget)
                continue
            y = projected
            polished = self.newton(y, s)
            if polished is None or (self.step_norm(polished - y) >= 1e-2
                                    and not self.downhill(y, polished, s)):
                continue
            if (self.definite(self.eigenvalues(polished, s))
                    and problem.energy(polished, s) <= problem.energy(y, s) + 1e-12 * self.scale):
                if was_damped[0] and flow[0] is not rigid:
                    rest = self.rigid_rest(start, s)
                    return polished if rest is None else rest
                return None if self.stalled_at_linkage_limit(flow[0] is rigid, polished, s) \
                    else polished
            _, modes = problem.stability(polished, s)      # a saddle: push off
            y = problem.project(polished + self.step_off_vector(modes[:, 0]), s)
        return None

    def rigid_rest(self, start, s):
        """The rigid flow's minimum from ``start``, where the elastic flow from there
        was damped on its way to a minimum (its chords gave where a module passed near
        flat, so it may have crossed onto a branch the rigid mechanism does not reach:
        bench_round_commands seed 0, stream 11, head load 0.5 N, a module's flat
        neighbour swung through to (pi/3, 2 pi/3), 2.2 J below where the rigid flow and
        the reference rest).  None where it rests on none (stalled at a flat module, out
        of budget): the elastic flow's minimum stands."""
        alternatives = list(self.crossing_alternatives)
        rest = self.slide(start, s, rigid_first=True)
        if rest is None:
            self.crossing_alternatives = alternatives
        return rest

    def stalled_at_linkage_limit(self, rigid, y, s):
        """Whether a rigid flow's rest ``y`` is at a linkage limit (a module flat, at the
        crossing of two branches of its configurations), where it stalls: the projection
        on the constraints is undefined there, the flow goes on along one of the branches
        leaving the crossing (test/reference_paths.py takes the steepest), and the
        reduced Hessian's margin test does not apply.  (config/neck.yaml, bench_round_
        commands seed 0, stream 10, head load -> -10 N: it rested with module 0 flat,
        2e-7 rad, where the reference's flow goes on to 0.26 rad.)"""
        return bool(rigid and self.linkage_limit(y, s))

    def downhill(self, a, b, s, samples=16):
        """Whether the energy falls all the way along the straight line from ``a`` to ``b``
        (projected): then Newton's ``b`` is the minimum of the valley the flow came to
        rest in, however far, not one across a ridge.  In a very soft valley (lambda_min
        ~1e-6 of the scale, a neck just past buckling) the flow comes to rest, by its
        velocity, a few 1e-2 short of the minimum."""
        problem = self.problem
        energies = [problem.energy(problem.project(a + t * (b - a), s), s)
                    for t in np.linspace(0.0, 1.0, samples + 1)]
        slack = 1e-12 * (abs(energies[0]) + self.scale)
        return all(e1 <= e0 + slack for e0, e1 in zip(energies, energies[1:]))

    def flow_to_rest(self, velocity, y, tol, rtol=1e-7, stop=None):
        """Integrate dy/dt = velocity until |velocity| <= tol, or until ``stop(solver)``
        (called after each step) returns a state, which is then returned; ``None`` if
        the solver fails."""
        with np.errstate(all='ignore'):
            solver = LSODA(velocity, 0.0, y, 1e7 / self.scale, rtol=rtol, atol=1e-3 * rtol)
            while solver.status == 'running':
                checkpoint()            # between solver steps (and inside: velocity)
                solver.step()
                if _inf_norm(velocity(solver.t, solver.y)) <= tol:
                    return solver.y
                if stop is not None:
                    stopped = stop(solver)
                    if stopped is not None:
                        return stopped
        return solver.y if solver.status == 'finished' else None

    def rigid_flow_to_rest(self, velocity, y, s, tol):
        """:meth:`flow_to_rest` for the rigid flow, going on through the flat crossings
        of the problem's linkage (its optional ``flatness`` and ``crossing_ways``).

        At a module's flat crossing the projected flow stalls (the projection is
        undefined there) where the mechanism goes on along one of the half-branches
        leaving it: each leg stops once the flattest module is CROSSING_APPROACH flat
        (or ten times flatter than the leg's start), and where a crossing is next to it
        the flow goes on from :meth:`through_crossing`'s half-branch; else (a module
        flat at a linkage limit, no crossing) it flows on.  ``None`` where no way leads
        out; after MAX_CROSSING_LEGS legs it flows on without stopping (as before there
        was this rule: a flow creeping onto a linkage limit is not cut short)."""
        flatness = getattr(self.problem, 'flatness', None)
        if flatness is None:
            return self.flow_to_rest(velocity, y, tol, 1e-10)
        for _ in range(MAX_CROSSING_LEGS):
            level = min(CROSSING_APPROACH, 0.1 * flatness(y, s))
            rest = self.flow_to_rest(velocity, y, tol, 1e-10,
                                     stop=self.crossing_stop(y, s, flatness, level))
            if rest is None or flatness(rest, s) >= level:
                return rest
            onward = self.through_crossing(rest, s)
            if onward is False:
                return None
            y = rest if onward is None else onward
        return self.flow_to_rest(velocity, y, tol, 1e-10)

    def crossing_stop(self, y, s, flatness, level):
        """The ``stop`` of a rigid flow's leg from ``y``: the first state it reaches
        ``level`` flat at, after a step or inside one.  A step over a module's flat
        crossing (both its rods turned through its base line, the problem's optional
        ``turned_through_base``) is searched on the step's dense output, as the
        reference's legs are: without, one of two mirror-image flows passed its crossing
        within a step and the other stopped at its own (the upright N = 2 paper neck's
        branch point under a head load, test_stack_formulations)."""
        turned = getattr(self.problem, 'turned_through_base', None)
        previous = [y]

        def stop(solver):
            v = solver.y
            if flatness(v, s) < level:
                return v
            if turned is not None and turned(previous[0], v, s):
                flattest = self.flattest_in_step(solver, s, flatness)
                if flatness(flattest, s) < level:
                    return flattest
            previous[0] = v
            return None
        return stop

    @staticmethod
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

    def through_crossing(self, y, s):
        """The state to flow on from, where the flow reached ``y`` next to a flat
        crossing: out along the half-branch of steepest descent (the energy drop per
        unit length from the crossing, :func:`.flat_crossing.ways_out`) among those the
        mechanism moves away on; the others are kept in ``crossing_alternatives``
        (a landing that passed one is ambiguous where they land elsewhere).  None if
        ``y`` is at no crossing; False if no half-branch leads away (it rests there)."""
        ways = self.problem.crossing_ways(y, s)
        if ways is None:
            return None
        if not ways:
            return False
        ways.sort(key=lambda way: way[0], reverse=True)
        self.crossing_alternatives.extend(state for _, state in ways[1:])
        return ways[0][1]

    def step_off_vector(self, mode):
        """``mode`` scaled to the step-off distance in the weighted state norm."""
        return self.settings.step_off * mode / max(self.step_norm(mode), 1e-300)


def _bracket(test, a, b, tries=8):
    """(a, b, test(a), test(b)) with test(b) < 0 where it can be reached.

    b is a verified indefinite state, so lambda_min there is below a tolerance
    but may still be positive: extend the bracket past it by the secant.
    """
    test_a, test_b = test(a), test(b)
    for _ in range(tries):
        slope = (test_a - test_b) / (b - a)
        if test_b < 0.0 or not slope > 0.0:
            break
        a, test_a, b = b, test_b, b + 2.0 * test_b / slope
        test_b = test(b)
    return a, b, test_a, test_b


def _shrink_bracket(test, a, b, test_a, test_b, xtol=1e-12):
    """Narrow [a, b] (test(a) > 0 > test(b)) around the root to about xtol.

    Secant estimates, each bracketed by two probes 2% of the width either side,
    so a test function that is nearly linear there (lambda_min at a simple
    crossing) shrinks the bracket ~25-fold per round.  Probes that cannot be
    solved (a singular Jacobian right at the root) are skipped.
    """
    for _ in range(60):
        width = b - a
        if width <= xtol * max(1.0, abs(b)):
            break
        guess = a + width * test_a / (test_a - test_b)
        nudge = 0.02 * width
        progress = False
        for t in sorted({min(max(guess - nudge, a + nudge), b - nudge),
                         min(max(guess + nudge, a + nudge), b - nudge)}):
            try:
                value = test(t)
            except _Lost:
                continue
            progress = True
            if value > 0.0 and t > a:
                a, test_a = t, value
            elif value <= 0.0 and t < b:
                b, test_b = t, value
        if not progress:
            break
    return a, b, test_a, test_b


def _admissible(problem, s):
    check = getattr(problem, 'admissible', None)
    return True if check is None else check(s)


class _Segment:
    """The part of a path between s_a and s_b, reparametrised to t in [0, 1] (either direction)."""

    def __init__(self, problem, s_a, s_b):
        self.problem, self.s_a, self.ds = problem, s_a, s_b - s_a
        self.size = problem.size
        for name in ('state_weights', 'canonical'):
            if hasattr(problem, name):
                setattr(self, name, getattr(problem, name))
        if hasattr(problem, 'on_constraints'):
            self.on_constraints = lambda y, t: problem.on_constraints(y, self.at(t))
        if hasattr(problem, 'rigid_descent'):
            self.rigid_descent = lambda y, t: problem.rigid_descent(y, self.at(t))
        if hasattr(problem, 'damped'):
            self.damped = lambda y, t: problem.damped(y, self.at(t))
        if hasattr(problem, 'mirror'):
            self.mirror = lambda y, t: problem.mirror(y, self.at(t))
        if hasattr(problem, 'eigenvalues'):
            self.eigenvalues = lambda y, t: problem.eigenvalues(y, self.at(t))

    def at(self, t):
        return self.s_a + t * self.ds

    def residual(self, y, t):
        return self.problem.residual(y, self.at(t))

    def jacobian(self, y, t):
        return self.problem.jacobian(y, self.at(t))

    def residual_s(self, y, t):
        return self.ds * self.problem.residual_s(y, self.at(t))

    def energy(self, y, t):
        return self.problem.energy(y, self.at(t))

    def energy_s(self, y, t):
        return self.ds * self.problem.energy_s(y, self.at(t))

    def stability(self, y, t):
        return self.problem.stability(y, self.at(t))

    def descent(self, y, t):
        return self.problem.descent(y, self.at(t))

    def project(self, y, t):
        return self.problem.project(y, self.at(t))


def track(problem: PathProblem, y0, settings: TrackerSettings = TrackerSettings(),
          certificate='') -> Track:
    """Follow the stable equilibrium at ``y0`` (s = 0) to s = 1, jumping where it must.

    Raises :class:`TrackingError` if ``y0`` is not (close to) a stable
    equilibrium at s = 0; every other outcome is reported in the result.
    ``certificate``: the :attr:`Track.certificate` ``y0`` was verified with, if any.
    Where ``settings.time_budget`` runs out, the result is the last verified state
    (status 'failed', the reason in ``message``).
    """
    tracker = _Tracker(problem, settings)
    y0 = np.array(y0, dtype=float)
    if settings.time_budget is None:    # (the Budget's with-block costs ~0.6 us)
        return tracker.run(y0, certificate=certificate)
    with Budget(settings.time_budget, settings.clock):
        return tracker.run(y0, certificate=certificate)
    return tracker.out_of_budget()      # reached only where the budget ran out


def track_settled(problem: PathProblem, y0, settings: TrackerSettings = TrackerSettings(),
                  certificate='') -> Track:
    """:func:`track` from ``y0``, or, where ``y0`` is not a stable equilibrium at s = 0,
    from where the mechanism released there settles (:func:`settle`, from ``y0``
    projected); the settling and the tracking share one ``settings.time_budget``."""
    started = None if settings.time_budget is None else settings.clock()

    def left():
        """``settings`` with what is left of the time budget."""
        if started is None:
            return settings
        spent = settings.clock() - started
        return replace(settings, time_budget=max(settings.time_budget - spent, 0.0))

    try:
        return track(problem, y0, settings, certificate)
    except TrackingError:
        pass
    y0 = settle(problem, problem.project(np.array(y0, dtype=float), 0.0), 0.0, left())
    return track(problem, y0, left())


def settle(problem: PathProblem, y0, s=0.0, settings: TrackerSettings = TrackerSettings()):
    """Where the overdamped mechanism released at ``y0`` comes to rest (at fixed s).

    Returns the verified stable state, or raises :class:`TrackingError`.  A start
    on a saddle's stable set is pushed off along the unstable mode (both ways;
    the lower-energy landing wins) so that the answer is always a minimum.
    ``settings.time_budget`` bounds it too (running out raises TrackingError).
    """
    with Budget(settings.time_budget, settings.clock):
        return _settle(problem, np.array(y0, dtype=float), s, settings)
    raise TrackingError(f'time budget of {settings.time_budget:g} s used up before the '
                        f'mechanism came to rest')


def _settle(problem, y0, s, settings):
    """:func:`settle` without its time budget."""
    tracker = _Tracker(problem, settings)
    eigenvalues, modes = problem.stability(y0, s)
    tracker.scale = max(float(np.max(np.abs(eigenvalues))), 1e-300)   # any start, not only a minimum
    y = tracker.newton(y0, s) if tracker.residual_ok(y0, s) else None
    if y is None or tracker.definite(tracker.eigenvalues(y, s)):
        landing = tracker.slide(y0, s)        # not on a saddle: the flow decides alone
        if landing is not None:
            return landing
    candidates = []
    for sign in (1.0, -1.0):
        start = y0 if y is None else y
        eig, modes = problem.stability(start, s)
        candidate = tracker.slide(problem.project(start + sign * tracker.step_off_vector(modes[:, 0]), s), s)
        if candidate is not None:
            candidates.append(candidate)
    if not candidates:
        raise TrackingError('no stable equilibrium reached from the given state')
    return min(candidates, key=lambda v: problem.energy(v, s))
