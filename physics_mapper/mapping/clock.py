"""Watching what the node's ticks depend on but cannot see from inside a tick (ROS-free).

With ``use_sim_time`` the node's clock is ``/clock``: its timers, its ticks and its diagnostics all
wait for it, so a missing ``/clock`` would stop the node without a word. :class:`ClockWatch` is fed
from a wall-clock (steady) timer with the node's clock and says when that clock has not advanced
for :data:`SIM_CLOCK_SILENCE` seconds; the node then publishes a WARN diagnostic by wall clock.

:func:`clock_sources_warning` words what the node reports when ``/clock`` has more than one publisher, and
:func:`duplicate_name_warning` what it reports when the ROS graph holds another node
of its own fully qualified name (two nodes publishing one map, answering one parameter service).
"""

from __future__ import annotations

#: Wall-clock seconds without the simulated clock advancing before the node warns.
SIM_CLOCK_SILENCE = 2.0


class ClockWatch:
    """Says when a simulated clock has stopped (or never started) advancing."""

    def __init__(self) -> None:
        self._last_clock_ns: int | None = None
        self._advanced_at: float | None = None  # wall-clock seconds when the clock last moved

    def observe(self, wall: float, clock_ns: int, sim_time: bool) -> str | None:
        """A warning if ``sim_time`` and the node's clock (``clock_ns``) has not moved for
        :data:`SIM_CLOCK_SILENCE` seconds of wall-clock time (``wall``, monotonic), else None.
        """
        if self._advanced_at is None or clock_ns != self._last_clock_ns:
            self._last_clock_ns, self._advanced_at = clock_ns, wall
        silent = wall - self._advanced_at
        if not sim_time or silent < SIM_CLOCK_SILENCE:
            return None
        since = "no /clock received" if clock_ns == 0 else f"/clock stopped at {clock_ns / 1e9:.3f} s"
        # Worded without the running time, so that the node logs it once, not every second.
        return (
            f"use_sim_time is true and {since} for {SIM_CLOCK_SILENCE:g} s or more: ticks and diagnostics wait "
            "for /clock (publish it, or set use_sim_time to false)"
        )


def clock_sources_warning(publishers: int, sim_time: bool) -> str | None:
    """The warning when ``sim_time`` and more than one publisher is on ``/clock``, or None.

    Two sources (two simulators, a bag played with ``--clock`` beside a simulator) make the node's
    clock jump between their times, which nothing else names. Meanwhile the node ticks by wall clock
    and its inputs' ages take no jump as time passed (``MapperNodeBase``, ``InputTracker``).
    """
    if not sim_time or publishers <= 1:
        return None
    return (
        f"use_sim_time is true and {publishers} publishers are on /clock: the node's clock jumps between their "
        "times; meanwhile ticks and diagnostics run by wall clock and no jump ages the inputs (keep one /clock source)"
    )


def duplicate_name_warning(full_name: str, count: int) -> str | None:
    """The warning when ``count`` nodes named ``full_name`` are on the ROS graph, or None for one."""
    if count <= 1:
        return None
    return (
        f"{count} nodes named {full_name} on this ROS domain: their maps, diagnostics and parameters mix "
        "(give each its own namespace or __node name)"
    )


#: Wall-clock seconds a best-effort input may have a matched publisher and no message before the node warns.
SILENT_PUBLISHER_SECONDS = 5.0


class SilentInputWatch:
    """Says when an object's input has publishers but none of their PoseArrays arrives.

    On a best-effort subscription, a message too large to arrive whole (its fragments not all
    delivered) is dropped without the middleware reporting a loss, so ``poses lost`` stays 0 while
    every array is lost. What can be seen is a matched publisher and nothing received: that is
    what this watch words.
    """

    def __init__(self) -> None:
        self._matched_since: dict[str, float] = {}

    def observe(self, wall: float, name: str, publishers: int, received: int, best_effort: bool) -> str | None:
        """A warning for object ``name`` (``publishers`` matched, ``received`` PoseArrays so far), or None."""
        if publishers == 0 or received > 0:
            self._matched_since.pop(name, None)
            return None
        since = self._matched_since.setdefault(name, wall)
        if wall - since < SILENT_PUBLISHER_SECONDS:
            return None
        advice = (
            "a best-effort input drops arrays too large to arrive whole, uncounted: set input_reliability: reliable"
            if best_effort
            else "is its publisher best effort? a reliable input does not match one"
        )
        return (
            f"hypotheses/{name}: {publishers} publisher(s) matched for {SILENT_PUBLISHER_SECONDS:g} s or more "
            f"but no PoseArray arrived ({advice})"
        )
