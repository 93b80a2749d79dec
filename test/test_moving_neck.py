"""A neck driven in real time: ticks reproduce the offline transient of the same profile,
N = 1 equals the one-module live motion (other coordinates, other equations), the
energy is kept without damping and the dissipated power is sum c theta'^2 with it, small
oscillations have the frequencies sqrt(eig(M^-1 H_reduced)) (all from the test's own
forward kinematics), commands and design changes act on the moving neck,
and heavy damping lands where the quasi-static stack tracker lands."""
from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from scipy.integrate import simpson, solve_ivp
from scipy.linalg import eigh, null_space

from tensegrity_ros.core import InvalidParameterError, ModuleParams
from tensegrity_ros.core.dynamics.moving_module import MovingModule
from tensegrity_ros.core.dynamics.moving_neck import MovingNeck
from tensegrity_ros.core.dynamics.neck_snap import NeckEquations, simulate_neck_snap
from tensegrity_ros.core.dynamics.transient import RhoRamp
from tensegrity_ros.core.neck.stack import settle_stack, Stack
from tensegrity_ros.core.simulation.dynamic_simulator import DynamicSimulator
from tensegrity_ros.core.simulation.events import Jump
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator
from test_moving_module import drive
from test_neck_dynamics import energy, FIG8A, forward, NECK

# config/neck.yaml: three modules, 20 g rods, 0.5 N on each head node; its m2 has a fold
# at rho = 0.1127 on the way up
_BASE = {'L1': 0.12, 'L2': 0.12, 'ka': 300.0, 'kb': 300.0, 'kc': 300.0, 'm1': 0.02, 'm2': 0.02}
BIRD = Stack((ModuleParams(rho=0.09, **_BASE), ModuleParams(rho=0.085, **_BASE),
              ModuleParams(rho=0.08, f3y=-0.5, f4y=-0.5, **_BASE)))
UPRIGHT = [[0.754, 0.754], [0.813, 0.813], [0.831, 0.831]]
ACROSS_THE_FOLD = (0.09, 0.085, 0.12)


def test_ticks_reproduce_the_offline_transient_of_the_neck_fold():
    ref = simulate_neck_snap(BIRD, ACROSS_THE_FOLD, 0.05, 0.01, UPRIGHT).summary
    live = MovingNeck(BIRD, UPRIGHT, damping=0.01, max_rate=0.05)
    assert live.command(ACROSS_THE_FOLD, 0.0) == [] and live.moving
    [report] = drive(live, 5.0)
    assert report['onset_rho'] == pytest.approx(ref['onset_rho'], rel=1e-7)
    for key in ('onset_time', 'peak_speed', 'peak_actuator_force', 'overshoot'):
        assert report[key] == pytest.approx(ref[key], rel=1e-6), key
    assert report['settle_time'] == pytest.approx(ref['settle_time'], rel=1e-4)
    assert np.array(report['final']['theta']) == pytest.approx(
        np.array(ref['final']['theta']), abs=1e-6)
    assert not live.moving and live.rho == ACROSS_THE_FOLD
    assert np.max(np.abs(live.theta_dot)) < 1e-6


def test_a_one_module_neck_moves_as_the_one_module_live_motion():
    module = MovingModule(FIG8A, (-1.0, -1.0), damping=0.2, max_rate=0.5)
    neck = MovingNeck(Stack((FIG8A,)), [[-1.0, -1.0]], damping=0.2, max_rate=0.5)
    module.command(0.9, 0.0)
    neck.command((0.9,), 0.0)
    drive(module, 0.9)
    drive(neck, 0.9)                    # mid-snap: the same state
    assert neck.theta[0] == pytest.approx(module.theta, abs=1e-7)
    assert neck.theta_dot[0] == pytest.approx(module.theta_dot, rel=1e-6, abs=1e-7)
    assert neck.actuator_forces[0] == pytest.approx(module.actuator_force, rel=1e-6)
    assert neck.nodes == pytest.approx(module.nodes, abs=1e-7)
    [a], [b] = drive(module, 20.0), drive(neck, 20.0)
    assert b['onset_rho'][0] == pytest.approx(a['onset_rho'], rel=1e-7)
    for key in ('peak_speed', 'peak_actuator_force', 'overshoot', 'settle_time'):
        assert b[key] == pytest.approx(a[key], rel=1e-5), key


def _held_samples(live, t0, t1, step):
    """(t, total energy, dissipated power) sampled while rho is held."""
    rows = []
    for t in np.arange(t0, t1 + step / 2, step):
        live.advance(t)
        theta, rate = live.theta, live.theta_dot
        power = float(np.sum(np.array(live.damping)[:, None] * rate ** 2))
        rows.append((t, energy(NECK.modules, live.rho[0], theta, rate)[0], power))
    return np.array(rows).T


def test_without_damping_the_live_neck_keeps_its_energy_after_commands():
    live = MovingNeck(NECK, [[1.2, 1.2], [1.0, 1.0]], damping=0.0, max_rate=(1.0, 0.5))
    live.command((0.45, 0.62), 0.0)
    live.command((0.45, 0.6), 0.1)                 # a second command on the moving neck
    t, total, _ = _held_samples(live, 0.5, 1.0, 0.01)
    scale = abs(energy(NECK.modules, 0.45, live.theta, 0 * live.theta)[1])
    assert np.max(np.abs(total - total[0])) / scale < 1e-8
    assert np.max(np.abs(live.theta_dot)) > 0.1    # it moves


def test_with_damping_the_energy_lost_is_the_dissipated_power_c_theta_dot_squared():
    live = MovingNeck(NECK, [[1.2, 1.2], [1.0, 1.0]], damping=(0.05, 0.02), max_rate=1.0)
    live.command((0.45, 0.62), 0.0)
    t, total, power = _held_samples(live, 0.3, 0.5, 0.0005)
    lost = total[0] - total
    dissipated = np.array([simpson(power[:k + 1], x=t[:k + 1]) for k in range(2, len(t), 40)])
    assert lost[2::40] == pytest.approx(dissipated, rel=1e-5)
    assert lost[-1] > 1e-3                         # J: a loss far above rounding (~1e-11 J)


def test_a_command_during_the_transient_acts_on_the_moving_neck():
    live = MovingNeck(BIRD, UPRIGHT, damping=0.01, max_rate=0.05)
    live.command(ACROSS_THE_FOLD, 0.0)
    drive(live, 0.55)                              # the snap has started (onset ~0.51 s)
    assert np.max(np.abs(live.theta_dot)) > 1.0
    t, theta, rate, rho = live.t, live.theta, live.theta_dot, live.rho
    assert live.command((0.09, 0.085, 0.09), t) == []
    assert live.rho == rho and live.theta == pytest.approx(theta, abs=1e-9)
    # the free top module keeps its momentum; module 1's angles are fixed by its chord,
    # module 2's actuator, whose velocity reverses: so do their rates (kinematics)
    assert live.theta_dot[[0, 2]] == pytest.approx(rate[[0, 2]], rel=1e-9, abs=1e-9)
    assert live.theta_dot[1] == pytest.approx(-rate[1], rel=1e-9)
    drive(live, t + 0.05)
    assert live.rho[2] == pytest.approx(rho[2] - 0.05 * 0.05, abs=1e-12)
    reports = drive(live, t + 5.0)
    assert len(reports) == 1 and not live.moving and live.rho == (0.09, 0.085, 0.09)
    rest = settle_stack(Stack(tuple(m.with_(rho=r) for m, r in zip(BIRD.modules, live.rho))),
                        live.theta)
    assert live.theta == pytest.approx(rest.theta, abs=1e-6) and rest.stable


def test_a_design_change_rebuilds_the_moving_neck_with_the_new_rods():
    live = MovingNeck(BIRD, UPRIGHT, damping=0.02, max_rate=0.05)
    live.command(ACROSS_THE_FOLD, 0.0)
    drive(live, 0.3)
    longer = Stack((BIRD.modules[0], BIRD.modules[1].with_(L1=0.13), BIRD.modules[2]))
    live.change(live.t, params=longer)
    a1, a3 = live.nodes[3], live.nodes[4]          # A1(1) = A4(0), A3(1)
    assert np.hypot(*(a3 - a1)) == pytest.approx(0.13, abs=1e-9)
    drive(live, 5.0)
    assert not live.moving
    rest = settle_stack(Stack(tuple(m.with_(rho=r) for m, r in zip(longer.modules, live.rho))),
                        live.theta)
    assert live.theta == pytest.approx(rest.theta, abs=1e-6)


def test_bad_targets_are_refused_and_change_nothing():
    live = MovingNeck(BIRD, UPRIGHT, damping=0.01, max_rate=0.05)
    for bad in ((0.09, 0.085), (0.09, float('nan'), 0.08), 'abc', (0.09, -1.0, 0.08)):
        with pytest.raises(InvalidParameterError, match='rho'):
            live.command(bad, 0.1)
    assert live.t == 0.0 and live.target == live.rho == (0.09, 0.085, 0.08)
    with pytest.raises(InvalidParameterError, match='damping'):
        MovingNeck(BIRD, UPRIGHT, damping=(0.01, 0.01), max_rate=0.05)


def test_heavy_damping_lands_where_the_quasi_static_neck_lands():
    """The overdamped limit (docs/model.md section 5) for the neck, through the simulator:
    damping 0.05 N m s/rad leaves no overshoot, yet the snap still passes 1 rad/s (much
    heavier damping creeps through the fold below the onset speed: no snap to report)."""
    limits = [ModuleLimits(0.05, 0.15, max_rho_rate=0.05)] * 3
    sim = DynamicSimulator(BIRD.modules, UPRIGHT, limits, damping=[0.05] * 3)
    assert sim.command_rho(2, 0.12, 0).accepted
    jumps, now = [], 0
    while (sim.moving or now == 0) and now < 30 * 10**9:
        now += 50_000_000
        jumps += sim.advance(now).of_type(Jump)
    static = Simulator(BIRD.modules, UPRIGHT, [ModuleLimits(0.05, 0.15)] * 3)
    static_jumps, t = list(static.command_rho(2, 0.12, 0).of_type(Jump)), 0
    while getattr(static, 'pending', False):   # a simulator that bounds its work per call
        t += 1                                 # finishes the path in advance()
        static_jumps += static.advance(t).of_type(Jump)
    [static_jump] = static_jumps
    [jump] = jumps
    assert (jump.kind, jump.module) == (static_jump.kind, 2)
    assert jump.modules[2].rho == pytest.approx(static_jump.modules[2].rho, abs=1e-9)
    assert sim.state.theta == pytest.approx(static.state.theta, abs=1e-8)
    figures = jump.dynamics
    assert not figures['lands_elsewhere'] and figures['settled']
    assert figures['overshoot'] < 1e-9
    assert figures['onset_rho'] == figures['modules']['onset_rho'][2]
    assert figures['final']['theta1'] == pytest.approx(static.state.theta[2][0], abs=1e-6)
    assert sim.stable and [sim.live(i).theta1_dot for i in range(3)] == [0.0] * 3


def _modal_reference(modules, rho, theta):
    """Small-oscillation frequencies sqrt(eig(M^-1 H_reduced)) of a neck at rest, in its
    local angles q (2N) under the chord constraints, from the test's own kinematics:
    M is the Hessian of the kinetic energy in q', H the Hessian of U - lambda . c."""
    q0, k = np.asarray(theta, dtype=float).ravel(), 2 * len(modules)
    eye = np.eye(k)

    def potential(q):
        return energy(modules, rho[0], q.reshape(-1, 2), np.zeros((len(modules), 2)))[1]

    def chords(q):                       # |A3(i) - A4(i)|^2 - rho(i+1)^2, complex-safe
        x = forward(modules, rho[0], q.reshape(-1, 2))
        return np.array([(x[2 + 2 * i] - x[3 + 2 * i]) @ (x[2 + 2 * i] - x[3 + 2 * i])
                         - rho[i + 1] ** 2 for i in range(len(modules) - 1)])

    def chord_jacobian(q):               # complex step: exact to rounding
        return np.array([chords(q + 1e-30j * e).imag / 1e-30 for e in eye]).T

    h = 1e-4
    grad = np.array([(potential(q0 + h * e) - potential(q0 - h * e)) / (2 * h) for e in eye])
    hess = np.array([[(potential(q0 + h * a + h * b) - potential(q0 + h * a - h * b)
                       - potential(q0 - h * a + h * b) + potential(q0 - h * a - h * b))
                      / (4 * h * h) for b in eye] for a in eye])
    jc = chord_jacobian(q0)
    lam = np.linalg.lstsq(jc.T, grad, rcond=None)[0]
    chord_hess = np.array([(chord_jacobian(q0 + h * e) - chord_jacobian(q0 - h * e)) / (2 * h)
                           for e in eye])                    # [l, i, m] = d2 c_i / dq_l dq_m
    lagrangian = hess - np.einsum('i,lim->lm', lam, chord_hess)
    kinetic = np.array([[energy(modules, rho[0], q0.reshape(-1, 2), (a + b).reshape(-1, 2))[0]
                         for b in eye] for a in eye]) - potential(q0)   # T(e_a + e_b)
    diagonal = np.diag(kinetic) / 4.0                        # T(2 e_a) / 4 = T(e_a)
    mass = kinetic - np.add.outer(diagonal, diagonal)        # T(e_a + e_b) - T(e_a) - T(e_b)
    tangent = null_space(jc) if len(modules) > 1 else eye
    values, vectors = eigh(tangent.T @ lagrangian @ tangent, tangent.T @ mass @ tangent)
    return np.sqrt(values), tangent @ vectors


def test_small_oscillations_of_the_neck_have_the_frequencies_of_its_reduced_hessian():
    rest = settle_stack(NECK, [[1.2, 1.2], [1.0, 1.0]])
    rho = [m.rho for m in NECK.modules]
    omega, shapes = _modal_reference(NECK.modules, rho, rest.theta)
    system = NeckEquations(NECK, RhoRamp(tuple(rho), tuple(rho), 1.0), 0.0)
    for mode in range(len(omega)):
        y0 = system.with_angle_rates(0.0, system.start_state(rest.nodes),
                                     1e-6 * shapes[:, mode] / np.max(np.abs(shapes[:, mode])))
        watched = int(np.argmax(np.abs(shapes[:, mode])))
        period = 2 * np.pi / omega[mode]
        sol = solve_ivp(system.rhs, (0.0, 5.2 * period), y0, method='DOP853', rtol=1e-12,
                        atol=1e-15, events=lambda t, y: system.rates(t, y)[1][watched])
        crossings = sol.t_events[0]
        measured = np.pi * (len(crossings) - 1) / (crossings[-1] - crossings[0])
        assert len(crossings) >= 9
        assert measured == pytest.approx(omega[mode], rel=1e-6), mode     # ~6e-8 seen


@settings(max_examples=3, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, 2), st.floats(0.075, 0.115), st.integers(1, 10)),
                min_size=1, max_size=3))
def test_whatever_the_commands_a_moving_neck_claims_no_stable_state_and_ends_at_rest(steps):
    """Commands to random modules and targets at random ticks (50 ms)."""
    limits = [ModuleLimits(0.05, 0.15, max_rho_rate=0.05)] * 3
    sim = DynamicSimulator(BIRD.modules, UPRIGHT, limits, damping=[0.05] * 3)
    now, targets = 0, [m.rho for m in BIRD.modules]
    for index, rho, ticks in steps:
        assert sim.command_rho(index, rho, now).accepted
        targets[index] = rho
        for _ in range(ticks):
            now += 50_000_000
            sim.advance(now)
            assert not (sim.moving and (sim.stable or sim.status(index).level == 'ok'))
    while sim.moving and now < 60 * 10**9:
        now += 50_000_000
        sim.advance(now)
    assert not sim.moving and sim.stable
    assert [sim.module(i)[0].rho for i in range(3)] == targets
    rest = settle_stack(Stack(sim.modules), np.reshape(sim.state.theta, (3, 2)))
    assert sim.state.theta == pytest.approx(rest.theta, abs=1e-6)


# ---------------------------------------------------------------------------
# issue 31: the dynamics mode's early warning, and what 50 Hz sampling shows of a snap

def _bird_simulator():
    limits = [ModuleLimits(0.05, 0.15, max_rho_rate=0.05)] * 3
    return DynamicSimulator(BIRD.modules, UPRIGHT, limits, damping=[0.01] * 3)


def _fastest(sim):
    return max(max(abs(sim.live(i).theta1_dot), abs(sim.live(i).theta2_dot))
               for i in range(len(sim)))


def test_a_neck_command_at_rest_warns_of_the_fold_ahead_before_the_rods_snap():
    """Issue 31 (3): config/neck.yaml, every max_rho_rate 0.05 m/s, damping 0.01; m2's
    actuator to 0.12 crosses the neck's fold (0.1127, 0.65 s ahead).  As in the quasi-static
    mode the path is tracked ahead from the rest state in the calls' leftover time and a
    JumpAhead says where the branch ends while the actuator is still short of it and the
    rods have not snapped (it used to stay silent); the jump at rest has the same fold."""
    from tensegrity_ros.core.simulation.events import JumpAhead
    sim = _bird_simulator()
    warnings, now = list(sim.command_rho(2, 0.12, 0).of_type(JumpAhead)), 0
    while not warnings and now < 10**9:
        now += 20_000_000
        warnings += sim.advance(now).of_type(JumpAhead)
        assert _fastest(sim) < 1.0
    [warning] = warnings
    assert (warning.module, warning.rho, warning.end.kind) == (2, 0.12, 'fold')
    assert sim.live(2).rho < warning.end.rho
    static = Simulator(BIRD.modules, UPRIGHT, [ModuleLimits(0.05, 0.15)] * 3,
                       time_budget=None)
    [static_jump] = static.command_rho(2, 0.12, 0).of_type(Jump)
    assert warning.end.rho == pytest.approx(static_jump.modules[2].rho, abs=1e-9)
    jumps = []
    while sim.moving and now < 30 * 10**9:
        now += 20_000_000
        jumps += sim.advance(now).of_type(Jump)
    [jump] = jumps
    assert jump.modules[2].rho == pytest.approx(warning.end.rho, abs=1e-12)


def _own_local_rates(nodes, velocities):
    """Local angle rates of every module from node positions and velocities (the test's
    own kinematics: d/dt atan2(d) = d x d' / |d|^2)."""
    def turn(a, b):
        d, v = nodes[b] - nodes[a], velocities[b] - velocities[a]
        return (d[0] * v[1] - d[1] * v[0]) / (d @ d)
    out = []
    for i in range(len(nodes) // 2 - 1):
        a1, a2 = (0, 1) if i == 0 else (3 + 2 * (i - 1), 2 + 2 * (i - 1))
        a3, a4 = 2 + 2 * i, 3 + 2 * i
        out += [turn(a1, a3) - turn(a1, a2), turn(a1, a2) - turn(a2, a4)]
    return np.array(out)


def test_sampled_at_50_hz_a_neck_snap_shows_its_peak_speed_to_ten_percent():
    """Issue 31 (2): 20 ms ticks through config/neck.yaml's fold.  The live rates (what
    joint_states carries) are the integrated ones at the state's time: the offline
    transient of the same profile (solve_ivp's DOP853, another integrator) read there with
    the test's own kinematics, to 1e-6 rad/s.  Their largest |theta'| is within 10 % of the
    jump's peak_speed (7.73 rad/s: the fastest swing lasts ~0.1 s, five ticks)."""
    ref = simulate_neck_snap(BIRD, ACROSS_THE_FOLD, 0.05, 0.01, UPRIGHT)
    sim = _bird_simulator()
    sim.command_rho(2, 0.12, 0)
    jumps, sampled, now = [], [], 0
    while (sim.moving or now == 0) and now < 10 * 10**9:
        now += 20_000_000
        jumps += sim.advance(now).of_type(Jump)
        t = sim.state_time_ns * 1e-9
        assert t == now * 1e-9                        # not behind: the state is the tick's
        live = np.ravel([(sim.live(i).theta1_dot, sim.live(i).theta2_dot) for i in range(3)])
        if t <= ref.history.t[-1]:
            y = ref.solution(t)
            nodes = np.vstack([[0.0, 0.0], [0.09, 0.0], y[:12].reshape(-1, 2)])
            velocities = np.vstack([[0.0, 0.0], [0.0, 0.0], y[12:].reshape(-1, 2)])
            assert live == pytest.approx(_own_local_rates(nodes, velocities), abs=1e-6)
        sampled.append(np.max(np.abs(live)))
    [jump] = jumps
    assert jump.dynamics['peak_speed'] == pytest.approx(7.73, abs=0.01)
    assert max(sampled) >= 0.9 * jump.dynamics['peak_speed']


def test_a_neck_command_given_on_the_way_to_a_fold_warns_as_the_quasi_static_mode():
    """V1 (issue 31, 3): config/neck.yaml, every max_rho_rate 0.05 m/s; m2's actuator to
    0.10 (no fold), then, 0.2 s on the way, to 0.12 (the fold at 0.1127 is ~0.45 s ahead).
    The quasi-static simulator warns of the fold (JumpAhead); fails at f8d033b: the
    dynamics mode warns only of commands given at rest, and the rods snap unannounced."""
    from tensegrity_ros.core.simulation.events import JumpAhead
    found = {}
    limits = [ModuleLimits(0.05, 0.15, max_rho_rate=0.05)] * 3
    for name, sim in (('quasi-static', Simulator(BIRD.modules, UPRIGHT, limits)),
                      ('dynamics', _bird_simulator())):
        warnings = list(sim.command_rho(2, 0.10, 0).of_type(JumpAhead))
        now = 0
        while now < 200_000_000:
            now += 20_000_000
            warnings += sim.advance(now).of_type(JumpAhead)
        assert not warnings
        warnings = list(sim.command_rho(2, 0.12, now).of_type(JumpAhead))
        while not warnings and now < 600_000_000:       # before the actuator reaches 0.1127
            now += 20_000_000
            warnings += sim.advance(now).of_type(JumpAhead)
        found[name] = [(w.module, w.end.kind, round(w.end.rho, 6)) for w in warnings]
    assert found['quasi-static'] == [(2, 'fold', 0.112693)]
    assert found['dynamics'] == found['quasi-static']
