"""The ``physics_mapper`` ROS 2 node (SPEC section 4): weighted pose hypotheses in, a physically valid map out.

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
  pose (:mod:`msg_adapters.pose_array_cdr`); only the hypotheses kept are converted.
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
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, PoseStamped
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rcl_interfaces.srv import SetParameters
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.exceptions import InvalidTopicNameException, ParameterException, ParameterNotDeclaredException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions
from rclpy.timer import Timer
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import MarkerArray

from msg_adapters.diagnostics import diagnostics_msg
from msg_adapters.hypotheses import received_pose_array, received_weights
from msg_adapters.results import configuration_msgs, markers_msg, object_pose_msgs, static_markers_msg
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
from physics_mapper.model.resources import ResourceError, resolve_resource
from physics_mapper.model.scene import (
    BOUNDS,
    FALLBACKS,
    SEARCH_LIMITS,
    SETTLE_EXITS,
    STRATEGIES,
    Bound,
    Fallback,
    SearchParams,
    SettleExit,
    Strategy,
)
from physics_mapper.model.scene_files import SceneError, load_scene
from physics_mapper.ros.qos import DIAGNOSTICS_QOS, MAP_QOS, input_qos
from physics_mapper.ros.spinning import STOP_POLL, SignalStop, shutdown_ros
from physics_mapper.search.branch_and_bound import SearchResult

#: Seconds between two /diagnostics messages unless ``diagnostics_period`` says otherwise (the ~1 Hz convention).
DEFAULT_DIAGNOSTICS_PERIOD = 1.0


@dataclass(frozen=True)
class ParameterSpec:
    """A node parameter: ``default`` None means the scene file's ``search:`` value; ``limits`` inclusive.

    The search parameters' limits are the scene model's (:data:`~physics_mapper.scene.SEARCH_LIMITS`).
    A ``read_only`` parameter is read once, at start-up.
    """

    name: str
    description: str
    default: float | int | bool | str | None = None
    limits: tuple[float, float] | None = None
    read_only: bool = False


#: Every parameter but ``scene_file``, in the order ``ros2 param list`` shows them. Add new ones here;
#: :meth:`PhysicsMapperNode.parameter_values` reads them all, :meth:`PhysicsMapperNode.settings` uses them.
PARAMETERS = (
    ParameterSpec(
        "rate_hz", "ticks per second; each tick snapshots the inputs and searches", DEFAULT_RATE_HZ, (0.01, 100.0)
    ),
    ParameterSpec("deadline", "wall-clock seconds of search per tick; must be < 1/rate_hz", None),
    ParameterSpec("probability_threshold", "T: nodes with p(C) < T are checked but not expanded"),
    ParameterSpec("penetration_threshold", "deepest allowed overlap between two bodies, metres"),
    ParameterSpec("jitter_threshold", "largest per-object jitter J_i of a stable object (m + weighted rad)"),
    ParameterSpec("angular_weight", "metres per radian of rotation in the jitter J_i"),
    ParameterSpec("settle_time", "simulated seconds under gravity for the stability test"),
    ParameterSpec("fallback", f"when no configuration is valid: {', '.join(FALLBACKS)}", None),
    ParameterSpec("refine_max_speed", "fallback refine: fastest an object moves while refined, m/s"),
    ParameterSpec("refine_mean_radius", "fallback refine: start at the weighted mean of hypotheses this near, m"),
    ParameterSpec("strategy", f"{' or '.join(STRATEGIES)}: per group conflict-directed or the paper's, or joint"),
    ParameterSpec("bound", f"{' or '.join(BOUNDS)}: T bounds p(C) / p(first valid), / p(group root), or p(C)"),
    ParameterSpec("settle_exit", f"{' or '.join(SETTLE_EXITS)}: settlings may stop at rest or once unstable"),
    ParameterSpec("interaction_margin", "metres between two hypotheses' bodies below which objects share a group"),
    ParameterSpec("queue_limit", "nodes the search's queues hold at most (each group an equal share)"),
    ParameterSpec("trace_limit", "trace entries the search keeps at most"),
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


def deadline_first(current_deadline: float, parameters: Sequence[Parameter]) -> list[Parameter]:
    """``parameters`` in an order in which setting them one by one keeps ``deadline < 1/rate_hz`` at every step.

    If the end state satisfies it, so does every step: a deadline that shrinks is set before
    ``rate_hz``, one that grows after it (the other parameters keep their order).
    """
    new_deadline = next((p.value for p in parameters if p.name == "deadline"), None)
    shrinks = isinstance(new_deadline, float) and new_deadline <= current_deadline
    first = "deadline" if shrinks else "rate_hz"
    return sorted(parameters, key=lambda p: p.name != first)


class PhysicsMapperNode(Node):
    """Subscribes to every scene object's hypotheses and publishes the best physically valid map.

    ``stop``: the process's signal handling; a signal interrupts the tick's search at once.
    """

    def __init__(self, *, stop: SignalStop | None = None, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._stop = stop or SignalStop()
        self._logger: Any = self.get_logger()  # type: ignore[no-untyped-call]  # rclpy 7 leaves it unannotated
        try:
            self._start()
        except BaseException:
            self.destroy_node()  # also when a signal interrupts the start-up: no handle outlives the node
            raise

    def _start(self) -> None:
        scene_file = self.declare_parameter(
            "scene_file",
            "",
            ParameterDescriptor(description="scene YAML (path or package://pkg/path); read once", read_only=True),
        ).value
        scene_path = resolve_scene_path(str(scene_file))
        scene = load_scene(scene_path)
        for spec in PARAMETERS:
            default = getattr(scene.search, spec.name) if spec.default is None else spec.default
            self.declare_parameter(spec.name, default, _descriptor(spec, default))
        values = self.parameter_values()
        problem = self._problem(values)
        if problem is not None:
            raise InputError(f"invalid parameters: {problem}")
        self._warn_about_unknown_parameters()
        self.mapper = Mapper(scene)
        self._report: TickReport | None = None  # the last tick's
        self._fault: TickReport | None = None  # the first tick of this diagnostics period that the engine failed
        self._ticks = TickStatistics()
        self._inputs_group = MutuallyExclusiveCallbackGroup()  # type: ignore[no-untyped-call]
        reliability = cast(InputReliability, values["input_reliability"])
        for name in scene.object_names:
            self._subscribe(name, reliability)
        self._configuration_pub = self.create_publisher(PoseArray, CONFIGURATION_TOPIC, MAP_QOS)
        self._settled_pub = self.create_publisher(PoseArray, SETTLED_TOPIC, MAP_QOS)
        self._markers_pub = self.create_publisher(MarkerArray, MARKERS_TOPIC, MAP_QOS)
        # Latched: RViz shows the fixed bodies before the first map (each map repeats them).
        self._markers_pub.publish(static_markers_msg(scene, stamp_ns=self._now_ns()))
        self._object_pubs: list[tuple[Publisher, Publisher]] = [
            (
                self.create_publisher(PoseStamped, object_pose_topic(name), MAP_QOS),
                self.create_publisher(PoseStamped, object_settled_pose_topic(name), MAP_QOS),
            )
            for name in scene.object_names
        ]
        self._published_objects: tuple[int, SearchResult] | None = None
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self._order_set_parameters_requests()
        self._tick_timer = self.create_timer(1.0 / float(values["rate_hz"]), self._tick)
        self._diagnostics_timer = self.create_timer(float(values["diagnostics_period"]), self._publish_diagnostics)
        self._last_message = ""
        self._logger.info(
            f"scene {scene_path}: objects {', '.join(scene.object_names)} in frame {scene.frame_id!r}; "
            f"listening on {self.get_namespace().rstrip('/')}/hypotheses/<object>[/weights] ({reliability})"
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
        """The mapper's settings from parameter values (:meth:`parameter_values`)."""
        search = SearchParams(
            probability_threshold=float(values["probability_threshold"]),
            penetration_threshold=float(values["penetration_threshold"]),
            jitter_threshold=float(values["jitter_threshold"]),
            angular_weight=float(values["angular_weight"]),
            settle_time=float(values["settle_time"]),
            deadline=float(values["deadline"]),
            fallback=cast(Fallback, str(values["fallback"])),
            refine_max_speed=float(values["refine_max_speed"]),
            refine_mean_radius=float(values["refine_mean_radius"]),
            strategy=cast(Strategy, str(values["strategy"])),
            bound=cast(Bound, str(values["bound"])),
            settle_exit=cast(SettleExit, str(values["settle_exit"])),
            interaction_margin=float(values["interaction_margin"]),
            queue_limit=int(values["queue_limit"]),
            trace_limit=int(values["trace_limit"]),
        )
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
        return mapper_settings_problem(self.settings(values))

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """Refuse a change that leaves the combination of values invalid; accepted ones apply at the next tick."""
        problem = self._problem(self.parameter_values({p.name: p.value for p in parameters}))
        return SetParametersResult(successful=problem is None, reason=problem or "")

    def _on_parameters_set(self, parameters: list[Parameter]) -> None:
        """A new tick rate or diagnostics period applies at once: its timer is re-armed, not left to run out."""
        for parameter in parameters:
            if parameter.name == "rate_hz":
                self._rearm(self._tick_timer, 1.0 / float(parameter.value))
            elif parameter.name == "diagnostics_period":
                self._rearm(self._diagnostics_timer, float(parameter.value))

    @staticmethod
    def _rearm(timer: Timer, period: float) -> None:
        timer.timer_period_ns = round(period * NANOSECONDS_PER_SECOND)
        timer.reset()  # type: ignore[no-untyped-call]

    def _order_set_parameters_requests(self) -> None:
        """SetParameters (``ros2 param set``, ``ros2 param load``) sets a request's parameters one at a time.

        rclpy would set them in the request's order, so raising ``rate_hz`` and lowering
        ``deadline`` together succeeded or failed with their order. The request is set in
        :func:`deadline_first` order instead: it succeeds whenever its end state is valid.
        SetParametersAtomically is judged as a whole by :meth:`_on_set_parameters`.
        """
        service = next(s for s in self.services if s.srv_name.endswith("/set_parameters"))

        def set_parameters(request: SetParameters.Request, response: SetParameters.Response) -> Any:
            parameters = [Parameter.from_parameter_msg(p) for p in request.parameters]  # type: ignore[no-untyped-call]
            results: dict[int, SetParametersResult] = {}
            for parameter in deadline_first(float(self.get_parameter("deadline").value), parameters):
                try:
                    result = self.set_parameters_atomically([parameter])
                except ParameterNotDeclaredException as error:
                    result = SetParametersResult(successful=False, reason=str(error))
                results[id(parameter)] = result
            response.results = [results[id(p)] for p in parameters]
            return response

        service.callback = set_parameters

    def _warn_about_unknown_parameters(self) -> None:
        """Name the ``--params-file`` and ``-p`` values meant for this node that it has no parameter for (ignored)."""
        # rclpy keeps the overrides rcl matched to this node (params files and -p) in a private attribute only.
        overrides: Mapping[str, Any] = getattr(self, "_parameter_overrides", {})
        unknown = sorted(name for name in overrides if not self.has_parameter(name))
        if unknown:
            known = ", ".join(["scene_file", *(spec.name for spec in PARAMETERS)])
            self._logger.warning(
                f"unknown parameters ignored (from --params-file or -p): {', '.join(unknown)}; "
                f"this node's parameters are: {known}"
            )

    # --- inputs ---------------------------------------------------------------------------------

    def _subscribe(self, name: str, reliability: InputReliability) -> None:
        scene = self.mapper.scene
        frame, workspace = scene.frame_id, scene.workspace
        inputs = self.mapper.inputs

        def on_poses(raw: bytes, info: Mapping[str, Any]) -> None:
            received = self._received(info)
            inputs.add_poses(
                name, received_pose_array(raw, expected_frame=frame, workspace=workspace, received=received)
            )

        def on_weights(msg: Float64MultiArray, info: Mapping[str, Any]) -> None:
            inputs.add_weights(name, received_weights(msg, received=self._received(info)))

        try:
            self._input_subscription(PoseArray, poses_topic(name), on_poses, name, "poses", reliability, raw=True)
            self._input_subscription(Float64MultiArray, weights_topic(name), on_weights, name, "weights", reliability)
        except InvalidTopicNameException:
            raise InputError(f"object name {name!r} cannot be part of a ROS topic name") from None

    def _input_subscription(
        self,
        msg_type: type,
        topic: str,
        callback: Callable[[Any, Mapping[str, Any]], None],
        name: str,
        kind: MessageKind,
        reliability: InputReliability,
        *,
        raw: bool = False,
    ) -> None:
        """A hypothesis subscription: its callback gets the message info, lost messages are counted."""
        self.create_subscription(
            msg_type,
            topic,
            cast(Callable[[Any], None], callback),  # rclpy passes two-parameter callbacks the message info
            input_qos(reliability),
            callback_group=self._inputs_group,
            event_callbacks=SubscriptionEventCallbacks(message_lost=self._on_lost(name, kind)),
            raw=raw,
        )

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
        """Outputs carry the newest input stamp used (SPEC section 4)."""
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
        self._diagnostics_pub.publish(diagnostics)
        message = diagnostics.status[0].message
        if message != self._last_message:
            self._last_message = message
            self._logger.info(message)

    def destroy_node(self) -> None:
        mapper = getattr(self, "mapper", None)
        if mapper is not None:
            mapper.close()
        super().destroy_node()  # type: ignore[no-untyped-call]


def main(args: Sequence[str] | None = None) -> int:
    """Run the node until SIGINT or SIGTERM (exit 0); bad scene or parameters: one error line, exit 2."""
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
        node = PhysicsMapperNode(stop=stop)
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
