"""Corners of the neck stack through the node (config/neck.yaml, three modules).

Speed-limited modules inside a stack, a tracking failure inside a stack, and a runtime
geometry / stiffness change of one stack module.  Same style as test_node_neck.py: the
node and a client node in-process, spun until a condition holds (no sleeps); what the
node must do is computed with the core (track_stack) first.
"""
import dataclasses

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from tensegrity_ros.core import TrackingError
from tensegrity_ros.core.neck.stack import settle_stack, Stack, track_stack
from test_node import values
from test_node_neck import MODULES

pytestmark = pytest.mark.ros

RHO0 = {'m0': 0.09, 'm1': 0.085, 'm2': 0.08}      # rho_initial of config/neck.yaml


def _module_status(n, m):
    return n.statuses()[m]


def _wait_diagnostics(h):
    """Wait for a /diagnostics published from now on; return it."""
    k = len(h.diagnostics)
    h.spin_until(lambda: len(h.diagnostics) > k, what='a fresh /diagnostics')
    return h.diagnostics[-1]


def _node_status(diag):
    return next(s for s in diag.status if s.name.endswith(': node'))


def _published_theta(msg):
    pos = dict(zip(msg.name, msg.position))
    return np.array([[pos[f'{m}_theta1'], pos[f'{m}_theta2']] for m in MODULES])


def _published_rhos(msg):
    pos = dict(zip(msg.name, msg.position))
    return {m: pos[f'{m}_rho'] for m in MODULES}


# ---------------------------------------------------------------------------
# 1. Speed-limited modules inside a stack

RATE = 0.05         # m/s: 1 mm per 50 Hz tick


def test_speed_limited_stack_moves_gradually_and_reaches_the_targets(neck):
    n = neck(parameters={**{f'{m}.max_rho_rate': RATE for m in MODULES},
                         'publish_rate': 50.0})
    h = n.h
    assert [h.node.get_parameter(f'{m}.max_rho_rate').value for m in MODULES] == [RATE] * 3
    stack0, eq0 = h.node.stack_state()
    h.spin_until(lambda: h.counter('rejected_total') is not None, what='/diagnostics')
    rejected0 = h.counter('rejected_total')

    def move(send, targets, what):
        """Send a command; wait until every target is published; check the motion."""
        start = _published_rhos(h.joint_states[-1])
        k = len(h.joint_states)
        send()
        h.spin_until(lambda: all(_published_rhos(h.joint_states[-1])[m] == v
                                 for m, v in targets.items()), what=what)
        moving = h.joint_states[k:]
        sec0 = moving[0].header.stamp.sec
        stamps = [(m.header.stamp.sec - sec0) + 1e-9 * m.header.stamp.nanosec for m in moving]
        rhos = [_published_rhos(m) for m in moving]
        for m in MODULES:
            series = [r[m] for r in rhos]
            if m not in targets:
                assert series == [start[m]] * len(series), m          # others stay put
                continue
            target = targets[m]
            sign = 1.0 if target > start[m] else -1.0
            # monotone toward the target, never faster than the limit (stamp = time held)
            for (r0, t0), (r1, t1) in zip(zip(series, stamps), zip(series[1:], stamps[1:])):
                assert 0.0 <= sign * (r1 - r0) <= RATE * (t1 - t0) + 1e-9, (m, r0, r1, t1 - t0)
            inside = [r for r in series if min(start[m], target) < r < max(start[m], target)]
            # gradual, not one step: a move of 15-20 ticks shows fewer intermediate states
            # only when a loaded machine merges ticks; the rate bound above is the contract
            assert len(inside) >= 3, (m, len(inside))
            # it took at least distance / RATE (the first stamp is at or before the start)
            arrived = stamps[series.index(target)]
            assert arrived - stamps[0] >= abs(target - start[m]) / RATE - 1e-6, m
        # every published intermediate state is an equilibrium of the stack at its rhos
        for msg in moving[::3]:
            r = _published_rhos(msg)
            at = Stack(tuple(p.with_(rho=r[m]) for p, m in zip(stack0.modules, MODULES)))
            here = settle_stack(at, _published_theta(msg))
            assert here.stable
            np.testing.assert_allclose(_published_theta(msg), here.theta, atol=1e-9)

    # joint_commands: two modules at once, 20 mm and 15 mm (20 and 15 ticks)
    move(lambda: h.jc_pub.publish(JointState(name=['m0_rho', 'm2_rho'], position=[0.11, 0.065])),
         {'m0': 0.11, 'm2': 0.065}, 'joint_commands targets reached')
    # rho_cmd of the middle module, 20 mm down
    move(lambda: n.rho_pubs['m1'].publish(Float64(data=0.065)), {'m1': 0.065},
         'm1 target reached')
    # the end state: exactly the commanded rhos, on the start branch, no jump
    end = Stack((stack0.modules[0].with_(rho=0.11), stack0.modules[1].with_(rho=0.065),
                 stack0.modules[2].with_(rho=0.065)))
    stack, eq = h.node.stack_state()
    assert stack == end and eq.stable
    expected = track_stack(stack0, end, eq0)
    assert expected.status == 'ok' and not expected.jumps
    np.testing.assert_allclose(eq.theta, expected.final.theta, atol=1e-9)
    assert all(h.node.simulator.target(i) is None for i in range(3))   # motion finished
    assert not h.jumps and h.node.counters['jumps_total'] == 0
    diag = _wait_diagnostics(h)
    v = values(_node_status(diag))
    assert int(v['rejected_total']) == rejected0 == 0
    assert v['tracking_failures'] == '0' and v['callback_exceptions'] == '0'
    h.spin_until(lambda: all(s['tracking'] == 'ok' and float(s['rho']) == end.modules[i].rho
                             for i, s in enumerate(n.statuses()[m] for m in MODULES)),
                 what='final statuses')


def test_speed_limited_module_and_a_jumping_module_in_one_joint_commands(neck):
    """m0 speed-limited, m2 not: m2's target is tracked at once (the loaded neck snaps at
    a fold, which takes the tracker a while); m0 starts moving when the message arrived and
    is published at no more than its limit, not with a catch-up step for the tracking time."""
    n = neck(parameters={'m0.max_rho_rate': RATE, 'publish_rate': 50.0})
    h = n.h
    result = h.node.set_parameters_atomically([Parameter('m2.force_a3', value=[0.0, -3.5]),
                                               Parameter('m2.force_a4', value=[0.0, -3.5])])
    assert result.successful
    stack0, eq0 = h.node.stack_state()
    snap = track_stack(stack0, stack0.with_module(2, rho=0.12), eq0)
    assert [j.kind for j in snap.jumps] == ['fold']
    rest = track_stack(snap.end, snap.end.with_module(0, rho=0.1), snap.final)
    assert rest.status == 'ok' and not rest.jumps
    k = len(h.joint_states)
    h.jc_pub.publish(JointState(name=['m0_rho', 'm2_rho'], position=[0.1, 0.12]))
    h.spin_until(lambda: _published_rhos(h.joint_states[-1])['m0'] == 0.1, what='m0 at 0.1')
    # from the state the command's callback published (m2 landed, m0 not moved yet)
    moving = h.joint_states[k:]
    moving = moving[[_published_rhos(m)['m2'] for m in moving].index(0.12):]
    assert [_published_rhos(m)['m2'] for m in moving] == [0.12] * len(moving)
    sec0 = moving[0].header.stamp.sec
    stamps = [(m.header.stamp.sec - sec0) + 1e-9 * m.header.stamp.nanosec for m in moving]
    m0 = [_published_rhos(m)['m0'] for m in moving]
    assert m0[0] == 0.09
    for (r0, t0), (r1, t1) in zip(zip(m0, stamps), zip(m0[1:], stamps[1:])):
        assert 0.0 <= r1 - r0 <= RATE * (t1 - t0) + 1e-9, (r0, r1, t1 - t0)
    # (the first segment covers the tracking time of m2's jump: the actuator kept moving
    # meanwhile, so how many intermediate states there are depends on the machine)
    assert stamps[m0.index(0.1)] >= 0.01 / RATE - 1e-6     # 10 mm at RATE from the message
    assert len(h.jumps) == 1
    v = values(h.jumps[0])
    assert v['module'] == 'm2' and v['kind'] == 'fold' and v['cause'] == 'joint_commands'
    assert float(v['m0_rho']) == 0.09                     # m0 had not moved yet
    stack, eq = h.node.stack_state()
    assert stack == rest.end and eq.stable
    np.testing.assert_allclose(eq.theta, rest.final.theta, atol=1e-8)


# ---------------------------------------------------------------------------
# 2. Tracking failure inside a stack


def test_unreachable_command_holds_the_last_verified_state_and_recovers(neck):
    """m1's actuator is m0's top chord |A3A4|, at most rho + L1 + L2 = 0.33 m: with
    m1.rho_max raised to 0.4 m, a 0.35 m command is accepted input whose end state does
    not exist.  On the way the neck jumps off module 0's and module 1's flat crossings
    (rho(i) + rho(i+1) = L1 + L2; published on jumps), then the tracker stops at module
    1's reach limit; the node holds the last verified state on the way."""
    n = neck()
    h = n.h
    assert h.node.set_parameters([Parameter('m1.rho_max', value=0.4)])[0].successful
    stack0, eq0 = h.node.stack_state()
    expected = track_stack(stack0, stack0.with_module(1, rho=0.35), eq0)
    assert expected.status == 'failed' and expected.final.stable
    stop = expected.end.modules[1].rho
    assert RHO0['m1'] < stop < 0.33
    h.spin_until(lambda: h.counter('tracking_failures') is not None, what='/diagnostics')
    rejected0 = h.counter('rejected_total')
    assert h.counter('tracking_failures') == 0

    n.rho_pubs['m1'].publish(Float64(data=0.35))
    h.spin_until(lambda: h.counter('tracking_failures') == 1, what='tracking failure counted')
    # held where the tracker stopped: a verified stable equilibrium, not the target
    stack, eq = h.node.stack_state()
    assert stack == expected.end
    assert eq.stable and eq.residual < 1e-12 * eq.eigenvalues[-1] and eq.eigenvalues[0] > 0.0
    np.testing.assert_allclose(eq.theta, expected.final.theta, atol=1e-9)
    pos, _ = n.wait_state(lambda p: p['m1_rho'] == stop, 'joint_states at the stop')
    assert [pos[f'{m}_rho'] for m in ('m0', 'm2')] == [RHO0['m0'], RHO0['m2']]
    np.testing.assert_allclose(_published_theta(h.joint_states[-1]), eq.theta, atol=0)
    assert h.stable[-1].data is True
    # the reason: m1's status (WARN), the log, /diagnostics
    h.spin_until(lambda: 'stopped at m1' in _module_status(n, 'm1')['tracking'],
                 what='m1 status with the failure')
    v = _module_status(n, 'm1')
    assert v['tracking'].startswith(f'rho_cmd: stopped at m1 rho={stop!r}: ')
    assert expected.message in v['tracking'] and float(v['rho']) == stop
    m1_status = next(s for s in reversed(h.equilibrium) if values(s)['module'] == 'm1')
    assert m1_status.level == DiagnosticStatus.WARN
    assert 'tracking stopped early' in m1_status.message
    h.spin_until(lambda: h.warnings('m1: tracking failed'), what='tracking warning logged')
    assert 'holding the last verified equilibrium' in h.warnings('m1: tracking failed')[-1]
    assert any('tracking failed' in _node_status(d).message and
               _node_status(d).level == DiagnosticStatus.WARN for d in h.diagnostics)
    assert h.counter('rejected_total') == rejected0          # valid input, not a rejection
    assert h.node.counters['callback_exceptions'] == 0
    h.spin_until(lambda: len(h.jumps) == len(expected.jumps), what='the jumps on the way')

    # a following valid command is tracked from the held state; the failure clears
    n.rho_pubs['m1'].publish(Float64(data=0.1))
    pos, _ = n.wait_state(lambda p: p['m1_rho'] == 0.1, 'm1_rho = 0.1')
    stack, eq = h.node.stack_state()
    assert stack == stack0.with_module(1, rho=0.1) and eq.stable
    onward = track_stack(expected.end, stack, expected.final)     # from the held state
    np.testing.assert_allclose(eq.theta, onward.final.theta, atol=1e-8)
    h.spin_until(lambda: _module_status(n, 'm1')['tracking'] == 'ok', what='tracking ok')
    assert h.counter('tracking_failures') == 1


def _raises(start, end, state):
    raise TrackingError('injected: the start state is not an equilibrium')


def _unstable(real):
    def track(start, end, state):
        result = real(start, end, state)
        ev = np.array(result.final.eigenvalues, dtype=float)
        ev[0] = -abs(ev[0])                     # a saddle: must never be published
        return dataclasses.replace(result, final=dataclasses.replace(result.final,
                                                                     eigenvalues=ev))
    return track


@pytest.mark.parametrize('failure, reason', [
    ('raises', 'injected: the start state is not an equilibrium'),
    ('unstable', 'tracker returned an unstable state'),
])
def test_tracker_error_in_a_stack_keeps_the_state_unchanged(neck, monkeypatch, failure, reason):
    """The node's explicit paths for a tracker that raises or hands back a non-minimum
    (injected: the real tracker reaches neither from a verified state)."""
    # the tracker is injected where the node's simulator calls it
    import tensegrity_ros.core.simulation.mechanisms as node_module
    n = neck()
    h = n.h
    real = node_module.track_stack
    h.spin_until(lambda: h.counter('tracking_failures') is not None, what='/diagnostics')
    before = h.node.stack_state()
    published = h.joint_states[-1]
    monkeypatch.setattr(node_module, 'track_stack',
                        _raises if failure == 'raises' else _unstable(real))
    h.jc_pub.publish(JointState(name=['m0_rho', 'm1_rho'], position=[0.1, 0.09]))
    h.spin_until(lambda: h.counter('tracking_failures') == 1, what='tracking failure counted')
    after = h.node.stack_state()
    assert after[0] == before[0] and after[1] is before[1]   # the very same verified state
    k = len(h.joint_states)
    h.spin_until(lambda: len(h.joint_states) > k, what='a timer joint_states')
    assert list(h.joint_states[-1].position) == list(published.position)
    h.spin_until(lambda: reason in _module_status(n, 'm0')['tracking'], what='m0 status')
    assert _module_status(n, 'm0')['tracking'].startswith('joint_commands: ')
    assert h.warnings('m0: tracking failed')
    assert h.counter('rejected_total') == 0 and h.node.counters['callback_exceptions'] == 0
    monkeypatch.undo()
    h.jc_pub.publish(JointState(name=['m0_rho', 'm1_rho'], position=[0.1, 0.09]))
    n.wait_state(lambda p: p['m0_rho'] == 0.1 and p['m1_rho'] == 0.09, 'recovered command')
    stack, eq = h.node.stack_state()
    expected = track_stack(before[0], stack, before[1])
    np.testing.assert_allclose(eq.theta, expected.final.theta, atol=1e-9)
    h.spin_until(lambda: _module_status(n, 'm0')['tracking'] == 'ok', what='tracking ok')


# ---------------------------------------------------------------------------
# 3. Runtime geometry / stiffness change of one stack module


def test_runtime_geometry_change_of_one_module_is_tracked_and_bad_values_refused(neck):
    n = neck()
    h = n.h
    h.spin_until(h.params.services_are_ready, what='parameter services')
    stack0, eq0 = h.node.stack_state()
    new = stack0.with_module(1, L2=0.13)
    expected = track_stack(stack0, new, eq0)
    assert expected.status == 'ok' and not expected.jumps
    result = h.call(h.params.set_parameters([Parameter('m1.L2', value=0.13)]), 'set m1.L2')
    assert result.results[0].successful, result.results[0].reason
    stack, eq = h.node.stack_state()
    assert stack == new and eq.stable
    np.testing.assert_allclose(eq.theta, expected.final.theta, atol=1e-9)
    # m1 is no longer symmetric: the angles change, the head tilts
    assert abs(eq.theta[1][0] - eq.theta[1][1]) > 0.05
    assert abs(eq.head_angle) > 1e-3
    pos, effort = n.wait_state(lambda p: p['m1_theta2'] == eq.theta[1][1], 'new joint_states')
    for i, m in enumerate(MODULES):
        assert pos[f'{m}_rho'] == RHO0[m]
        assert (pos[f'{m}_theta1'], pos[f'{m}_theta2']) == tuple(eq.theta[i])
        assert effort[f'{m}_rho'] == eq.actuator_forces[i]
    # all three statuses are republished together (the stack's margin is every module's)
    h.spin_until(lambda: float(_module_status(n, 'm1')['L2']) == 0.13 and all(
        float(v['stability_margin']) == eq.stability_margin for v in n.statuses().values()),
        what='updated statuses')
    for m, v in n.statuses().items():
        assert v['stable'] == 'true' and v['tracking'] == 'ok' and v['jumps_total'] == '0'
    h.spin_until(lambda: n.head[-1].pose.position.x == pytest.approx(eq.head_position[0],
                                                                     abs=1e-12),
                 what='new head pose')
    assert not h.jumps

    # invalid values are refused with a reason; parameter, state and output unchanged
    h.spin_until(lambda: h.counter('rejected_parameter_value') is not None, what='/diagnostics')
    count = h.counter('rejected_parameter_value')
    for name, value, words in (('m1.L1', -0.12, 'm1.L1 must be finite and > 0'),
                               ('m1.L2', 0.0, 'm1.L2 must be finite and > 0'),
                               ('m1.kc', -1.0, 'm1.kc must be finite and >= 0')):
        result = h.call(h.params.set_parameters([Parameter(name, value=value)]), f'set {name}')
        assert not result.results[0].successful, name
        assert words in result.results[0].reason, result.results[0].reason
        assert h.node.stack_state()[0] == stack and h.node.stack_state()[1] is eq
    assert h.node.get_parameter('m1.L1').value == 0.12
    assert h.node.get_parameter('m1.L2').value == 0.13
    assert h.node.get_parameter('m1.kc').value == 0.0
    h.spin_until(lambda: h.counter('rejected_parameter_value') == count + 3,
                 what='refusals counted')
    k = len(h.joint_states)
    h.spin_until(lambda: len(h.joint_states) > k, what='a timer joint_states')
    np.testing.assert_allclose(_published_theta(h.joint_states[-1]), eq.theta, atol=0)
    assert h.node.counters['tracking_failures'] == 0 and not h.jumps


def test_softening_a_module_under_a_heavy_head_buckles_it_continuously(neck):
    """m1's springs 300 -> 200 N/m under a heavy head: the neck passes a supercritical
    branch point and turns sideways smoothly: no message on ``jumps``, none counted."""
    n = neck()
    h = n.h
    stack0, eq0 = n.load_head(3.5)
    assert not h.node.counters['jumps_total']
    soft = stack0.with_module(1, ka=200.0, kb=200.0, kc=200.0)
    expected = track_stack(stack0, soft, eq0)            # found with the core first
    assert expected.status == 'ok' and expected.jumps == () and len(expected.passages) == 1
    assert 200.0 < expected.passages[0].stack.modules[1].ka < 300.0
    h.spin_until(h.params.services_are_ready, what='parameter services')
    result = h.call(h.params.set_parameters([Parameter('m1.k', value=200.0)]), 'set m1.k')
    assert result.results[0].successful, result.results[0].reason
    # the path may take more than one call's time budget: it ends on ticks
    h.spin_until(lambda: h.node.stack_state()[0] == soft, what='the softened neck')
    stack, eq = h.node.stack_state()
    assert eq.stable
    np.testing.assert_allclose(eq.theta, expected.final.theta, atol=1e-8)
    assert abs(eq.head_angle) > 0.05                       # sideways
    n.wait_state(lambda p: p['m2_theta1'] == eq.theta[2][0], 'buckled joint_states')
    h.spin_until(lambda: all(s.get('jumps_total') == '0' and float(s['kc']) == 200.0 * (m == 'm1')
                             + 300.0 * (m != 'm1') for m, s in n.statuses().items()),
                 what='statuses after the change')
    assert not h.jumps and h.node.counters['jumps_total'] == 0
    # (/diagnostics is published on its own timer: the path may end before its first one)
    h.spin_until(lambda: h.counter('rejected_total') is not None, what='/diagnostics')
    assert h.node.counters['tracking_failures'] == 0 and h.counter('rejected_total') == 0
