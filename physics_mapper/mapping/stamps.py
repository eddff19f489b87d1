"""Time stamps as integer nanoseconds, and their ``builtin_interfaces/Time`` parts (ROS-free).

Stamps stay integers end to end: float seconds cannot hold nanoseconds at today's epoch.
"""

from __future__ import annotations

NANOSECONDS_PER_SECOND = 1_000_000_000


def to_nanoseconds(sec: int, nanosec: int) -> int:
    """A ``builtin_interfaces/Time`` (``sec``, ``nanosec``) as integer nanoseconds."""
    return int(sec) * NANOSECONDS_PER_SECOND + int(nanosec)


def time_parts(stamp_ns: int) -> tuple[int, int]:
    """Integer nanoseconds as ``builtin_interfaces/Time``'s ``(sec, nanosec)``."""
    sec, nanosec = divmod(stamp_ns, NANOSECONDS_PER_SECOND)
    return sec, nanosec
