"""The ``physics_mapper`` ROS 2 node: weighted pose hypotheses in, a physically valid map out.

A thin shell: subscriptions hand messages to ``msg_adapters`` and the ROS-free
:class:`~physics_mapper.mapping.mapper.Mapper`; a timer at ``rate_hz`` runs one tick and
publishes the map, another at ``diagnostics_period`` publishes ``/diagnostics``. Run it with
``ros2 run physics_mapper node --ros-args -p scene_file:=<path>`` or, without a ROS installation,
``physics-mapper node --ros-args ...``. Topic names and QoS are in :mod:`physics_mapper.mapping.topics`.

- **Arrival times.** A message's arrival is the time the middleware received it (rclpy's message
  info), not the time its callback runs: a tick's search holds the executor for up to
  ``deadline``, and messages arriving meanwhile would all seem to arrive just after it, so that
  weights would pair by processing order. The node spins single-threaded; its subscriptions
  and its timers are in separate callback groups and the input tracker is locked, so a
  multi-threaded executor works too (BENCHMARKS.md, "Input flood", measured both).
- **Large arrays.** PoseArrays are received serialised and read without a Python object per
  pose (:mod:`physics_mapper.msg_adapters.pose_array_cdr`); only the hypotheses kept are converted.
- **Lost messages** (the middleware's message-lost event) are counted per input and shown in
  the diagnostics; ``input_reliability: reliable`` avoids them with reliable publishers.
- **Parameters** are read in one place (:meth:`PhysicsMapperNode.parameter_values`); a change is
  judged on the combination of values the node would end up with, and a ``rate_hz`` or
  ``diagnostics_period`` change re-arms its timer at once.
- **Signals.** SIGINT and SIGTERM stop the node cleanly at any moment, exit code 0
  (:class:`~physics_mapper.ros.spinning.SignalStop`).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, cast

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.exceptions import InvalidTopicNameException, ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.lifecycle.publisher import LifecyclePublisher
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription
from rclpy.time_source import USE_SIM_TIME_NAME
from rclpy.timer import Timer
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import MarkerArray

from physics_mapper.mapping.clock import ClockWatch, SilentInputWatch, duplicate_name_warning
from physics_mapper.mapping.detections import DETECTIONS_TOPIC, detection_inputs
from physics_mapper.mapping.inputs import InputSettings, MessageKind
from physics_mapper.mapping.mapper import DEFAULT_RATE_HZ, Mapper, MapperSettings, TickReport, mapper_settings_problem
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.mapping.tick_statistics import TickStatistics
from physics_mapper.mapping.topics import (
    CONFIGURATION_TOPIC,
    DIAGNOSTICS_TOPIC,
    INPUT_RELIABILITIES,
    MARKERS_TOPIC,
    NODE_NAME,
    SETTLED_TOPIC,
    InputReliability,
    object_pose_topic,
    object_settled_pose_topic,
    poses_topic,
    weights_topic,
)
from physics_mapper.model.errors import EXIT_BAD_INPUT, InputError
from physics_mapper.model.limits import MAX_DIAGNOSTIC_TEXT, clipped
from physics_mapper.model.resources import ResourceError, resolve_resource
from physics_mapper.model.scene import SEARCH_LIMITS, Scene, SearchParams, search_parameter_doc
from physics_mapper.model.scene_files import SceneError, load_scene, search_with_overrides
from physics_mapper.model.scene_loading import SceneLoading
from physics_mapper.msg_adapters.diagnostics import diagnostics_msg
from physics_mapper.msg_adapters.hypotheses import received_pose_array, received_weights
from physics_mapper.msg_adapters.results import configuration_msgs, markers_msg, object_pose_msgs, static_markers_msg
from physics_mapper.ros.qos import DIAGNOSTICS_QOS, MAP_QOS, input_qos
from physics_mapper.ros.spinning import STOP_POLL, SignalStop, shutdown_ros
from physics_mapper.search.results import SearchResult

#: Seconds between two /diagnostics messages unless ``diagnostics_period`` says otherwise (the ~1 Hz convention).
DEFAULT_DIAGNOSTICS_PERIOD = 1.0
#: Wall-clock seconds between two checks of the simulated clock and of the node's name on the graph.
WATCH_PERIOD = 1.0
#: Seconds a scene may take to load before the node spins and reports what it is doing (a decomposition).
LOADING_REPORT_AFTER = 0.2


@dataclass(frozen=True)
class ParameterSpec:
    """A node parameter: ``default`` None means the scene file's ``search:`` value; ``limits`` inclusive.

    The search parameters' limits are the scene model's (:data:`~physics_mapper.model.scene.SEARCH_LIMITS`).
    A ``read_only`` parameter is read once, at start-up.
    """

    name: str
    description: str
    default: float | int | bool | str | None = None
    limits: tuple[float, float] | None = None
    read_only: bool = False


#: Parameters rclpy declares on every node itself.
RCLPY_PARAMETERS = (USE_SIM_TIME_NAME, "start_type_description_service")
#: rclpy's QoS override parameters (``qos_overrides./topic.publisher.depth``), never unknown.
QOS_OVERRIDES_PREFIX = "qos_overrides."
#: Distinct input notes (object, text) logged in full before they are throttled.
MAX_LOGGED_INPUT_NOTES = 1000
SCENE_FILE_DESCRIPTOR = ParameterDescriptor(
    description="scene YAML (path or package://pkg/path); read once", read_only=True
)

#: The search parameters, each a node parameter of the same name.
SEARCH_PARAMETER_NAMES = tuple(f.name for f in fields(SearchParams))

#: Every parameter but ``scene_file``, in the order ``ros2 param list`` shows them. Add new ones here;
#: :meth:`PhysicsMapperNode.parameter_values` reads them all, :meth:`PhysicsMapperNode.settings` uses them.
PARAMETERS = (
    ParameterSpec(
        "rate_hz", "ticks per second; each tick snapshots the inputs and searches", DEFAULT_RATE_HZ, (0.01, 100.0)
    ),
    # Every search parameter, described and bounded by the scene model; defaults from the scene file.
    *(ParameterSpec(name, search_parameter_doc(name)) for name in SEARCH_PARAMETER_NAMES),
    ParameterSpec("max_hypotheses_per_object", "hypotheses kept per object (the heaviest)", 100, (1, 100000)),
    ParameterSpec("max_age", "seconds after which received hypotheses are stale", 10.0, (0.01, 86400.0)),
    ParameterSpec("require_weights", "refuse PoseArrays without a weights message instead of uniform weights", False),
    ParameterSpec(
        "diagnostics_period",
        "seconds between two /diagnostics messages (the map topics follow rate_hz)",
        DEFAULT_DIAGNOSTICS_PERIOD,
        (0.01, 3600.0),
    ),
    ParameterSpec(
        "input_reliability",
        f"QoS reliability of the hypothesis subscriptions, {' or '.join(INPUT_RELIABILITIES)}: best_effort matches "
        "every publisher (lost messages are counted in the diagnostics); reliable loses no message of a reliable "
        "publisher and does not match best-effort ones",
        "best_effort",
        read_only=True,
    ),
)


def _descriptor(spec: ParameterSpec, default: object) -> ParameterDescriptor:
    descriptor = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
    limits = SEARCH_LIMITS.get(spec.name, spec.limits)
    if limits is None:
        return descriptor
    low, high = limits
    if isinstance(default, int) and not isinstance(default, bool):
        descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    else:
        descriptor.floating_point_range = [FloatingPointRange(from_value=low, to_value=high, step=0.0)]
    return descriptor


def resolve_scene_path(text: str) -> Path:
    """A scene file path, or a ``package://<pkg>/<path>`` URL (:mod:`physics_mapper.model.resources`).

    Without an ament index (pip wheels only), ``package://physics_mapper/`` is this installation's
    shipped files (:func:`~physics_mapper.model.shipped.share_directory`: the same ``config/`` tree).
    """
    if not text:
        raise InputError("parameter scene_file is required, e.g. --ros-args -p scene_file:=config/scenes/pyramid.yaml")
    try:
        return resolve_resource(text, None)
    except ResourceError as error:
        raise InputError(f"scene_file {error}") from None


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
        self._declared: set[str] = set()
        self._mapper: Mapper | None = None
        self._entities: list[Subscription | Publisher] = []
        self._timers: list[Timer] = []
        self._refusals_logged: set[tuple[str, str]] = set()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)

    def configure(self) -> None:
        """Read the parameters and the scene; subscribe to the inputs and create the publishers."""
        unknown = self._unknown_parameters()
        scene_path = resolve_scene_path(str(self._declare("scene_file", "", SCENE_FILE_DESCRIPTOR)))
        scene = self._load_scene(scene_path)
        for note in scene.notes:
            self._logger.warning(note)
        for spec in PARAMETERS:
            default = getattr(scene.search, spec.name) if spec.default is None else spec.default
            self._declare(spec.name, default, _descriptor(spec, default))
        values = self.parameter_values()
        problem = self._problem(values)
        if problem is not None:
            raise InputError(f"invalid parameters: {problem}")
        self._drop_unknown_parameters(unknown)
        self._mapper = Mapper(scene)
        self._report: TickReport | None = None  # the last tick's
        self._fault: TickReport | None = None  # the first tick of this diagnostics period that the engine failed
        self._ticks = TickStatistics()
        self._inputs_group = MutuallyExclusiveCallbackGroup()  # type: ignore[no-untyped-call]
        reliability = cast(InputReliability, values["input_reliability"])
        topics = [topic for name in scene.object_names for topic in self._subscribe(name, reliability)]
        topics += self._subscribe_detections(reliability)
        self._configuration_pub = self._map_publisher(PoseArray, CONFIGURATION_TOPIC)
        self._settled_pub = self._map_publisher(PoseArray, SETTLED_TOPIC)
        self._markers_pub = self._map_publisher(MarkerArray, MARKERS_TOPIC)
        self._object_pubs: list[tuple[Publisher, Publisher]] = [
            (
                self._map_publisher(PoseStamped, object_pose_topic(name)),
                self._map_publisher(PoseStamped, object_settled_pose_topic(name)),
            )
            for name in scene.object_names
        ]
        self._published_objects: tuple[int, SearchResult] | None = None
        self._diagnostics_pub = self._map_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        self._clock_watch = ClockWatch()
        self._silent_inputs = SilentInputWatch()
        self._best_effort = reliability == "best_effort"
        self._watch_warnings: dict[str, str] = {}  # what the watch found, by kind, added to every diagnostics
        self._last_message = ""
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

    def start_ticking(self) -> None:
        """Start the tick timer (``rate_hz``) and the diagnostics timer (``diagnostics_period``)."""
        values = self.parameter_values()
        # Latched: RViz shows the fixed bodies before the first map (each map repeats them).
        self._markers_pub.publish(static_markers_msg(self.mapper.scene, stamp_ns=self._now_ns()))
        self._tick_timer = self.create_timer(1.0 / float(values["rate_hz"]), self._tick)
        self._diagnostics_timer = self.create_timer(float(values["diagnostics_period"]), self._publish_diagnostics)
        # By wall clock: with use_sim_time the timers above wait for /clock, and a missing one must be reported.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timers = [
            self._tick_timer,
            self._diagnostics_timer,
            self.create_timer(WATCH_PERIOD, self._watch, clock=steady),
        ]

    def stop_ticking(self) -> None:
        """Stop both timers (the subscriptions go on collecting hypotheses)."""
        for timer in self._timers:
            self.destroy_timer(timer)
        self._timers = []

    def release(self) -> None:
        """Destroy the subscriptions and publishers and close the physics world (:meth:`configure` undone)."""
        self.stop_ticking()
        for entity in self._entities:
            if isinstance(entity, Subscription):
                self.destroy_subscription(entity)
            else:
                self._destroy_publisher(entity)
        self._entities = []
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

    def _declare(self, name: str, default: object, descriptor: ParameterDescriptor) -> object:
        """Declare a parameter of this node once (a params file's value wins over ``default``); its value."""
        if name not in self._declared:
            if self.has_parameter(name):  # declared from an override: declared again, typed
                self.undeclare_parameter(name)
            self.declare_parameter(name, default, descriptor)
            self._declared.add(name)
        return self.get_parameter(name).value

    def _unknown_parameters(self) -> list[str]:
        """The overrides meant for this node that name no parameter of it (nor of rclpy)."""
        known = {"scene_file", *(spec.name for spec in PARAMETERS), *RCLPY_PARAMETERS}
        names = self.list_parameters([], 0).names
        return sorted(n for n in names if n not in known and not n.startswith(QOS_OVERRIDES_PREFIX))

    def _drop_unknown_parameters(self, unknown: Sequence[str]) -> None:
        """Undeclare and name the overrides this node has no parameter for (they are ignored)."""
        for name in unknown:
            self.undeclare_parameter(name)
        if unknown:
            known = ", ".join(["scene_file", *(spec.name for spec in PARAMETERS)])
            self._logger.warning(
                f"unknown parameters ignored (from --params-file or -p): {', '.join(unknown)}; "
                f"this node's parameters are: {known}"
            )

    # --- parameters -----------------------------------------------------------------------------

    def parameter_values(self, changes: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Every parameter's value (:data:`PARAMETERS`), with ``changes`` applied: the one place they are read."""
        changes = changes or {}
        return {
            spec.name: changes[spec.name] if spec.name in changes else self.get_parameter(spec.name).value
            for spec in PARAMETERS
        }

    @staticmethod
    def settings(values: Mapping[str, Any]) -> MapperSettings:
        """The mapper's settings from parameter values (:meth:`parameter_values`); raises
        :class:`SceneError` for search parameters a scene file could not hold either."""
        overrides = {name: values[name] for name in SEARCH_PARAMETER_NAMES}
        search = search_with_overrides(SearchParams(), overrides, "parameters", key="")
        inputs = InputSettings(
            max_age=float(values["max_age"]),
            max_hypotheses=int(values["max_hypotheses_per_object"]),
            require_weights=bool(values["require_weights"]),
        )
        return MapperSettings(search, inputs, float(values["rate_hz"]))

    def _problem(self, values: Mapping[str, Any]) -> str | None:
        """What makes a combination of parameter values invalid, or None."""
        reliability = values["input_reliability"]
        if reliability not in INPUT_RELIABILITIES:
            return f"input_reliability must be one of {', '.join(INPUT_RELIABILITIES)}, got {reliability!r}"
        try:
            settings = self.settings(values)
        except SceneError as error:
            return f"{error.key} {error.problem}" if error.key else error.problem
        return mapper_settings_problem(settings)

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """Refuse a change that leaves the combination of values invalid; accepted ones apply at the next tick.

        rclpy sets a SetParameters request's parameters one at a time, in its order, each judged on
        its own: to raise ``rate_hz`` and shorten ``deadline`` together, send the deadline first, or
        both in one SetParametersAtomically request, which is judged as a whole. While the node is
        still declaring its parameters (:meth:`configure`) there is no combination to judge yet.
        """
        if self._mapper is None:
            return SetParametersResult(successful=True)
        problem = self._problem(self.parameter_values({p.name: p.value for p in parameters}))
        return SetParametersResult(successful=problem is None, reason=problem or "")

    def _on_parameters_set(self, parameters: list[Parameter]) -> None:
        """A new tick rate or diagnostics period applies at once: its timer is re-armed, not left to run out."""
        if not self._timers:
            return  # not ticking: start_ticking() reads the new values
        for parameter in parameters:
            if parameter.name == "rate_hz":
                self._rearm(self._tick_timer, 1.0 / float(parameter.value))
            elif parameter.name == "diagnostics_period":
                self._rearm(self._diagnostics_timer, float(parameter.value))

    @staticmethod
    def _rearm(timer: Timer, period: float) -> None:
        timer.timer_period_ns = round(period * NANOSECONDS_PER_SECOND)
        timer.reset()  # type: ignore[no-untyped-call]

    # --- inputs ---------------------------------------------------------------------------------

    def _subscribe(self, name: str, reliability: InputReliability) -> list[str]:
        """Subscribe to object ``name``'s hypotheses; the topics' names as resolved (namespace, remaps)."""
        scene, inputs = self.mapper.scene, self.mapper.inputs
        frame, workspace = scene.frame_id, scene.workspace

        def on_poses(raw: bytes, info: Mapping[str, Any]) -> None:
            received = received_pose_array(
                raw, expected_frame=frame, workspace=workspace, received=self._received(info)
            )
            inputs.add_poses(name, received)
            if received.frame_assumed:
                self._log_input_once(name, f"a PoseArray without a frame_id is taken in the scene frame {frame!r}")
            if received.refusal is not None:
                self._log_input_once(name, f"PoseArray refused: {received.refusal}")

        def on_weights(msg: Float64MultiArray, info: Mapping[str, Any]) -> None:
            received = received_weights(msg, received=self._received(info))
            inputs.add_weights(name, received)
            if received.refusal is not None:
                self._log_input_once(name, f"weights refused: {received.refusal}")

        try:
            return [
                self._input_subscription(
                    PoseArray, poses_topic(name), on_poses, reliability, lost_as=(name, "poses"), raw=True
                ),
                self._input_subscription(
                    Float64MultiArray, weights_topic(name), on_weights, reliability, lost_as=(name, "weights")
                ),
            ]
        except InvalidTopicNameException:
            raise InputError(f"object name {name!r} cannot be part of a ROS topic name") from None

    def _subscribe_detections(self, reliability: InputReliability) -> list[str]:
        """Subscribe to ``detections`` (``vision_msgs/Detection3DArray``) where vision_msgs is installed.

        Its results are the hypotheses of the objects their class ids name
        (:mod:`physics_mapper.mapping.detections`), beside the per-object topics.
        """
        try:
            from vision_msgs.msg import Detection3DArray
        except ImportError:
            return []
        scene, inputs = self.mapper.scene, self.mapper.inputs

        def on_detections(msg: Any, info: Mapping[str, Any]) -> None:
            detected = detection_inputs(msg, scene, received=self._received(info))
            for name, received in detected.objects.items():
                inputs.add_poses(name, received)
                if received.refusal is not None:
                    self._log_input_once(name, f"detections refused: {received.refusal}")
            for note in detected.unused:
                self._log_input_once(DETECTIONS_TOPIC, note)

        # A lost array cannot be laid to one object: the middleware's losses are not counted for it.
        return [self._input_subscription(Detection3DArray, DETECTIONS_TOPIC, on_detections, reliability)]

    def _log_input_once(self, name: str, what: str) -> None:
        """Log what became of an object's input, once per object and text: a stream of bad messages
        logs one line (the diagnostics count them all); past :data:`MAX_LOGGED_INPUT_NOTES` notes,
        at most one line per second."""
        key = (name, what)
        if key in self._refusals_logged:
            return
        if len(self._refusals_logged) < MAX_LOGGED_INPUT_NOTES:
            self._refusals_logged.add(key)
            self._logger.warning(f"{name}: {what}")
        else:
            self._logger.warning(f"{name}: {what}", throttle_duration_sec=1.0)

    def _input_subscription(
        self,
        msg_type: type,
        topic: str,
        callback: Callable[[Any, Mapping[str, Any]], None],
        reliability: InputReliability,
        *,
        lost_as: tuple[str, MessageKind] | None = None,
        raw: bool = False,
    ) -> str:
        """A hypothesis subscription: its callback gets the message info, and with ``lost_as``
        (object name, kind) the middleware's lost messages are counted; returns the topic's resolved name."""
        events = None if lost_as is None else SubscriptionEventCallbacks(message_lost=self._on_lost(*lost_as))
        subscription = self.create_subscription(
            msg_type,
            topic,
            cast(Callable[[Any], None], callback),  # rclpy passes two-parameter callbacks the message info
            input_qos(reliability),
            callback_group=self._inputs_group,
            event_callbacks=events,
            raw=raw,
        )
        self._entities.append(subscription)
        return str(subscription.topic_name)

    def _on_lost(self, name: str, kind: MessageKind) -> Callable[[QoSMessageLostInfo], None]:
        def lost(info: QoSMessageLostInfo) -> None:
            self.mapper.inputs.add_lost(name, kind, int(info.total_count_change), self._now())

        return lost

    def _received(self, info: Mapping[str, Any]) -> float:
        """When the middleware received a message, on the node's clock (seconds).

        The middleware's receive stamp is system time; the node's clock may be simulated time,
        so the message's wait since then is taken from the node's clock now.
        """
        now_ns = self._now_ns()
        received_ns = int(info.get("received_timestamp", 0) or 0)
        waited_ns = max(0, time.time_ns() - received_ns) if received_ns else 0
        return (now_ns - waited_ns) / NANOSECONDS_PER_SECOND

    def _now_ns(self) -> int:
        """The node clock, integer nanoseconds (exact, for stamps)."""
        return self.get_clock().now().nanoseconds

    def _now(self) -> float:
        """The node clock, seconds (receive times and ages)."""
        return self._now_ns() / NANOSECONDS_PER_SECOND

    # --- ticks and outputs ----------------------------------------------------------------------

    def _tick(self) -> None:
        start = time.monotonic()
        settings = self.settings(self.parameter_values())
        with self._stop.interruptible():  # a signal stops a search at once
            report = self.mapper.tick(self._now(), settings)
        self._report = report
        if report.engine_fault is not None and self._fault is None:
            self._fault = report
        self._publish_map(report)
        tick_time = time.monotonic() - start
        self._ticks.record(
            start=start,
            search_time=report.search_time,
            tick_time=tick_time,
            deadline=settings.search.deadline,
            rate_hz=settings.rate_hz,
        )

    def _publish_map(self, report: TickReport) -> None:
        """Outputs carry the newest input stamp used."""
        result, scene = report.result, self.mapper.scene
        stamp_ns = report.snapshot.stamp_ns
        if result is None or stamp_ns is None:
            return
        configurations = configuration_msgs(result, frame_id=scene.frame_id, stamp_ns=stamp_ns)
        if configurations is None:
            return
        self._configuration_pub.publish(configurations[0])
        self._settled_pub.publish(configurations[1])
        self._markers_pub.publish(markers_msg(result, scene, stamp_ns=stamp_ns))
        self._publish_objects(result, stamp_ns)

    def _publish_objects(self, result: SearchResult, stamp_ns: int) -> None:
        """Each object's chosen and settled pose, when the map's poses or stamp changed (the topics are latched)."""
        last = self._published_objects
        if (
            last is not None
            and last[0] == stamp_ns
            and (last[1].poses, last[1].settled_poses)
            == (
                result.poses,
                result.settled_poses,
            )
        ):
            return
        per_object = object_pose_msgs(result, frame_id=self.mapper.scene.frame_id, stamp_ns=stamp_ns)
        if per_object is None:
            return
        for (pose_pub, settled_pub), (pose, settled) in zip(self._object_pubs, per_object, strict=True):
            pose_pub.publish(pose)
            settled_pub.publish(settled)
        self._published_objects = (stamp_ns, result)

    def _load_scene(self, path: Path) -> Scene:
        """The scene, loaded in a thread while this node spins, reporting a decomposition in its diagnostics.

        A signal stops the load at once (the decomposition's child process is killed): KeyboardInterrupt.
        A node already spun by an executor (the managed node, configured from a service call) waits
        for the load without spinning itself.
        """
        loading = SceneLoading(path, load_scene)
        if loading.wait(LOADING_REPORT_AFTER):  # from the cache: nothing to report
            return loading.result()
        if self.executor is not None:
            while not loading.wait(STOP_POLL):
                if self._stop.requested:
                    loading.cancel()
                    raise KeyboardInterrupt
            return loading.result()
        publisher = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        executor = SingleThreadedExecutor(context=self.context)
        executor.add_node(self)
        reported = -float("inf")
        try:
            while not loading.done:
                if self._stop.requested:
                    loading.cancel()
                    raise KeyboardInterrupt
                if time.monotonic() - reported >= DEFAULT_DIAGNOSTICS_PERIOD:
                    reported = time.monotonic()
                    publisher.publish(self._loading_diagnostics(loading.activity or f"loading {path}"))
                executor.spin_once(timeout_sec=STOP_POLL / 2)
        finally:
            executor.remove_node(self)
            executor.shutdown()
            self.destroy_publisher(publisher)
        return loading.result()

    def _loading_diagnostics(self, activity: str) -> DiagnosticArray:
        """A WARN search status while the scene loads: no search yet, and why."""
        status = DiagnosticStatus(
            level=DiagnosticStatus.WARN,
            name=f"{self.get_name()}: search",
            message=clipped(f"{activity}: the search starts when the geometry is ready", MAX_DIAGNOSTIC_TEXT),
            hardware_id=self.get_fully_qualified_name(),
        )
        message = DiagnosticArray(status=[status])
        message.header.stamp = self.get_clock().now().to_msg()
        return message

    def _watch(self) -> None:
        """Check, by wall clock, what no tick can see: a stopped simulated clock, another node of this name."""
        sim_time = bool(self.get_parameter("use_sim_time").value)
        clock = self._clock_watch.observe(time.monotonic(), self._now_ns(), sim_time)
        full_name = self.get_fully_qualified_name()
        count = sum(
            1
            for name, namespace in self.get_node_names_and_namespaces()
            if name == self.get_name() and namespace == self.get_namespace()
        )
        found = {"clock": clock, "name": duplicate_name_warning(full_name, count)}
        for name, inputs in self.mapper.inputs.objects.items():
            publishers = self.count_publishers(poses_topic(name))
            silent = self._silent_inputs.observe(
                time.monotonic(), name, publishers, inputs.poses_received, self._best_effort
            )
            found[f"input {name}"] = silent
        for kind, warning in found.items():
            if warning is not None and kind not in self._watch_warnings:  # logged when it starts, not every second
                self._logger.warning(warning)
        self._watch_warnings = {kind: warning for kind, warning in found.items() if warning is not None}
        if clock is not None:  # the diagnostics timer waits for /clock too: published from here instead
            self._publish_diagnostics()

    def _publish_diagnostics(self) -> None:
        """The last tick's report, and how the ticks kept time since the previous message.

        A tick whose physics engine failed is reported instead, so that no failure goes unseen
        between two messages; before the first tick, the inputs so far.
        """
        report, self._fault = self._fault or self._report, None
        if report is None:
            settings = self.settings(self.parameter_values())
            report = TickReport(self.mapper.inputs.snapshot(self._now(), settings.inputs), None, 0.0, False, settings)
        diagnostics = diagnostics_msg(
            report,
            node_name=self.get_name(),
            hardware_id=self.get_fully_qualified_name(),
            stamp_ns=self._now_ns(),
            ticks=self._ticks.take_period(),
        )
        warnings = list(getattr(self, "_watch_warnings", {}).values())
        if warnings:
            status = diagnostics.status[0]
            status.level = max(status.level, DiagnosticStatus.WARN, key=lambda level: level[0])
            status.message = clipped("; ".join([*warnings, status.message]), MAX_DIAGNOSTIC_TEXT)
        self._diagnostics_pub.publish(diagnostics)
        message = diagnostics.status[0].message
        if message != self._last_message:
            self._last_message = message
            self._logger.info(message)

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


class ManagedPhysicsMapperNode(MapperNodeBase, LifecycleNode):
    """The same node as a managed (lifecycle) node: it starts unconfigured and follows its transitions.

    ``configure`` reads the parameters and the scene and creates the subscriptions and (inactive)
    publishers; ``activate`` starts ticking and publishing; ``deactivate`` stops both (inputs are
    still collected); ``cleanup`` destroys what ``configure`` made; ``shutdown`` stops everything.
    A scene or parameters that cannot be used fail ``configure`` with the reason in the log, and
    the node stays unconfigured.
    """

    def _map_publisher(self, msg_type: type, topic: str, qos: QoSProfile = MAP_QOS) -> Publisher:
        publisher = self.create_lifecycle_publisher(msg_type, topic, qos)  # type: ignore[no-untyped-call]
        self._entities.append(publisher)
        return cast(Publisher, publisher)

    def _destroy_publisher(self, publisher: Publisher) -> None:
        self.destroy_lifecycle_publisher(cast(LifecyclePublisher, publisher))

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            self.configure()
        except (SceneError, InputError, ParameterException) as error:
            self._logger.error(f"configure failed: {error}")
            self.release()
            return TransitionCallbackReturn.FAILURE
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.start_ticking()
        return super().on_activate(state)  # activates the publishers

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.stop_ticking()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.release()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.release()
        return TransitionCallbackReturn.SUCCESS


def main(args: Sequence[str] | None = None, *, managed: bool = False) -> int:
    """Run the node (``managed``: the lifecycle node) until SIGINT or SIGTERM (exit 0); bad scene or
    parameters: one error line, exit 2."""
    stop = SignalStop()
    stop.install()  # rclpy installs none: see physics_mapper.ros.spinning
    try:
        rclpy.init(args=list(sys.argv if args is None else args), signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as error:  # rclpy's RCLError: malformed --ros-args, unreadable --params-file
        reason = str(error).split(" Error: ")[0].removeprefix("failed to initialize rcl: ")
        print(f"physics_mapper node: error: {reason}", file=sys.stderr)
        return EXIT_BAD_INPUT
    node = None
    try:
        if stop.requested:  # a signal during start-up: no node to start
            return 0
        node = ManagedPhysicsMapperNode(stop=stop) if managed else PhysicsMapperNode(stop=stop)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop.requested:
            executor.spin_once(timeout_sec=STOP_POLL)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (SceneError, InputError, ParameterException) as error:
        print(f"physics_mapper node: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    finally:
        if node is not None:
            node.destroy_node()
        shutdown_ros()
    return 0
