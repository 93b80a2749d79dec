"""The neck tracker on in-range inputs that used to end in a tracking failure (issue 10 (a)).

A module of a neck folds flat onto its top chord where rho(i) + rho(i+1) = L1 + L2 (a
linkage limit: the chord constraint's gradient vanishes, two branches of
configurations cross).  The independent gradient-flow reference (reference_paths)
goes across continuously onto the crossing branch (t1 = -t2), with no jump; so must
the tracker.  Where the reference is too slow for a test, the tracker's answer is
checked by invariants with the reference's own Newton and Hessian: every state and
landing a stable equilibrium at its s, jumps a finite distance, continuity across the
limit (the state closes in on the flat state like a square root).
"""
import numpy as np
import pytest

from reference_paths import (angle_distance, critical_solve, flow_to_rest, ModuleSystem,
                             NeckSystem, quasi_static_path)
from tensegrity_ros.core import ModuleParams
from tensegrity_ros.core.neck.stack import settle_stack, Stack, track_stack
from tensegrity_ros.core.simulation.simulator import Simulator

#: Numerically sensitive throughout: `make test-numerics` runs it under other CPUs' arithmetic.
pytestmark = pytest.mark.numerics


def paper_neck(n, rho=0.75):
    return Stack(tuple(ModuleParams.paper(rho) for _ in range(n)))


def all_rhos(stack, rho):
    return Stack(tuple(m.with_rho(rho) for m in stack.modules))


def upright(n):
    return np.full((n, 2), 0.7227342478134157)     # cos t = 0.75: the upright paper neck


def mirrored(theta):
    """The mirror image of a symmetric neck (x -> -x swaps each module's two rods)."""
    return np.asarray(theta).reshape(-1, 2)[:, ::-1].ravel()


def assert_stable_for_the_reference(start, end, theta, s):
    system = (NeckSystem(start.modules, end.modules) if len(start) > 1
              else ModuleSystem(start.modules[0], end.modules[0]))
    star, ok = system.critical_point(np.ravel(theta), s)
    assert ok and angle_distance(star, np.ravel(theta)) < 1e-9, (theta, star)
    assert system.is_stable_equilibrium(star, s), (theta, s)


def assert_jump_off_a_crossing(jump, s_star, module):
    """A jump off ``module``'s flat crossing: located at s* (where rho(i) + rho(i+1) =
    L1 + L2) to 1e-9, from the module flat, onto a minimum of the reference model at the
    landing's own parameters a move away, below the departure (an overdamped mechanism
    cannot climb); ambiguous, as another half-branch out of the crossing (or the mirror
    image) lands elsewhere."""
    assert jump.kind == 'branch_point' and abs(jump.s - s_star) < 1e-9, (jump.s, s_star)
    departure, landing = np.ravel(jump.from_theta), np.ravel(jump.to_theta)
    assert angle_distance(departure[2 * module:2 * module + 2], np.zeros(2)) < 1e-5
    landed = jump.landing_stack or jump.stack
    assert_stable_for_the_reference(landed, landed, landing, 1.0)
    assert angle_distance(landing, departure) > 1e-2
    before = NeckSystem(jump.stack.modules).energy(departure, 1.0)
    assert NeckSystem(landed.modules).energy(landing, 1.0) < before
    assert jump.ambiguous


def test_m0_rho_across_the_flat_module_matches_the_reference():
    """N = 3 config/neck.yaml-like neck, m0 rho 0.2 -> 1.5 (module 0 flat at rho 1.25):
    was 'step size underflow (far)' at rho 1.25."""
    neck = paper_neck(3)
    low = track_stack(neck, neck.with_module(0, rho=0.2), upright(3))
    assert low.status == 'ok', low.message
    got = track_stack(low.end, low.end.with_module(0, rho=1.5), low.final)
    assert got.status == 'ok', got.message
    assert got.jumps == ()
    # the reference across the limit (a mirror-symmetric neck: either side is right)
    before = track_stack(low.end, low.end.with_module(0, rho=1.2), low.final)
    a, b = before.end, before.end.with_module(0, rho=1.3)
    ref = quasi_static_path(NeckSystem(a.modules, b.modules), np.ravel(before.final.theta))
    mine = track_stack(a, b, before.final)
    assert mine.status == 'ok' and mine.jumps == () and ref.jumps == []
    final = np.ravel(mine.final.theta)
    assert min(angle_distance(final, ref.final),
               angle_distance(mirrored(final), ref.final)) < 1e-6, (final, ref.final)
    assert abs(final[0] + final[1]) < 1e-9 and abs(final[0]) > 0.1     # t1 = -t2: crossed over


@pytest.mark.parametrize('past', [1e-4, 1e-6])
def test_all_rhos_across_the_flat_neck_go_on_continuously(past):
    """All rhos 0.75 -> 1 + past: every module flat at rho = 1.  The state goes on next
    to the flat state, ~sqrt(past) away (continuity), stable for the reference."""
    neck = paper_neck(3)
    end = all_rhos(neck, 1.0 + past)
    got = track_stack(neck, end, upright(3))
    assert got.status == 'ok', got.message
    assert got.jumps == ()
    distance = angle_distance(np.ravel(got.final.theta), np.zeros(6))
    assert 0.3 * np.sqrt(past) < distance < 30.0 * np.sqrt(past), distance
    assert_stable_for_the_reference(end, end, got.final.theta, 0.0)


def test_all_rhos_to_1_2_and_back_to_0_4_without_failure():
    """The bench case 'N3 joint_commands all 0.75 -> 1.2 -> 0.4': was 'could not land
    after the branch_point' (and 20 s unbounded)."""
    sim = Simulator(list(paper_neck(3).modules), None, time_budget=None)
    for rho in (1.2, 0.4):
        outcome = sim.command_rhos({0: rho, 1: rho, 2: rho}, 0)
        assert outcome.status == 'ok', outcome.events
        assert sim.stable
    stack = Stack(tuple(sim.modules))
    assert_stable_for_the_reference(stack, stack, sim.state.theta, 0.0)


def test_n10_head_load_jumps_land_on_stable_equilibria():
    """N = 10, head load 0 -> -40 N (half at each top node): was 'could not land after
    the branch_point' at s = 0.0532 (the landing flow rested 0.043 short of the soft
    buckled minimum).  Too slow for the reference's path: invariants instead."""
    neck = paper_neck(10)
    end = neck.with_module(9, f3y=-20.0, f4y=-20.0)
    got = track_stack(neck, end, upright(10))
    assert got.status == 'ok', got.message
    folds = [j for j in got.jumps if j.kind == 'fold']
    assert folds, 'the buckled neck snaps under the head load'
    # (the perfect neck's supercritical buckling at s = 0.0532 is reported as a
    # branch_point jump whose landing is not an equilibrium at s* itself: the open item
    # (b3) of issue 10, made continuous on branch j10buckle; not checked here)
    for jump in folds:
        assert angle_distance(np.ravel(jump.to_theta), np.ravel(jump.from_theta)) > 1e-3
        assert_stable_for_the_reference(neck, end, jump.to_theta, jump.s)
    assert_stable_for_the_reference(end, end, got.final.theta, 0.0)


def test_a_toggle_at_a_flat_crossing_jumps_off_it():
    """The random N = 2 neck of the neck jump property's seed 22: module 0 is driven flat
    onto its chord (crossed, so rho0 + rho1 = L1 + L2 at s*) with loads pushing along
    the fold: the chord force grows without bound (1.7e7 N at the last verified state,
    where the loads are ~10 N) and no minimum goes on continuously (the nearest one
    past it is 0.04 rad away and does not close in).  The tracker stopped there ('linkage
    limit', a stated give-up); the reference's flow stalls there (> 900 s).  Released
    just past the crossing, the mechanism slides off it (leave_crossing): a jump at s*,
    onto a minimum of the reference model, ambiguous (the crossing's other half-branch
    lands elsewhere), and the command ends on a minimum the reference verifies."""
    m0 = ModuleParams(rho=0.7029816069752837, L2=0.8896829207187873, ka=75.31350239567674,
                      kb=109.1915012560552, kc=97.56022268463681, f3x=4.876756188802016,
                      f3y=7.031361397022615, f4x=3.3696132323704453, f4y=-8.971224650494813)
    m1 = ModuleParams(rho=0.6845353092751134, L2=1.0733590368587003, ka=73.00847770438497,
                      kb=98.63967716243373, kc=89.77382855830412, f3x=-2.8351431821311524,
                      f3y=5.940334654732881, f4x=-0.7910111026040079, f4y=-7.9363378293778215)
    start = Stack((m0, m1))
    end = start.with_module(0, rho=1.3063288693672621, f3y=-2.2080569051909187) \
        .with_module(1, rho=0.5936679294565745, f4y=-8.6652768990632)
    got = track_stack(start, end, np.array([[0.8, 0.8], [-1.2, -0.9]]))
    assert got.status == 'ok', got.message
    # where: rho0(s) + rho1(s) = L1 + L2 of module 0, solved here by hand
    total = lambda stack: stack.modules[0].rho + stack.modules[1].rho      # noqa: E731
    s_star = (m0.L1 + m0.L2 - total(start)) / (total(end) - total(start))
    (jump,) = got.jumps
    assert_jump_off_a_crossing(jump, s_star, 0)
    assert_stable_for_the_reference(start, end, got.final.theta, 1.0)


@pytest.mark.parametrize('n', [1, 2])
def test_a_short_command_across_a_fold_reached_to_rounding_jumps_there(n):
    """The top module (fig. 8b's loads, L2 = 1.05) tracked to 1e-7 m short of its fold,
    then commanded to 1e-6 m past it (found by j14core2): the steps underflow within
    ~1e-12 m of the fold, where lambda_min is still ~1e-6 of the scale; was 'step size
    underflow (far)' with no jump.  Now one fold, at the long command's fold to 1e-8 m,
    landing where the long command lands, a stable equilibrium for the reference."""
    modules = [ModuleParams.paper(0.75) for _ in range(n - 1)]
    stack = Stack(tuple(modules + [ModuleParams.paper(0.3, F3=5.0, F4=5.0, L2=1.05)]))
    state = settle_stack(stack, np.full((n, 2), -0.5))
    long = track_stack(stack, stack.with_module(n - 1, rho=1.6), state)
    fold = long.jumps[0].stack.modules[-1].rho
    near = stack.with_module(n - 1, rho=fold - 1e-7)
    past = stack.with_module(n - 1, rho=fold + 1e-6)
    approach = track_stack(stack, near, state)
    got = track_stack(near, past, approach.final)
    assert got.status == 'ok', got.message
    assert [j.kind for j in got.jumps] == ['fold']
    jump = got.jumps[0]
    assert abs(jump.stack.modules[-1].rho - fold) < 1e-8
    assert angle_distance(np.ravel(jump.to_theta), np.ravel(long.jumps[0].to_theta)) < 1e-4
    assert_stable_for_the_reference(near, past, jump.to_theta, jump.s)


def test_a_buckling_next_to_a_linkage_limit_is_the_reference_paths():
    """config/neck.yaml's modules (found by a seeded run of round-number commands), head
    pulled up 1 N, m0 at 0.15 m, m1's actuator 0.08 -> 0.13 m: the neck's symmetric
    state loses stability at m1 rho 0.0899946 (5e-6 m short of m0's linkage limit, rho0 +
    rho1 = L1 + L2 = 0.24), where the critical mode is inexact (|psi . F_s| / |F_s| =
    5e-6, not 0): it was taken for a fold, and the jump reported landed in a minimum that
    exists only from 5e-5 m further on.  The reference's quasi-static path has no jump
    there: the neck goes on continuously, and so does the tracker now (a passage), to
    the reference's end state or its mirror image: the neck and its state are
    mirror-symmetric, so the side the passage buckles to is a convention, and which one
    each takes turns on rounding (the Nehalem BLAS kernel's tracker took the other)."""
    def neck(rho1):
        return Stack((
            ModuleParams(rho=0.15, L1=0.12, L2=0.12, ka=300.0, kb=300.0, kc=300.0,
                         m1=0.02, m2=0.02),
            ModuleParams(rho=rho1, L1=0.12, L2=0.12, ka=300.0, kb=300.0, kc=300.0,
                         m1=0.02, m2=0.02),
            ModuleParams(rho=0.09, L1=0.12, L2=0.12, ka=300.0, kb=300.0, kc=300.0,
                         m1=0.02, m2=0.02, f3y=1.0, f4y=1.0)))
    state = np.array([0.28968699, 2.85190566, 0.78366205, 2.3579306, 0.74311249, 2.39848016,
                      1.89924432, 0.78994397])
    start, end = neck(0.08), neck(0.13)
    track = track_stack(start, end, state)
    assert track.status == 'ok', track.message
    assert track.jumps == ()
    held = track_stack(start, start, state).final
    ref = quasi_static_path(NeckSystem(start.modules, end.modules), np.ravel(held.theta))
    assert ref.jumps == []
    final = np.ravel(track.final.theta)
    mirrored = track.final.theta[:, ::-1].ravel()
    assert min(angle_distance(final, ref.final), angle_distance(mirrored, ref.final)) < 1e-9


def test_a_jump_that_lands_past_its_event_says_where_its_landing_is_an_equilibrium():
    """A jump whose landing minimum exists only past its event (the tracker reports it at
    its own parameters, ``Event.landing_s``): the simulator's Jump carries those parameters
    (``landing``) and the ``jumps`` message ``landing_rho`` and ``landing_<m>_rho``
    (before, it gave the landing angles beside the event's rho alone).  The parameters are
    those of the neck this was found on (config/neck.yaml's modules, head pulled up 1 N,
    m1 0.0899946 -> 0.0900446 m), the jump given by hand: that one is no jump (above)."""
    from tensegrity_ros.core.simulation.mechanisms import make_jump
    from tensegrity_ros.ros import conversions as ros_conversions

    def module(rho, load=0.0):
        return ModuleParams(rho=rho, L1=0.12, L2=0.12, ka=300.0, kb=300.0,
                            kc=300.0, m1=0.02, m2=0.02, f3y=load, f4y=load)
    at = lambda rho1: (module(0.15), module(rho1), module(0.09, 1.0))     # noqa: E731
    fold, landing = 0.0899946, 0.0900446
    raw = ('fold', 0.19989, at(fold), np.zeros((3, 2)), np.full((3, 2), 0.1), False,
           at(landing))
    event = make_jump(raw, module=1, cause='rho_cmd', count=1)
    assert event.landing[1].rho == landing and event.modules[1].rho == fold
    message = ros_conversions.jump_status(name='tensegrity: m1 jump', hardware_id='t',
                                          modules=('m0', 'm1', 'm2'), jump=event)
    values = {kv.key: kv.value for kv in message.values}
    assert float(values['rho']) == event.modules[1].rho
    assert float(values['landing_rho']) == float(values['landing_m1_rho']) == landing
    assert float(values['landing_m0_rho']) == 0.15
    assert float(values['m1_rho']) == float(values['rho'])
    assert f'an equilibrium at rho={landing:.6g}' in message.message


def test_a_command_from_a_state_verified_on_the_commands_scale_is_not_refused():
    """config/neck.yaml's modules after a seeded stream of round-number commands (seed 0,
    stream 11 of benchmarks/bench_round_commands.py: m0 had been stopped flat at a linkage
    limit and then flipped), m1's actuator 0.12 -> 0.06 m: the tracker's step towards a
    branch point on lambda_min's linear law asks a nested tracker for the branch away from
    it, whose own margin test (scaled to the state's stiffness, not the command start's)
    refused that verified state; the TrackingError escaped the command, which failed as
    'the start state is not a stable equilibrium' although the start was one (lambda_min
    20.9 N/m).  It now ends ok on a stable equilibrium of the reference."""
    def module(rho, load=0.0):
        return ModuleParams(rho=rho, L1=0.12, L2=0.12, ka=300.0, kb=300.0,
                            kc=300.0, m1=0.02, m2=0.02, f3y=load, f4y=load)
    start = Stack((module(0.06), module(0.12), module(0.14, -10.0)))
    end = start.with_module(1, rho=0.06)
    # the simulator's state (absolute rod angles, chord multipliers), as it held it
    state = np.array([41938.62133894537, 43434.52924331135, -587.7159189593756,
                      -578.5188129169165, -20442.630944396464, 21236.061250160812,
                      -2.873990985436973, -2.1466265455692977])
    held = track_stack(start, start, state).final
    assert held.stable and held.eigenvalues[0] > 20.0
    track = track_stack(start, end, held)
    assert track.status == 'ok', track.message
    assert track.final.stable
    for jump in track.jumps:
        assert_stable_for_the_reference(start, end, jump.to_theta, jump.s)
    assert_stable_for_the_reference(start, end, track.final.theta, 1.0)


def test_a_pitchfork_next_to_a_linkage_limit_is_passed_as_the_reference_passes_it():
    """config/neck.yaml's modules, unloaded, rhos (0.13, 0.09, 0.05) m, m1's actuator
    0.09 -> 0.15 m (benchmarks/bench_round_commands.py seed 0, stream 0): module 0 folds
    flat at s = 1/3 (rho0 + rho1 = L1 + L2), and 9.6e-5 in s before that the symmetric
    neck buckles sideways at a supercritical pitchfork.  The tracker reported a jump
    ('fold', 0.02 rad): next to the linkage limit the fold test |psi . F_s| is
    ill-conditioned (a chord multiplier amplifies a 1e-5 asymmetry of the mode: 2.6e-3
    against the 1e-6 branch tolerance).  The reference passes it continuously; so must
    the tracker, ending where the reference ends (or on its mirror image)."""
    def module(rho):
        return ModuleParams(rho=rho, L1=0.12, L2=0.12, ka=300.0, kb=300.0,
                            kc=300.0, m1=0.02, m2=0.02)
    start = Stack((module(0.13), module(0.09), module(0.05)))
    end = start.with_module(1, rho=0.15)
    held = settle_stack(start, [[-0.411138, -0.411138], [0.94797, 0.94797],
                                [1.140333, 1.140333]])
    assert held.stable
    track = track_stack(start, end, held)
    ref = quasi_static_path(NeckSystem(start.modules, end.modules), np.ravel(held.theta))
    assert ref.jumps == [] and len(ref.passages) == 1
    assert track.status == 'ok', track.message
    assert track.jumps == ()
    assert [abs(p.s - ref.passages[0].s) < 1e-7 for p in track.passages] == [True]
    final = np.ravel(track.final.theta)
    assert min(angle_distance(final, ref.final),
               angle_distance(mirrored(final), ref.final)) < 1e-6, (final, ref.final)


def neck_yaml(rhos, head=0.0):
    """config/neck.yaml's modules at actuator lengths ``rhos``, ``head`` N at each top node."""
    def module(rho, load=0.0):
        return ModuleParams(rho=rho, L1=0.12, L2=0.12, ka=300.0, kb=300.0,
                            kc=300.0, m1=0.02, m2=0.02, f3y=load, f4y=load)
    return Stack((module(rhos[0]), module(rhos[1]), module(rhos[2], head)))


@pytest.mark.parametrize('rhos, head, theta, index, rho, s_star', [
    # bench_round_commands seed 0, stream 8: m1 0.08 -> 0.15 m buckles 1.1e-4 m short of
    # m1's linkage limit (rho1 + rho2 = 0.24), m1 0.031 rad from flat
    ((0.06, 0.08, 0.12), -2.0, [[0.948, 0.948], [-0.586, -0.586], [-0.383, -0.383]], 1,
     0.15, 0.5698197),
    # stream 16: m2 0.13 -> 0.15 m, m0 hanging down, buckles 1.2e-4 m short of m1's
    # linkage limit, m1 0.031 rad from flat
    ((0.09, 0.09, 0.13), -2.0, [[-1.571, -1.571], [0.411, 0.411], [0.250, 0.250]], 2,
     0.15, 0.9940939),
    # stream 18, head pulled up: m1 0.12 -> 0.15 m buckles 1.1e-5 m short of the end,
    # where m0 and m1 are both at their linkage limits (was over 20 s: the landing's
    # retries never ended, and the buckled branch was lost at the first amplitude tried)
    ((0.09, 0.12, 0.09), 1.0, [[0.505, 0.505], [0.505, 0.505], [0.743, 0.743]], 1,
     0.15, 0.9996386)])
def test_buckling_next_to_a_flat_module_is_continuous(rhos, head, theta, index, rho, s_star):
    """config/neck.yaml's modules, mirror-symmetric, driven to a
    supercritical branch point next to a module folded almost flat: was 'could not land
    after the fold'.  Near the flat module the critical mode is inexact (|psi . F_s| /
    |F_s| 4.9e-6 and 1.1e-4, not 0), so it was taken for a fold; and the landing flow's
    damped projection (elastic chords) rested ~5e-5 m off the constraints on the
    symmetric state, whose projection Newton took to the symmetric saddle.  As the
    reference's quasi-static path, the neck now buckles continuously (a passage, no
    jump) and ends where it ends (or on its mirror image: which side a perfect pitchfork
    buckles to is a convention)."""
    start = neck_yaml(rhos, head)
    end = start.with_module(index, rho=rho)
    state = settle_stack(start, np.array(theta))
    track = track_stack(start, end, state)
    assert track.status == 'ok', track.message
    assert track.jumps == () and len(track.passages) == 1
    assert abs(track.passages[0].s - s_star) < 1e-6
    ref = quasi_static_path(NeckSystem(start.modules, end.modules), np.ravel(state.theta))
    assert ref.jumps == [] and len(ref.passages) == 1
    final = np.ravel(track.final.theta)
    assert min(angle_distance(final, ref.final),
               angle_distance(mirrored(final), ref.final)) < 1e-9, (final, ref.final)


def test_a_command_from_two_flat_modules_leaves_them():
    """config/neck.yaml's modules, no head load, as a seeded stream left them (bench_round_
    commands seed 0, stream 19: a command stopped at module 0's linkage limit), module 0
    flat (5.7e-11 rad) and module 1 at its own limit (rho0 + rho1 = rho1 + rho2 = 0.24);
    joint_commands {0.12, 0.09, 0.12} takes both away from their limits.  The minimum
    just past the flat state was found at the start's stiffness scale, inflated by the
    chord force (lambda_max 4.4e10 N/m; 7.3e3 N/m there), so Newton stopped 0.14 N from
    equilibrium, 9e-5 rad off it, and every step from there was 'far': was 'step size
    underflow at s=1e-06 (far)'.  Now ok, each landing and the end stable for the
    reference."""
    start = neck_yaml((0.11375000000000107, 0.12624999999999892, 0.1137499999999995))
    state = np.array([5.710242027633342e-11, 3.141592653532572, -0.007977820282589513,
                      3.1418005516052805, 0.3023670678687126, 2.822824334879997,
                      226481513.07760066, -0.9786008860000873])
    held = track_stack(start, start, state).final
    assert held.stable and np.max(np.abs(held.theta[0])) < 1e-9
    end = neck_yaml((0.12, 0.09, 0.12))
    track = track_stack(start, end, held)
    assert track.status == 'ok', track.message
    for jump in track.jumps:
        rho0 = start.modules[0].rho
        s = (jump.landing_stack.modules[0].rho - rho0) / (0.12 - rho0)
        assert_stable_for_the_reference(start, end, jump.to_theta, s)
    assert_stable_for_the_reference(end, end, track.final.theta, 0.0)


def test_a_settle_next_to_a_flat_module_rests_where_the_reference_flow_does():
    """config/neck.yaml's modules, no head load, module 0 4e-4 rad from flat and module 1
    at its own linkage limit (the state a stream left: bench_round_commands seed 0, stream
    19, before the scale fix above); the next command settled from there.  The landing
    flow's damped projection (elastic chords) rested 1e-4 m off the constraints, whose
    projection Newton took to a saddle: was 'no stable equilibrium reached from the given
    state'; going on rigid from that rest point then rested elsewhere (module 0 0.014 rad
    from where the rigid flow goes).  The flow now starts over rigid: it rests where the
    reference's flow does."""
    from reference_paths import settle_reference
    stack = neck_yaml((0.11375000625, 0.12624996375, 0.11375000625))
    theta = np.array([[0.0004, 0.0003], [-0.0079, -0.0002], [0.3106, 0.3106]])
    got = settle_stack(stack, theta)
    assert got.stable
    reference = settle_reference(NeckSystem(stack.modules), theta.ravel())
    assert not reference.ambiguous
    assert angle_distance(np.ravel(got.theta), reference.state) < 1e-9
    assert_stable_for_the_reference(stack, stack, got.theta, 0.0)


def test_a_landing_by_a_module_at_its_linkage_limit_is_the_reference_paths():
    """config/neck.yaml's modules as a seeded stream left them (bench_round_commands seed
    0, stream 10: commands stopped at module 0's linkage limit, rho0 + rho1 = 0.24, and
    at a fold), head load -0.047 -> -10 N: the neck folds at s = 0.0823 with module 0 on
    one branch of its crossing at flat (-0.038, -0.0011 rad).  The elastic-chord flow
    rested 5.6e-5 m off the constraints; the rigid one, integrated as loosely as the
    elastic one, rested at the crossing or went through it onto the mirror branch (the
    way turns on ~1e-7 of it).  Was 'could not land after the fold'.  Now the jump lands
    where the reference's quasi-static path does, and so does the command."""
    rhos, load = (0.12714285714285406, 0.11285714285714055, 0.11), -0.04680362720831721
    at = lambda s: neck_yaml(rhos, load + s * (-10.0 - load))       # noqa: E731
    start = at(0.0)
    state = np.array([-0.014637887761961775, 3.1420287001042175, 0.36509384119798977,
                      2.746184073161542, 0.38380108303212673, 2.7273323792052877,
                      -0.9784359822956004, 1.0726442579687958])
    held = track_stack(start, start, state).final
    assert held.stable
    mine = track_stack(start, at(1.0), held)
    assert mine.status == 'ok', mine.message
    ref = quasi_static_path(NeckSystem(start.modules, at(1.0).modules), np.ravel(held.theta))
    assert [j.kind for j in mine.jumps] == [j.kind for j in ref.jumps] == ['fold']
    assert angle_distance(np.ravel(mine.jumps[0].to_theta), ref.jumps[0].landing) < 1e-3
    assert angle_distance(np.ravel(mine.final.theta), ref.final) < 1e-9


def test_a_module_driven_flat_under_load_jumps_off_its_crossing():
    """config/neck.yaml's modules, head pushed down 10 N, joint_commands {0.10, 0.15, 0.06}
    from {0.06, 0.06, 0.14} (bench_round_commands seed 0, stream 11): module 0 is driven
    flat (rho0 + rho1 = 0.24 at s = 12/13) with the load along the fold, its chord force
    growing ~1/angle.  The steps underflowed 1e-8 in s short of it, 1e-4 rad from flat
    (chord force 8.4e4 N), where the equilibrium equations are singular to rounding (the
    Jacobian's singular values 1.3e-12 .. 1e5) at a minimum (lambda_min 183 N/m): was
    'step size underflow (newton)', then a stated linkage-limit give-up.  The mechanism
    slides off the crossing there, onto a minimum of the reference model; the neck and
    the departure are mirror-symmetric and the landing is not, so the jump is ambiguous."""
    start = neck_yaml((0.06, 0.06, 0.14), -10.0)
    # the simulator's state as the stream left it: its rod angles wound up to ~4e4 rad
    # (7e-12 rad apart in floating point), which is what stopped the steps that early
    state = np.array([41935.02593766776, 43431.47123832769, -590.033733331424,
                      -581.7803264575689, -20445.955874025265, 21234.4956300763,
                      3.531982553097078, -0.14649542490653558])
    held = track_stack(start, start, state).final
    assert held.stable
    end = neck_yaml((0.10, 0.15, 0.06), -10.0)
    got = track_stack(start, end, held)
    assert got.status == 'ok', got.message
    (jump,) = got.jumps
    assert_jump_off_a_crossing(jump, 12.0 / 13.0, 0)
    assert_stable_for_the_reference(end, end, got.final.theta, 1.0)


def test_a_landing_flow_through_a_flat_crossing_takes_the_reference_paths_half_branch():
    """config/neck.yaml's modules as a seeded stream left them (bench_round_commands seed
    0, stream 16: module 1 at its linkage limit, rho1 + rho2 = 0.24 = L1 + L2, m0 hanging
    down), head load -2 -> +1 N: the neck folds at s = 0.627 with modules 1 and 2 almost
    flat.  The landing's rigid flow reaches module 1's flat crossing, where it stalls (the
    projection on the chord is undefined there): was 'could not land after the fold',
    after each rigid flow had spent its budget.  The tracker now goes on, as the
    reference's flow does, along the steepest of the half-branches leaving the crossing;
    the two leaving ones are mirror images of each other within 3e-4 of their descent
    rates, and land on mirror images, so the jump is ambiguous (so says the reference) and
    either landing is right."""
    start = neck_yaml((0.11, 0.09, 0.15), -2.0)
    end = neck_yaml((0.11, 0.09, 0.15), 1.0)
    state = np.array([4.797937458533063, 4.631076826745917, 3.2129635268714893,
                      6.291842383950489, 3.318669734513109, 6.2343703730939986,
                      -3.2558463920996448, -1.845205163904667])
    held = track_stack(start, start, state).final
    assert held.stable
    mine = track_stack(start, end, held)
    assert mine.status == 'ok', mine.message
    ref = quasi_static_path(NeckSystem(start.modules, end.modules), np.ravel(held.theta))
    assert [j.kind for j in mine.jumps] == [j.kind for j in ref.jumps] == ['fold']
    jump, theirs = mine.jumps[0], ref.jumps[0]
    assert abs(jump.s - theirs.s) < 1e-6
    assert jump.ambiguous and theirs.ambiguous
    landing = np.ravel(jump.to_theta)
    assert min(angle_distance(landing, theirs.landing),
               angle_distance(mirrored(landing), theirs.landing)) < 1e-6, (landing, theirs.landing)
    final = np.ravel(mine.final.theta)
    assert min(angle_distance(final, ref.final),
               angle_distance(mirrored(final), ref.final)) < 1e-6, (final, ref.final)


def test_a_flat_crossings_half_branches_are_the_reference_ones():
    """The crossing the tracker finds next to a state with module 1 8e-4 rad from flat
    (rho1 + rho2 = L1 + L2, as in stream 16 above), and its four half-branch states
    1e-4 rad out, are the reference's (``change_point_branches``, in the local angles
    of its own model), to 1e-9 rad."""
    from tensegrity_ros.core.neck import flat_crossing
    from tensegrity_ros.core.neck.stack import StackPath
    stack = neck_yaml((0.11, 0.09, 0.15), -2.0)
    path = StackPath(stack, stack)
    y = path.state_from_angles([[-0.578, -0.593], [6e-4, -8e-5], [-0.007, -0.0097]], 0.0)
    module, crossing, states = flat_crossing.crossing_at(path, y, 0.0)
    theirs, their_states = NeckSystem(stack.modules).change_point_branches(
        np.ravel(path.angles(y, 0.0)), 0.0)
    assert module == 1
    assert angle_distance(np.ravel(path.angles(crossing, 0.0)), theirs) < 1e-9
    mine = [np.ravel(path.angles(x, 0.0)) for x in states]
    assert len(mine) == len(their_states) == 4
    for state in their_states:
        assert min(angle_distance(x, state) for x in mine) < 1e-9


def test_a_tracker_that_stops_at_events_lands_without_rigid_flows():
    """config/neck.yaml's modules, no head load, rhos {0.15, 0.14, 0.07} as a seeded stream
    left them (bench_round_commands seed 1, stream 9), m0 0.15 -> 0.07 m: the neck reaches
    a branch point at s = 0.625 with module 0 7e-3 rad from flat.  Trackers run on the way
    that stop at events (away from a branch point, back along a landing) still land at a
    critical point reached to rounding, only to see whether the minimum goes on; with the
    rigid restart of their landing flows the command took over 20 s.  They land as before
    (elastic-chord flows only), and the command ends ok on a stable equilibrium."""
    from tensegrity_ros.core import continuation
    from tensegrity_ros.core.neck.stack import StackPath
    counted = [0]

    class Counted(StackPath):
        def rigid_descent(self, y, s):
            counted[0] += 1
            return super().rigid_descent(y, s)

    start = neck_yaml((0.15, 0.14, 0.07))
    end = neck_yaml((0.07, 0.14, 0.07))
    state = np.array([0.5672531271029837, 3.720388097726451, 1.701456766552253,
                      3.83229100925178, 2.1530863299995513, 3.399594131571089,
                      -1.4836295251972489, 2.0115815304567644])
    held = track_stack(start, start, state).final
    assert held.stable
    got = continuation.track(Counted(start, end), held.state)
    assert got.status == 'ok', got.message
    assert counted[0] < continuation.TrackerSettings().flow_evaluations // 8, counted[0]
    assert_stable_for_the_reference(end, end, StackPath(end, end).angles(got.state, 0.0), 0.0)


def test_a_buckled_neck_back_onto_its_symmetric_branch_past_a_flat_module_does_not_jump():
    """config/neck.yaml's modules (head 0.5 N down), from a buckled state at rhos (0.15,
    0.14, 0.14) m, joint_commands to (0.15, 0.05, 0.07) m (bench_round_commands seed 0,
    stream 4): module 0 folds flat at s = 5/9, and 2.3e-4 in s later the buckled neck
    runs back onto its symmetric branch (lambda_min falls linearly to 0: a supercritical
    pitchfork run backwards).  That branch moves like sqrt(s - s_flat) there, so the
    landing taken 1e-3 past lay 0.05 away (beyond a step's reach, taken for a jump), and
    Newton from the critical state does not converge (its Jacobian is singular): a fold
    jump of 0.017 rad was reported.  The reference has no jump; neither has the tracker
    now, and both end on the same state."""
    def module(rho, load=0.0):
        return ModuleParams(rho=rho, L1=0.12, L2=0.12, ka=300.0, kb=300.0,
                            kc=300.0, m1=0.02, m2=0.02, f3y=load, f4y=load)
    start = Stack((module(0.15), module(0.14), module(0.14, -0.5)))
    end = Stack((module(0.15), module(0.05), module(0.07, -0.5)))
    state = np.array([0.5615421196209428, 3.7262394299446866, 0.6430744154901497,
                      3.802209448696547, 0.06150503374070685, 3.3013744374402445,
                      -3.000369435471334, -1.5751514047327158])
    held = track_stack(start, start, state).final
    assert held.stable
    track = track_stack(start, end, held)
    ref = quasi_static_path(NeckSystem(start.modules, end.modules), np.ravel(held.theta))
    assert ref.jumps == []
    assert track.status == 'ok' and track.jumps == (), (track.message, track.jumps)
    final = np.ravel(track.final.theta)
    assert min(angle_distance(final, ref.final),
               angle_distance(mirrored(final), ref.final)) < 1e-6, (final, ref.final)


#: config/neck.yaml's neck where a command stopped at module 1's linkage limit left it
#: (bench_round_commands seed 3, stream 7: module 1 flat, 3.2e-7 rad, chord force 34 N;
#: lambda_min 0.045 N/m, residual 1.6e-11): head load 0.294 N, its tracker state.
AT_LIMIT_RHOS, AT_LIMIT_HEAD = (0.10999999999998769, 0.12500000000000924,
                                0.11499999999997847), 0.29422245819794735
AT_LIMIT_STATE = [0.2044801989685769, 2.9371124546211753, 3.1977304540927954e-07,
                  3.1415923338033607, -0.24955340103716184, 3.391146054599081,
                  -1.0892820002174797, -0.9494043905950271]


@pytest.mark.parametrize('rho', [0.11, 0.05])
def test_a_command_from_a_state_left_at_a_linkage_limit_is_tracked(rho):
    """The next command from where a linkage limit stopped the last one (m2's actuator
    0.115 -> ``rho``) was refused: Newton from the kept state, at the flat module's
    singular point, went astray to an indefinite state 'polishing' it, so the start was
    'not a stable equilibrium', and settling found none ('no stable equilibrium reached
    from the given state': 10 to 21 commands a seed in seeds 2-5).  The kept state is
    taken as it is (it passes the residual test; Newton did not converge from it), and
    the command ends where the reference's quasi-static path ends."""
    start = neck_yaml(AT_LIMIT_RHOS, AT_LIMIT_HEAD)
    end = start.with_module(2, rho=rho)
    y = np.array(AT_LIMIT_STATE)
    track = track_stack(start, end, y)
    assert track.status == 'ok', track.message
    ref = quasi_static_path(NeckSystem(start.modules, end.modules),
                            np.ravel(track_stack(start, start, y).final.theta))
    assert ref.jumps == [] and track.jumps == ()
    assert angle_distance(np.ravel(track.final.theta), ref.final) < 1e-6


def test_commands_on_from_a_state_left_at_a_linkage_limit_meet_one_fold():
    """Commands from the same state to three targets past a fold (m2 0.12, 0.13, 0.15 m)
    each jump once, at the same actuator length to 1e-9 m, onto a stable equilibrium
    (the reference's Newton and Hessian)."""
    start = neck_yaml(AT_LIMIT_RHOS, AT_LIMIT_HEAD)
    at = []
    for rho in (0.12, 0.13, 0.15):
        end = start.with_module(2, rho=rho)
        track = track_stack(start, end, np.array(AT_LIMIT_STATE))
        assert track.status == 'ok', track.message
        (jump,) = track.jumps
        assert jump.kind == 'fold'
        at.append(jump.stack.modules[2].rho)
        assert_stable_for_the_reference(start, end, jump.to_theta, jump.s)
    assert max(at) - min(at) < 1e-9, at


def test_a_step_ending_unresolved_next_to_a_fold_jumps_there():
    """config/neck.yaml's neck, head load -0.5 N, all three actuators (0.09, 0.085, 0.09)
    -> (0.14, 0.12, 0.12) m (bench_round_commands seed 2, stream 17): a step ended on a
    state Newton did not resolve (lambda_min 0.021 of 2098 N/m, Newton's update halving
    at 2.9e-5), and every step from it was refused ('step size underflow at s=0.756
    (far)').  It is a fold: the reference's fold equations {KKT = 0, det = 0} solved from
    the tracker's departure give the same s to 1e-9, and the reference's overdamped flow
    from the departure rests on the tracker's landing.  (The command then reaches module
    0's flat crossing, rho0 + rho1 = 0.24 at s = 13/17, and jumps off it.)"""
    start, end = neck_yaml((0.09, 0.085, 0.09), -0.5), neck_yaml((0.14, 0.12, 0.12), -0.5)
    y = np.array([0.7536928926207191, 2.387899760969074, 0.7536928926207188, 2.387899760969074,
                  0.7079379081767014, 2.433654745413091, 1.1922131678701695, 1.0275430091216988])
    track = track_stack(start, end, y)
    assert track.status == 'ok', track.message
    jump, off = track.jumps[:2]
    assert jump.kind == 'fold'
    assert_jump_off_a_crossing(off, 13.0 / 17.0, 0)
    system = NeckSystem(start.modules, end.modules)
    theta = np.ravel(jump.from_theta)
    fold = critical_solve(system, theta, jump.s).x
    assert np.max(np.abs(system.critical_residual(fold))) < 1e-10
    assert abs(fold[-1] - jump.s) < 1e-9 and angle_distance(fold[:6], theta) < 1e-3
    rest = flow_to_rest(system, theta, jump.s + 1e-9)      # (just past: the flow at the
    assert angle_distance(rest.state, np.ravel(jump.to_theta)) < 1e-6   # fold itself stalls)


def test_a_command_ending_on_a_flat_crossing_the_mechanism_snaps_from_reports_the_jump():
    """config/neck.yaml as bench_round_commands seed 0, stream 6 left it, commanded to
    rho = (0.10, 0.14, 0.05): at s = 1 module 0 is exactly at its flat crossing (rho0 +
    rho1 = L1 + L2 to 3e-17 m), approached like sqrt(1 - s).  Two half-branches leave the
    crossing downhill (the reference's change_point_branches and its own energy), and the
    mechanism released there comes to rest (the reference's flow) 0.015 rad away, 4e-4 J
    lower: a jump at s = 1.  The tracker made that move silently (through_linkage_limit's
    closing-in test, its offset capped by the command's end, compared two states before
    the crossing); it now reports it, landing where the reference's flow from a leaving
    half-branch rests, ambiguous as the other one rests on the mirror image."""
    start = neck_yaml((0.09, 0.12749999999999545, 0.09))
    end = neck_yaml((0.10, 0.14, 0.05))
    theta = np.array([[0.43646902873496424, 0.43646902873496407],
                      [0.43646902873496424, 0.4364690287349643],
                      [-0.7250552169156804, -0.7250552169156809]])
    held = track_stack(start, start, theta).final
    assert held.stable
    mine = track_stack(start, end, held)
    assert mine.status == 'ok', mine.message
    assert [j.kind for j in mine.jumps] == ['fold']
    jump = mine.jumps[0]
    assert jump.s == 1.0 and jump.ambiguous
    # independent evidence: the reference's crossing next to where the jump starts, its
    # leaving half-branches, their energies and where its flow from them rests
    ref = NeckSystem(end.modules)
    found = ref.change_point_branches(np.ravel(jump.from_theta), 1.0)
    assert found is not None
    crossing, states = found
    assert angle_distance(crossing, np.ravel(jump.from_theta)) < 1e-6
    leaving = [x for x in states if float(ref.velocity(x, 1.0) @ (x - crossing)) > 0]
    assert len(leaving) == 2
    assert all(ref.energy(x, 1.0) < ref.energy(crossing, 1.0) for x in leaving)
    rests = [flow_to_rest(ref, x, 1.0).state for x in leaving]
    landing = np.ravel(jump.to_theta)
    assert min(min(angle_distance(landing, r), angle_distance(mirrored(landing), r))
               for r in rests) < 1e-6, (landing, rests)
    assert angle_distance(rests[0], rests[1]) > 1e-2           # elsewhere: ambiguous
    assert angle_distance(landing, crossing) > 1e-2            # a finite move ...
    assert ref.energy(crossing, 1.0) - ref.energy(landing, 1.0) > 1e-4    # ... downhill
    final = np.ravel(mine.final.theta)
    assert angle_distance(final, landing) < 1e-9
    # and the reference's quasi-static path ends with that jump (it ended on the crossing)
    path = quasi_static_path(NeckSystem(start.modules, end.modules), np.ravel(held.theta))
    assert [(j.kind, j.s, j.ambiguous) for j in path.jumps] == [('fold', 1.0, True)]
    assert min(angle_distance(final, path.final),
               angle_distance(mirrored(final), path.final)) < 1e-6, (final, path.final)
