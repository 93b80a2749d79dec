"""The joint names of a serialized ``sensor_msgs/JointState`` exactly as they were sent.

rclpy cuts a string at its first NUL when it converts a message to Python, so a joint
named ``'m0_rho\\x00'`` arrives as ``'m0_rho'`` and would command ``m0``.  The node
receives ``joint_commands`` serialized and reads the names from the CDR bytes with this
module, so that names are compared exactly.  :func:`names_and_positions` reads the
positions in the same pass: the node then needs no second, full deserialization of
every command (rclpy's took 11-17 us per neck command here, this reader about 5).
ROS-free (plain ``struct``).
"""
from __future__ import annotations

import struct

#: CDR encapsulation identifiers of plain (non-parameter-list) data, big/little endian:
#: CDR_BE, CDR_LE (XCDR1) and PLAIN_CDR2_BE, PLAIN_CDR2_LE (XCDR2).
_PLAIN = {0x0000: '>', 0x0001: '<', 0x0006: '>', 0x0007: '<'}
#: The XCDR1 ones (8-byte values aligned to 8; XCDR2 aligns them to 4).
_XCDR1 = {0x0000: '>', 0x0001: '<'}
_HEADER = 4          # encapsulation id and options precede the aligned body
_NAMES_AT = _HEADER + 8     # header.frame_id, then the names, follow the stamp


def exact_names(raw: bytes):
    """The ``name`` strings of a serialized JointState (NULs and all), or None if the
    encoding is not one this reader knows or the bytes are malformed."""
    order = _order(raw, _PLAIN)
    if order is None:
        return None
    try:
        return _names(raw, order)[0]
    except (struct.error, ValueError):
        return None


def names_and_positions(raw: bytes):
    """(names exactly as sent, positions as floats) of a JointState serialized as plain
    CDR (XCDR1: what the ROS 2 middlewares send), or None for another encoding or bytes
    that are not a whole JointState (read those with rclpy's ``deserialize_message``).
    ``velocity`` and ``effort`` are skipped, but must be there."""
    order = _order(raw, _XCDR1)
    if order is None:
        return None
    try:
        names, offset = _names(raw, order)
        return names, _positions(raw, offset, order)
    except (struct.error, ValueError):
        return None


class NamesAndPositions:
    """:func:`names_and_positions` for a stream of messages: a controller sends the same
    joints every time, so the bytes of the last message's frame_id and names are kept,
    and a message that repeats them (one byte comparison) has only its positions read;
    its names are then the very list returned before (do not change it)."""

    def __init__(self):
        self._kept = None   # (encapsulation bytes, frame_id + names bytes, names, offset, order)

    def __call__(self, raw: bytes):
        kept = self._kept
        if kept is not None and raw.startswith(kept[0]) and raw.startswith(kept[1], _NAMES_AT):
            names, offset, order = kept[2], kept[3], kept[4]
        else:
            order = _order(raw, _XCDR1)
            if order is None:
                return None
            try:
                names, offset = _names(raw, order)
            except (struct.error, ValueError):
                return None
            self._kept = (raw[:_HEADER], raw[_NAMES_AT:offset], names, offset, order)
        try:
            return names, _positions(raw, offset, order)
        except (struct.error, ValueError):
            return None


def _order(raw, encodings):
    """The byte order ('<' or '>') of ``raw``'s encapsulation if it is one of ``encodings``."""
    if len(raw) < _HEADER:
        return None
    return encodings.get(int.from_bytes(raw[:2], 'big'))


def _names(raw, order):
    """(the name strings, the offset after them)."""
    offset = _NAMES_AT                            # after header.stamp: sec, nanosec
    _, offset = _string(raw, offset, order)       # header.frame_id
    count, offset = _uint32(raw, offset, order)
    names = []
    for _ in range(count):
        name, offset = _string(raw, offset, order)
        names.append(name)
    return names, offset


def _positions(raw, offset, order):
    """The positions from ``offset`` (after the names); velocity and effort must follow."""
    positions, offset = _doubles(raw, offset, order)
    for _ in ('velocity', 'effort'):
        _, offset = _doubles(raw, offset, order, skip=True)
    return positions


def _doubles(raw, offset, order, skip=False):
    """A CDR sequence<double> (XCDR1: uint32 count, doubles aligned to 8 in the body):
    (the values, or None if ``skip``; the offset after it)."""
    count, offset = _uint32(raw, offset, order)
    if count:
        offset = _HEADER + -(-(offset - _HEADER) // 8) * 8
    end = offset + 8 * count
    if end > len(raw):
        raise ValueError('sequence beyond the message')
    if skip:
        return None, end
    return struct.unpack_from(f'{order}{count}d', raw, offset), end


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
