"""Node: no false jumps (issue 12) and loads beyond the supported range (issue 10 item 2)."""
import pytest
from geometry_msgs.msg import Vector3
from rclpy.parameter import Parameter

from tensegrity_ros.core import ModuleParams, settle, track_module
from test_node import harness, ros, values  # noqa: F401  (fixtures)


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
    h.spin_until(lambda: h.diagnostics, what='a diagnostics message (1 Hz)')
    assert h.counter('tracking_failures') == 0


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
