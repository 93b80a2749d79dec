"""The joint names of a serialized ``sensor_msgs/JointState`` exactly as they were sent.

rclpy cuts a string at its first NUL when it converts a message to Python, so a joint
named ``'m0_rho\\x00'`` arrives as ``'m0_rho'`` and would command ``m0``.  The node
receives ``joint_commands`` serialized and reads the names from the CDR bytes with this
module, so that names are compared exactly.  ROS-free (plain ``struct``).
"""
from __future__ import annotations

import struct

#: CDR encapsulation identifiers of plain (non-parameter-list) data, big/little endian:
#: CDR_BE, CDR_LE (XCDR1) and PLAIN_CDR2_BE, PLAIN_CDR2_LE (XCDR2).
_PLAIN = {0x0000: '>', 0x0001: '<', 0x0006: '>', 0x0007: '<'}
_HEADER = 4          # encapsulation id and options precede the aligned body


def exact_names(raw: bytes):
    """The ``name`` strings of a serialized JointState (NULs and all), or None if the
    encoding is not one this reader knows or the bytes are malformed."""
    if len(raw) < _HEADER:
        return None
    order = _PLAIN.get(int.from_bytes(raw[:2], 'big'))
    if order is None:
        return None
    try:
        offset = _HEADER + 8                          # header.stamp: sec, nanosec
        _, offset = _string(raw, offset, order)       # header.frame_id
        count, offset = _uint32(raw, offset, order)
        names = []
        for _ in range(count):
            name, offset = _string(raw, offset, order)
            names.append(name)
        return names
    except (struct.error, ValueError):
        return None


def _uint32(raw, offset, order):
    offset = _HEADER + -(-(offset - _HEADER) // 4) * 4        # align to 4 in the body
    return struct.unpack_from(order + 'I', raw, offset)[0], offset + 4


def _string(raw, offset, order):
    """A CDR string: uint32 length (terminating NUL included), bytes."""
    length, offset = _uint32(raw, offset, order)
    end = offset + length
    if length < 1 or end > len(raw):
        raise ValueError('string beyond the message')
    data = raw[offset:end - 1]                               # drop the terminating NUL
    return data.decode('utf-8', errors='replace'), end
