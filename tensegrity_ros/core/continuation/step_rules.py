"""The acceptance rules of one continuation step (public: a problem's own fast path,
:mod:`..stack_fast_step`, applies exactly these)."""
from __future__ import annotations


def positive_definite(eigenvalues, scale, settings):
    """A verified minimum: lambda_min > definiteness_tol * max(|lambda_max|, scale / 1000)."""
    return eigenvalues[0] > settings.definiteness_tol * max(abs(eigenvalues[-1]), scale * 1e-3)


def motion_bound(reach, settings):
    """The step in s that moves the mechanism by max_step_motion along a tangent of step
    norm ``reach``."""
    return settings.max_step_motion / max(reach, 1e-300)


def step_bound(reach, lam, rate, settings):
    """The largest step in s the step rules allow from a state whose tangent has step
    norm ``reach`` and smallest eigenvalue ``lam`` changing at ``rate`` = d lambda / ds:
    the mechanism moves by at most max_step_motion, lambda_min is predicted to shrink to
    no less than eigenvalue_shrink of itself."""
    ds = motion_bound(reach, settings)
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


def on_one_branch(defect, motion, settings):
    """The step's end lies on the branch through its start: ``defect`` (the step norm of
    y1 - y0 - ds (t0 + t1) / 2, the tangents at both ends) is at most
    ``trapezoid_defect`` of ``motion`` (the step norm of y1 - y0), or rounding.  A step
    whose corrector converged onto another branch past a fold (near its prediction, the
    energy change within the trapezoid's slack) leaves the snap in the defect."""
    return defect <= settings.trapezoid_defect * motion + settings.same_state_tol


def energy_consistent(energy0, energy1, energy_s0, energy_s1, ds, scale):
    """The envelope theorem: along one branch dE/ds = U_s (a jump to another breaks it)."""
    expected = 0.5 * (energy_s0 + energy_s1) * ds
    slack = 1e-9 * (abs(energy0) + abs(energy1) + scale) + 0.5 * abs((energy_s1 - energy_s0) * ds)
    return abs((energy1 - energy0) - expected) <= slack
