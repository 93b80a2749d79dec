"""The path follower: natural steps, arclength steps where they fail, and step control.

It knows nothing of jumps.  Per step: a tangent predictor and a Newton corrector; the
step is bounded so that lambda_min is predicted to at most halve and the mechanism moves
at most ``max_step_motion``; a step is accepted only if Newton contracts, lands near the
prediction, the energy change matches the envelope theorem and the stability matrix is
still positive definite (or a normal-form certificate holds, :mod:`.certificates`).  A
rejected step is handed to the ``events`` policy (:class:`.tracker.Events`), which may
move the state (past an event, across a linkage limit) or end the run; else it is
retried as a pseudo-arclength step (which follows a sharply turning branch and goes
round a fold), then shrunk.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from . import certificates
from .correctors import arc_point, curve_tangent
from .results import PITCHFORK_CERTIFIED, Track, TrackingError
from .step_rules import near_prediction, on_one_branch, step_bound
from ..numerics import bounded_work


@dataclass
class Move:
    """What the events policy did with a rejected step: the state is now (y, s).
    ``event``: a jump on the way; ``restart``: the step size starts over (a new branch,
    or across a limit); ``rescale``: the tolerances follow the new state's stiffness;
    ``new_branch``: the remembered margin state no longer belongs to this branch."""

    y: np.ndarray
    s: float
    event: object = None
    restart: bool = True
    rescale: bool = True
    new_branch: bool = False


@dataclass
class Stop:
    """The run ends on its last verified state, failed, for ``message``."""

    message: str


@dataclass
class Rejected:
    """A rejected natural step from the verified (y, s): the policy's input."""

    y: np.ndarray
    s: float
    eigenvalues: np.ndarray
    tangent: np.ndarray
    ds: float
    reason: str
    end_eigenvalues: object
    rate: object
    s_end: float


class Follower:
    """One run along a path: follows its stable branch, asking ``events`` what to do
    where a step is rejected."""

    def __init__(self, run, events):
        self.run = run
        self.events = events
        self.next_tangent = None        # (y, s, tangent) where the last step ended

    # -- one natural step ------------------------------------------------------
    def try_step(self, y, s, tangent, ds):
        """Corrector at s + ds; returns (state, eigenvalues, reason) with reason '' if accepted."""
        run = self.run
        s1 = s + ds
        predicted = y + ds * tangent
        y1 = run.newton(predicted, s1)
        if y1 is None:
            return None, None, 'newton'
        if not near_prediction(run.step_norm(y1 - predicted), run.step_norm(tangent), ds,
                               run.settings):
            return None, None, 'far'
        if not run.energy_consistent(y, s, y1, s1):
            return None, None, 'energy'
        if not self.trapezoid(y, tangent, y1, s1, ds):
            return None, None, 'far'
        eigenvalues = run.eigenvalues(y1, s1)
        if not run.definite(eigenvalues):
            return y1, eigenvalues, 'indefinite'
        return y1, eigenvalues, ''

    def trapezoid(self, y, tangent, y1, s1, ds):
        """:func:`.step_rules.on_one_branch` for the step y -> (y1, s1); the tangent at
        y1 is kept for the next step from there (:meth:`tangent_at`)."""
        run = self.run
        try:
            tangent1 = run.tangent(y1, s1)
        except np.linalg.LinAlgError:
            return True                     # (singular there: the step's other tests decide)
        self.next_tangent = (y1, s1, tangent1)
        step = y1 - y
        return on_one_branch(run.step_norm(step - (0.5 * ds) * (tangent + tangent1)),
                             run.step_norm(step), run.settings)

    def tangent_at(self, y, s):
        """The branch's tangent at (y, s): kept from the step that ended there, else solved."""
        kept = self.next_tangent
        if kept is not None and kept[0] is y and kept[1] == s:
            return kept[2]
        return self.run.tangent(y, s)

    def certified(self, eigenvalues, end_eigenvalues, rate, ds, remaining):
        """A step ending below the margin test, still on a minimum by the normal form."""
        run = self.run
        return (certificates.still_certified(run, eigenvalues, end_eigenvalues)
                or certificates.linear_approach(run, eigenvalues, end_eigenvalues, rate, ds,
                                                remaining))

    # -- arclength steps -------------------------------------------------------
    def arc_trapezoid(self, y, direction, y1, direction1, h):
        """:func:`.step_rules.on_one_branch` for the arclength step of length h from y to
        y1 (the curve's unit directions at both ends): where a module passes near flat,
        the chord's multiplier joins two arms of equilibria a corrector can reach within
        the alignment test; the step that reached the other arm missed the trapezoid
        rule (fresh seed 1295778658, path 0: module 0 passing 0.022 rad from flat, the
        arm reached had a fold that was taken for this branch's)."""
        run, n = self.run, len(y)
        step = y1 - y
        chord = (0.5 * h) * (direction[:n] + direction1[:n])
        return on_one_branch(run.step_norm(step - chord), run.step_norm(step), run.settings)

    def arc_step(self, y, s, tangent, ds):
        """One arclength step as long as the rejected natural step: ('regular', y1, s1,
        eigenvalues) where the branch goes on stable and forward, ('bracket', direction,
        h, definite) where a test function changed sign on it (for the events policy
        to locate), or ``None`` if the step failed."""
        run = self.run
        direction = curve_tangent(run, y, s)
        h = ds * math.sqrt(1.0 + float(tangent @ tangent))
        end = arc_point(run, y, s, direction, h)
        if end is None:
            return None
        y1, s1 = end
        direction1 = curve_tangent(run, y1, s1, direction)
        if direction1 @ direction < run.settings.arc_alignment:
            return None             # turned too much for one step: another branch, or too long
        if not self.arc_trapezoid(y, direction, y1, direction1, h):
            return None             # the corrector reached another arm of the branch
        eigenvalues = run.eigenvalues(y1, s1)
        definite = run.definite(eigenvalues)
        if definite and direction1[-1] > 0.0 and s1 > s:
            return 'regular', y1, s1, eigenvalues
        return 'bracket', direction, h, definite

    def back_to_end(self, y1, s1, s_end):
        """An arclength step that went past the end of the command, brought back to it
        (a natural step back on the regular branch): ('regular', y, s_end, eigenvalues),
        or ``None`` (the step is then refused and retried shorter)."""
        run = self.run
        try:
            y = run.newton(y1 + (s_end - s1) * run.tangent(y1, s1), s_end)
        except np.linalg.LinAlgError:
            return None
        if y is None or run.step_norm(y - y1) > run.settings.max_state_step:
            return None
        eigenvalues = run.eigenvalues(y, s_end)
        return ('regular', y, s_end, eigenvalues) if run.definite(eigenvalues) else None

    def arc_or_event(self, rejected):
        """After a rejected step the events policy did not act on: an arclength step,
        ('regular', y, s, eigenvalues), or the critical point located on it (or None)."""
        y, s, s_end = rejected.y, rejected.s, rejected.s_end
        arc = self.arc_step(y, s, rejected.tangent, rejected.ds)
        if arc is not None and arc[0] == 'regular' and arc[2] > s_end:
            arc = self.back_to_end(*arc[1:3], s_end)
        if arc is None or arc[0] == 'regular':
            return arc
        return 'found', self.events.locate_on_arc(self.run, y, s, *arc[1:])

    # -- the run -----------------------------------------------------------------
    def start(self, y, certificate):
        """The verified start: (y, eigenvalues); raises TrackingError where ``y`` is no
        stable equilibrium (nor one ``certificate`` verifies)."""
        run, s = self.run, 0.0
        run.certificate = certificate
        eigenvalues = run.eigenvalues(y, s)
        run.rescale(eigenvalues)
        y = np.asarray(y, dtype=float)
        polished = run.newton(y, s)
        if run.newton_unresolved and run.residual_ok(y, s):
            # a verified start at a singular point (a fold, a flat module): Newton does
            # not converge from it and may go astray (13.9 in the state from one kept at
            # a linkage limit, bench_round_commands seed 3, stream 15): keep the start
            polished = None
        if polished is None and not run.residual_ok(y, s):
            raise TrackingError('the start state is not an equilibrium')
        if polished is not None and run.step_norm(polished - y) > run.settings.passage_radius:
            # Newton from a rough guess may converge to a minimum whose basin does not
            # hold the guess: where the mechanism comes to rest is settle()'s to decide
            raise TrackingError('the start state is not an equilibrium')
        y = y if polished is None else polished
        run.unresolved = y if polished is None or run.newton_unresolved else None
        eigenvalues = run.eigenvalues(y, s)
        if run.definite(eigenvalues):
            run.certificate = ''
        elif not certificates.certified_start(run, eigenvalues):
            raise TrackingError('the start state is not a stable equilibrium')
        return y, eigenvalues

    def follow(self, y, s_end=1.0, certificate=''):
        """Follow the branch from (y, 0) to s_end: a :class:`.results.Track`."""
        y, eigenvalues = self.start(y, certificate)
        path = _Position(self.run, y, 0.0, eigenvalues)
        first_only = self.run.settings.stop_at_first_event
        while path.s < s_end:
            stop = self.step(path, s_end)
            if stop is not None:
                return path.result('failed', stop.message)
            if first_only and path.events:
                return path.result(message='stopped at the first event (stop_at_first_event)')
        return path.result()

    def step(self, path, s_end):
        """One step from ``path``'s state (which it moves); a :class:`Stop` to end."""
        run, cfg = self.run, self.run.settings
        run.steps += 1
        bounded_work.checkpoint()    # a bounded caller may pause (or give up) here
        if run.steps > cfg.max_steps:
            return Stop('too many steps')
        y, s, eigenvalues = path.y, path.s, path.eigenvalues
        try:
            tangent = self.tangent_at(y, s)
        except np.linalg.LinAlgError:
            tangent = np.zeros_like(y)
        if path.rate is None:
            path.rate = run.eigenvalue_rate(y, s, tangent, eigenvalues[0])
        path.ds = ds = min(path.ds, s_end - s,
                           step_bound(run.motion(y, s, tangent), eigenvalues[0], path.rate, cfg))
        y1, eig1, reason = self.try_step(y, s, tangent, ds)
        certified = reason == 'indefinite' and self.certified(eigenvalues, eig1, path.rate, ds,
                                                              s_end - s)
        if not reason or certified:
            path.natural(y1, ds, eig1, PITCHFORK_CERTIFIED if certified else '')
            return None
        return self.rejected(path, Rejected(y, s, eigenvalues, tangent, ds, reason, eig1,
                                            path.rate, s_end))

    def rejected(self, path, rejected):
        """What follows a rejected step: the policy's move, an arclength step, the
        policy's answer at the event or underflow, else a shorter step."""
        action = self.events.before_arc(self.run, rejected)
        found = None
        if isinstance(action, tuple):       # ('found', critical point) on the path
            found = action[1]
        elif action is not None:
            return path.apply(action)
        if found is None and rejected.reason == 'newton' and not path.shortened:
            # Newton did not converge: first the natural step at half the length (the
            # step was too long for its prediction: 97 of 152 rejected steps of
            # bench_neck_paths' 'all' family went on to an arclength step that failed too)
            path.shortened = True
            path.ds *= 0.5
            return None
        if found is None:
            arc = self.arc_or_event(rejected)
            if arc is not None and arc[0] == 'regular':
                path.arc(*arc[1:])
                return None
            found = None if arc is None else arc[1]
        action = self.events.after_arc(self.run, rejected, found)
        if action is not None:
            return path.apply(action)
        path.ds *= 0.25 if rejected.reason == 'indefinite' else 0.5
        return None


class _Position:
    """Where a run is: the verified (y, s) and its eigenvalues, the events so far, the
    step size and d lambda_min / ds (None: to be measured)."""

    def __init__(self, run, y, s, eigenvalues):
        self.run, self.y, self.s, self.eigenvalues = run, y, s, eigenvalues
        self.events, self.ds, self.rate = [], 1.0, None
        self.shortened = False      # the step was halved once since the last accepted one
        self.keep()

    def keep(self):
        """Note a verified state (with its certificate and the events before it): where
        the time budget runs out, the command ends there.  (Without a budget nothing
        reads it: no copy on the small-step path.)"""
        run = self.run
        if run.settings.time_budget is not None:
            run.kept = (self.y, self.s, self.eigenvalues, tuple(self.events), run.certificate)

    def natural(self, y1, ds, eigenvalues1, certificate):
        """An accepted natural step of ``ds`` to y1."""
        run = self.run
        run.certificate = certificate
        self.shortened = False
        self.rate = run.last_rate = (eigenvalues1[0] - self.eigenvalues[0]) / ds
        s1 = self.s + ds
        self.y, self.s, self.eigenvalues = y1, s1, eigenvalues1
        if run.newton_unresolved:          # (try_step's Newton: the last one run)
            run.unresolved = y1
        if run.settings.time_budget is not None:        # (self.keep(), inline: every step)
            run.kept = (y1, s1, eigenvalues1, tuple(self.events), certificate)
        run.note_margin(y1, s1, eigenvalues1)
        run.rescale(eigenvalues1)
        self.ds *= 2.0

    def arc(self, y1, s1, eigenvalues1):
        """An accepted arclength step to (y1, s1) (the step size stays)."""
        run = self.run
        run.last_rate = (eigenvalues1[0] - self.eigenvalues[0]) / (s1 - self.s)
        self.y, self.s, self.eigenvalues, self.rate = y1, s1, eigenvalues1, None
        self.shortened = False
        self.keep()
        run.note_margin(y1, s1, eigenvalues1)
        run.rescale(eigenvalues1)

    def apply(self, action):
        """Apply the events policy's :class:`Move` (or return its :class:`Stop`)."""
        if isinstance(action, Stop):
            return action
        run = self.run
        self.y, self.s, self.shortened = action.y, action.s, False
        if action.event is not None:
            self.events.append(action.event)
        if action.new_branch:
            run.clear_of_margin = None     # another branch (or across a limit)
            run.normal_form_failed = None
        self.eigenvalues = run.eigenvalues(self.y, self.s)
        self.keep()
        if action.rescale:
            run.rescale(self.eigenvalues)
        if action.restart:
            self.ds, self.rate = 1.0, None
        return None

    def result(self, status='ok', message=''):
        run = self.run
        return Track(state=self.y, s=self.s, eigenvalues=np.asarray(self.eigenvalues),
                     events=tuple(self.events), status=status, message=message,
                     steps=run.steps, passages=tuple(run.passages),
                     certificate=run.certificate, undecided=tuple(run.undecided))


def out_of_budget(run):
    """The result of a run whose time budget ran out: its last verified state."""
    y, s, eigenvalues, events, run.certificate = run.kept
    return Track(state=y, s=s, eigenvalues=np.asarray(eigenvalues), events=tuple(events),
                 status='failed',
                 message=f'time budget of {run.settings.time_budget:g} s used up '
                         f'(last verified state at s={float(s)!r})',
                 steps=run.steps, passages=tuple(run.passages), certificate=run.certificate,
                 undecided=tuple(run.undecided))
