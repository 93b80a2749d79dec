"""Exact joint names (and positions) from serialized JointState bytes, checked against
rclpy's own serialization (the reference) for names rclpy can carry, and against
hand-placed NULs."""
import math
import struct

from hypothesis import given, settings, strategies as st
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

from tensegrity_ros.ros.joint_state_names import (exact_names, names_and_positions,
                                                  NamesAndPositions)

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


DOUBLES = st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=7)


def _same(a, b):
    return len(a) == len(b) and all(x == y or (math.isnan(x) and math.isnan(y))
                                    for x, y in zip(a, b))


@settings(max_examples=300, deadline=None, derandomize=True)
@given(NAMES, DOUBLES, DOUBLES, DOUBLES,
       st.text(st.characters(blacklist_characters='\x00', blacklist_categories=('Cs',)),
               max_size=9))
def test_positions_as_rclpy_serializes_them(names, position, velocity, effort, frame_id):
    """Every length of every array (none, fewer or more than names) and frame_id (each
    shifts the 8-byte alignment), NaN and inf included: rclpy's round trip is the reference."""
    msg = JointState(name=names, position=position, velocity=velocity, effort=effort)
    msg.header.frame_id = frame_id
    msg.header.stamp.sec = -3
    raw = serialize_message(msg)
    read_names, read_positions = names_and_positions(raw)
    assert read_names == names
    assert _same(read_positions, deserialize_message(raw, JointState).position)
    assert all(isinstance(v, float) for v in read_positions)


def test_a_cut_message_is_not_read():
    """Bytes that stop anywhere before the last effort value are not a JointState."""
    raw = serialize_message(JointState(name=['m0_rho'], position=[0.1], effort=[1.0, 2.0]))
    whole = names_and_positions(raw)
    assert whole == (['m0_rho'], (0.1,))
    readings = [names_and_positions(raw[:cut]) for cut in range(len(raw))]
    assert all(r is None or r == whole for r in readings)
    shortest = min(cut for cut, r in enumerate(readings) if r is not None)
    assert struct.unpack_from('<2d', raw, shortest - 16) == (1.0, 2.0)


def test_xcdr2_is_left_to_rclpy():
    """XCDR2 aligns doubles to 4, not 8: not read here (the node deserializes it)."""
    raw = serialize_message(JointState(name=['m0_rho'], position=[0.1]))
    xcdr2 = struct.pack('>H', 0x0007) + raw[2:]
    assert exact_names(xcdr2) == ['m0_rho']
    assert names_and_positions(xcdr2) is None


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.binary(max_size=64))
def test_malformed_bytes_give_none_or_a_reading_never_an_exception(raw):
    read = names_and_positions(raw)
    assert read is None or (isinstance(read[0], list) and isinstance(read[1], tuple))


def _message(names, position, frame_id, stamp):
    msg = JointState(name=names, position=position)
    msg.header.frame_id = frame_id
    msg.header.stamp.sec = stamp
    return serialize_message(msg)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.sampled_from([['m0_rho'], ['m0_rho', 'm2_rho'], ['m0_rhp'],
                                           ['m0_rho', 'm0_rho'], []]),
                          DOUBLES, st.sampled_from(['', 'a', 'base']),
                          st.integers(-5, 5), st.sampled_from([None, 0, 9, -8, 'xcdr2'])),
                min_size=1, max_size=8))
def test_a_stream_is_read_as_each_message_alone(stream):
    """NamesAndPositions (names kept from the last message) reads every message of a
    stream -- repeated or changed names, frame_ids and stamps, cut or XCDR2 bytes -- as
    names_and_positions reads it alone."""
    read = NamesAndPositions()
    for names, position, frame_id, stamp, damage in stream:
        raw = _message(names, position, frame_id, stamp)
        if damage == 'xcdr2':
            raw = struct.pack('>H', 0x0007) + raw[2:]
        elif damage is not None:
            raw = raw[:damage]
        got, alone = read(raw), names_and_positions(raw)
        assert (got is None) == (alone is None)
        if got is not None:
            assert got[0] == alone[0] and _same(got[1], alone[1])


def test_repeated_names_are_not_read_again():
    """A controller's stream (new stamps and positions, the same joints): the names come
    back as the very list read from the first message, the positions as sent."""
    read = NamesAndPositions()
    first = read(_message(['m0_rho', 'm1_rho', 'm2_rho'], [0.09, 0.085, 0.08], '', 1))
    for k in range(5):
        positions = [0.09 + k * 1e-4, 0.085, 0.08 - k * 1e-4]
        names, got = read(_message(['m0_rho', 'm1_rho', 'm2_rho'], positions, '', 2 + k))
        assert names is first[0] and list(got) == positions
    other = read(_message(['m0_rho', 'm2_rho'], [0.1, 0.2], '', 9))
    assert other == (['m0_rho', 'm2_rho'], (0.1, 0.2))
