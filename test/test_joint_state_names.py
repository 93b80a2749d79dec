"""Exact joint names from serialized JointState bytes, checked against rclpy's own
serialization (the reference) for names rclpy can carry, and against hand-placed NULs."""
import pytest
from hypothesis import given, settings, strategies as st
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from tensegrity_ros.joint_state_names import exact_names

NAMES = st.lists(st.text(st.characters(blacklist_characters='\x00',
                                       blacklist_categories=('Cs',)), max_size=12),
                 max_size=6)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(NAMES, st.text(st.characters(blacklist_characters='\x00',
                                    blacklist_categories=('Cs',)), max_size=9))
def test_names_as_rclpy_serializes_them(names, frame_id):
    msg = JointState(name=names, position=[0.0] * len(names))
    msg.header.frame_id = frame_id
    assert exact_names(serialize_message(msg)) == names


@pytest.mark.parametrize('name', [b'm0_rho\x00', b'\x00', b'a\x00b\x00'])
def test_a_nul_inside_a_name_is_kept(name):
    placeholder = 'Z' * len(name)
    raw = serialize_message(JointState(name=['x', placeholder], position=[0.0, 1.0]))
    at = raw.index(placeholder.encode())
    raw = raw[:at] + name + raw[at + len(name):]
    assert exact_names(raw) == ['x', name.decode()]


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.binary(max_size=64))
def test_malformed_bytes_give_none_or_names_never_an_exception(raw):
    names = exact_names(raw)
    assert names is None or isinstance(names, list)
