"""The ``physics_mapper`` ROS 2 node: weighted pose hypotheses in, a physically valid map out.

A thin shell: subscriptions hand messages to ``msg_adapters`` and the ROS-free
:class:`~physics_mapper.mapping.mapper.Mapper`; a timer at ``rate_hz`` runs one tick and
publishes the map, another at ``diagnostics_period`` publishes ``/diagnostics``. Run it with
``ros2 run physics_mapper node --ros-args -p scene_file:=<path>`` or, without a ROS installation,
``physics-mapper node --ros-args ...``. Topic names and QoS are in :mod:`physics_mapper.mapping.topics`.

Messages become inputs stamped with their arrival (:mod:`physics_mapper.ros.node_inputs`), moved from sensor frames
into the scene's (:mod:`physics_mapper.ros.node_frames`); the parameters are declared, validated and read in
:mod:`physics_mapper.ros.parameters`; the scene loads while the node spins (:mod:`physics_mapper.ros.node_scene`); the
outputs are published by :mod:`physics_mapper.ros.map_publishers` and :mod:`physics_mapper.ros.node_diagnostics`; the
managed node is :mod:`physics_mapper.ros.managed_node`, the process :mod:`physics_mapper.ros.run_node`. The node spins
single-threaded; its subscriptions and its timers are in separate callback groups and the input tracker is locked, so
a multi-threaded executor works too (BENCHMARKS.md, "Input flood", measured both). SIGINT and SIGTERM stop it cleanly
at any moment, exit code 0 (:class:`~physics_mapper.ros.spinning.SignalStop`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any, cast

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription
from rclpy.timer import Timer

from physics_mapper.mapping.mapper import Mapper
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.mapping.topics import (
    DIAGNOSTICS_TOPIC,
    NODE_NAME,
    InputReliability,
)
from physics_mapper.model.errors import InputError
from physics_mapper.msg_adapters.results import static_markers_msg
from physics_mapper.ros.map_publishers import MapPublishers, TfOutput, map_publishers
from physics_mapper.ros.node_diagnostics import WATCH_PERIOD, NodeDiagnostics, wall_clock
from physics_mapper.ros.node_frames import SensorFrames
from physics_mapper.ros.node_inputs import InputHandlers, InputNotes
from physics_mapper.ros.node_scene import load_scene_spinning, resolve_scene_path
from physics_mapper.ros.node_subscriptions import InputSubscriptions
from physics_mapper.ros.parameters import PARAMETERS, SCENE_FILE_DESCRIPTOR, NodeParameters, parameters_problem
from physics_mapper.ros.qos import DIAGNOSTICS_QOS, MAP_QOS
from physics_mapper.ros.spinning import SignalStop

__all__ = ["PARAMETERS", "MapperNodeBase", "PhysicsMapperNode"]


class MapperNodeBase(Node):
    """The node's work, shared by :class:`PhysicsMapperNode` and :class:`ManagedPhysicsMapperNode`.

    :meth:`configure` declares the parameters, loads the scene and creates the subscriptions and
    publishers; :meth:`start_ticking` and :meth:`stop_ticking` start and stop the tick and
    diagnostics timers; :meth:`release` destroys what :meth:`configure` made. ``stop``: the
    process's signal handling; a signal interrupts the tick's search at once.
    """

    def __init__(self, *, stop: SignalStop | None = None, **kwargs: Any) -> None:
        # Every override (params file, -p) becomes a parameter first, so that the ones this node
        # has none for can be named (rclpy offers no other public view of them).
        super().__init__(NODE_NAME, automatically_declare_parameters_from_overrides=True, **kwargs)
        self._stop = stop or SignalStop()
        self._logger: Any = self.get_logger()  # type: ignore[no-untyped-call]  # rclpy 7 leaves it unannotated
        self._node_parameters = NodeParameters(self)
        self._mapper: Mapper | None = None
        self._outputs: MapPublishers | None = None
        self._frames: SensorFrames | None = None
        self._entities: list[Subscription | Publisher] = []
        self._tick_timers: dict[str, Timer] = {}  # by job: "tick", "diagnostics", "watch"
        self._by_wall_clock = False  # the tick and diagnostics timers (several /clock sources)
        self._input_notes = InputNotes(self._logger)
        self._inputs_group = MutuallyExclusiveCallbackGroup()  # type: ignore[no-untyped-call]
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)

    def configure(self) -> None:
        """Read the parameters and the scene; subscribe to the inputs and create the publishers."""
        unknown = self._node_parameters.unknown_parameters()
        scene_path = resolve_scene_path(str(self._node_parameters.declare("scene_file", "", SCENE_FILE_DESCRIPTOR)))
        scene = load_scene_spinning(self, scene_path, self._stop)
        for note in scene.notes:
            self._logger.warning(note)
        self._node_parameters.declare_all(scene.search)
        values = self._node_parameters.parameter_values()
        problem = parameters_problem(values)
        if problem is not None:
            raise InputError(f"invalid parameters: {problem}")
        self._node_parameters.drop_unknown_parameters(unknown)
        self._mapper = Mapper(scene)
        reliability = cast(InputReliability, values["input_reliability"])
        self._frames = SensorFrames(self, scene, self._input_notes.log_once, float(values["transform_timeout"]))
        self._entities += self._frames.subscribe(self._inputs_group)
        handlers = InputHandlers(self, self._mapper, self._input_notes, self._frames)
        subscriptions = InputSubscriptions(self, handlers, reliability, self._inputs_group, [])
        topics = subscriptions.objects(scene.object_names) + subscriptions.detections()
        self._entities += subscriptions.made
        diagnostics_pub = self._map_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        diagnostics = NodeDiagnostics(
            self, self._mapper, self._node_parameters, diagnostics_pub, best_effort=reliability == "best_effort"
        )
        self._outputs = map_publishers(self._map_publisher, scene.object_names, diagnostics, self)
        self._logger.info(
            f"scene {scene_path}: objects {', '.join(scene.object_names)} in frame {scene.frame_id!r}; "
            f"listening on {', '.join(topics)} ({reliability})"
        )

    @property
    def mapper(self) -> Mapper:
        """The ROS-free mapper of the configured node."""
        if self._mapper is None:
            raise RuntimeError("the node is not configured")
        return self._mapper

    @property
    def outputs(self) -> MapPublishers:
        """The output publishers of the configured node."""
        if self._outputs is None:
            raise RuntimeError("the node is not configured")
        return self._outputs

    def start_ticking(self) -> None:
        """Start the tick timer (``rate_hz``), the diagnostics timer (``diagnostics_period``) and the watch."""
        values = self._node_parameters.parameter_values()
        # Latched, before the first map (each map repeats them): RViz shows the fixed bodies, a consumer the names.
        self.outputs.markers.publish(static_markers_msg(self.mapper.scene, stamp_ns=self._now_ns()))
        self.outputs.publish_status(None, self.mapper.scene, self._now_ns())
        # The watch runs by wall clock: with use_sim_time the other timers wait for /clock, and a missing one
        # must be reported.
        self._tick_timers = {"watch": self.create_timer(WATCH_PERIOD, self._watch, clock=wall_clock())}
        self._start_periodic(values, by_wall_clock=False)

    def _start_periodic(self, values: Mapping[str, Any], *, by_wall_clock: bool) -> None:
        """(Re)start the tick and diagnostics timers, on the node's clock or by wall clock."""
        clock = wall_clock() if by_wall_clock else None
        diagnostics = self.outputs.diagnostics
        for job in ("tick", "diagnostics"):
            if job in self._tick_timers:
                self.destroy_timer(self._tick_timers.pop(job))
        self._tick_timers["tick"] = self.create_timer(1.0 / float(values["rate_hz"]), self._tick, clock=clock)
        period = float(values["diagnostics_period"])
        self._tick_timers["diagnostics"] = self.create_timer(period, diagnostics.publish, clock=clock)
        self._by_wall_clock = by_wall_clock

    def _watch(self) -> None:
        """The wall-clock watch; while ``/clock`` has several publishers the node's clock jumps between their
        times, and a timer on it would fire at every jump forward: the ticks then run by wall clock."""
        diagnostics = self.outputs.diagnostics
        diagnostics.watch()
        several = diagnostics.several_clock_sources
        self.mapper.inputs.set_several_clocks(several)
        if several != self._by_wall_clock and self._tick_timers:
            self._start_periodic(self._node_parameters.parameter_values(), by_wall_clock=several)

    def stop_ticking(self) -> None:
        """Stop every timer (the subscriptions go on collecting hypotheses)."""
        for timer in self._tick_timers.values():
            self.destroy_timer(timer)
        self._tick_timers = {}

    def release(self) -> None:
        """Destroy the subscriptions and publishers and close the physics world (:meth:`configure` undone)."""
        self.stop_ticking()
        for entity in self._entities:
            if isinstance(entity, Subscription):
                self.destroy_subscription(entity)
            else:
                self._destroy_publisher(entity)
        self._entities = []
        self._outputs = None
        if self._mapper is not None:
            self._mapper.close()
            self._mapper = None

    def _map_publisher(self, msg_type: type, topic: str, qos: QoSProfile = MAP_QOS) -> Publisher:
        """An output publisher (the managed node's publish only while it is active)."""
        publisher = self.create_publisher(msg_type, topic, qos)
        self._entities.append(publisher)
        return publisher

    def _destroy_publisher(self, publisher: Publisher) -> None:
        self.destroy_publisher(publisher)

    # --- parameters -----------------------------------------------------------------------------

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """Refuse read-only and invalid changes (judged at :meth:`configure` before it); others apply next tick."""
        problem = self._node_parameters.read_only_problem(parameters)
        if problem is None and self._mapper is not None:
            problem = self._node_parameters.change_problem(parameters)
        return SetParametersResult(successful=problem is None, reason=problem or "")

    def _on_parameters_set(self, parameters: list[Parameter]) -> None:
        """A new tick rate or diagnostics period applies at once: its timer is re-armed, not left to run out."""
        if not self._tick_timers:
            return  # not ticking: start_ticking() reads the new values
        for parameter in parameters:
            if parameter.name == "rate_hz":
                self._rearm(self._tick_timers["tick"], 1.0 / float(parameter.value))
            elif parameter.name == "diagnostics_period":
                self._rearm(self._tick_timers["diagnostics"], float(parameter.value))

    @staticmethod
    def _rearm(timer: Timer, period: float) -> None:
        timer.timer_period_ns = round(period * NANOSECONDS_PER_SECOND)
        timer.reset()  # type: ignore[no-untyped-call]

    def _now_ns(self) -> int:
        """The node clock, integer nanoseconds (exact, for stamps)."""
        return self.get_clock().now().nanoseconds

    # --- ticks and outputs ----------------------------------------------------------------------

    def _tick(self) -> None:
        start = time.monotonic()
        values, settings = self._node_parameters.parameter_values(), self._node_parameters.settings()
        if self._frames is not None:  # inputs whose wait for a transform is over are refused before the snapshot
            self._frames.flush(float(values["transform_timeout"]))
        with self._stop.interruptible():  # a signal stops a search at once
            report = self.mapper.tick(self._now_ns() / NANOSECONDS_PER_SECOND, settings)
        self._input_notes.log_tick(report.snapshot)
        diagnostics = self.outputs.diagnostics
        diagnostics.record(report)
        self.outputs.publish_map(report, self.mapper.scene, TfOutput.of(values))
        tick_time = time.monotonic() - start
        diagnostics.ticks.record(
            start=start,
            search_time=report.search_time,
            tick_time=tick_time,
            deadline=settings.search.deadline,
            rate_hz=settings.rate_hz,
        )

    def destroy_node(self) -> None:
        self.release()
        super().destroy_node()  # type: ignore[no-untyped-call]


class PhysicsMapperNode(MapperNodeBase):
    """Subscribes to every scene object's hypotheses and publishes the best physically valid map, from its start."""

    def __init__(self, *, stop: SignalStop | None = None, **kwargs: Any) -> None:
        super().__init__(stop=stop, **kwargs)
        try:
            self.configure()
            self.start_ticking()
        except BaseException:
            self.destroy_node()  # also when a signal interrupts the start-up: no handle outlives the node
            raise
