"""One map-building tick, ROS-free: snapshot the inputs, resume or restart the search, time it.

The node (``physics_mapper.ros.node``) owns a :class:`Mapper`, feeds its :attr:`Mapper.inputs`
from subscriptions (detections through :meth:`Mapper.add_detections`, which associates them to
instances, :mod:`~physics_mapper.mapping.association`) and calls :meth:`Mapper.tick` from its
timer; everything it publishes comes from the returned :class:`TickReport`. Which objects the
search may leave out, and how likely, is :mod:`~physics_mapper.mapping.existence`: an object
that is silent or was never seen never stops the map of the others.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from physics_mapper.mapping.association import AssociationSettings, InstanceTracks, Tracking
from physics_mapper.mapping.detections import DetectionInputs, detection_inputs
from physics_mapper.mapping.existence import (
    MapMemory,
    absent_objects,
    learn_from_result,
    searched_hypotheses,
)
from physics_mapper.mapping.frames import Transform
from physics_mapper.mapping.inputs import InputSettings, InputSnapshot, InputTracker
from physics_mapper.mapping.previous_map import PreviousMapCheck, result_hypotheses, search_with_previous_map
from physics_mapper.mapping.seen_too_deep import moved_out_of_static
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Scene, SearchParams, search_params_problem
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.refine import load_solver
from physics_mapper.physics.world import PhysicsEngineError
from physics_mapper.search.best_first import Search
from physics_mapper.search.results import Code, SearchResult

#: Seconds a tick's search may run past its deadline: the search looks at the clock every
#: few simulation steps and then assembles its result. The overrun measured here is about a
#: millisecond (BENCHMARKS.md, "Deadline slack"); the bound leaves room for a busy machine.
DEADLINE_SLACK = 0.05


#: Ticks per second unless the node's ``rate_hz`` parameter says otherwise.
DEFAULT_RATE_HZ = 2.0


@dataclass(frozen=True)
class MapperSettings:
    """Everything a tick depends on; the node builds it from its parameters at each tick.

    rate_hz: ticks per second; ``search.deadline`` (seconds) must be shorter than 1 / rate_hz.
    association: how detections are matched to instances (its ``max_age`` is ``inputs.max_age``).
    """

    search: SearchParams
    inputs: InputSettings
    rate_hz: float = DEFAULT_RATE_HZ
    association: AssociationSettings = field(default_factory=AssociationSettings)


def mapper_settings_problem(settings: MapperSettings) -> str | None:
    """Say which setting is out of range, or return None."""
    problem = search_params_problem(settings.search)
    if problem is not None:
        return problem
    if settings.rate_hz <= 0.0:
        return f"rate_hz must be positive, got {settings.rate_hz:g}"
    period = 1.0 / settings.rate_hz
    if settings.search.deadline >= period:
        return f"deadline {settings.search.deadline:g} s must be shorter than the tick period 1/rate_hz = {period:g} s"
    if settings.inputs.max_age <= 0.0:
        return f"max_age must be positive, got {settings.inputs.max_age:g}"
    if settings.inputs.max_hypotheses < 1:
        return f"max_hypotheses_per_object must be at least 1, got {settings.inputs.max_hypotheses}"
    return None


@dataclass(frozen=True)
class TickReport:
    """What one tick saw and found.

    ``result`` is None while no object has ever had usable hypotheses. ``hypotheses`` are those
    searched, in object order (with *absent* where an object may be left out); ``absent`` names the
    objects the map leaves out (every object without a result). ``tracking`` says what the
    association of instances did since the previous tick. ``search_time`` is the
    wall-clock seconds this tick spent in the search (at most ``deadline`` plus a small slack).
    ``resumed`` says the tick continued the previous search (same inputs and settings); with the
    grouped strategy, ``result.groups`` say which groups were kept when some were restarted.
    ``settling_in_progress`` is the configuration (of group ``settling_group``'s objects, for a
    grouped search) whose settling the deadline cut short (a settling longer than one tick's
    search): the next tick continues it. ``engine_fault`` says how the physics engine failed this
    tick (``result`` is None then); the next tick searches again in a rebuilt world. ``moved_out`` counts the
    instances' poses moved out of a static body before the search (:mod:`~physics_mapper.mapping.seen_too_deep`).
    """

    snapshot: InputSnapshot
    result: SearchResult | None
    search_time: float
    resumed: bool
    settings: MapperSettings
    settling_in_progress: Code | None = None
    engine_fault: str | None = None
    settling_group: int | None = None
    hypotheses: tuple[RankedHypotheses, ...] = ()
    absent: tuple[str, ...] = ()
    tracking: Tracking = field(default_factory=Tracking)
    moved_out: int = 0

    @property
    def present(self) -> tuple[int, ...]:
        """Scene indices of the objects the map holds, in scene order."""
        return tuple(i for i, name in enumerate(self.snapshot.names) if name not in self.absent)


class Mapper:
    """A scene's physics world, its inputs and the search in progress.

    A world whose engine fails (:data:`~physics_mapper.physics.world.PhysicsEngineError`) is
    discarded with the search that used it; the next tick builds a new one and searches again.
    """

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.inputs = InputTracker(scene.object_names)
        #: The instances' tracks (:mod:`~physics_mapper.mapping.association`), fed by :meth:`add_detections`.
        self.tracks = InstanceTracks(scene)
        self.memory = MapMemory()
        self._tracks_lock = threading.Lock()  # subscriptions associate while a tick expires tracks
        self._births: list[str] = []
        self._ends: list[str] = []
        self._checker: PhysicsChecker | None = PhysicsChecker(scene)
        self._search: Search | None = None
        self._previous_map: PreviousMapCheck | None = None  # the last tick's check of the previous map

    def add_detections(
        self,
        message: Any,
        received: float,
        transforms: Mapping[str, Transform] | None = None,
        unresolved: Mapping[str, str] | None = None,
    ) -> DetectionInputs:
        """A ``Detection3DArray`` received at ``received`` (node clock, s), a message or its arrays as the node
        reads them (:class:`~physics_mapper.mapping.detection_data.DetectionArrayData`): its detections
        associated to instances and given to :attr:`inputs`; instances whose tracks ended forget their inputs.
        ``transforms`` and ``unresolved``: its sensor frames into the scene's (:func:`detection_inputs`)."""
        with self._tracks_lock:
            detected = detection_inputs(
                message,
                self.scene,
                received=received,
                tracks=self.tracks,
                transforms=transforms,
                unresolved=unresolved,
            )
            if detected.association is not None:  # first: an instance may end and start again in one array
                self._births += detected.association.born
                self._ended(detected.association.ended)
            for name, poses in detected.objects.items():
                self.inputs.add_poses(name, poses)
        return detected

    def _ended(self, names: tuple[str, ...]) -> None:
        for name in names:
            self.inputs.forget(name)
        self._ends += names

    @property
    def checker(self) -> PhysicsChecker:
        """The scene's physics world, built anew if a fault discarded the last one."""
        if self._checker is None:
            self._checker = PhysicsChecker(self.scene)
        return self._checker

    def _discard_world(self) -> None:
        """Forget a failed world and the search that used it."""
        checker, self._checker, self._search = self._checker, None, None
        if checker is not None:
            checker.close()

    def close(self) -> None:
        self._discard_world()

    def tick(self, now: float, settings: MapperSettings) -> TickReport:
        """Snapshot the inputs at ``now`` (seconds) and search until ``settings.search.deadline``."""
        with self._tracks_lock:
            self.tracks.settings = replace(settings.association, max_age=settings.inputs.max_age)
            self._ended(self.tracks.expire(now))
            births, ends = tuple(self._births), tuple(self._ends)
            self._births, self._ends = [], []
            instances = tuple(self.tracks.instances_per_class().items())
            tracking = Tracking(births, ends, instances, self.tracks.outside, self.tracks.doubles)
            snapshot = self.inputs.snapshot(now, settings.inputs)
            hypotheses = searched_hypotheses(snapshot, self.memory, self.tracks, now, settings.inputs.max_age)
        names = self.scene.object_names
        waiting = len(snapshot.missing) == len(names) and not self.memory.poses
        if waiting:
            return TickReport(snapshot, None, 0.0, False, settings, absent=names, tracking=tracking)
        moved_out = 0
        try:
            threshold = settings.search.penetration_threshold
            hypotheses, moved_out = moved_out_of_static(self.checker, hypotheses, threshold)
            report = self._search_tick(snapshot, hypotheses, settings)
            hypotheses = report.hypotheses
        except PhysicsEngineError as error:
            self._discard_world()
            fault = f"physics engine failed: {error}; the world is rebuilt and the search starts again at the next tick"
            report = TickReport(snapshot, None, 0.0, False, settings, engine_fault=fault)
        absent = absent_objects(names, hypotheses, report.result)
        with self._tracks_lock:
            self._ended(learn_from_result(self.memory, self.tracks, names, hypotheses, report.result, now))
        return replace(report, hypotheses=hypotheses, absent=absent, tracking=tracking, moved_out=moved_out)

    def _search_tick(
        self, snapshot: InputSnapshot, hypotheses: tuple[RankedHypotheses, ...], settings: MapperSettings
    ) -> TickReport:
        """Resume the search in progress if inputs and settings allow (a grouped search: every group
        whose objects' hypotheses did not change), else start a new one; run it to the deadline.

        Grouping and carrying over the previous search's groups count as search time. The report's hypotheses
        are those its result's code ranks: ``hypotheses``, or where the previous map's check made the map, the
        check's (the first tick's check adds *held* poses where the tick's refined map rests the instances).
        """
        if settings.search.fallback == "refine":
            load_solver()  # the first time: 0.2 s outside the deadline (not imported before, for memory)
        started = time.monotonic()
        previous = self._search
        search, result, self._previous_map = search_with_previous_map(
            self.checker,
            hypotheses,
            settings.search,
            self.memory.settled,
            settings.search.deadline,
            previous,
            self._previous_map,
            refined=self.memory.refined,
        )
        self._search = search
        elapsed = time.monotonic() - started
        return TickReport(
            snapshot,
            result,
            elapsed,
            search is previous,
            settings,
            search.settling_in_progress,
            settling_group=search.settling_group,
            hypotheses=result_hypotheses(hypotheses, result, self._previous_map),
        )
