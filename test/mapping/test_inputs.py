"""Input bookkeeping without DDS: validation, weights pairing, grace, staleness, refusals, resuming."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import pytest
from conftest import SCENES

from physics_mapper.mapping.inputs import (
    WEIGHTS_GRACE,
    InputSettings,
    InputTracker,
    InUse,
    Level,
    ObjectInputs,
    ReceivedPoses,
    check_poses,
    check_weights,
    rank,
)
from physics_mapper.mapping.mapper import Mapper, MapperSettings, mapper_settings_problem
from physics_mapper.model.scene import SearchParams, Workspace
from physics_mapper.model.scene_files import load_scene

#: A 20 m box about the origin, as a scene's default workspace may be.
WORKSPACE = Workspace((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))
IDENTITY = (0.0, 0.0, 0.0, 1.0)
SETTINGS = InputSettings(max_age=10.0, max_hypotheses=100, require_weights=False)


def poses(xs: Sequence[float], *, received: float, stamp_ns: int = 0, frame: str = "world") -> ReceivedPoses:
    """A PoseArray of unrotated poses at (x, 0, 0.1), stamped ``stamp_ns``, received at ``received`` seconds."""
    raw = [((x, 0.0, 0.1), IDENTITY) for x in xs]
    return check_poses(
        raw, frame_id=frame, expected_frame="world", workspace=WORKSPACE, stamp_ns=stamp_ns, received=received
    )


def xs_in_rank_order(inputs: ObjectInputs, now: float, settings: InputSettings = SETTINGS) -> list[float]:
    status = inputs.status(now, settings)
    assert status.hypotheses is not None, status.message
    return [h.pose.position[0] for h in status.hypotheses.hypotheses]


# --- validation of single messages -------------------------------------------------------------


def test_a_pose_array_in_another_frame_is_refused_as_a_whole() -> None:
    received = poses([0.0], received=1.0, frame="camera")
    assert received.refusal == "frame_id 'camera' is not the scene frame 'world'"


def test_a_pose_array_without_a_frame_is_taken_in_the_scene_frame() -> None:
    received = poses([0.0], received=1.0, frame="")
    assert received.refusal is None and received.frame_assumed
    assert not poses([0.0], received=1.0, frame="world").frame_assumed


def test_a_huge_frame_id_is_quoted_clipped() -> None:
    frame = "camera_" + "x" * 200_000
    refusal = poses([0.0], received=1.0, frame=frame).refusal
    assert refusal is not None and len(refusal) < 200
    assert refusal == f"frame_id {frame[:57] + '... (200007 characters)'!r} is not the scene frame 'world'"


def test_an_empty_pose_array_is_refused() -> None:
    assert (
        check_poses([], frame_id="world", expected_frame="world", workspace=WORKSPACE, stamp_ns=0, received=0).refusal
        == "empty PoseArray"
    )


@pytest.mark.parametrize(
    ("position", "orientation", "problem"),
    [
        ((math.nan, 0.0, 0.1), IDENTITY, "non-finite value (NaN or Inf) in pose"),
        ((0.0, math.inf, 0.1), IDENTITY, "non-finite value (NaN or Inf) in pose"),
        ((0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 0.0), "zero quaternion"),
        ((0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 2.0), "quaternion norm 2 is not 1"),
        (
            (0.0, 0.0, 1e15),
            IDENTITY,
            "(0, 0, 1e+15) m is outside the workspace x [-10, 10], y [-10, 10], z [-10, 10] m",
        ),
        ((4e292, 0.0, 0.1), IDENTITY, "(4e+292, 0, 0.1) m is outside the workspace"),
    ],
)
def test_a_bad_pose_is_dropped_and_the_others_kept(
    position: tuple[float, ...], orientation: tuple[float, ...], problem: str
) -> None:
    raw = [((0.5, 0.0, 0.1), IDENTITY), (position, orientation), ((0.7, 0.0, 0.1), IDENTITY)]
    received = check_poses(raw, frame_id="world", expected_frame="world", workspace=WORKSPACE, stamp_ns=0, received=0.0)
    assert received.refusal is None  # poses are checked when they are adopted
    in_use = rank(received, check_weights([0.2, 0.5, 0.3], received=0.0), max_hypotheses=100)
    assert isinstance(in_use, InUse)
    assert [h.pose.position[0] for h in in_use.hypotheses.hypotheses] == [0.7, 0.5]
    assert [h.weight for h in in_use.hypotheses.hypotheses] == pytest.approx([0.6, 0.4])  # its weight dropped too
    assert len(in_use.notes) == 1 and in_use.notes[0].startswith(f"dropped 1 of 3 poses: poses[1]: {problem}")


def test_a_pose_array_without_any_usable_pose_is_refused() -> None:
    raw = [((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))] * 2
    received = check_poses(raw, frame_id="world", expected_frame="world", workspace=WORKSPACE, stamp_ns=0, received=0.0)
    assert rank(received, None, max_hypotheses=100) == "no usable pose (poses[0]: zero quaternion ...)"
    inputs = ObjectInputs("cube")
    inputs.add_poses(received)
    status = inputs.status(1.0, SETTINGS)
    assert (status.level, status.hypotheses) == (Level.ERROR, None)
    assert status.message == "PoseArray refused: no usable pose (poses[0]: zero quaternion ...)"


def test_only_the_heaviest_poses_are_checked_and_converted() -> None:
    """Adopting a huge array costs what its kept hypotheses cost: bad poses past them are never looked at."""
    count, kept = 10_000, 5
    raw = [((0.001 * i, 0.0, 0.1), IDENTITY) for i in range(count)]
    raw[-1] = ((math.nan, 0.0, 0.1), IDENTITY)  # light, never reached
    raw[3] = ((0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 0.0))  # among the heaviest: dropped and named
    weights = check_weights([float(count - i) for i in range(count)], received=0.0)  # index 0 heaviest
    in_use = rank(
        check_poses(raw, frame_id="world", expected_frame="world", workspace=WORKSPACE, stamp_ns=0, received=0.0),
        weights,
        kept,
    )
    assert isinstance(in_use, InUse)
    assert [h.pose.position[0] for h in in_use.hypotheses.hypotheses] == pytest.approx(
        [0.0, 0.001, 0.002, 0.004, 0.005]
    )
    assert in_use.notes == (
        "dropped 1 of the 6 heaviest of 10000 poses: poses[3]: zero quaternion",
        "kept the 5 heaviest of 10000 hypotheses (max_hypotheses_per_object)",
    )


@pytest.mark.parametrize(
    ("values", "refusal"),
    [
        ([0.5, -0.1], "negative weight"),
        ([0.0, 0.0], "weights sum to zero"),
        ([math.nan, 1.0], "non-finite weight (NaN or Inf)"),
        ([], "empty weights array"),
    ],
)
def test_unusable_weights_are_refused(values: list[float], refusal: str) -> None:
    assert check_weights(values, received=0.0).refusal == refusal


# --- pairing ---------------------------------------------------------------------------------


def test_weights_rank_the_poses_they_are_paired_with() -> None:
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1, 0.2, 0.3], received=1.0))
    inputs.add_weights(check_weights([0.2, 0.5, 0.3], received=1.01))
    status = inputs.status(1.1, SETTINGS)
    assert status.level == Level.OK
    assert status.message == "3 hypotheses, weighted"
    assert xs_in_rank_order(inputs, 1.1) == [0.2, 0.3, 0.1]
    assert status.hypotheses is not None
    assert [h.weight for h in status.hypotheses.hypotheses] == pytest.approx([0.5, 0.3, 0.2])


def test_weights_arriving_before_their_poses_are_paired_too() -> None:
    inputs = ObjectInputs("cube")
    inputs.add_weights(check_weights([0.1, 0.9], received=1.0))
    inputs.add_poses(poses([0.1, 0.2], received=1.01))
    assert xs_in_rank_order(inputs, 1.02) == [0.2, 0.1]


def test_weights_of_another_length_are_never_paired() -> None:
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1, 0.2, 0.3], received=1.0))
    inputs.add_weights(check_weights([0.1, 0.9], received=1.0))
    status = inputs.status(1.0 + WEIGHTS_GRACE, SETTINGS)
    assert status.level == Level.WARN
    assert "no weights message of length 3 (weights received have length 2)" in status.message
    assert "uniform weights" in status.message
    assert xs_in_rank_order(inputs, 1.0 + WEIGHTS_GRACE) == [0.1, 0.2, 0.3]  # published order ranks them


def test_a_weights_message_belongs_to_the_pose_array_closest_in_time() -> None:
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1, 0.2], received=1.0))
    inputs.add_weights(check_weights([0.1, 0.9], received=1.01))
    assert xs_in_rank_order(inputs, 1.1) == [0.2, 0.1]
    # A new PoseArray of the same length: the old weights are closer to the old poses, so the
    # new poses wait for their own weights and the old pair stays in use meanwhile.
    inputs.add_poses(poses([0.3, 0.4], received=2.0))
    status = inputs.status(2.05, SETTINGS)
    assert status.message.startswith("newest PoseArray is waiting for its weights message")
    assert xs_in_rank_order(inputs, 2.05) == [0.2, 0.1]
    inputs.add_weights(check_weights([0.8, 0.2], received=2.02))
    assert xs_in_rank_order(inputs, 2.1) == [0.3, 0.4]


def test_weights_farther_than_max_age_are_not_paired() -> None:
    settings = InputSettings(max_age=1.0)
    inputs = ObjectInputs("cube")
    inputs.add_weights(check_weights([0.1, 0.9], received=0.0))
    inputs.add_poses(poses([0.1, 0.2], received=1.5))
    status = inputs.status(1.6, settings)
    assert "uniform weights" in status.message
    assert xs_in_rank_order(inputs, 1.6, settings) == [0.1, 0.2]


def test_without_any_weights_message_the_weights_are_uniform_at_once_with_a_warning() -> None:
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.3, 0.1, 0.2], received=1.0))
    status = inputs.status(1.0, SETTINGS)
    assert status.level == Level.WARN
    assert status.message == "no weights message: uniform weights, ranked in published order"
    assert xs_in_rank_order(inputs, 1.0) == [0.3, 0.1, 0.2]


def test_missing_weights_after_the_grace_period_give_uniform_weights() -> None:
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1, 0.2], received=1.0))
    inputs.add_weights(check_weights([0.1, 0.9], received=1.0))
    inputs.add_poses(poses([0.5, 0.6], received=3.0))  # its weights never come
    assert "waiting for its weights" in inputs.status(3.0 + WEIGHTS_GRACE / 2, SETTINGS).message
    status = inputs.status(3.0 + WEIGHTS_GRACE, SETTINGS)
    assert "uniform weights" in status.message
    assert xs_in_rank_order(inputs, 3.0 + WEIGHTS_GRACE) == [0.5, 0.6]


def test_require_weights_refuses_poses_without_weights() -> None:
    settings = InputSettings(require_weights=True)
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1, 0.2], received=1.0))
    status = inputs.status(1.0, settings)
    assert status.level == Level.ERROR
    assert status.hypotheses is None
    assert status.message == "PoseArray refused: no weights message of length 2 and require_weights is true"
    inputs.add_weights(check_weights([0.3, 0.7], received=1.2))
    assert xs_in_rank_order(inputs, 1.3, settings) == [0.2, 0.1]


# --- limits, refusals, staleness ---------------------------------------------------------------


def test_only_the_heaviest_hypotheses_are_kept() -> None:
    settings = InputSettings(max_hypotheses=2)
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1, 0.2, 0.3, 0.4], received=1.0))
    inputs.add_weights(check_weights([0.1, 0.4, 0.2, 0.3], received=1.0))
    status = inputs.status(1.0, settings)
    assert status.level == Level.WARN
    assert "kept the 2 heaviest of 4 hypotheses" in status.message
    assert xs_in_rank_order(inputs, 1.0, settings) == [0.2, 0.4]
    assert status.hypotheses is not None
    assert sum(h.weight for h in status.hypotheses.hypotheses) == pytest.approx(1.0)


def test_dropped_poses_lose_their_weights_and_are_reported() -> None:
    raw = [((0.1, 0.0, 0.1), IDENTITY), ((0.2, 0.0, 0.1), (0.0, 0.0, 0.0, 0.0)), ((0.3, 0.0, 0.1), IDENTITY)]
    inputs = ObjectInputs("cube")
    inputs.add_poses(
        check_poses(raw, frame_id="world", expected_frame="world", workspace=WORKSPACE, stamp_ns=0, received=1.0)
    )
    inputs.add_weights(check_weights([0.2, 0.7, 0.1], received=1.0))
    status = inputs.status(1.0, SETTINGS)
    assert status.level == Level.WARN
    assert "dropped 1 of 3 poses: poses[1]: zero quaternion" in status.message
    assert status.hypotheses is not None
    assert [h.weight for h in status.hypotheses.hypotheses] == pytest.approx([2 / 3, 1 / 3])


def test_a_refused_message_keeps_the_previous_hypotheses_and_the_next_good_one_recovers() -> None:
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1], received=1.0))
    assert inputs.status(1.0, SETTINGS).hypotheses is not None
    inputs.add_poses(poses([0.9], received=2.0, frame="camera"))
    status = inputs.status(2.0, SETTINGS)
    assert status.level == Level.WARN
    assert status.message.startswith("PoseArray refused: frame_id 'camera' is not the scene frame 'world'")
    assert xs_in_rank_order(inputs, 2.0) == [0.1]
    assert dict(status.details)["poses refused"] == "1"
    assert dict(status.details)["last PoseArray refused"].endswith("frame_id 'camera' is not the scene frame 'world'")
    inputs.add_poses(poses([0.5], received=3.0))
    assert xs_in_rank_order(inputs, 3.0) == [0.5]
    assert "refused" not in inputs.status(3.0, SETTINGS).message


def test_weights_that_are_refused_refuse_the_poses_they_belong_to() -> None:
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1, 0.2], received=1.0))
    inputs.add_weights(check_weights([-1.0, 2.0], received=1.0))
    status = inputs.status(1.1, SETTINGS)
    assert status.level == Level.ERROR
    assert status.hypotheses is None
    assert status.message == (
        "weights refused: negative weight; PoseArray refused: its weights message is unusable: negative weight"
    )


def test_an_object_without_messages_is_missing() -> None:
    status = ObjectInputs("cube").status(5.0, SETTINGS)
    assert (status.level, status.message, status.hypotheses) == (Level.WARN, "no hypotheses received yet", None)


def test_hypotheses_older_than_max_age_are_stale_until_fresh_ones_arrive() -> None:
    settings = InputSettings(max_age=2.0)
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1], received=1.0))
    assert inputs.status(2.9, settings).hypotheses is not None
    status = inputs.status(3.5, settings)
    assert (status.level, status.hypotheses) == (Level.ERROR, None)
    assert status.message == "stale: newest usable hypotheses are 2.5 s old (max_age 2 s)"
    inputs.add_poses(poses([0.1], received=4.0))
    assert inputs.status(4.0, settings).level == Level.WARN  # fresh again (uniform weights warning)


def test_the_snapshot_waits_for_every_object_and_carries_the_newest_stamp() -> None:
    tracker = InputTracker(["a", "b"])
    tracker.add_poses("a", poses([0.1], received=1.0, stamp_ns=1_732_233_600_123_456_789))
    snapshot = tracker.snapshot(1.0, SETTINGS)
    assert snapshot.missing == ("b",)
    assert snapshot.hypotheses is None
    tracker.add_poses("b", poses([0.2], received=1.1, stamp_ns=1_732_233_600_123_456_790))
    snapshot = tracker.snapshot(1.2, SETTINGS)
    assert snapshot.missing == ()
    assert snapshot.hypotheses is not None and len(snapshot.hypotheses) == 2
    assert snapshot.stamp_ns == 1_732_233_600_123_456_790  # exact: one nanosecond newer


# --- the tick ---------------------------------------------------------------------------------


def pyramid_settings(deadline: float = 10.0, **search: Any) -> MapperSettings:
    """Settings for ticks; the default deadline lets a tick finish the 8 configurations on any machine."""
    return MapperSettings(SearchParams(deadline=deadline, **search), SETTINGS, rate_hz=0.05)


def feed_pyramid(mapper: Mapper, received: float, top_z: float = 0.3) -> None:
    """Two exact hypotheses per cube of the pyramid, the top cube at height ``top_z``."""
    for name, x, z in (("cube_left", -0.105, 0.1), ("cube_right", 0.105, 0.1), ("cube_top", 0.0, top_z)):
        raw = [((x, 0.0, z), IDENTITY), ((x, 0.0, z + 0.05), IDENTITY)]
        mapper.inputs.add_poses(
            name,
            check_poses(
                raw, frame_id="world", expected_frame="world", workspace=WORKSPACE, stamp_ns=0, received=received
            ),
        )


def test_unchanged_inputs_resume_the_search_and_changed_ones_restart_it() -> None:
    mapper = Mapper(load_scene(SCENES / "pyramid.yaml"))
    try:
        assert mapper.tick(0.0, pyramid_settings()).result is None
        feed_pyramid(mapper, 1.0)
        first = mapper.tick(1.0, pyramid_settings())
        assert first.result is not None and first.result.valid and first.result.code == (1, 1, 1)
        assert first.result.stats.exhausted and not first.resumed
        feed_pyramid(mapper, 2.0)  # the same hypotheses published again
        again = mapper.tick(2.0, pyramid_settings())
        assert again.resumed
        assert again.result is not None and again.result.stats.visited == first.result.stats.visited
        # The deadline and the fallback change neither the visits nor their outcomes: progress is kept.
        assert mapper.tick(2.5, pyramid_settings(deadline=0.1)).resumed
        kept = mapper.tick(2.5, pyramid_settings(fallback="settled"))
        assert kept.resumed and kept.result is not None and kept.result.stats.visited == first.result.stats.visited
        assert not mapper.tick(2.5, pyramid_settings(settle_time=0.4)).resumed  # other rules: a new search
        feed_pyramid(mapper, 3.0, top_z=0.35)  # new contents
        assert not mapper.tick(3.0, pyramid_settings()).resumed
    finally:
        mapper.close()


@pytest.mark.parametrize(
    ("settings", "problem"),
    [
        (MapperSettings(SearchParams(deadline=0.5), SETTINGS, 2.0), "shorter than the tick period 1/rate_hz = 0.5 s"),
        (MapperSettings(SearchParams(deadline=-1.0), SETTINGS, 2.0), "deadline must be positive"),
        (MapperSettings(SearchParams(), InputSettings(max_age=0.0), 2.0), "max_age must be positive"),
        (MapperSettings(SearchParams(), InputSettings(max_hypotheses=0), 2.0), "max_hypotheses_per_object"),
    ],
)
def test_invalid_settings_are_named(settings: MapperSettings, problem: str) -> None:
    text = mapper_settings_problem(settings)
    assert text is not None and problem in text


def test_valid_settings_pass() -> None:
    assert mapper_settings_problem(pyramid_settings()) is None


def test_a_refused_pose_array_and_refused_weights_are_both_reported() -> None:
    inputs = ObjectInputs("cube")
    inputs.add_poses(
        check_poses([], frame_id="world", expected_frame="world", workspace=WORKSPACE, stamp_ns=0, received=1.0)
    )
    inputs.add_weights(check_weights([], received=1.01))
    status = inputs.status(1.1, SETTINGS)
    assert status.message == "PoseArray refused: empty PoseArray; weights refused: empty weights array"
    details = dict(status.details)
    assert (details["poses refused"], details["weights refused"]) == ("1", "1")


def test_messages_the_middleware_lost_are_counted_per_kind_and_named_while_recent() -> None:
    """The node's message-lost events (best-effort inputs drop large arrays): counted, and a warning for max_age."""
    inputs = ObjectInputs("cube")
    inputs.add_poses(poses([0.1], received=1.0))
    inputs.add_weights(check_weights([1.0], received=1.0))
    inputs.add_lost("poses", 3, now=2.0)
    inputs.add_lost("poses", 1, now=4.0)
    inputs.add_lost("weights", 2, now=4.0)
    status = inputs.status(5.0, SETTINGS)
    assert status.level == Level.WARN and status.hypotheses is not None  # what arrived stays in use
    assert "messages lost in the middleware (4 poses, 2 weights in total, the last 1.0 s ago)" in status.message
    details = dict(status.details)
    assert (details["poses lost"], details["weights lost"]) == ("4", "2")
    inputs.add_poses(poses([0.1], received=14.0))
    inputs.add_weights(check_weights([1.0], received=14.0))
    later = inputs.status(4.0 + SETTINGS.max_age + 0.1, SETTINGS)  # the last loss is older than max_age
    assert later.level == Level.OK and dict(later.details)["poses lost"] == "4"  # still counted
