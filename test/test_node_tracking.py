"""Node: no false jumps (issue 12) and loads beyond the supported range (issue 10 item 2)."""
from geometry_msgs.msg import Vector3
import pytest
from rclpy.parameter import Parameter
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from tensegrity_ros.core import ModuleParams, settle, track_module
from test_node import fig8a_overrides, values


def test_unloaded_module_to_rho_beyond_L_publishes_no_jump(harness):
    """At rho = L the upper branch meets the flat state continuously: no `jumps` message."""
    h = harness().ready()
    start = settle(ModuleParams(rho=0.75), [0.7, 0.7])
    assert not track_module(ModuleParams(rho=0.75), ModuleParams(rho=1.3), start.theta).jumps
    rho, t1, t2, _ = h.command_rho(1.3)
    assert rho == 1.3 and abs(t1) < 1e-9 and abs(t2) < 1e-9           # the flat state
    h.wait_status(lambda v: float(v['rho']) == 1.3)
    assert h.stable[-1].data is True
    assert h.node.counters['jumps_total'] == 0 and h.jumps == []
    assert h.node.counters['tracking_failures'] == 0
    # the range ends there with a branch point, but no jump follows: no early warning
    assert h.eq()['rho_stable_max_end'] == 'limit'          # now on the flat state
    assert h.node.counters['jump_warnings'] == 0 and not h.warnings('leaves the stable branch')


def test_a_command_that_needs_several_ticks_warns_and_the_node_keeps_answering(harness):
    """Bounded work (issue 10): with no time budget left for any call, the fig. 8a jump past
    C1 is tracked over many timer ticks; the node warns and counts it, keeps publishing
    and answering meanwhile, and ends where one call would."""
    h = harness(fig8a_overrides(publish_rate=200.0)).ready()
    h.node.simulator.time_budget = 0.0
    expected = track_module(ModuleParams.paper(0.5, F3=5.0, F4=5.0),
                            ModuleParams.paper(0.1, F3=5.0, F4=5.0),
                            settle(ModuleParams.paper(0.5, F3=5.0, F4=5.0), [-1.0, -1.0]).theta)
    h.rho_pub.publish(Float64(data=0.1))
    h.spin_until(lambda: h.node.counters['commands_deferred'] == 1, what='the deferral')
    assert h.node.simulator.pending
    h.spin_until(lambda: h.warnings('goes on in the next calls'), what='a WARN line')
    n = len(h.joint_states)
    h.spin_until(lambda: len(h.joint_states) > n + 2, what='joint_states meanwhile')
    assert h.state()[0] == 0.5                               # the verified start, until done
    h.spin_until(h.params.services_are_ready, what='parameter services')
    answer = h.call(h.params.get_parameters(['m0.L1']), 'a parameter service answer')
    assert answer.values[0].double_value == 1.0
    h.spin_until(lambda: h.jumps, timeout=60.0, what='the jump')
    jump = values(h.jumps[0])
    assert float(jump['rho']) == float(expected.jumps[0].params.rho)
    h.wait_status(lambda v: float(v['rho']) == 0.1)
    assert h.state()[1:3] == (float(expected.final.theta1), float(expected.final.theta2))
    h.spin_until(lambda: h.counter('commands_deferred') == 1, what='the diagnostics count')
    assert h.node.counters['tracking_failures'] == 0 and h.stable[-1].data is True


def test_a_load_beyond_the_supported_range_is_refused_and_the_state_kept(harness):
    """`m0/force_a3 {x: 1e10}` on the default module (load/(k L) = 1e8) used to leave the
    node unstable until reset; now it is refused as out of range."""
    h = harness().ready()
    h.rejected('rejected_out_of_range',
               lambda: h.force_pubs['a3'].publish(Vector3(x=1e10, y=0.0, z=0.0)))
    assert h.stable[-1].data is True
    assert values(h.equilibrium[-1])['f3x'] == '0'
    # one inside the range is tracked and stays stable
    h.force_pubs['a3'].publish(Vector3(x=1e5, y=0.0, z=0.0))
    h.spin_until(lambda: float(h.eq()['f3x']) == 1e5, what='the load applied')
    assert h.stable[-1].data is True


@pytest.mark.parametrize('param', [Parameter('m0.L1', value=1e49), Parameter('m0.ka', value=1e49)])
def test_parameters_beyond_the_range_are_refused_and_read_back_live(harness, param):
    h = harness().ready()
    before = h.node.get_parameter(param.name).value
    result = h.node.set_parameters([param])[0]
    assert not result.successful and 'supported range' in result.reason
    assert h.node.get_parameter(param.name).value == before


def test_a_reset_that_needs_several_ticks_answers_at_once_and_settles_on_the_ticks(harness):
    h = harness(fig8a_overrides()).ready()
    assert h.command_rho(0.3)[0] == 0.3
    h.node.simulator.time_budget = 0.0
    h.spin_until(h.reset_client.service_is_ready, what='reset service')
    response = h.call(h.reset_client.call_async(Trigger.Request()), 'reset')
    assert response.success and 'reset under way' in response.message
    h.spin_until(lambda: not h.node.simulator.pending, what='the settle on the ticks')
    h.wait_status(lambda v: float(v['rho']) == 0.5)
    start = settle(ModuleParams.paper(0.5, F3=5.0, F4=5.0), [-1.0, -1.0])
    assert h.node.module_state()[1].theta1 == start.theta1
    assert h.node.counters['commands_deferred'] == 1 and h.stable[-1].data is True
