"""The tracker's tolerances and step limits, each named and cited where it is used."""
from __future__ import annotations

from dataclasses import dataclass
import time
from typing import Callable

from ..numerics.tolerances import DEFINITENESS_TOL

#: Newton's contraction test on a buckled branch followed away from its branch point
#: (:func:`.branch_switching.away_from_branch_point`): in that nearly cubic valley Newton
#: converges linearly, by 2/3 an iterate (x - x^3 / (3 x^2)), so the usual 1/2 stops it at
#: a state up to 2x off the minimum whose residual already passes the tolerance (the
#: unloaded module 1.5e-8 in rho past its branch point: 3.5e-4 rad for 1.76e-4; then 180
#: false jumps).  Not everywhere: it made the N = 3 neck's command up to 1e-10 before its
#: branch point list a false passage 7e-8 early.
PITCHFORK_CONTRACTION = 0.75
#: A critical point is located to this in s (docs/model.md section 3): a command that ends
#: closer than this past one ends at the critical point itself (see
#: :func:`.lander.at_the_critical_point`).
LOCATION_TOL = 1e-9
#: A command ending closer than this in s past a supercritical branch point ends at the
#: branch point itself: a buckled state that close is not told from it (the normal form's
#: linear law of lambda_min puts s* within ~1e-11 from a state 3e-5 in s away on the
#: N = 3 neck: see :func:`.branch_switching.toward_branch_point`).  The unloaded paper
#: module commanded to rho = 1.0 from below met its branch point 4.4e-13 in s before the
#: end, rho's rounding, and ended 'past' it 8e-9 rad out, a state the next command back
#: up could not leave (the time budget ran out).
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
#: chord gradient (over l_ref) is below this (see :func:`.flows.rigid_flow_to_rest`); it
#: goes on through at most MAX_CROSSING_LEGS such stops per flow.
CROSSING_APPROACH = 1e-3
MAX_CROSSING_LEGS = 16
#: A landing flow's Jacobian (the problem's optional ``descent_jacobian``, for LSODA's
#: corrector) is charged to the flow's evaluation budget as this many velocities: what
#: it costs (a neck N = 2..10: 1.7-2.2 velocities' CPU time).
JACOBIAN_EVALUATIONS = 2
#: A landing flow evaluates its velocity after a step, to see whether it is at rest
#: (|velocity| <= its tolerance), only where LSODA's own estimate of it (the Nordsieck
#: history's derivative, :func:`.flows.speed_estimate`) is below this many tolerances:
#: over bench_neck_paths seeds 0-1 (133507 steps) the estimate was at most 35
#: tolerances at a step the flow stopped at, and 86 % of the steps were above 1e3.
REST_CHECK_MARGIN = 1e3
#: A landing flow (elastic) is integrated to this relative tolerance (LSODA's rtol).
ELASTIC_FLOW_RTOL = 1e-7
#: A rigid landing flow is integrated to this relative tolerance (LSODA's rtol; the
#: reference's, test/reference_paths.py): near a module folded flat its way, and where
#: it rests, turns on ~1e-7 (config/neck.yaml's fold at s = 0.0823: at rtol 1e-7 it
#: came to rest at module 0's flat crossing, the reference past it).
RIGID_FLOW_RTOL = 1e-10
#: A rigid landing flow starting with every module at least this flat (the problem's
#: ``flatness``, its smallest chord gradient over l_ref) is integrated at
#: ELASTIC_FLOW_RTOL until a module is this flat, then at RIGID_FLOW_RTOL: far from flat
#: the way is no knife edge, and half the rigid flows start 0.4-0.6 flat
#: (bench_neck_paths seeds 0-1: the same 108 answers, 13.2 -> 12.1 s of CPU in all).
FAR_FROM_FLAT = 0.1
#: Where a command ends on a module's flat crossing, a mechanism released there that
#: comes to rest farther than this (weighted state norm) has jumped (see
#: :func:`.linkage_limits.snap_at_end_crossing`): ten times the passage radius; a minimum
#: going on through the crossing stays ~sqrt(the step in s) of it, ~1e-6 at the last steps.
SNAP_DISTANCE = 1e-3
#: Next to an exact crossing (see ``flat_crossing.rounding``), Newton's iterates that
#: stall within this many rounding radii of it are at it: the radius is an
#: order-of-magnitude estimate of the chord's rounding (bench_round_commands seed 2,
#: stream 11: stalled at 1.015 radii, the residual 0.26, 1e7 times the tolerance, since
#: no state there is resolved better).
EXACT_CROSSING_STALL = 4.0
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


@dataclass(frozen=True)
class TrackerSettings:
    """Tolerances and step limits of :func:`track` (named, so they can be tuned and cited)."""

    #: A state change this large (weighted state norm) is no longer a step's: the
    #: landings' leashes and the nearness tests of critical states are counted in it.
    max_state_step: float = 0.05
    #: Largest predicted motion in one step: the problem's ``motion`` (a neck: its largest
    #: node displacement over l_ref), else the weighted state norm.  0.2: the tangent
    #: predictor misses by ~its square, which Newton removes in one more iteration than
    #: at 0.1, for half the steps; where it does not converge, the step is halved before
    #: anything else (:meth:`.follower.Follower.rejected`).
    max_step_motion: float = 0.2
    #: The smallest eigenvalue may be predicted to shrink to this fraction per step.
    eigenvalue_shrink: float = 0.5
    #: A step's end is on its start's branch where the trapezoid rule y1 - y0 = ds (t0 +
    #: t1) / 2 (t the branch's tangents) holds to this fraction of the step's motion
    #: (:func:`.step_rules.on_one_branch`).  On a smooth branch its defect is ds^3 / 12
    #: times the third derivative, under 0.14 of the motion on 99 % of bench_neck_paths'
    #: steps; a step across a fold onto another branch leaves the snap unexplained (0.63 of
    #: it where a random N = 3 neck's module 2 snaps 0.16 rad inside one step of 0.08 in
    #: s).  Shortening a step is the only cost of a false alarm.
    trapezoid_defect: float = 0.25
    #: Residual accepted as an equilibrium, relative to the stability scale.
    residual_tol: float = 1e-10
    #: Positive definite means lambda_min > this * |lambda_max| (see :mod:`..tolerances`).
    definiteness_tol: float = DEFINITENESS_TOL
    #: Newton iterations per corrector.
    newton_iterations: int = 12
    #: Below this |psi . F_s| / |F_s| the critical point is a branch point.
    branch_tol: float = 1e-6
    #: The mechanism lands with the parameters frozen this far past the event (in s,
    #: at least; made larger where the command is short, see ``lander.landing_offset``).
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
    #: is a critical point reached to rounding (see ``lander.end_at_rounding``).
    rounding_critical: float = 1e-5
    #: Past a linkage limit the minimum is looked for this far on (in s, and 100 times
    #: closer, to see that it closes in: see ``linkage_limits.through_linkage_limit``).
    linkage_offset: float = 1e-6
    #: Seconds one command may take before it gives up (None: no limit): checked at every
    #: check point (:func:`..bounded_work.checkpoint`), nested landings, followers and
    #: bisections included, so a command ends at most one check point's work past it,
    #: on its last verified state (status 'failed').
    time_budget: float | None = None
    #: The clock ``time_budget`` is read on (tests inject a counting clock).
    clock: Callable[[], float] = time.perf_counter
    #: End the run at its first jump (status 'ok', ``s`` short of 1 where there is one):
    #: the event as the full run reports it (its landing decides that it is a jump), no
    #: tracking past it.  For questions that need only where stability is first lost (a
    #: neck's critical head load, ``tensegrity tolerance head-load``).  Not passed on to
    #: the runs a landing nests (:meth:`.run_state.RunState.sub_run`).
    stop_at_first_event: bool = False
    #: Evaluate the problem's gradient flows by its compiled kernels where it has them
    #: (a neck: :mod:`..stack_flow_kernel`, numba, loaded on first use; the same
    #: equations to rounding, ~10 times faster).  Off by default: a quasi-static node
    #: never loads numba.  For batch questions (``tensegrity tolerance`` on a neck).
    compiled_flows: bool = False
