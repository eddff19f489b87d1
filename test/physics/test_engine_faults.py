"""Engine faults: a pybullet world that fails mid-search is rebuilt, and the mapper goes on.

The world is broken the way a crashed or closed physics server breaks it: its client is
disconnected from under the mapper, between two ticks. The node over DDS is tested in
``test_node_reliability.py``.
"""

from __future__ import annotations

from conftest import PROBLEMS
from diagnostic_msgs.msg import DiagnosticStatus

from physics_mapper.mapping.inputs import InputSettings, check_poses, check_weights
from physics_mapper.mapping.mapper import Mapper, MapperSettings
from physics_mapper.model.bullet import pybullet
from physics_mapper.model.scene import SearchParams
from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.diagnostics import diagnostics_msg

#: A tick period of 2 s leaves room for the whole pyramid search (125 configurations) in one tick.
WHOLE = MapperSettings(SearchParams(deadline=1.5), InputSettings(), rate_hz=0.5)
#: One millisecond per tick: the search is still running when the world is broken.
SLICE = MapperSettings(SearchParams(deadline=0.001), InputSettings(), rate_hz=0.5)


PYRAMID = load_problem(PROBLEMS / "pyramid.yaml")


def feed(mapper: Mapper, received: float, *, reverse_weights: bool = False) -> None:
    """The pyramid problem's hypotheses and weights (in reverse order if asked), received at ``received`` s."""
    scene = PYRAMID.scene
    for name, ranked in zip(scene.object_names, PYRAMID.hypotheses, strict=True):
        raw = [(h.pose.position, h.pose.orientation) for h in ranked.hypotheses]
        weights = [h.weight for h in ranked.hypotheses]
        poses = check_poses(
            raw, frame_id="world", expected_frame="world", workspace=scene.workspace, stamp_ns=7, received=received
        )
        mapper.inputs.add_poses(name, poses)
        mapper.inputs.add_weights(name, check_weights(weights[::-1] if reverse_weights else weights, received=received))


def pyramid_mapper() -> Mapper:
    """A mapper on the pyramid scene with the pyramid problem's hypotheses in use."""
    mapper = Mapper(PYRAMID.scene)
    feed(mapper, 0.0)
    return mapper


def break_world(mapper: Mapper) -> None:
    pybullet.disconnect(physicsClientId=mapper.checker.client_id)


def test_a_world_broken_mid_search_is_rebuilt_and_the_search_restarts() -> None:
    mapper = pyramid_mapper()
    try:
        started = mapper.tick(0.1, SLICE)
        assert started.result is not None and not started.result.stats.exhausted
        break_world(mapper)
        broken = mapper.tick(0.2, SLICE)
        rebuilt = mapper.tick(0.3, WHOLE)
    finally:
        mapper.close()
    assert broken.result is None
    assert broken.engine_fault == (
        "physics engine failed: Not connected to physics server.; "
        "the world is rebuilt and the search starts again at the next tick"
    )
    status = diagnostics_msg(broken, node_name="n", hardware_id="/n", stamp_ns=0).status[0]
    assert (status.level, status.message) == (DiagnosticStatus.ERROR, broken.engine_fault)
    assert {kv.key: kv.value for kv in status.values}["search"] == "physics engine failed"
    assert rebuilt.engine_fault is None and not rebuilt.resumed
    assert rebuilt.result is not None and rebuilt.result.stats.exhausted
    assert (rebuilt.result.valid, rebuilt.result.code) == (True, (5, 4, 4))  # the pyramid's solution, C544


def test_a_world_broken_between_searches_is_rebuilt_too() -> None:
    """A search that had finished touches no physics; the fault shows when new hypotheses arrive."""
    mapper = pyramid_mapper()
    try:
        done = mapper.tick(0.1, WHOLE)
        assert done.result is not None and done.result.stats.exhausted
        break_world(mapper)
        unchanged = mapper.tick(0.2, WHOLE)  # resumes the finished search: nothing to simulate
        feed(mapper, 0.25, reverse_weights=True)
        broken = mapper.tick(0.3, WHOLE)
        rebuilt = mapper.tick(0.4, WHOLE)
    finally:
        mapper.close()
    assert unchanged.engine_fault is None and unchanged.result is not None
    assert (unchanged.result.code, unchanged.result.stats.visited) == (done.result.code, done.result.stats.visited)
    assert broken.engine_fault is not None and broken.result is None
    assert rebuilt.engine_fault is None and rebuilt.result is not None and rebuilt.result.stats.exhausted
