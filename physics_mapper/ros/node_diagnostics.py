"""What the node says on ``/diagnostics``: its ticks, its faults, and what its wall-clock watch found.

:class:`NodeDiagnostics` keeps the last tick's report and the first tick of the period whose physics
engine failed (reported instead, so that no failure goes unseen between two messages), how the
ticks kept time, and the warnings of the watch that runs by wall clock (a stopped simulated clock,
a second node of this name, inputs with no publisher or gone silent).
"""

from __future__ import annotations

import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.publisher import Publisher

from physics_mapper.mapping.clock import ClockWatch, SilentInputWatch, clock_sources_warning, duplicate_name_warning
from physics_mapper.mapping.mapper import Mapper, TickReport
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.mapping.tick_statistics import TickStatistics
from physics_mapper.mapping.topics import poses_topic
from physics_mapper.model.limits import MAX_DIAGNOSTIC_TEXT, clipped
from physics_mapper.msg_adapters.diagnostics import diagnostics_msg
from physics_mapper.ros.parameters import NodeParameters

#: The topic of the simulated clock (rclpy's time source subscribes to it, from the root namespace).
CLOCK_TOPIC = "/clock"
#: Wall-clock seconds between two checks of the simulated clock and of the node's name on the graph.
WATCH_PERIOD = 1.0


class NodeDiagnostics:
    """The ``/diagnostics`` of one configured node (its ``mapper``), published by ``publisher``."""

    def __init__(
        self, node: Node, mapper: Mapper, parameters: NodeParameters, publisher: Publisher, *, best_effort: bool
    ) -> None:
        self._node = node
        self._mapper = mapper
        self._parameters = parameters
        self._publisher = publisher
        self._best_effort = best_effort
        self._logger: Any = node.get_logger()  # type: ignore[no-untyped-call]  # rclpy 7 leaves it unannotated
        self._report: TickReport | None = None  # the last tick's
        self._fault: TickReport | None = None  # the first tick of this diagnostics period that the engine failed
        self.ticks = TickStatistics()
        self._clock_watch = ClockWatch()
        self._silent_inputs = SilentInputWatch()
        self._watch_warnings: dict[str, str] = {}  # what the watch found, by kind, added to every diagnostics
        self._last_message = ""

    @property
    def last_report(self) -> TickReport | None:
        """The last tick's report, or None before the first tick."""
        return self._report

    def record(self, report: TickReport) -> None:
        """A tick's report: the last one, and the period's first engine fault."""
        self._report = report
        if report.engine_fault is not None and self._fault is None:
            self._fault = report

    @property
    def several_clock_sources(self) -> bool:
        """Whether the last watch saw more than one ``/clock`` publisher under ``use_sim_time``."""
        return "clock sources" in self._watch_warnings

    def watch(self) -> None:
        """Check, by wall clock, what no tick can see: a stopped simulated clock, another node of this name."""
        node = self._node
        sim_time = bool(node.get_parameter("use_sim_time").value)
        clock = self._clock_watch.observe(time.monotonic(), node.get_clock().now().nanoseconds, sim_time)
        count = sum(
            1
            for name, namespace in node.get_node_names_and_namespaces()
            if name == node.get_name() and namespace == node.get_namespace()
        )
        found = {
            "clock": clock,
            "clock sources": clock_sources_warning(node.count_publishers(CLOCK_TOPIC), sim_time),
            "name": duplicate_name_warning(node.get_fully_qualified_name(), count),
        }
        for name, inputs in self._mapper.inputs.objects.items():
            publishers = node.count_publishers(poses_topic(name))
            silent = self._silent_inputs.observe(
                time.monotonic(), name, publishers, inputs.poses_received, self._best_effort
            )
            found[f"input {name}"] = silent
        for kind, warning in found.items():
            if warning is not None and kind not in self._watch_warnings:  # logged when it starts, not every second
                self._logger.warning(warning)
        self._watch_warnings = {kind: warning for kind, warning in found.items() if warning is not None}
        if clock is not None:  # the diagnostics timer waits for /clock too: published from here instead
            self.publish()

    def publish(self) -> None:
        """The last tick's report, and how the ticks kept time since the previous message.

        A tick whose physics engine failed is reported instead, so that no failure goes unseen
        between two messages; before the first tick, the inputs so far.
        """
        node = self._node
        now_ns = node.get_clock().now().nanoseconds
        report, self._fault = self._fault or self._report, None
        if report is None:
            settings = self._parameters.settings()
            snapshot = self._mapper.inputs.snapshot(now_ns / NANOSECONDS_PER_SECOND, settings.inputs)
            report = TickReport(snapshot, None, 0.0, False, settings)
        diagnostics = diagnostics_msg(
            report,
            node_name=node.get_name(),
            hardware_id=node.get_fully_qualified_name(),
            stamp_ns=now_ns,
            ticks=self.ticks.take_period(),
        )
        warnings = list(self._watch_warnings.values())
        if warnings:
            status = diagnostics.status[0]
            status.level = max(status.level, DiagnosticStatus.WARN, key=lambda level: level[0])
            status.message = clipped("; ".join([*warnings, status.message]), MAX_DIAGNOSTIC_TEXT)
        self._publisher.publish(diagnostics)
        message = diagnostics.status[0].message
        if message != self._last_message:
            self._last_message = message
            self._logger.info(message)


def wall_clock() -> Clock:
    """A clock for timers that must not follow ``/clock`` (steady: never jumps)."""
    return Clock(clock_type=ClockType.STEADY_TIME)
