"""How the node's ticks keep time, for the diagnostics (ROS-free): counts since start, longest per period.

The diagnostics come at about 1 Hz while ticks come at ``rate_hz`` (up to 100 Hz); each
diagnostics message summarises the ticks since the previous one (:meth:`TickStatistics.take_period`).
Times are wall-clock seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

from physics_mapper.mapping.mapper import DEADLINE_SLACK

#: A tick that starts later than this many tick periods after the previous one is late (a timer slot was lost).
LATE_FACTOR = 1.5


@dataclass(frozen=True)
class TickPeriod:
    """The ticks since the node started and those of the last diagnostics period.

    ``overruns``: searches that ran past ``deadline`` + :data:`~physics_mapper.mapping.mapper.DEADLINE_SLACK`;
    ``late``: ticks that started more than :data:`LATE_FACTOR` periods after the previous one;
    ``max_search_time`` and ``max_tick_time`` (search plus publishing) are this period's longest.
    """

    ticks: int
    overruns: int
    late: int
    period_ticks: int
    max_search_time: float
    max_tick_time: float


class TickStatistics:
    """Accumulates every tick's timing; :meth:`take_period` reports and starts a new period."""

    def __init__(self) -> None:
        self._ticks = self._overruns = self._late = 0
        self._period_ticks = 0
        self._max_search_time = self._max_tick_time = 0.0
        self._last_start: float | None = None

    def record(self, *, start: float, search_time: float, tick_time: float, deadline: float, rate_hz: float) -> None:
        """One tick that started at ``start`` (monotonic seconds), searched and took ``tick_time`` in all."""
        self._ticks += 1
        self._period_ticks += 1
        if search_time > deadline + DEADLINE_SLACK:
            self._overruns += 1
        if self._last_start is not None and start - self._last_start > LATE_FACTOR / rate_hz:
            self._late += 1
        self._last_start = start
        self._max_search_time = max(self._max_search_time, search_time)
        self._max_tick_time = max(self._max_tick_time, tick_time)

    def take_period(self) -> TickPeriod:
        """The counts so far and this period's longest times; the next period starts empty."""
        period = TickPeriod(
            self._ticks, self._overruns, self._late, self._period_ticks, self._max_search_time, self._max_tick_time
        )
        self._period_ticks = 0
        self._max_search_time = self._max_tick_time = 0.0
        return period
