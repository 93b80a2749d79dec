"""Tracker: fig. 8 of the paper end to end, exact event locations, hysteresis, generic problems."""
import math

from hypothesis import given, settings as hyp_settings, strategies as st
import numpy as np
import pytest
from scipy.optimize import brentq, fsolve

from tensegrity_ros.core import (BRANCH_POINT, equilibria, FOLD, ModuleParams, settle, track,
                                 track_module, TrackingError)
from tensegrity_ros.core.continuation import positive_definite, TrackerSettings
from tensegrity_ros.core.neck.stack import StackEquilibrium

#: Numerically sensitive throughout: `make test-numerics` runs it under other CPUs' arithmetic.
pytestmark = pytest.mark.numerics


def fig8(rho, L2=1.0, F=5.0):
    return ModuleParams.paper(rho, L2=L2, F3=F, F4=F)


def lower_branch(rho=0.5, L2=1.0):
    return settle(fig8(rho, L2), [-1.0, -1.0])


# Independent locations of C1 and C2 for L1 = L2 = 1, k = 100, F = 5 on the symmetric
# branch t1 = t2 = t: G = 200 rho sin t - 100 sin 2t - 5 cos t, and the antisymmetric
# (branch point) or symmetric (fold) Hessian eigenvalue vanishes.
def _g(t, rho):
    return 200 * rho * math.sin(t) - 100 * math.sin(2 * t) - 5 * math.cos(t)


C1_T, C1_RHO = fsolve(lambda z: [_g(*z), 200 * z[1] * math.cos(z[0]) + 5 * math.sin(z[0])],
                      [-1.41, 0.155], xtol=1e-12)
C2_T, C2_RHO = fsolve(lambda z: [_g(*z), 200 * z[1] * math.cos(z[0]) - 200 * math.cos(2 * z[0])
                                 + 5 * math.sin(z[0])], [-0.3, 0.87], xtol=1e-12)


def test_lower_branch_start_is_the_paper_configuration():
    start = lower_branch()
    assert start.stable
    assert start.theta1 == pytest.approx(start.theta2, abs=1e-12)
    assert start.theta1 < 0


def test_fig8a_decreasing_rho_branch_point_then_lands_on_upper_branch():
    start = lower_branch()
    result = track_module(fig8(0.5), fig8(0.05), start.theta)
    assert result.status == 'ok'
    (jump,) = result.jumps
    assert jump.kind == BRANCH_POINT
    # located to 1e-9 in s: rho = 0.5 - 0.45 s
    assert abs(jump.s - (0.5 - C1_RHO) / 0.45) < 1e-9
    assert jump.params.rho == pytest.approx(C1_RHO, abs=1e-9)
    assert jump.from_theta == pytest.approx([C1_T, C1_T], abs=1e-6)
    assert np.all(jump.to_theta > 0.5)                       # the upper branch
    assert jump.to_theta[0] == pytest.approx(jump.to_theta[1], abs=1e-8)
    assert not jump.ambiguous
    assert result.final.stable and result.final.theta1 > 0


def test_fig8a_increasing_rho_fold():
    result = track_module(fig8(0.5), fig8(1.2), lower_branch().theta)
    (jump,) = result.jumps
    assert jump.kind == FOLD
    assert abs(jump.s - (C2_RHO - 0.5) / 0.7) < 1e-9
    assert jump.from_theta == pytest.approx([C2_T, C2_T], abs=1e-6)
    assert np.all(jump.to_theta > 0)
    assert result.final.stable


@pytest.mark.parametrize('target', [0.05, 1.2])
def test_fig8a_hysteresis_going_back_gives_no_jump(target):
    there = track_module(fig8(0.5), fig8(target), lower_branch().theta)
    back = track_module(fig8(target), fig8(0.5), there.final.theta)
    assert back.jumps == ()
    assert back.final.theta1 > 0          # stays on the upper branch


@pytest.mark.parametrize('target', [C1_RHO + 1e-6, C2_RHO - 1e-6])
def test_commands_stopping_just_short_of_an_event_report_none(target):
    result = track_module(fig8(0.5), fig8(target), lower_branch().theta)
    assert result.status == 'ok'
    assert result.jumps == ()
    assert result.final.stable and result.final.theta1 < 0
    assert result.final.stability_margin < 5.0      # close to the critical point


@pytest.mark.parametrize('target', [C1_RHO - 1e-6, C2_RHO + 1e-6])
def test_commands_just_past_an_event_jump(target):
    result = track_module(fig8(0.5), fig8(target), lower_branch().theta)
    assert len(result.jumps) == 1
    assert result.final.theta1 > 0


def test_fig8b_both_ends_are_folds():
    start = lower_branch(L2=1.05)
    down = track_module(fig8(0.5, 1.05), fig8(0.05, 1.05), start.theta)
    up = track_module(fig8(0.5, 1.05), fig8(1.2, 1.05), start.theta)
    assert [j.kind for j in down.jumps] == [FOLD]
    assert [j.kind for j in up.jumps] == [FOLD]
    # the fold is where the stable count of the exact solver changes
    for jump in down.jumps + up.jumps:
        rho = jump.params.rho
        counts = [equilibria(fig8(r, 1.05)).num_stable for r in (rho - 1e-6, rho + 1e-6)]
        assert sorted(counts) == [1, 2]


def test_event_is_a_degenerate_equilibrium_of_the_exact_solver():
    result = track_module(fig8(0.5), fig8(1.2), lower_branch().theta)
    jump = result.jumps[0]
    near = [e for e in equilibria(jump.params)
            if np.max(np.abs(np.asarray(e.theta) - jump.from_theta)) < 1e-3]
    assert near, 'the exact solver finds the critical configuration'
    assert min(abs(e.eigenvalues[0]) for e in near) < 1e-4


def test_rho_and_forces_changing_together():
    start = settle(ModuleParams.paper(0.5, F3=5, F4=5), [-1, -1])
    end = ModuleParams.paper(0.3, F3=8, F4=3, L2=1.2).with_(f3x=1.0, f4x=-2.0)
    result = track_module(ModuleParams.paper(0.5, F3=5, F4=5), end, start.theta)
    assert result.status == 'ok'
    exact = [e.theta for e in equilibria(end).stable]
    assert any(np.max(np.abs(result.final.theta - t)) < 1e-8 for t in exact)


def test_several_events_in_one_command():
    """Pushing turns into pulling while rho grows: two folds on one straight path."""
    start_params = ModuleParams.paper(0.82, F3=-9, F4=-6)
    end_params = ModuleParams.paper(1.05, F3=8, F4=-1)
    start = settle(start_params, [0.45, 0.47])
    result = track_module(start_params, end_params, start.theta)
    assert result.status == 'ok'
    assert [j.kind for j in result.jumps] == [FOLD, FOLD]
    assert result.jumps[0].s < result.jumps[1].s
    for jump in result.jumps:
        counts = {equilibria(jump.params.with_(rho=jump.params.rho + d)).num_stable
                  for d in (-1e-6, 1e-6)}
        assert counts != {2}, 'each fold changes the stable count'
    assert result.final.stable


def test_random_paths_end_on_an_exact_stable_equilibrium():
    rng = np.random.default_rng(7)
    for _ in range(40):
        a = ModuleParams(rho=rng.uniform(0.2, 1.5), L2=rng.uniform(0.6, 1.6),
                         f3y=rng.uniform(-8, 8), f4y=rng.uniform(-8, 8),
                         f3x=rng.uniform(-3, 3), f4x=rng.uniform(-3, 3))
        b = a.with_(rho=rng.uniform(0.2, 1.5), f3y=rng.uniform(-8, 8), f4y=rng.uniform(-8, 8))
        start = settle(a, rng.uniform(-3, 3, 2))
        result = track_module(a, b, start.theta)
        assert result.status == 'ok', result.message
        assert result.final.stable
        exact = [e.theta for e in equilibria(b).stable]
        distance = min(np.max(np.abs((result.final.theta - t + np.pi) % (2 * np.pi) - np.pi))
                       for t in exact)
        assert distance < 1e-8


def test_invalid_theta_is_refused():
    with pytest.raises(ValueError, match='shape'):
        track_module(fig8(0.5), fig8(0.6), [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match='finite'):
        track_module(fig8(0.5), fig8(0.6), [math.nan, 0.0])


class Cusp:
    """A generic n-dimensional PathProblem: U = y0^4/4 - y0^2/2 + b(s) y0 + sum(c_i y_i^2 / 2).

    y0 follows the S-shaped curve y^3 - y + b = 0 with b = -1 + 2 s; the right branch
    folds at b = 2 / (3 sqrt 3) and the mechanism lands on the left branch.
    """

    def __init__(self, n=3):
        self.size = n
        self.c = np.arange(1.0, n) * 2.0

    def residual(self, y, s):
        return np.concatenate([[y[0] ** 3 - y[0] + (2 * s - 1)], self.c * y[1:]])

    def jacobian(self, y, s):
        return np.diag(np.concatenate([[3 * y[0] ** 2 - 1], self.c]))

    def residual_s(self, y, s):
        return np.concatenate([[2.0], np.zeros(self.size - 1)])

    def energy(self, y, s):
        return (y[0] ** 4 / 4 - y[0] ** 2 / 2 + (2 * s - 1) * y[0]
                + 0.5 * np.sum(self.c * y[1:] ** 2))

    def energy_s(self, y, s):
        return 2.0 * y[0]

    def stability(self, y, s):
        values, vectors = np.linalg.eigh(self.jacobian(y, s))
        return values, vectors

    def descent(self, y, s):
        return -self.residual(y, s)

    def project(self, y, s):
        return y


def test_tracker_is_generic_over_the_problem_dimension():
    problem = Cusp(3)
    start = np.array([brentq(lambda y: y ** 3 - y - 1, 1, 2), 0.0, 0.0])
    result = track(problem, start)
    (event,) = result.events
    assert event.kind == FOLD
    assert event.s == pytest.approx((1 + 2 / (3 * math.sqrt(3))) / 2, abs=1e-9)
    assert event.state[0] == pytest.approx(1 / math.sqrt(3), abs=1e-5)
    assert event.landing[0] < -1 / math.sqrt(3)
    assert result.state[0] == pytest.approx(brentq(lambda y: y ** 3 - y + 1, -2, -1), abs=1e-10)


class Ghost:
    """U = y0^3 / 3 - (c - s) y0 + y1^2: the minimum y0 = sqrt(c - s) ends at a fold at
    s = c, past which there is none (the flow runs off to y0 -> -inf at a bounded speed)."""

    size = 2

    def __init__(self, c):
        self.c = c

    def residual(self, y, s):
        return np.array([y[0] ** 2 - (self.c - s), 2.0 * y[1]])

    def jacobian(self, y, s):
        return np.diag([2.0 * y[0], 2.0])

    def residual_s(self, y, s):
        return np.array([1.0, 0.0])

    def energy(self, y, s):
        return y[0] ** 3 / 3 - (self.c - s) * y[0] + y[1] ** 2

    def energy_s(self, y, s):
        return y[0]

    def stability(self, y, s):
        return np.linalg.eigh(self.jacobian(y, s))

    def descent(self, y, s):
        return -np.tanh(self.residual(y, s))

    def project(self, y, s):
        return y


@pytest.mark.parametrize('c', [0.5, 0.999638580089214])
def test_a_landing_that_finds_no_minimum_is_given_up(c):
    """A fold with no minimum past it: the landing is retried frozen further past the
    fold, up to 1e-3 in s, then the command fails there.  At s* = 0.999638580089214
    (a fold of config/neck.yaml in bench_round_commands seed 0, stream 18, m1 -> 0.15 m)
    (s* + 1e-3) - s* rounds to 0.00099999999999989 < 1e-3, and the retries never ended
    (that command ran past 20 s; here the time budget stops it)."""
    from tensegrity_ros.core import TrackerSettings
    result = track(Ghost(c), np.array([math.sqrt(c), 0.0]), TrackerSettings(time_budget=5.0))
    assert result.status == 'failed'
    assert result.message == f'could not land after the fold at s={c!r}', result.message
    assert result.s == pytest.approx(c, abs=1e-9)


def test_tracker_refuses_an_unstable_start():
    with pytest.raises(TrackingError):
        # y0 = 0 is a maximum at s = 0.5 ... and not an equilibrium at s = 0
        track(Cusp(2), np.array([0.0, 0.0]))


# -- the tracker's definiteness and a tracked neck state's "stable" agree (issue 10) ------


@hyp_settings(max_examples=300, deadline=None, derandomize=True)
@given(high=st.floats(1e-30, 1e30), decades=st.floats(0.0, 12.0),
       softer=st.floats(1e-3, 1.0))
def test_a_neck_state_the_tracker_accepts_reads_back_stable(high, decades, softer):
    """lambda_min = lambda_max / 10^decades; the tracker's scale is the start's
    lambda_max, down to 1000 times larger than the local one (see core/numerics/tolerances.py
    for why one module's classification of solver roots uses 1e-8 instead)."""
    eigenvalues = np.array([high * 10.0 ** -decades, high])
    if positive_definite(eigenvalues, high / softer, TrackerSettings()):
        stack_state = StackEquilibrium.__new__(StackEquilibrium)
        object.__setattr__(stack_state, 'eigenvalues', eigenvalues)
        assert stack_state.stable
