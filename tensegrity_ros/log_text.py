"""Text from outside (message fields, parameter names and values) made safe for a log line.

A log line must stay one short line whatever a client sends: control characters are
escaped (``repr``) and anything long is cut, saying how much was left out.  ROS-free.
"""
from __future__ import annotations

#: Most characters of one shown value (a joint name, a parameter value ...).
VALUE_LIMIT = 80
#: Most characters of one whole log line built from outside text.
LINE_LIMIT = 400


def shown(value, limit: int = VALUE_LIMIT) -> str:
    """``repr(value)`` (control characters escaped), cut to about ``limit`` characters."""
    text = repr(value)
    if len(text) <= limit:
        return text
    return f'{text[:limit]}... ({len(text) - limit} more characters)'


def clipped(text: str, limit: int = LINE_LIMIT) -> str:
    """A finished log line cut to ``limit`` characters, control characters escaped."""
    text = ''.join(c if c.isprintable() else repr(c)[1:-1] for c in text[:limit + 1])
    if len(text) <= limit:
        return text
    return f'{text[:limit]}... (cut)'
