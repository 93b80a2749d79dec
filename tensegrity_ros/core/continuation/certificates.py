"""Minima below the margin test, shown positive definite by a simple branch point's normal form.

Within ~1e-6 in s of a simple branch point lambda_min = c (s - s*) (1 + O(s - s*)) is
below the margin test (lambda_min > definiteness_tol lambda_max) yet positive: a state
there is a minimum where lambda_min is positive and matches that linear law to 25 %
(rounding noise, ~1e-16 of lambda_max, cannot), and every other eigenvalue passes the
margin test (one soft mode).  See :mod:`..tolerances` for the certificates' names.
"""
from __future__ import annotations

from ..numerics.tolerances import BRANCH_POINT_CERTIFIED, verified_minimum


def soft_minimum(run, eigenvalues):
    """lambda_min positive and every other eigenvalue passes the margin test."""
    return bool(eigenvalues[0] > 0.0
                and (len(eigenvalues) == 1 or run.definite(eigenvalues[1:])))


def degenerate_minimum(run, eigenvalues):
    """Every eigenvalue but lambda_min passes the margin test and lambda_min is zero
    to within it, either sign (a supercritical branch point itself: see
    :func:`.branch_switching.at_branch_point`)."""
    return bool(run.definite(eigenvalues[1:])
                and verified_minimum(eigenvalues, BRANCH_POINT_CERTIFIED))


def certified_start(run, eigenvalues):
    """A start below the margin test that ``run.certificate`` verifies: a soft
    minimum (lambda_min positive) next to a passed pitchfork, or a supercritical
    branch point itself (:func:`.branch_switching.at_branch_point`)."""
    if run.certificate == BRANCH_POINT_CERTIFIED:
        return degenerate_minimum(run, eigenvalues)
    return bool(run.certificate and soft_minimum(run, eigenvalues))


def still_certified(run, previous, eigenvalues):
    """A step from a pitchfork-certified state (``run.certificate``) to one still
    below the margin test keeps the certificate where lambda_min grew (and the step
    passed every other check): on the buckled branch lambda_min grows linearly away
    from the branch point, so the new state lies further along it."""
    return bool(run.certificate and eigenvalues[0] > previous[0]
                and soft_minimum(run, eigenvalues))


def on_linear_law(run, previous, eigenvalues, rate, ds):
    """A step's end is a minimum whose lambda_min, positive, falls as the linear law
    of a simple branch point predicts it (within 25 %) from the verified state before
    (eigenvalues ``previous``) and the rate over the step before that (see
    :func:`linear_approach`)."""
    if not (rate is not None and rate < 0.0 and eigenvalues is not None
            and soft_minimum(run, eigenvalues)):
        return False
    predicted = previous[0] + rate * ds
    return bool(predicted > 0.0 and abs(eigenvalues[0] - predicted) <= 0.25 * predicted)


def linear_approach(run, previous, eigenvalues, rate, ds, remaining):
    """A step towards a branch point that ends below the margin test is still on a
    minimum where lambda_min is positive and where the linear law predicts it (within
    25 %) from the verified state before and the rate over the step before that: near
    a simple branch point lambda_min = c (s* - s), so a command ending within ~1e-6
    before one (e.g. on the buckled branch going back) ends on a minimum, while
    rounding noise, ~1e-16 of lambda_max, cannot match the law.  Only where the law
    keeps lambda_min positive up to the command's end (``remaining`` in s): a command
    through the branch point is left to the event's localisation, as before."""
    return bool(rate is not None and previous[0] + rate * remaining > 0.0
                and on_linear_law(run, previous, eigenvalues, rate, ds))


def pitchfork_certified(run, eigenvalues, far, fraction):
    """Whether a buckled state a ``fraction`` of the way (in s) from a supercritical
    branch point to a verified buckled minimum (eigenvalues ``far``, with a 100x
    margin) is a minimum although its lambda_min is below the margin test.

    Predicted as ``fraction * far[0]`` by the linear law (on the N = 3 neck 1e-9 in s
    past, lambda_min / lambda_max = 9.4e-12 matched it to 2e-4)."""
    predicted = fraction * far[0]
    return soft_minimum(run, eigenvalues) and abs(eigenvalues[0] - predicted) <= 0.25 * predicted
