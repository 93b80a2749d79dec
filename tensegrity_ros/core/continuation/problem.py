"""The problem the tracker solves: equilibrium equations along a parameter path (plain interface).

One module (:class:`..tracking.ModulePath`, 2 angles) and a neck
(:class:`..stack.StackPath`, rod angles and chord multipliers) both implement
:class:`PathProblem`; everything below it is generic.
"""
from __future__ import annotations

from typing import Protocol


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
    itself, where ``descent`` lets the constraints give), ``descent_jacobian`` and
    ``rigid_descent_jacobian`` (their derivatives in y, for the integrator's implicit
    corrector; else it makes them by finite differences), ``damped(y, s)`` (whether
    ``descent`` does so at y), ``flatness``, ``turned_through_base`` and
    ``crossing_ways`` (a linkage's crossings, see :func:`.flows.rigid_flow_to_rest`)
    and ``mirror(y, s)`` (the state's mirror image, or None where the problem has no
    mirror symmetry at s).  Linkage limits (:mod:`.linkage_limits`) use
    ``linkage_limit(y, s)`` (a description, '' where none) and ``crossing_rounding``.
    ``motion(y, s, dy)`` (optional) measures a step for the step bound (default: the
    weighted state norm; a neck: its largest node displacement).
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


def admissible(problem, s):
    """Whether the parameters at s are valid (the problem's optional ``admissible``)."""
    check = getattr(problem, 'admissible', None)
    return True if check is None else check(s)


class SubPath:
    """The part of a path between s_a and s_b, reparametrised to t in [0, 1] (either
    direction): what a nested run follows (a landing back to its event, a buckled
    branch away from its branch point)."""

    def __init__(self, problem, s_a, s_b):
        self.problem, self.s_a, self.ds = problem, s_a, s_b - s_a
        self.size = problem.size
        for name in ('state_weights', 'canonical'):
            if hasattr(problem, name):
                setattr(self, name, getattr(problem, name))
        if hasattr(problem, 'motion'):
            self.motion = lambda y, t, dy: problem.motion(y, self.at(t), dy)
        if hasattr(problem, 'on_constraints'):
            self.on_constraints = lambda y, t: problem.on_constraints(y, self.at(t))
        if hasattr(problem, 'rigid_descent'):
            self.rigid_descent = lambda y, t: problem.rigid_descent(y, self.at(t))
        if hasattr(problem, 'descent_jacobian'):
            self.descent_jacobian = lambda y, t: problem.descent_jacobian(y, self.at(t))
        if hasattr(problem, 'rigid_descent_jacobian'):
            self.rigid_descent_jacobian = lambda y, t: problem.rigid_descent_jacobian(
                y, self.at(t))
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
