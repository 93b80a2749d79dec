"""The tolerances for "positive definite", named in one place and why they differ.

A state is a minimum only if lambda_min > tol * |lambda_max|, with two values of tol:

* ``DEFINITENESS_TOL`` (1e-9): the tracker's acceptance test
  (:func:`.continuation.positive_definite`) and a neck state's
  :attr:`.neck.stack.StackEquilibrium.stable`.  Tracked states are Newton-converged to
  rounding, and near a branch point with a 1e-9 asymmetry the stable branch's
  lambda_min / lambda_max dips to ~3e-9 (test_stack_imperfect: with 1e-8 the
  tracker stops there, "step size underflow").
* ``DEGENERACY_TOL`` (1e-8): the classification of every equilibrium of a module
  (:func:`.module.classification.classify`, :attr:`.module.classification.Equilibrium.stable`),
  whose roots come from the polynomial solver and are only that accurate (test_degenerate:
  with 1e-9 states on a fold classify as minima).

So a one-module state that the tracker verified with 1e-9 < lambda_min / lambda_max
<= 1e-8 (within ~1e-16 in s of a fold, within ~1e-8 in rho of the unloaded paper
module's branch point at rho = L) classifies as 'degenerate'; the tracker marks it
(:data:`MARGIN_CERTIFIED`, on :attr:`.module.classification.Equilibrium.certificate`), so that
it is still ``stable``, as the tracker verified it (before, the node showed such a
state, e.g. the paper module commanded to rho = 1 + 1e-8, as ERROR "not a stable
equilibrium").

One exception to DEFINITENESS_TOL: within ~1e-7 in s of a simple branch point (past a
passed pitchfork, or before one) lambda_min grows linearly from zero and falls below
it (9.4e-12 of lambda_max 1e-9 past, N = 3 neck).  There a state is a minimum if
lambda_min is positive and matches that linear law to 25 % (rounding noise cannot);
the tracker then says so (:attr:`.continuation.Track.certificate`), and
:attr:`.neck.stack.StackEquilibrium.stable`, a tracked module's
:attr:`.module.classification.Equilibrium.stable` (the unloaded paper module 1e-10 in rho past
rho = L: 2e-10 of lambda_max) and the simulator accept it.  A certified state is also a
start the tracker takes, and a command from it back towards the branch point is solved
by the normal form (:func:`.continuation.branch_switching.toward_branch_point`).

At a supercritical branch point itself (a command ending within the tracker's location
tolerance, 1e-9 in s, of it: the unloaded paper module commanded to rho = L exactly)
lambda_min is zero to within the margin band, of either sign, and no sign test can
decide.  There the state is a minimum by the normal form's quartic term, which the
tracker checks by finding the buckled branch past it stable; such a state carries
:data:`BRANCH_POINT_CERTIFIED` and is a minimum where |lambda_min| is within
DEFINITENESS_TOL of |lambda_max| (and it is a start the tracker takes).
"""

#: The tracker's (and a tracked neck state's) definiteness: lambda_min > this * |lambda_max|.
DEFINITENESS_TOL = 1e-9
#: The certificate of a tracked module state that passed the tracker's margin test
#: (DEFINITENESS_TOL) but classifies as degenerate (DEGENERACY_TOL): see above.
MARGIN_CERTIFIED = 'tracker_margin_test'
#: The certificate of a state at a supercritical branch point itself: a command ending
#: there within the tracker's location tolerance (the unloaded paper module commanded to
#: rho = L).  lambda_min is zero to the margin test there, either sign; the state is a
#: minimum by the normal form's quartic term (its buckled branch is stable): see above.
BRANCH_POINT_CERTIFIED = 'supercritical_branch_point'
#: An eigenvalue with |lambda| <= DEGENERACY_TOL * max|lambda| counts as zero in the
#: classification of solver roots.
DEGENERACY_TOL = 1e-8


def verified_minimum(eigenvalues, certificate=''):
    """Whether ``eigenvalues`` (ascending) make a verified minimum: lambda_min above
    DEFINITENESS_TOL of |lambda_max|, or positive where the tracker certified the state
    by a branch point's normal form (a non-empty ``certificate``, see above)."""
    low, band = eigenvalues[0], DEFINITENESS_TOL * max(abs(eigenvalues[-1]), 1e-300)
    if certificate == BRANCH_POINT_CERTIFIED:
        return bool(low > -band)
    return bool(low > band or (certificate and low > 0.0))
