"""A small stack command as one continuation step, with few evaluations (issue 14).

A node sends actuator targets at 1 kHz: each is a small move that the generic
tracker (:mod:`.continuation`) covers in one step.  :func:`whole_command_step`
takes that step with the tracker's own acceptance rules and nothing else:

* the start state's evaluation (rods, forces, Hessian, constraint Jacobian) is the
  previous command's final one, kept on its record (:func:`keep_final_point`), so
  only what depends on the new command (dF/ds, dE/ds) is computed at s = 0;
* the tangent is solved with the previous command's last Newton LU factors, kept with
  it: a Jacobian at a point ~1e-6 from the start (the command's first Newton update),
  so the tangent is off by ~1e-6 of itself and the prediction by ~1e-6 of the step,
  far below the prediction's own error (~the step squared), which Newton removes;
* every evaluation is a point held here (``path.evaluate``), never looked up again;
* Newton factors the Jacobian once (at the prediction, made by the path's
  ``prediction_jacobian_at`` from one outer product, without the Hessian and constraint
  Jacobian that only the end needs) and stops at the first iterate whose update is
  below 1e-11 (the answer is the tracker's to 1e-10);
* the step bound's probe of d lambda_min / ds (one more evaluation and reduced
  eigenproblem, a fifth of the step) runs only where lambda_min fell by more than
  10 % over the step: elsewhere the end's eigenvalues, computed anyway, show that no
  critical point was near (a fold ahead makes lambda_min fall like a square root).

Anything the tracker would do differently (a soft mode, a long command, an event)
returns ``None`` and the caller runs the tracker in full.  The path object is the
stack's ``StackPath`` (duck-typed here, so that this module sits below it).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import dgesv as _dgesv, dgetrf as _dgetrf, dgetrs as _dgetrs

from .. import continuation as _continuation

#: The attribute of a stack record that keeps its final evaluation (not a field).
_KEPT = '_final_point'
#: Newton stops at an iterate whose update is below this (relative to 1 + |y|): the
#: state is then the converged one to ~1e-11, inside the 1e-10 the answers keep.  (At
#: 1e-12 a third of a stream's commands needed a third evaluation for a second update
#: of 4-5e-12: ~5 us of a ~98 us command.)
_CONVERGED = 1e-11
#: An update larger than this fraction of the previous one: the kept Jacobian is stale.
_STALE = 0.1
#: Where the smallest eigenvalue at the end of the step is at least this fraction of the
#: start's, the step went nowhere near a critical point and the step bound's probe is
#: skipped (see :func:`whole_command_step`).
_STEADY = 0.9


def _inf_norm(v):
    """max |v_i| (0 for an empty vector); in Python, cheaper than numpy for a few entries
    (it may miss a NaN: every step that matters ends with a numpy residual test)."""
    return max(map(abs, v.tolist()), default=0.0)


def keep_final_point(record, path, point, factors):
    """Keep ``point`` (the evaluation at ``record.state`` and the path's end) and
    ``factors`` (Newton's last LU factors) on the record, so that the next command, which
    starts there, neither evaluates it again nor factors a Jacobian for its tangent."""
    record.__dict__[_KEPT] = (path.l_ref, path.f_ref, point, factors)


def _start_point(path, y, known):
    """(evaluation at (y, 0), LU factors or ``None``): the ones kept on ``known`` when
    made at the same state and scales (the point's s-rates belong to another path and
    are dropped), else a fresh evaluation and no factors."""
    kept = None if known is None else known.__dict__.get(_KEPT)
    if kept is not None and kept[0] == path.l_ref and kept[1] == path.f_ref:
        point = kept[2]
        if point.values is path.at(0.0) and (y is known.state or np.array_equal(known.state, y)):
            point.rates = None
            return point, kept[3]
    return path.evaluate(y, 0.0), None


def _newton(path, y, tol, iterations):
    """The tracker's corrector at s = 1: (state, point, residual, LU factors), state
    ``None`` unless Newton converges and the residual ends within ``tol``.

    The Jacobian of the first iterate is kept (LU factors reused): on a small step the
    iterates move by ~1e-6, so the contraction stays fast; where it does not (an update
    more than ``_STALE`` of the previous one: a long step near a fold) the Jacobian is
    renewed at the current iterate.  Converged means an update
    below ``_CONVERGED`` (relative): that iterate is the root to ~1e-11, and its residual
    is already known, so the update is not applied (the generic corrector would apply
    it and evaluate once more).  Not converged within ``iterations``: handed over."""
    previous = math.inf
    settled = _CONVERGED * (1.0 + _inf_norm(y))
    point = path.evaluate(y, 1.0)
    f = path.residual_at(point)
    lu, pivots, info = _dgetrf(path.prediction_jacobian_at(point))
    if info != 0:
        return None, point, math.inf, None
    converged = False
    for _ in range(iterations):
        delta, _ = _dgetrs(lu, pivots, f)
        size = _inf_norm(delta)
        if size > _STALE * previous:           # slow: the kept Jacobian is stale, renew it
            lu, pivots, info = _dgetrf(path.jacobian_at(point))
            if info != 0:
                break
            delta, _ = _dgetrs(lu, pivots, f)
            size = _inf_norm(delta)
        if size <= settled:
            converged = True
            break
        if not math.isfinite(size) or size > 0.5 * previous:
            break
        y = y - delta
        point = path.evaluate(y, 1.0)
        f = path.residual_at(point)
        previous = size
    values = f.tolist()
    residual = max(map(abs, values))
    if not math.isfinite(sum(values)):        # max() may pass over a NaN; a sum does not
        return None, point, math.inf, None
    return (y if converged and residual <= tol else None), point, residual, (lu, pivots)


def whole_command_step(path, y, settings, known=None):
    """The tracker's first step when it spans the whole command: (state, eigenvalues,
    energy, residual, point, LU factors) at s = 1, or ``None`` wherever the tracker would do
    anything else.

    A small command is one continuation step, accepted by the tracker's own rules
    (:mod:`~.continuation.step_rules`): a stable equilibrium at s = 0, a whole step within
    the step bound, Newton converging near the prediction, the energy change matching the
    envelope theorem, the trapezoid rule (the tangent at s = 1 from Newton's last factors),
    a positive definite reduced Hessian at s = 1.  The step bound's
    eigenvalue half (its forward-difference probe) is applied only where the smallest
    eigenvalue at s = 1 is below ``_STEADY`` of the start's; where it is not, the step
    is taken without it.  What that gives up: a lambda_min that falls steeply at s = 0
    and recovers to 90 % by s = 1 makes the tracker shorten its step, not this one (an
    event inside would need two critical points within one small command; none was
    found in the tests, where Newton, the stability test or the probe decline every
    command that reaches a fold).  ``known`` is the record of ``y`` when it was verified
    at the start parameters: its eigenvalues, residual and energy are those at s = 0."""
    cfg = settings
    start, factors = _start_point(path, y, known)
    # (the eigenvalues' tests on Python floats: the same comparisons, without numpy scalars)
    eigenvalues = (path.eigenvalues_at(start) if known is None else known.eigenvalues).tolist()
    scale = max(abs(eigenvalues[-1]), 1e-300)
    tol = cfg.residual_tol * scale
    weights = path.state_weights                          # (the prediction's miss)
    residual0 = _inf_norm(path.residual_at(start)) if known is None else known.residual
    if not _continuation.positive_definite(eigenvalues, scale, cfg) or residual0 > tol:
        return None
    if factors is None:                       # (backward = -tangent: no negation needed)
        _, _, backward, info = _dgesv(path.jacobian_at(start), path.residual_s_at(start))
    else:
        backward, info = _dgetrs(*factors, path.residual_s_at(start))
    if info != 0:
        return None
    reach = _inf_norm(weights * backward)
    # the step bound's measure, as the tracker's: the node displacement, which the weighted
    # norm bounds, so it is computed only where that bound is not enough
    motion = reach if reach <= cfg.max_step_motion else path.motion_at(start, backward)
    if not motion <= cfg.max_step_motion:      # cheap early out: step_bound below says the same
        return None
    energy0 = path.energy_at(start) if known is None else known.energy
    energy_s0 = path.energy_s_at(start)
    predicted = y - backward
    y1, end, residual, factors = _newton(path, predicted, tol, cfg.newton_iterations)
    if y1 is None or not _continuation.near_prediction(_inf_norm(weights * (y1 - predicted)),
                                                       reach, 1.0, cfg):
        return None
    energy1 = path.energy_at(end)
    if not (_continuation.energy_consistent(energy0, energy1, energy_s0,
                                            path.energy_s_at(end), 1.0, scale)
            and _trapezoid(path, y, y1, end, backward, factors, cfg)):
        return None
    eigenvalues1 = path.eigenvalues_at(end)
    values1 = eigenvalues1.tolist()
    if not _continuation.positive_definite(values1, scale, cfg):
        return None
    if not _within_step_bound(path, y, backward, motion, eigenvalues[0], values1[0], cfg):
        return None
    return y1, eigenvalues1, energy1, residual, end, factors


def _trapezoid(path, y, y1, end, backward, factors, cfg):
    """:func:`~.continuation.on_one_branch` for the whole command y -> y1 (``backward`` is
    -the tangent at y; the one at y1 from Newton's last factors)."""
    backward1, info = _dgetrs(*factors, path.residual_s_at(end))
    weights = path.state_weights
    return info == 0 and _continuation.on_one_branch(
        _inf_norm(weights * (y1 - y + 0.5 * (backward + backward1))),
        _inf_norm(weights * (y1 - y)), cfg)


def _within_step_bound(path, y, backward, reach, lam0, lam1, cfg):
    """Whether the whole command is within the tracker's step bound: where lambda_min
    fell by more than ``_STEADY`` over it (a fold or branch point may be near), its
    forward-difference probe of d lambda_min / ds at the start decides."""
    if lam1 >= _STEADY * lam0:
        return True
    rate = _continuation.forward_rate(lambda y, s: path.eigenvalues_at(path.evaluate(y, s)),
                                      y, 0.0, -backward, lam0)
    return _continuation.step_bound(reach, lam0, rate, cfg) >= 1.0
