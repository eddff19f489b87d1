"""The node's parameters: their table, their declaration, their validation into the mapper's settings.

:data:`PARAMETERS` is the one table (``ros2 param list``'s order); :class:`NodeParameters` declares
them on a node (a params file's value wins over the default; the search parameters' defaults are
the scene file's), names the overrides that match none of them, and reads them in one place
(:meth:`NodeParameters.parameter_values`). :func:`settings` turns values into the mapper's
settings and :func:`parameters_problem` judges a combination of values as a whole.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time_source import USE_SIM_TIME_NAME

from physics_mapper.mapping.association import AssociationSettings
from physics_mapper.mapping.inputs import InputSettings
from physics_mapper.mapping.mapper import DEFAULT_RATE_HZ, MapperSettings, mapper_settings_problem
from physics_mapper.mapping.topics import INPUT_RELIABILITIES
from physics_mapper.model.scene import SEARCH_LIMITS, SearchParams, search_parameter_doc
from physics_mapper.model.scene_files import SceneError, search_with_overrides

#: Seconds between two /diagnostics messages unless ``diagnostics_period`` says otherwise (the ~1 Hz convention).
DEFAULT_DIAGNOSTICS_PERIOD = 1.0
#: ``tf_pose``'s values: which of an object's map poses its /tf frame and its ``~/objects`` entry take.
TF_POSES = ("settled", "chosen")


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
SCENE_FILE_DESCRIPTOR = ParameterDescriptor(
    description="scene YAML (path or package://pkg/path); read once", read_only=True
)

#: The search parameters, each a node parameter of the same name.
SEARCH_PARAMETER_NAMES = tuple(f.name for f in fields(SearchParams))

#: Every parameter but ``scene_file``, in the order ``ros2 param list`` shows them. Add new ones here;
#: :meth:`NodeParameters.parameter_values` reads them all, :func:`settings` uses them.
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
        "association_gate",
        "metres beyond which a detection never matches an instance (0: half the largest extent of its shape, "
        "and never beyond where the instance's filter gives a detection a 1 % chance, nor where the bodies "
        "overlap by less than a quarter of the shape)",
        0.0,
        (0.0, 10.0),
    ),
    ParameterSpec(
        "confirm_hits", "detections that confirm an instance's track (before, it may be absent)", 3, (1, 1000)
    ),
    ParameterSpec(
        "tentative_misses",
        "arrays in a row matching a tentative instance's track no detection, after which the track ends",
        2,
        (1, 1000),
    ),
    ParameterSpec(
        "diagnostics_period",
        "seconds between two /diagnostics messages (the map topics follow rate_hz)",
        DEFAULT_DIAGNOSTICS_PERIOD,
        (0.01, 3600.0),
    ),
    ParameterSpec(
        "transform_timeout",
        "seconds an input in a sensor frame waits for its transform into the scene frame (from /tf, /tf_static "
        "or the scene file's frames:) before it is refused",
        0.2,
        (0.0, 10.0),
    ),
    ParameterSpec("publish_tf", "publish each object's map pose on /tf as frame <tf_prefix><object name>", False),
    ParameterSpec("tf_prefix", "prefix of the objects' frame names on /tf", "physics_mapper/"),
    ParameterSpec(
        "tf_pose",
        f"the pose of each object's /tf frame and ~/objects entry: {' or '.join(TF_POSES)} (settled: after "
        "settling, a fallback's corrected estimate; chosen: the chosen hypothesis)",
        "settled",
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


#: Parameters read once, when the node is configured: a change is refused in every state.
READ_ONLY_PARAMETERS = frozenset({"scene_file", *(spec.name for spec in PARAMETERS if spec.read_only)})


def descriptor(spec: ParameterSpec, default: object) -> ParameterDescriptor:
    """The descriptor of ``spec`` declared with ``default``: its description, read-only flag and range."""
    described = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
    limits = SEARCH_LIMITS.get(spec.name, spec.limits)
    if limits is None:
        return described
    low, high = limits
    if isinstance(default, int) and not isinstance(default, bool):
        described.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    else:
        described.floating_point_range = [FloatingPointRange(from_value=low, to_value=high, step=0.0)]
    return described


def settings(values: Mapping[str, Any]) -> MapperSettings:
    """The mapper's settings from parameter values (:meth:`NodeParameters.parameter_values`); raises
    :class:`SceneError` for search parameters a scene file could not hold either."""
    overrides = {name: values[name] for name in SEARCH_PARAMETER_NAMES}
    search = search_with_overrides(SearchParams(), overrides, "parameters", key="")
    inputs = InputSettings(
        max_age=float(values["max_age"]),
        max_hypotheses=int(values["max_hypotheses_per_object"]),
        require_weights=bool(values["require_weights"]),
    )
    association = AssociationSettings(
        gate=float(values["association_gate"]),
        confirm_hits=int(values["confirm_hits"]),
        tentative_misses=int(values["tentative_misses"]),
        max_age=inputs.max_age,
    )
    return MapperSettings(search, inputs, float(values["rate_hz"]), association)


def parameters_problem(values: Mapping[str, Any]) -> str | None:
    """What makes a combination of parameter values invalid, or None."""
    reliability = values["input_reliability"]
    if reliability not in INPUT_RELIABILITIES:
        return f"input_reliability must be one of {', '.join(INPUT_RELIABILITIES)}, got {reliability!r}"
    if values["tf_pose"] not in TF_POSES:
        return f"tf_pose must be one of {', '.join(TF_POSES)}, got {values['tf_pose']!r}"
    try:
        mapper_settings = settings(values)
    except SceneError as error:
        return f"{error.key} {error.problem}" if error.key else error.problem
    return mapper_settings_problem(mapper_settings)


class NodeParameters:
    """The parameters of one node: declared once each, read in one place.

    Every override (params file, ``-p``) is a parameter of the node before :meth:`declare_all`
    (the node declares them automatically), so that the ones it has none for can be named.
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self._declared: set[str] = set()
        self._declaring = False

    def declare(self, name: str, default: object, descriptor: ParameterDescriptor) -> object:
        """Declare a parameter of this node once (a params file's value wins over ``default``); its value.

        A value set before (a SetParameters request to the unconfigured managed node) is kept: rclpy
        would declare the parameter with its command-line override again.
        """
        if name not in self._declared:
            self._declaring = True
            try:
                earlier = self._node.get_parameter(name) if self._node.has_parameter(name) else None
                if earlier is not None:  # declared from an override: declared again, typed
                    self._node.undeclare_parameter(name)
                self._node.declare_parameter(name, default, descriptor)
            finally:
                self._declaring = False
            self._declared.add(name)
            if earlier is not None and earlier.value != self._node.get_parameter(name).value:
                self._node.set_parameters([earlier])
        return self._node.get_parameter(name).value

    def read_only_problem(self, parameters: Sequence[Parameter]) -> str | None:
        """Why a change of a read-only parameter is refused (in every state; None while declaring them)."""
        names = sorted({p.name for p in parameters} & READ_ONLY_PARAMETERS)
        if self._declaring or not names:
            return None
        return (
            f"{', '.join(names)} is read-only: read once, when the node is configured (restart the node to change it)"
        )

    def declare_all(self, scene_search: SearchParams) -> None:
        """Declare every parameter of :data:`PARAMETERS`; the search ones default to the scene file's."""
        for spec in PARAMETERS:
            default = getattr(scene_search, spec.name) if spec.default is None else spec.default
            self.declare(spec.name, default, descriptor(spec, default))

    def unknown_parameters(self) -> list[str]:
        """The overrides meant for this node that name no parameter of it (nor of rclpy)."""
        known = {"scene_file", *(spec.name for spec in PARAMETERS), *RCLPY_PARAMETERS}
        names = self._node.list_parameters([], 0).names
        return sorted(n for n in names if n not in known and not n.startswith(QOS_OVERRIDES_PREFIX))

    def drop_unknown_parameters(self, unknown: Sequence[str]) -> None:
        """Undeclare and name the overrides this node has no parameter for (they are ignored)."""
        for name in unknown:
            self._node.undeclare_parameter(name)
        if unknown:
            known = ", ".join(["scene_file", *(spec.name for spec in PARAMETERS)])
            self._node.get_logger().warning(  # type: ignore[no-untyped-call]  # rclpy 7 leaves it unannotated
                f"unknown parameters ignored (from --params-file or -p): {', '.join(unknown)}; "
                f"this node's parameters are: {known}"
            )

    def parameter_values(self, changes: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Every parameter's value (:data:`PARAMETERS`), with ``changes`` applied: the one place they are read."""
        changes = changes or {}
        return {
            spec.name: changes[spec.name] if spec.name in changes else self._node.get_parameter(spec.name).value
            for spec in PARAMETERS
        }

    def settings(self) -> MapperSettings:
        """The mapper's settings from the parameters' current values."""
        return settings(self.parameter_values())

    def change_problem(self, parameters: Sequence[Parameter]) -> str | None:
        """What would make the combination of values invalid once ``parameters`` are set, or None.

        rclpy sets a SetParameters request's parameters one at a time, in its order, each judged on
        its own: to raise ``rate_hz`` and shorten ``deadline`` together, send the deadline first, or
        both in one SetParametersAtomically request, which is judged as a whole.
        """
        return parameters_problem(self.parameter_values({p.name: p.value for p in parameters}))
