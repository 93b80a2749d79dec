"""The pre-serialized joint_states (ros.conversions.JointStateBuffer) against the reference:
the same message built field by field and read back with rclpy's deserialization."""
import array
import math

from hypothesis import given, settings, strategies as st
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from tensegrity_ros.ros.conversions import JointStateBuffer

VALUE = st.floats(allow_nan=True, allow_infinity=True)
MODULE = st.tuples(*[VALUE] * 7)             # rho, theta1, theta2, force, 3 rates
STAMP = st.integers(min_value=0, max_value=(2 ** 31 - 1) * 10 ** 9)


def _same(a, b):
    return len(a) == len(b) and all(x == y or (math.isnan(x) and math.isnan(y))
                                    for x, y in zip(a, b))


def _expected(names, modules, velocity):
    position, effort, rates = [], [], []
    for rho, t1, t2, force, *dots in modules:
        position += [rho, t1, t2]
        effort += [force, 0.0, 0.0]
        rates += dots
    return JointState(name=[f'{m}_{j}' for m in names for j in ('rho', 'theta1', 'theta2')],
                      position=position, effort=effort, velocity=rates if velocity else [])


def _published(buffer, modules, stamp, velocity):
    for i, (rho, t1, t2, force, *dots) in enumerate(modules):
        buffer.set_module(i, rho, t1, t2, force)
        if velocity:
            buffer.set_velocity(i, *dots)
    out = buffer.stamped(stamp)
    if not isinstance(out, bytes):
        return out
    effort = array.array('d', [v for m in modules for v in (m[3], 0.0, 0.0)]).tobytes()
    assert out.endswith(effort)                 # nothing sent after the last field
    return deserialize_message(out, JointState)


@settings(max_examples=150, deadline=None, derandomize=True)
@given(st.lists(MODULE, min_size=1, max_size=10), st.lists(STAMP, min_size=1, max_size=3),
       st.booleans(), st.booleans())
def test_the_bytes_read_back_as_the_message_built_field_by_field(modules, stamps, velocity,
                                                                 serialized):
    """Successive publications (each overwrites the last), with and without velocities;
    ``serialized=False`` is the fallback that publishes the message itself."""
    names = [f'm{i}' for i in range(len(modules))]
    buffer = JointStateBuffer(names, velocity=velocity)
    assert buffer._layout is not None          # found on this platform
    if not serialized:
        buffer._layout = None
    for k, stamp in enumerate(stamps):
        shifted = [tuple(v + k for v in m) for m in modules]
        got = _published(buffer, shifted, stamp, velocity)
        want = _expected(names, shifted, velocity)
        assert got.name == want.name
        assert (got.header.stamp.sec, got.header.stamp.nanosec) == divmod(stamp, 10 ** 9)
        assert got.header.frame_id == ''
        for field in ('position', 'effort', 'velocity'):
            assert _same(getattr(got, field), getattr(want, field)), field
