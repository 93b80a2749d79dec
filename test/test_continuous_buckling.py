"""A supercritical branch point is passed continuously; every reported jump is a finite one.

Random symmetric necks (N = 1 .. 4 identical modules, upright) under a growing symmetric
head load: the tracker reports subcritical branch points and folds as jumps and passes
supercritical branch points without one.  Checked without the tracker's classification:
just past a passed branch point the state is within ~sqrt(distance) of the critical one
(the buckled minimum grows out of it), and every jump lands a finite distance away on a
stable equilibrium at its own load (to rounding: the rest point of a settle there).
The two explicit examples are soft necks (k ~ 10 N/m) whose branch-point landing, frozen
1e-3 in s past the event, is 0.09 and 0.8 rad from the landing minimum at the event's
load: it was reported there (0.011 and 0.08 rad from the rest point at the event's load).
"""
from hypothesis import event, example, given, Phase, settings, strategies as st
import numpy as np
import pytest
from scipy.optimize import brentq

from tensegrity_ros.core import equilibria, ModuleParams, track_module
from tensegrity_ros.core.continuation import TrackerSettings
from tensegrity_ros.core.neck.stack import settle_stack, Stack, StackPath, track_stack
from tensegrity_ros.core.numerics.tolerances import verified_minimum
from tensegrity_ros.core.simulation.start_state import upright_guess

#: Numerically sensitive throughout: `make test-numerics` runs it under other CPUs' arithmetic.
pytestmark = pytest.mark.numerics


def neck(n, rho, length, k, load):
    module = ModuleParams.paper(rho, L1=length, L2=length, k=k)
    return Stack(tuple([module] * (n - 1) + [module.with_(f3y=load, f4y=load)]))


def at_load(stack, load):
    return stack.with_module(len(stack) - 1, f3y=load, f4y=load)


def symmetric_branch_critical_load(start, theta, near):
    """The head load (per top node) where the upright mirror-symmetric branch of the
    identical-module neck ``start`` (unloaded, local angles ``theta``) loses stability,
    found without the tracker: Gauss-Newton restricted to mirror-symmetric states (every
    module's theta1 = theta2 = t_i, frames horizontal; unknowns t and the chord
    multipliers), followed in 30 load steps up to ``near``, then brentq on the smallest
    reduced-Hessian eigenvalue, which crosses zero linearly there (to ~1e-15 relative)."""
    n = len(start)
    basis = np.zeros((3 * n - 1, 2 * n - 1))        # symmetric unknowns -> tracker state
    for i in range(n):
        basis[2 * i, i], basis[2 * i + 1, i] = 1.0, -1.0
    basis[2 * n:, n:] = np.eye(n - 1)
    offset = np.zeros(3 * n - 1)
    offset[1:2 * n:2] = np.pi                        # rod A2A4 at pi - t in the base frame

    def solve(load, z):
        path = StackPath(start, at_load(start, load))
        for _ in range(40):
            y = offset + basis @ z
            step = np.linalg.lstsq(path.jacobian(y, 1.0) @ basis, path.residual(y, 1.0),
                                   rcond=None)[0]
            z = z - step
            if np.max(np.abs(step)) < 1e-15:
                break
        y = offset + basis @ z
        assert np.max(np.abs(path.residual(y, 1.0))) < 1e-12
        return path, y, z

    z = np.concatenate([np.asarray(theta)[:, 0], np.zeros(n - 1)])
    for load in np.linspace(0.0, near, 30)[1:]:
        z = solve(load, z)[2]

    def smallest(load):
        path, y, _ = solve(load, z)
        return path.eigenvalues(y, 1.0)[0]
    return brentq(smallest, near * (1 - 1e-6), near * (1 + 1e-6), xtol=1e-15, rtol=1e-15)


@settings(max_examples=30, deadline=None, derandomize=True,
          phases=(Phase.explicit, Phase.generate))     # no shrinking: minutes per example
@given(n=st.integers(1, 4), rho=st.floats(0.3, 0.9), length=st.floats(0.5, 2.0),
       k=st.floats(10.0, 1000.0))
@example(n=3, rho=0.7304230356637409, length=0.9144695211427292, k=10.268267950243567)
@example(n=3, rho=0.7136066672909007, length=0.8275333923024687, k=10.70272612111026)
def test_passages_are_continuous_and_jumps_are_finite(n, rho, length, k):
    start = neck(n, rho * length, length, k, 0.0)
    first = settle_stack(start, upright_guess(start.modules))
    end = at_load(start, -0.5 * k * length)
    result = track_stack(start, end, first)
    assert result.final.stable
    event(f'{len(result.passages)} passages, {len(result.jumps)} jumps')
    for jump in result.jumps:
        size = np.max(np.abs(jump.to_theta - jump.from_theta))
        assert size > 1e-3
        # the landing is a stable equilibrium at the jump's own load: released there, the
        # neck stays put (settle's flow and Newton polish, independent of the tracker's)
        assert not jump.landed_past
        landed = settle_stack(jump.stack, jump.to_theta)
        assert landed.stable and np.max(np.abs(landed.theta - jump.to_theta)) < 1e-9
    for passage in result.passages:
        load = passage.stack.modules[-1].f3y
        spread = []
        for beyond in (1e-2, 1e-4):
            past = track_stack(start, at_load(start, load * (1.0 + beyond)), first)
            assert past.status == 'ok' and past.jumps == () and len(past.passages) == 1
            spread.append(np.max(np.abs(past.final.theta - passage.theta)))
        assert spread[1] < 0.2 * spread[0]              # ~ sqrt: 0.1


#: How far past a passed branch point (relative load, or rho for the module) commands end.
JUST_PAST = (1e-9, 1e-8, 1e-7, 1e-6, 1e-5)
#: The longer command's end, relative to the branch point: its state fixes the buckled
#: branch's square root, which holds there to ~1 % (the N = 3 neck: 1.1 %).
FAR = 1e-3


def on_the_square_root(theta, critical, far, past):
    """Largest deviation of ``theta`` from the square-root law through the critical state
    and the longer command's end, relative to the predicted buckling amplitude."""
    predicted = critical + np.sqrt(past / FAR) * (far - critical)
    return np.max(np.abs(theta - predicted)) / np.max(np.abs(predicted - critical))


def test_a_neck_command_ending_just_past_its_passage_ends_ok():
    """N = 3 upright paper neck buckling sideways under head load (-6.854 N per node):
    a command ending 1e-9 .. 1e-5 past it (where lambda_min / lambda_max is 9e-12 ..
    9e-8, below DEFINITENESS_TOL up to 1e-7: these ended 'failed' before) ends ok on a
    stable state (certified by the pitchfork's normal form where the margin test cannot
    see it), on the square root through the passage and a longer command's state, and
    the next command on from there ends where one command all the way does.  Coming
    back down the buckled branch to the same load ends ok on the same state (to 3e-7:
    near the branch point Newton pins the state along the soft mode only so far, 1e-9
    past it, where lambda_min / lambda_max is 9e-12: the two ends differed by 1.5e-7,
    and by 2.1e-7 once the buckled branch's arclength points were taken at whatever s,
    ``continuation.correctors.arc_point``'s any_s; 1e-8 past: 2e-8 and 9e-9)."""
    start = neck(3, 0.6, 1.0, 100.0, 0.0)
    first = settle_stack(start, upright_guess(start.modules))
    whole = track_stack(start, at_load(start, -10.0), first)
    assert whole.status == 'ok' and whole.jumps == () and len(whole.passages) == 1
    passage = whole.passages[0]
    critical = passage.stack.modules[-1].f3y
    far = track_stack(start, at_load(start, critical * (1.0 + FAR)), first).final.theta
    for past in JUST_PAST:
        there = at_load(start, critical * (1.0 + past))
        result = track_stack(start, there, first)
        assert result.status == 'ok', (past, result.message)
        assert result.final.stable and result.jumps == () and len(result.passages) == 1
        assert on_the_square_root(result.final.theta, passage.theta, far, past) < 0.03, past
        on = track_stack(there, at_load(start, -10.0), result.final)
        assert on.status == 'ok' and on.final.stable and on.jumps == ()
        np.testing.assert_allclose(on.final.theta, whole.final.theta, atol=1e-9)
        back = track_stack(at_load(start, -10.0), there, whole.final)
        assert back.status == 'ok' and back.final.stable and back.jumps == (), past
        np.testing.assert_allclose(back.final.theta, result.final.theta, atol=3e-7, rtol=0)


def test_a_module_command_ending_just_past_its_passage_ends_ok():
    """The unloaded paper module buckles continuously at rho = L = 1 going down: commands
    ending 1e-9 .. 1e-5 in rho past it end ok on a minimum on the square root (to 1e-3;
    8e-5 seen), and go on from there to where one command all the way ends; coming
    back up to the same rho ends on the same state."""
    start = ModuleParams.paper(1.3)
    upright = [e.theta for e in equilibria(start).stable if np.allclose(e.theta, 0.0)][0]
    whole = track_module(start, ModuleParams.paper(0.5), upright)
    assert whole.status == 'ok' and whole.jumps == () and len(whole.passages) == 1
    far = track_module(start, ModuleParams.paper(1.0 - FAR), upright).final.theta
    for past in JUST_PAST:
        result = track_module(start, ModuleParams.paper(1.0 - past), upright)
        assert result.status == 'ok', (past, result.message)
        assert result.final.eigenvalues[0] > 0.0 and result.jumps == ()
        assert on_the_square_root(result.final.theta, np.zeros(2), far, past) < 1e-3, past
        on = track_module(ModuleParams.paper(1.0 - past), ModuleParams.paper(0.5),
                          result.final.theta, certificate=result.certificate)
        assert on.status == 'ok' and on.jumps == ()
        np.testing.assert_allclose(on.final.theta, whole.final.theta, atol=1e-9)
        back = track_module(ModuleParams.paper(0.5), ModuleParams.paper(1.0 - past),
                            whole.final.theta)
        assert back.status == 'ok' and back.jumps == (), past
        np.testing.assert_allclose(back.final.theta, result.final.theta, atol=1e-9)


def test_a_neck_command_from_just_past_its_passage_back_towards_it_ends_ok():
    """From a state certified 1e-9 (or 1e-7) past the N = 3 neck's passage, a command
    back towards it, ending 1e-10 .. 5e-10 past, stays on the buckled branch: ok, no jump,
    no passage, a minimum on the same side, on the square root through the passage and a
    longer command's end.  These ended 'failed' before (every natural step 'far': Newton
    pins such a state along the soft mode only to ~1e-6, above the corrector's slack).
    The same from -10 N, where the steps reach 3e-12 in s short of the end (certified by
    the linear law) and then fail: it then landed on a false fold, recursively, > 300 s.
    The square root holds here only to the noise floor, hence 50 %: 1e-10 past,
    lambda_min is 6e-12 of lambda_max, and Newton started on the one-command state itself
    moves it along the soft mode by -30 .. +12 % of the buckling amplitude (lambda_min
    by -50 .. +25 %): where the soft component lands within that is rounding (0.011 ..
    0.27 of the amplitude seen over these ends on the Haswell, Sandybridge, Nehalem and
    SkylakeX BLAS kernels; 25 % failed once, Sandybridge 5e-11).  The unbuckled state
    lies at 1, the mirror image at 2.  From -10 N to 5e-11 and 3e-11 past, the steps
    stop 1.8e-10 in s short of the end (every step 'far', and every run away from the
    branch point too): the command then ran for minutes (landings on a false fold, recursively; the
    node gave up after its 60 s work limit); the branch point is now found from the last
    state of the approach that passed the margin test 100-fold (a time budget here makes
    a regression fail, not hang).  That far state's linear law put s* 3.5e-11 in s off
    on the Haswell BLAS kernel (lambda_min of the near state is known to a few per cent
    only), and the end 3e-11 short (6.5e-11 in s) was not certified: the command then
    landed on a false fold and ended 'failed' ('the start state is not a stable
    equilibrium', a nested follower's); s* now comes from the branch point's own
    equations (to ~1e-14 in s), on every kernel."""
    start = neck(3, 0.6, 1.0, 100.0, 0.0)
    first = settle_stack(start, upright_guess(start.modules))
    whole = track_stack(start, at_load(start, -10.0), first)
    passage = whole.passages[0]
    critical = passage.stack.modules[-1].f3y
    far = track_stack(start, at_load(start, critical * (1.0 + FAR)), first).final.theta
    bounded = TrackerSettings(time_budget=30.0)
    for past, back_to in ((1e-9, 1e-10), (1e-9, 5e-10), (1e-7, 1e-10), (None, 1e-10),
                          (None, 5e-11), (None, 3e-11)):
        there = at_load(start, -10.0 if past is None else critical * (1.0 + past))
        certified = whole.final if past is None else track_stack(start, there, first).final
        result = track_stack(there, at_load(start, critical * (1.0 + back_to)), certified,
                             bounded)
        assert result.status == 'ok', (past, back_to, result.message)
        assert result.final.stable and result.jumps == () and result.passages == ()
        assert (result.final.theta - passage.theta).ravel() @ (far - passage.theta).ravel() > 0
        deviation = on_the_square_root(result.final.theta, passage.theta, far, back_to)
        assert deviation < 0.5, (past, back_to, deviation)     # 0.011 .. 0.27


def test_a_neck_command_from_just_past_its_passage_back_through_it_ends_unbuckled():
    """From the N = 3 neck's state certified 1e-9 past its passage, a command back through
    it to 1e-10 .. 5e-10 before it ends ok, no jump, on the unbuckled minimum at the end
    load, with the passage listed at the branch point's load to 1e-11 relative (7.4e-12
    seen: the normal form's estimate from a start 1e-9 past), that load being the
    symmetric branch's critical one, solved here without the tracker (the whole command's
    passage matches it to 1e-12: 1.1e-14 seen).  The
    unbuckled minimum is the mirror-symmetric one (each module's two rod angles equal; the
    start's differ by 6e-5 rad, the buckled branch's 1.9e-5 at 1e-10; to 2e-6: Newton pins
    it along the soft mode only to ~1e-6): checked so, and against a command up from the
    unloaded upright neck to the same end, which ends ok with no passage.  (A settle there
    does not reach rest: lambda_min is ~5e-13 of lambda_max.)  Both ended 'failed' before:
    every step from the start 'far', and the normal form handled only ends short of the
    branch point; going up, s* is located ~1.5e-8 early and the buckled state found past
    it could not be followed back to the end, before the true branch point."""
    start = neck(3, 0.6, 1.0, 100.0, 0.0)
    first = settle_stack(start, upright_guess(start.modules))
    whole = track_stack(start, at_load(start, -10.0), first)
    critical = whole.passages[0].stack.modules[-1].f3y
    independent = symmetric_branch_critical_load(start, first.theta, critical)
    assert abs(critical / independent - 1.0) < 1e-12
    there = at_load(start, critical * (1.0 + 1e-9))
    certified = track_stack(start, there, first).final
    for before in (1e-10, 5e-10):
        end = at_load(start, critical * (1.0 - before))
        result = track_stack(there, end, certified)
        assert result.status == 'ok', (before, result.message)
        assert result.final.stable and result.jumps == () and len(result.passages) == 1
        assert abs(result.passages[0].stack.modules[-1].f3y / independent - 1.0) < 1e-11
        asymmetry = np.abs(result.final.theta[:, 0] - result.final.theta[:, 1])
        assert np.max(np.abs(certified.theta[:, 0] - certified.theta[:, 1])) > 1e-5
        assert np.max(asymmetry) < 2e-6, before
        up = track_stack(start, end, first)
        assert up.status == 'ok' and up.final.stable, (before, up.message)
        assert up.jumps == () and up.passages == ()
        assert np.max(np.abs(result.final.theta - up.final.theta)) < 2e-6, before


def module_hessian_upright(rho, length=1.0, k=100.0):
    """docs/model.md section 1's Hessian of the unloaded module (L1 = L2 = length, ka = kb =
    kc = k) at theta = (0, 0), written out here rather than taken from the code."""
    h11 = length * ((k + k) * rho - k * length)
    h12 = -k * length * length
    return np.array([[h11, h12], [h12, h11]])


def test_the_unloaded_module_branch_point_is_at_rho_equal_to_the_rod_length():
    """The upright state of the unloaded paper module is an equilibrium for every rho and
    loses stability exactly at rho = L = 1 (eigenvalues 2 k rho and 2 k (rho - 1), mode
    (1, 1)), where the parallelogram pair (theta1 = theta2 = +-arccos rho) branches off
    (two stable non-flat solutions iff 2 rho < L1 + L2 = 2): the passage the module tests
    below list must be there."""
    for rho, sign in ((1.0 - 1e-3, -1.0), (1.0, 0.0), (1.0 + 1e-3, 1.0)):
        low = np.linalg.eigvalsh(module_hessian_upright(rho))[0]
        assert np.sign(np.round(low, 9)) == sign, rho
    assert abs(np.linalg.eigvalsh(module_hessian_upright(1.0))[0]) < 1e-12
    assert len([e for e in equilibria(ModuleParams.paper(0.999)).stable
                if abs(e.theta[0]) > 1e-6]) == 2
    assert len(equilibria(ModuleParams.paper(1.001)).stable) == 1


def test_a_module_command_from_just_past_its_passage_back_through_it_ends_unbuckled():
    """The module analogue of the neck's: from the unloaded paper module 1e-9, 5e-10 and
    2e-10 in rho past its passage at rho = 1 (reached from rho = 1.3; lambda_min /
    lambda_max = 2e-9, 1e-9 (at the margin test) and 4e-10 (certified by the normal
    form, as the neck's start is)), a command back up through it to 1e-10 and 5e-10
    before it ends ok, no jump, on a stable state, with one passage listed at rho = 1 (to
    1e-11: 2e-16 seen), on the unbuckled minimum theta = (0, 0), which is exact for the
    unloaded module (every term of the residual has a sine of an angle, so rounding leaves
    no floor there: 1e-26 rad seen, 1e-12 asserted, 1e-7 of the buckled amplitude), and
    so equal to the direct command from rho = 1.3; ending 1e-9 and 1e-8 before it too.
    Before: from 5e-10 past, every step was 'indefinite' (below the margin, not yet a
    crossing: lambda_min falls to zero only at s*), the tracker crawled, then jumped 999
    times between non-equilibria +-3.9e-4 rad and failed after 8 s; from 1e-9 past it
    passed only because a noisy rate (-1e-16) let one step be certified.  Ending 1e-9
    before, from 1e-9 and 5e-10 past: failed after 1.3 and 2.1 s with 180 and 303 false
    jumps; from 2e-10 past to 1e-9 and 1e-8 before: TrackingError ('the start state is
    not an equilibrium', from the tracker following the buckled branch away).  Both
    because that tracker's Newton stopped at a contraction of 1/2 while it converges by
    2/3 in the nearly cubic valley of a pitchfork, leaving a state 2x off the buckled
    minimum (3.5e-4 rad for 1.76e-4, 1.5e-8 past) whose residual (3e-9) is below the
    tolerance (2e-8); it allows 3/4 now (continuation.PITCHFORK_CONTRACTION; everywhere,
    it made the neck's command up to 1e-10 before its branch point list a false passage
    7e-8 early).  Now 2 .. 4 ms each.  The ends 1e-9 and 1e-8 before are verified
    minima (lambda_min / lambda_max 1e-9 and 1e-8) that ``Equilibrium.stable`` reads as
    degenerate (its DEGENERACY_TOL is 1e-8: tolerances.py)."""
    start = ModuleParams.paper(1.3)
    for past in (1e-9, 5e-10, 2e-10):
        there = ModuleParams.paper(1.0 - past)
        certified = track_module(start, there, np.zeros(2))
        assert certified.status == 'ok' and len(certified.passages) == 1
        assert bool(certified.certificate) == (past < 5e-10)
        for before in (1e-10, 5e-10, 1e-9, 1e-8):
            end = ModuleParams.paper(1.0 + before)
            result = track_module(there, end, certified.final.theta,
                                  certificate=certified.certificate)
            assert result.status == 'ok', (past, before, result.message)
            assert result.final.eigenvalues[0] > 0.0 and result.jumps == ()
            assert verified_minimum(result.final.eigenvalues, result.certificate)
            assert result.final.stable or before >= 1e-9
            assert len(result.passages) == 1, (past, before)
            assert abs(result.passages[0].rho - 1.0) < 1e-11
            assert np.max(np.abs(certified.final.theta)) > 1e-5
            assert np.max(np.abs(result.final.theta)) < 1e-12, (past, before)
            direct = track_module(start, end, np.zeros(2))
            assert direct.status == 'ok' and direct.jumps == () and direct.passages == ()
            assert np.max(np.abs(result.final.theta - direct.final.theta)) < 1e-12


def test_a_module_command_from_just_past_its_passage_back_towards_it_ends_ok():
    """The module analogue of the neck's: from 1e-9 and 2e-10 (certified) in rho past the
    unloaded paper module's passage, a command back towards it, ending 1e-10 and 5e-10
    past, stays on the buckled branch: ok, no jump, no passage, a verified minimum on the
    same side, on the exact buckled minimum theta1 = theta2 = arccos(rho) (the
    parallelogram: dU/dtheta = 2 k sin theta (rho - cos theta)), to 1e-10 rad (1.5e-11
    seen, 1e-6 of the amplitude 1.4e-5: rho's own rounding, 1e-16, moves it by
    1e-16 / theta ~ 1e-11)."""
    start = ModuleParams.paper(1.3)
    for past in (1e-9, 2e-10):
        there = ModuleParams.paper(1.0 - past)
        certified = track_module(start, there, np.zeros(2))
        for back_to in (1e-10, 5e-10):
            if back_to >= past:
                continue
            end = ModuleParams.paper(1.0 - back_to)
            result = track_module(there, end, certified.final.theta,
                                  certificate=certified.certificate)
            assert result.status == 'ok', (past, back_to, result.message)
            assert result.jumps == () and result.passages == ()
            assert verified_minimum(result.final.eigenvalues, result.certificate)
            assert result.final.theta @ certified.final.theta > 0.0
            exact = np.arccos(end.rho)
            deviation = np.max(np.abs(result.final.theta - exact))
            assert deviation < 1e-10, (past, back_to, deviation)


def test_a_tracked_module_state_verified_by_the_margin_test_reads_stable():
    """Within ~1e-8 in rho of the unloaded paper module's branch point (rho = 1) the upright
    state's lambda_min / lambda_max (docs/model.md's Hessian: 2 k (rho - 1) over 2 k rho) lies
    between the tracker's margin (1e-9) and the classification's degeneracy tolerance
    (1e-8): the tracker verifies it, the classification reads 'degenerate'.  The tracked
    record says so (MARGIN_CERTIFIED) and is ``stable``, and the simulator (the node's
    ``stable`` and ``equilibrium``) shows it stable, near a jump; before, an ok command
    there left the node at ERROR "not a stable equilibrium".  A solver root at the same
    parameters is not tracker-verified: it still reads degenerate, not stable."""
    from tensegrity_ros.core.numerics.tolerances import (DEFINITENESS_TOL, DEGENERACY_TOL,
                                                         MARGIN_CERTIFIED)
    from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator
    for rho in (1.0 + 2e-9, 1.0 + 1e-8, 1.0 - 1e-9):
        exact = np.linalg.eigvalsh(module_hessian_upright(rho)) if rho > 1.0 else None
        if exact is not None:
            assert DEFINITENESS_TOL < exact[0] / exact[-1] <= DEGENERACY_TOL
        start, theta = (1.3, np.zeros(2)) if rho > 1.0 else (0.9, np.full(2, 0.45))
        result = track_module(ModuleParams.paper(start), ModuleParams.paper(rho), theta)
        assert result.status == 'ok' and result.jumps == (), (rho, result.message)
        final = result.final
        assert final.kind == 'degenerate' and final.stable, (rho, final)
        assert final.certificate == MARGIN_CERTIFIED and result.certificate == ''
        if exact is not None:
            np.testing.assert_allclose(final.eigenvalues, exact, rtol=1e-6)
        # (no time budget: the outcome is what is tested, not the node's slicing; with the
        # default 50 ms of wall time per call a loaded machine defers the command, and the
        # status read right after it is the old state's: failed at load ~6 on 2 cores)
        sim = Simulator([ModuleParams.paper(start)], [theta], [ModuleLimits(0.05, 1.95)],
                        time_budget=None)
        assert sim.command_rho(0, rho, 0).status == 'ok'
        status = sim.status(0)
        assert sim.stable and status.level == 'warn' and 'near a jump' in status.message
    roots = [e for e in equilibria(ModuleParams.paper(1.0 + 2e-9))
             if np.max(np.abs(e.theta)) < 1e-6]
    assert roots and all(e.kind == 'degenerate' and not e.stable for e in roots)


def test_a_command_ending_exactly_at_the_branch_point_ends_on_it():
    """The default node's module (the unloaded paper module) commanded to rho = 1.0, its
    branch point exactly (docs/model.md's Hessian is singular there: eigenvalues 0 and 2 k),
    from above on the upright branch and from below on the buckled one: ok, no jump, on
    the upright state theta = 0 (a degenerate minimum: the supercritical pitchfork's
    quartic term; Newton in its cubic valley pins it to ~1e-8 rad), stable (certified:
    the margin test cannot see lambda_min = 0); the simulator shows it stable.  From there
    every next command goes where the exact answer is: down (buckling: one passage, no
    jump) onto the buckled minimum theta1 = theta2 = arccos(rho) (the parallelogram:
    dU/dtheta = 2 k sin theta (rho - cos theta)), 1e-9 .. 0.1 in rho, to 1e-10 rad; up
    onto theta = 0.  (Before, the command failed on the last verified state ~1e-9 in rho
    short, and from 1.0 the buckled side was lost: a command 1e-9 .. 1e-5 down jumped onto
    the mirror image, or ran out of time.)"""
    from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator
    assert np.linalg.eigvalsh(module_hessian_upright(1.0))[0] == 0.0
    at = ModuleParams.paper(1.0)
    # (0.51 and 0.99 on the buckled branch: the normal form's linear law put the branch
    # point 2e-16 in s past the end, and the command ended on a buckled state pinned 8e-9
    # rad off by the square-root law, from which the next command up never ended)
    for start, theta in ((1.3, np.zeros(2)), (1.1, np.zeros(2)), (0.75, np.full(2, 0.72)),
                         (0.5, np.ones(2)), (0.51, np.full(2, np.arccos(0.51))),
                         (0.99, np.full(2, np.arccos(0.99)))):
        result = track_module(ModuleParams.paper(start), at, theta)
        assert result.status == 'ok' and result.jumps == (), (start, result.message)
        assert result.end.rho == 1.0 and result.final.stable and result.certificate
        assert np.max(np.abs(result.final.theta)) < 1e-7, (start, result.final.theta)
        for after in (0.9, 1.0 - 1e-5, 1.0 - 1e-9, 1.0 + 1e-9, 1.2):
            on = track_module(at, ModuleParams.paper(after), result.final.theta,
                              certificate=result.certificate)
            assert on.status == 'ok' and on.jumps == () and on.final.stable, (start, after)
            assert len(on.passages) == (after < 1.0), (start, after)
            exact = np.full(2, np.arccos(min(after, 1.0)))
            if after < 1.0:                 # either side of the pitchfork is right
                exact *= np.sign(on.final.theta[0])
            deviation = np.max(np.abs(on.final.theta - exact))
            assert deviation < (1e-10 if after < 1.0 else 1e-7), (start, after, deviation)
        # (no time budget: the outcome is what is tested, not the node's slicing)
        sim = Simulator([ModuleParams.paper(start)], [theta], [ModuleLimits(0.05, 1.95)],
                        time_budget=None)
        assert sim.command_rho(0, 1.0, 0).status == 'ok' and sim.stable
        assert sim.status(0).level in ('ok', 'warn')
        assert sim.command_rho(0, 0.9, 0).status == 'ok' and sim.stable
