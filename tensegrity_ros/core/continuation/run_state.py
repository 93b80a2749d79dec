"""One tracking run's state and the primitives every concept verifies states with.

A :class:`RunState` holds the problem, the settings, the stiffness scale the
tolerances are relative to, and what the run learnt on the way (passages, the
certificate of the current state, states Newton did not resolve).  Its methods are
the verified-state toolkit: the Newton corrector, the stability eigenvalues, the
margin test, the weighted state norm.  The concepts (:mod:`.follower`,
:mod:`.locator`, :mod:`.lander`, :mod:`.flows`, ...) are functions of a run.
"""
from __future__ import annotations

from dataclasses import replace
import math

import numpy as np

from .problem import SubPath
from .settings import UNRESOLVED_UPDATE
from .step_rules import energy_consistent, forward_rate, positive_definite
from ..numerics import bounded_work


def solve(matrix, rhs):
    """matrix^-1 rhs (2 x 2 in Python floats: no numpy scalars on the module's path)."""
    if matrix.shape == (2, 2):
        (a, b), (c, d) = matrix.tolist()
        r0, r1 = rhs.tolist()
        det = a * d - b * c
        if det == 0.0 or not math.isfinite(det):
            raise np.linalg.LinAlgError('singular 2x2 matrix')
        return np.array([(d * r0 - b * r1) / det, (a * r1 - c * r0) / det])
    return np.linalg.solve(matrix, rhs)


def inf_norm(v):
    return max(map(abs, v.tolist()), default=0.0)


class RunState:
    """One tracking run: the problem, the scales and the settings, and what it found."""

    def __init__(self, problem, settings, nested):
        self.problem = problem
        self.settings = settings
        #: ``nested(problem, settings)``: a fresh tracker for a sub-path (a landing
        #: followed back to its event, a buckled branch away from its branch point).
        self.nested = nested
        self.scale = 1.0          # stability scale, set from the start state
        self.steps = 0
        self.last_rate = None     # d lambda_min / ds over the last accepted step
        self.base_scale = None    # the stability scale at the start
        self.passages = []        # (s, state) of the branch points passed continuously
        self.undecided = []       # Undecided: the passages whose side doubles cannot decide
        self.certificate = ''     # how the final state's definiteness was shown (Track)
        #: Newton's contraction test (see :meth:`newton`)
        self.contraction = 0.5
        #: Stop (failed) at a critical point instead of landing: a landing's own
        #: minimum followed back to its event (nested landings there could recurse).
        self.stop_at_events = False
        #: The s of the critical point it stopped at so (the run then ended failed).
        self.stopped_at_event = None
        #: From a pitchfork-certified state, solve a command's end short of its branch
        #: point by the normal form (off in the tracker that follows the branch away for it).
        self.normal_form_end = True
        self.normal_form_tried = None   # the s it was tried at (once per state)
        self.normal_form_failed = None  # lambda_min where it last failed (this branch)
        #: Set on the run that follows a minimum onto a landing
        #: (:func:`.lander.leads_to`): its own landings are not checked that way again.
        self.following_onto_landing = False
        #: The last verified state (what a spent time budget returns).
        self.kept = None
        self.newton_unresolved = False  # the last newton() stopped short of rounding level
        #: The start, or the state a step ended on, where Newton did not resolve it (see
        #: :func:`.lander.end_at_rounding`).
        self.unresolved = None
        #: (s, state, eigenvalues) of the last state whose lambda_min passed the margin
        #: test 100-fold (see :func:`.branch_switching.toward_branch_point`).
        self.clear_of_margin = None
        #: States out along the other half-branches of the flat crossings a landing flow
        #: passed (see :func:`.flows.through_crossing`).
        self.crossing_alternatives = []
        weights = getattr(problem, 'state_weights', None)
        self.weights = None if weights is None else np.asarray(weights, dtype=float)

    def sub_run(self, s_a, s_b, settings=None):
        """A fresh tracker on the part of this path from s_a to s_b (never stopping at
        its first event: a landing's checks read its events past it)."""
        settings = self.settings if settings is None else settings
        if settings.stop_at_first_event:
            settings = replace(settings, stop_at_first_event=False)
        return self.nested(SubPath(self.problem, s_a, s_b), settings)

    # -- norms -----------------------------------------------------------------
    def step_norm(self, v):
        """Size of a state change for the step limits (weighted max norm)."""
        return inf_norm(v if self.weights is None else self.weights * v)

    def motion(self, y, s, dy):
        """How far a state change dy moves the mechanism at (y, s), for the step bound:
        the problem's optional ``motion`` (a neck: its largest node displacement), else
        the weighted state norm."""
        measure = getattr(self.problem, 'motion', None)
        return self.step_norm(dy) if measure is None else measure(y, s, dy)

    def separation(self, a, b):
        """Distance of two states (weighted), with angles compared modulo 2 pi."""
        return self.step_norm(self.canonical(a - b))

    def canonical(self, y):
        return getattr(self.problem, 'canonical', lambda v: v)(y)

    def step_off_vector(self, mode):
        """``mode`` scaled to the step-off distance in the weighted state norm."""
        return self.settings.step_off * mode / max(self.step_norm(mode), 1e-300)

    # -- verification -------------------------------------------------------
    def residual_ok(self, y, s, factor=1.0):
        return (inf_norm(self.problem.residual(y, s))
                <= factor * self.settings.residual_tol * self.scale)

    def definite(self, eigenvalues):
        return positive_definite(eigenvalues, self.scale, self.settings)

    def newton(self, y, s):
        """Newton corrector; ``None`` unless it contracts and converges.

        It iterates to rounding level, not just below the acceptance tolerance:
        near a critical point a residual r leaves an error r / lambda_min along
        the soft mode, which is what the stability margin is computed from.
        Contracting: each update at most ``self.contraction`` of the one before (1/2;
        the tracker that follows a buckled branch away from its branch point allows
        :data:`.settings.PITCHFORK_CONTRACTION`).
        """
        tol = self.settings.residual_tol * self.scale
        contraction = self.contraction
        previous = size = math.inf
        f = self.problem.residual(y, s)
        for _ in range(self.settings.newton_iterations):
            try:
                delta = solve(self.problem.jacobian(y, s), f)
            except np.linalg.LinAlgError:
                break
            size = inf_norm(delta)
            if not math.isfinite(size) or size > contraction * previous + 1e-15:
                break                                   # no longer contracting
            y = y - delta
            f = self.problem.residual(y, s)
            previous = size
            if size <= 1e-14 * (1.0 + inf_norm(y)):
                break
        self.newton_unresolved = not size <= UNRESOLVED_UPDATE * (1.0 + inf_norm(y))
        return y if inf_norm(f) <= tol else None

    def energy_consistent(self, y0, s0, y1, s1):
        """:func:`.step_rules.energy_consistent` between two states."""
        problem = self.problem
        return energy_consistent(problem.energy(y0, s0), problem.energy(y1, s1),
                                 problem.energy_s(y0, s0), problem.energy_s(y1, s1),
                                 s1 - s0, self.scale)

    def tangent(self, y, s):
        """dy/ds along the branch: the problem's own ``tangent`` where it has one (the
        module's, in floats), else -F_y^-1 F_s."""
        own = getattr(self.problem, 'tangent', None)
        if own is not None:
            return own(y, s)
        return -solve(self.problem.jacobian(y, s), self.problem.residual_s(y, s))

    def eigenvalues(self, y, s):
        """Ascending stability eigenvalues (without modes where the problem can)."""
        cheap = getattr(self.problem, 'eigenvalues', None)
        return cheap(y, s) if cheap is not None else self.problem.stability(y, s)[0]

    def eigenvalue_rate(self, y, s, tangent, lam):
        """d lambda_min / ds along the branch, by a small forward difference."""
        return forward_rate(self.eigenvalues, y, s, tangent, lam)

    def margin(self, y, s):
        """The test function lambda_min in scale units (its root is the critical point)."""
        bounded_work.checkpoint()    # every probe of a localisation
        return self.eigenvalues(y, s)[0] / self.scale

    def critical(self, y, s, reference=None):
        """(lambda_min / scale, psi) with psi's sign aligned to ``reference``."""
        eigenvalues, modes = self.problem.stability(y, s)
        psi = modes[:, 0] / np.linalg.norm(modes[:, 0])
        if reference is not None and psi @ reference < 0.0:
            psi = -psi
        return eigenvalues[0] / self.scale, psi

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

    # -- the problem's optional descriptions --------------------------------------
    def linkage_limit(self, y, s):
        """The problem's description of the linkage limit at (y, s) ('' where none)."""
        return getattr(self.problem, 'linkage_limit', lambda *_: '')(y, s)

    def moves(self, y, s):
        """Whether the path moves the equilibrium conditions at (y, s) (not a command to
        the same parameters)."""
        return inf_norm(self.problem.residual_s(y, s)) > 0.0
