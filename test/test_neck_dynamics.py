"""Neck snap-through dynamics: N = 1 equals the module simulator (different coordinates,
different derivation), energy of a 2-module neck from the test's own forward kinematics,
and the rest state and actuator forces equal the quasi-static stack's."""
import numpy as np
import pytest

from tensegrity_ros.core import InvalidParameterError, ModuleParams, simulate_snap
from tensegrity_ros.core.dynamics.neck_snap import simulate_neck_snap
from tensegrity_ros.core.neck.stack import settle_stack, Stack

G = 9.80665
FIG8A = ModuleParams.paper(0.5, F3=5.0, F4=5.0).with_(m1=0.05, m2=0.05)


def forward(modules, rho0, theta):
    """Every node (A1(0), A2(0), A3(i), A4(i)) from local angles (N x 2); complex-safe."""
    nodes = [np.array([0.0, 0.0], dtype=complex), np.array([rho0, 0.0], dtype=complex)]
    a1, a2 = nodes
    for m, (t1, t2) in zip(modules, theta):
        e = (a2 - a1) / np.sqrt((a2 - a1) @ (a2 - a1))
        n = np.array([-e[1], e[0]])
        a3 = a1 + m.L1 * (np.cos(t1) * e + np.sin(t1) * n)
        a4 = a2 + m.L2 * (-np.cos(t2) * e + np.sin(t2) * n)
        nodes += [a3, a4]
        a1, a2 = a4, a3
    return np.array(nodes)


def energy(modules, rho0, theta, theta_dot):
    """Kinetic energy of the bars plus springs, loads and weights, from the angles alone."""
    theta = np.asarray(theta, dtype=float)
    x = forward(modules, rho0, theta).real
    v = np.zeros_like(x)
    for k in range(theta.size):
        step = np.zeros(theta.size)
        step[k] = 1e-30
        v += forward(modules, rho0, theta + 1j * step.reshape(theta.shape)).imag / 1e-30 \
            * theta_dot.ravel()[k]
    kinetic = potential = 0.0
    for i, m in enumerate(modules):
        a1, a2 = (0, 1) if i == 0 else (3 + 2 * (i - 1), 2 + 2 * (i - 1))
        a3, a4 = 2 + 2 * i, 3 + 2 * i
        for p, q, mass in ((a1, a3, m.m1), (a2, a4, m.m2)):
            kinetic += mass / 6.0 * (v[p] @ v[p] + v[p] @ v[q] + v[q] @ v[q])
            potential += mass * G * (x[p, 1] + x[q, 1]) / 2.0
        for p, q, k in ((a2, a3, m.ka), (a1, a4, m.kb), (a3, a4, m.kc)):
            potential += 0.5 * k * (x[p] - x[q]) @ (x[p] - x[q])
        potential -= m.f3x * x[a3, 0] + m.f3y * x[a3, 1] + m.f4x * x[a4, 0] + m.f4y * x[a4, 1]
    return kinetic + potential, potential


def test_one_module_neck_equals_the_module_simulator():
    module = simulate_snap(FIG8A, 0.9, 0.5, 0.2, (-1.0, -1.0)).summary
    neck = simulate_neck_snap(Stack((FIG8A,)), 0.9, 0.5, 0.2, [[-1.0, -1.0]]).summary
    assert neck['onset_rho'][0] == pytest.approx(module['onset_rho'], rel=1e-7)
    for key in ('peak_speed', 'peak_actuator_force', 'overshoot', 'settle_time'):
        assert neck[key] == pytest.approx(module[key], rel=1e-5), key
    assert neck['final']['theta'][0] == pytest.approx(
        [module['final']['theta1'], module['final']['theta2']], abs=1e-8)


NECK = Stack((ModuleParams(rho=0.6, m1=0.05, m2=0.05),
              ModuleParams(rho=0.5, f3y=-3.0, f4y=-2.0, f3x=1.0, m1=0.04, m2=0.06)))


def test_two_module_neck_without_damping_keeps_its_energy_while_held():
    snap = simulate_neck_snap(NECK, [0.45, 0.62], 1.0, 0.0, [[1.2, 1.2], [1.0, 1.0]], hold=0.6)
    h = snap.history
    held = np.flatnonzero(h.t >= 0.15)[::25]
    values = [energy(NECK.modules, 0.45, h.theta[i], h.theta_dot[i]) for i in held]
    total = np.array([v[0] for v in values])
    scale = max(abs(v[1]) for v in values)
    assert np.max(np.abs(total - total[0])) / scale < 1e-8
    assert np.max(np.abs(h.theta_dot[held])) > 0.1                # it moves


def test_two_module_neck_comes_to_rest_where_the_stack_tracker_lands():
    snap = simulate_neck_snap(NECK, [0.45, 0.62], 0.5, 0.3, [[1.2, 1.2], [1.0, 1.0]])
    s = snap.summary
    assert s['settled'] and not s['lands_elsewhere']
    rest = settle_stack(Stack(tuple(m.with_(rho=r) for m, r in zip(NECK.modules, (0.45, 0.62)))),
                        np.array(s['final']['theta']))
    assert np.array(s['final']['theta']) == pytest.approx(rest.theta, abs=1e-6)
    # at rest the dynamic actuator forces are the static ones (sign conventions agree)
    assert snap.history.actuator_force[-1] == pytest.approx(rest.actuator_forces, abs=1e-4)


def test_neck_bad_input():
    with pytest.raises(InvalidParameterError, match='module 1: m1=0.0'):
        simulate_neck_snap(Stack((FIG8A, FIG8A.with_(m1=0.0))), 0.6, 0.1, 0.1,
                           [[-1, -1], [1, 1]])
    with pytest.raises(InvalidParameterError, match='2 values'):
        simulate_neck_snap(NECK, [0.5, 0.5, 0.5], 0.1, 0.1, [[1, 1], [1, 1]])


def test_the_overshoot_of_a_rod_swinging_through_pi_is_read_on_continuous_angles():
    """Issue 35: config/neck.yaml with an uneven heavy head (3.0 N down at A3, 3.1 N at A4
    of m2), m0's actuator from 0.09 down across the neck's fold (0.0579) to 0.05 at
    0.05 m/s, damping 0.01: m0's rod 1 swings through pi, where its wrapped angle jumps by
    2 pi.  The overshoot was read on wrapped angles (1.423 rad); on the continuous
    trajectory it is 0.730 rad, as MuJoCo finds.  The reference here: the history's own
    angles unwrapped by numpy, the largest swing past the rest angle after the onset."""
    base = {'L1': 0.12, 'L2': 0.12, 'ka': 300.0, 'kb': 300.0, 'kc': 300.0, 'm1': 0.02, 'm2': 0.02}
    neck = Stack((ModuleParams(rho=0.09, **base), ModuleParams(rho=0.085, **base),
                  ModuleParams(rho=0.08, f3y=-3.0, f4y=-3.1, **base)))
    snap = simulate_neck_snap(neck, [0.05, 0.085, 0.08], 0.05, 0.01,
                              [[0.754, 0.754], [0.813, 0.813], [0.831, 0.831]])
    s, h = snap.summary, snap.history
    theta = np.unwrap(h.theta.reshape(len(h.t), -1), axis=0)
    assert np.ptp(h.theta.reshape(len(h.t), -1)[:, 0]) > 6.0          # it wraps
    final = np.array(s['final']['theta']).ravel()
    final += 2 * np.pi * np.round((theta[-1] - final) / (2 * np.pi))
    after = h.t >= s['onset_time']
    start = theta[np.argmax(after)]
    own = np.max((theta[after] - final) * np.sign(final - start))
    assert s['overshoot'] == pytest.approx(0.730, abs=1e-3)
    assert s['overshoot'] == pytest.approx(own, rel=1e-3)


# ---------------------------------------------------------------------------
# the compiled evaluation (numba) and the numpy one are the same equations

def _uneven_neck_equations(extend_ramp):
    from tensegrity_ros.core.dynamics.neck_snap import NeckEquations
    from tensegrity_ros.core.dynamics.transient import RhoRamp
    base = {'L1': 0.12, 'L2': 0.13, 'ka': 300.0, 'kb': 310.0, 'kc': 290.0, 'm1': 0.02, 'm2': 0.025}
    mods = (ModuleParams(rho=0.09, **base), ModuleParams(rho=0.085, f3x=0.3, **base),
            ModuleParams(rho=0.08, f3y=-0.5, f4y=-0.6, **base))
    eq = settle_stack(Stack(mods), [[0.754, 0.754], [0.813, 0.813], [0.831, 0.831]])
    ramp = RhoRamp((0.08, 0.085, 0.08), (0.09, 0.09, 0.12), 0.05)
    return NeckEquations(Stack(mods), ramp, (0.01, 0.02, 0.03), extend_ramp), eq


@pytest.mark.parametrize('extend_ramp', [False, True])
def test_the_compiled_and_the_numpy_evaluations_agree(extend_ramp):
    """Random states on and past the ramp, an uneven three-module neck: the right-hand side,
    local angles and rates, actuator forces and the batch readings agree to rounding."""
    from tensegrity_ros.core.dynamics import neck_kernel
    if neck_kernel.compiled() is None:
        pytest.skip('numba is not installed (or TENSEGRITY_NO_NUMBA is set)')
    system, eq = _uneven_neck_equations(extend_ramp)
    rng = np.random.default_rng(5)
    ts = np.array([0.0, 0.1, 0.5, 0.9, 1.5])
    ys = system.start_state(eq.nodes) + rng.normal(0.0, 0.01, (len(ts), 24))
    compiled = [system.rhs(t, y) for t, y in zip(ts, ys)], system.readings(ts, ys)
    system._compiled = None                       # the numpy evaluation
    numpy = [system.rhs(t, y) for t, y in zip(ts, ys)], system.readings(ts, ys)
    assert np.array(compiled[0]) == pytest.approx(np.array(numpy[0]), rel=1e-12, abs=1e-9)
    for a, b in zip(compiled[1], numpy[1]):
        assert a == pytest.approx(b, rel=1e-12, abs=1e-12)


def test_the_quasi_static_node_never_loads_numba():
    """numba is loaded by the first live neck only: a quasi-static node of a neck (and a
    dynamics-mode module) runs without it (a fresh interpreter, as the node's process)."""
    import subprocess
    import sys
    code = """
import sys, rclpy
from rclpy.parameter import Parameter
from tensegrity_ros.ros.node import TensegrityNode
from tensegrity_ros.core import ModuleParams
from tensegrity_ros.core.simulation.dynamic_simulator import DynamicSimulator
from tensegrity_ros.core.simulation.simulator import ModuleLimits
rclpy.init()
node = TensegrityNode(parameter_overrides=[Parameter('modules', value=['m0', 'm1'])])
p = ModuleParams.paper(0.5, F3=5.0, F4=5.0).with_(m1=0.05, m2=0.05)
sim = DynamicSimulator([p], [[-1.0, -1.0]], [ModuleLimits(0.05, 1.95, 0.1)], damping=[0.05])
sim.command_rho(0, 0.6, 0); sim.advance(10**9)
node.destroy_node(); rclpy.shutdown()
print('numba' in sys.modules)
"""
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == 'False'
