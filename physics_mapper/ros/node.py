"""The ``physics_mapper`` ROS 2 node (SPEC section 4): weighted pose hypotheses in, a physically valid map out.

A thin shell: subscriptions hand messages to ``msg_adapters`` and the ROS-free
:class:`~physics_mapper.mapper.Mapper`; a timer at ``rate_hz`` runs one tick and
publishes what it found. Run it with ``ros2 run physics_mapper node --ros-args -p
scene_file:=<path>`` or, without a ROS installation, ``physics-mapper node --ros-args ...``.
Topic names are in :mod:`physics_mapper.mapping.topics`, QoS in :mod:`physics_mapper.ros.qos`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidTopicNameException, ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import MarkerArray

from msg_adapters.diagnostics import diagnostics_msg
from msg_adapters.hypotheses import received_poses, received_weights
from msg_adapters.results import configuration_msgs, markers_msg, static_markers_msg
from physics_mapper.core.errors import EXIT_BAD_INPUT, InputError
from physics_mapper.core.resources import ResourceError, resolve_resource
from physics_mapper.core.scene import FALLBACKS, SEARCH_LIMITS, Fallback, SearchParams
from physics_mapper.core.scene_files import SceneError, load_scene
from physics_mapper.mapping.inputs import InputSettings
from physics_mapper.mapping.mapper import DEFAULT_RATE_HZ, Mapper, MapperSettings, TickReport, mapper_settings_problem
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.mapping.topics import (
    CONFIGURATION_TOPIC,
    DIAGNOSTICS_TOPIC,
    MARKERS_TOPIC,
    NODE_NAME,
    SETTLED_TOPIC,
    poses_topic,
    weights_topic,
)
from physics_mapper.ros.qos import DIAGNOSTICS_QOS, INPUT_QOS, MAP_QOS
from physics_mapper.ros.spinning import shutdown_ros


@dataclass(frozen=True)
class ParameterSpec:
    """A node parameter: ``default`` None means the scene file's ``search:`` value; ``limits`` inclusive.

    The search parameters' limits are the scene model's (:data:`~physics_mapper.scene.SEARCH_LIMITS`).
    """

    name: str
    description: str
    default: float | int | bool | str | None = None
    limits: tuple[float, float] | None = None


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
    ParameterSpec("max_hypotheses_per_object", "hypotheses kept per object (the heaviest)", 100, (1, 100000)),
    ParameterSpec("max_age", "seconds after which received hypotheses are stale", 10.0, (0.01, 86400.0)),
    ParameterSpec("require_weights", "refuse PoseArrays without a weights message instead of uniform weights", False),
)


def _descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    descriptor = ParameterDescriptor(description=spec.description)
    limits = SEARCH_LIMITS.get(spec.name, spec.limits)
    if limits is None:
        return descriptor
    low, high = limits
    if isinstance(spec.default, int) and not isinstance(spec.default, bool):
        descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    else:
        descriptor.floating_point_range = [FloatingPointRange(from_value=low, to_value=high, step=0.0)]
    return descriptor


def resolve_scene_path(text: str) -> Path:
    """A scene file path, or a ``package://<pkg>/<path>`` URL (:mod:`physics_mapper.core.resources`).

    Without an ament index (pip wheels only), ``package://physics_mapper/`` is this installation's
    shipped files (:func:`~physics_mapper.core.shipped.share_directory`: the same ``config/`` tree).
    """
    if not text:
        raise InputError("parameter scene_file is required, e.g. --ros-args -p scene_file:=config/scenes/pyramid.yaml")
    try:
        return resolve_resource(text, None)
    except ResourceError as error:
        raise InputError(f"scene_file {error}") from None


class PhysicsMapperNode(Node):
    """Subscribes to every scene object's hypotheses and publishes the best physically valid map."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        scene_file = self.declare_parameter(
            "scene_file",
            "",
            ParameterDescriptor(description="scene YAML (path or package://pkg/path); read once", read_only=True),
        ).value
        scene_path = resolve_scene_path(str(scene_file))
        scene = load_scene(scene_path)
        for spec in PARAMETERS:
            default = getattr(scene.search, spec.name) if spec.default is None else spec.default
            self.declare_parameter(spec.name, default, _descriptor(spec))
        problem = mapper_settings_problem(self._settings({}))
        if problem is not None:
            raise InputError(f"invalid parameters: {problem}")
        self.mapper = Mapper(scene)
        for name in scene.object_names:
            self._subscribe(name)
        self._configuration_pub = self.create_publisher(PoseArray, CONFIGURATION_TOPIC, MAP_QOS)
        self._settled_pub = self.create_publisher(PoseArray, SETTLED_TOPIC, MAP_QOS)
        self._markers_pub = self.create_publisher(MarkerArray, MARKERS_TOPIC, MAP_QOS)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        # Latched: RViz shows the fixed bodies before the first map (each map repeats them).
        self._markers_pub.publish(static_markers_msg(scene, stamp_ns=self._now_ns()))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._rate_hz = float(self.get_parameter("rate_hz").value)
        self._timer = self.create_timer(1.0 / self._rate_hz, self._tick)
        self._last_message = ""
        self._logger: Any = self.get_logger()  # type: ignore[no-untyped-call]  # rclpy 7 leaves it unannotated
        self._logger.info(
            f"scene {scene_path}: objects {', '.join(scene.object_names)} in frame {scene.frame_id!r}; "
            f"listening on {self.get_namespace().rstrip('/')}/hypotheses/<object>[/weights]"
        )

    def _subscribe(self, name: str) -> None:
        scene = self.mapper.scene
        frame, workspace = scene.frame_id, scene.workspace
        inputs = self.mapper.inputs
        try:
            self.create_subscription(
                PoseArray,
                poses_topic(name),
                lambda msg: inputs.add_poses(
                    name, received_poses(msg, expected_frame=frame, workspace=workspace, received=self._now())
                ),
                INPUT_QOS,
            )
            self.create_subscription(
                Float64MultiArray,
                weights_topic(name),
                lambda msg: inputs.add_weights(name, received_weights(msg, received=self._now())),
                INPUT_QOS,
            )
        except InvalidTopicNameException:
            raise InputError(f"object name {name!r} cannot be part of a ROS topic name") from None

    def _now_ns(self) -> int:
        """The node clock, integer nanoseconds (exact, for stamps)."""
        return self.get_clock().now().nanoseconds

    def _now(self) -> float:
        """The node clock, seconds (receive times and ages)."""
        return self._now_ns() / NANOSECONDS_PER_SECOND

    def _settings(self, changes: dict[str, Any]) -> MapperSettings:
        """The settings from the current parameters, with ``changes`` (name -> value) applied."""

        def value(name: str) -> Any:
            return changes[name] if name in changes else self.get_parameter(name).value

        search = SearchParams(
            probability_threshold=float(value("probability_threshold")),
            penetration_threshold=float(value("penetration_threshold")),
            jitter_threshold=float(value("jitter_threshold")),
            angular_weight=float(value("angular_weight")),
            settle_time=float(value("settle_time")),
            deadline=float(value("deadline")),
            fallback=cast(Fallback, str(value("fallback"))),
            refine_max_speed=float(value("refine_max_speed")),
            refine_mean_radius=float(value("refine_mean_radius")),
        )
        inputs = InputSettings(
            max_age=float(value("max_age")),
            max_hypotheses=int(value("max_hypotheses_per_object")),
            require_weights=bool(value("require_weights")),
        )
        return MapperSettings(search, inputs, float(value("rate_hz")))

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """Refuse a change that leaves the settings invalid; accepted ones apply at the next tick."""
        problem = mapper_settings_problem(self._settings({p.name: p.value for p in parameters}))
        return SetParametersResult(successful=problem is None, reason=problem or "")

    def _tick(self) -> None:
        settings = self._settings({})
        if settings.rate_hz != self._rate_hz:
            self._rate_hz = settings.rate_hz
            self._timer.timer_period_ns = round(1e9 / settings.rate_hz)
        now_ns = self._now_ns()
        report = self.mapper.tick(now_ns / NANOSECONDS_PER_SECOND, settings)
        self._publish(report, now_ns)

    def _publish(self, report: TickReport, now_ns: int) -> None:
        """Outputs carry the newest input stamp used (SPEC section 4); diagnostics the tick's time."""
        result, scene = report.result, self.mapper.scene
        stamp_ns = report.snapshot.stamp_ns
        if result is not None and stamp_ns is not None:
            configurations = configuration_msgs(result, frame_id=scene.frame_id, stamp_ns=stamp_ns)
            if configurations is not None:
                self._configuration_pub.publish(configurations[0])
                self._settled_pub.publish(configurations[1])
                self._markers_pub.publish(markers_msg(result, scene, stamp_ns=stamp_ns))
        diagnostics = diagnostics_msg(
            report, node_name=self.get_name(), hardware_id=self.get_fully_qualified_name(), stamp_ns=now_ns
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
    try:
        rclpy.init(args=list(sys.argv if args is None else args))
    except RuntimeError as error:  # rclpy's RCLError: malformed --ros-args, unreadable --params-file
        reason = str(error).split(" Error: ")[0].removeprefix("failed to initialize rcl: ")
        print(f"physics_mapper node: error: {reason}", file=sys.stderr)
        return EXIT_BAD_INPUT
    node = None
    try:
        node = PhysicsMapperNode()
        rclpy.spin(node)
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
