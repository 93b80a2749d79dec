"""The ``equilibrium`` status filled in place (ros.conversions.EquilibriumStatusBuffer,
only the changed values formatted again) against one built afresh: the same level, texts and
key/value pairs, whatever state the reused message held before (another module, a jump, a failure,
a warning)."""
from diagnostic_msgs.msg import DiagnosticStatus
from hypothesis import given, settings, strategies as st
from rclpy.serialization import deserialize_message, serialize_message

from tensegrity_ros.core.module import ModuleParams
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator
from tensegrity_ros.ros.conversions import equilibrium_status, EquilibriumStatusBuffer

NECK = [ModuleParams(rho=r, L1=0.12, L2=0.12, ka=300.0, kb=300.0, kc=300.0, m1=0.02,
                     m2=0.02) for r in (0.09, 0.085, 0.08)]
NECK_THETA = [[0.754, 0.754], [0.813, 0.813], [0.831, 0.831]]


def _pairs(msg):
    return [(kv.key, kv.value) for kv in msg.values]


def _fields(msg):
    return msg.level, msg.name, msg.message, msg.hardware_id, _pairs(msg)


def _statuses(sim):
    return [(f'node: {name}', name, sim.status(i)) for i, name in enumerate(sim.names)]


def _states():
    """ModuleStatus records of very different states: a neck moving, one module that
    jumps across its fold (last jump, count, range) and warns near it."""
    out = []
    neck = Simulator(NECK, NECK_THETA)
    out += _statuses(neck)
    neck.command_rhos({0: 0.092, 2: 0.079}, 0)
    out += _statuses(neck)
    one = Simulator([ModuleParams.paper(0.8)], [[0.7, 0.7]],
                    [ModuleLimits(0.05, 1.95, warn_margin=0.5)])
    out += _statuses(one)
    for rho in (1.2, 1.6, 0.3):
        one.command_rho(0, rho, 0)
        out += _statuses(one)
    return out


STATES = _states()


def test_the_states_differ_in_what_a_status_shows():
    kinds = {(s.level, s.last_jump is None, s.num_equilibria is None) for _, _, s in STATES}
    assert len(kinds) >= 3


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.lists(st.sampled_from(range(len(STATES))), min_size=2, max_size=6))
def test_a_reused_status_equals_a_fresh_one(sequence):
    buffer = EquilibriumStatusBuffer()
    for k in sequence:
        name, module, status = STATES[k]
        fresh = equilibrium_status(name=name, hardware_id='/hw', module=module, status=status)
        before = buffer.msg
        reused = buffer.update(name=name, hardware_id='/hw', module=module, status=status)
        assert before is None or reused is before               # filled in place
        assert _fields(reused) == _fields(fresh)
        sent = deserialize_message(serialize_message(reused), DiagnosticStatus)  # as published
        assert _fields(sent) == _fields(fresh)
