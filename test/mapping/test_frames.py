"""The transform buffer answers as tf2 does: chains, interpolation, static frames, extrapolation refused."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from physics_mapper.mapping.frames import (
    MAX_SAMPLES_PER_FRAME,
    LookupFailure,
    StampedTransform,
    Transform,
    TransformBuffer,
    TransformWait,
    rotate_covariance,
    transform_poses,
)
from physics_mapper.model.geometry import quaternion_about_axis

SECOND = 1_000_000_000
QUARTER_TURN_Z = quaternion_about_axis((0.0, 0.0, 1.0), math.pi / 2)


def transform(
    parent: str,
    child: str,
    stamp_s: float,
    xyz: tuple[float, float, float],
    q: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0),
) -> StampedTransform:
    return StampedTransform(parent, child, round(stamp_s * SECOND), xyz, q)


def found(result: Transform | LookupFailure) -> Transform:
    assert isinstance(result, Transform), result
    return result


def test_a_chain_through_static_frames_composes_every_edge() -> None:
    buffer = TransformBuffer()
    assert buffer.add(transform("world", "robot", 0.0, (1.0, 0.0, 0.0), QUARTER_TURN_Z), static=True) is None
    assert buffer.add(transform("robot", "camera", 0.0, (0.0, 2.0, 0.5)), static=True) is None
    camera_in_world = found(buffer.lookup("world", "camera", 123 * SECOND))
    # (0, 2, 0.5) in the robot frame, turned a quarter about z: (-2, 0, 0.5), then shifted by (1, 0, 0).
    np.testing.assert_allclose(camera_in_world.translation, [-1.0, 0.0, 0.5], atol=1e-12)
    np.testing.assert_allclose(camera_in_world.rotation.as_quat(), QUARTER_TURN_Z, atol=1e-12)
    world_in_camera = found(buffer.lookup("camera", "world", 0))
    np.testing.assert_allclose((world_in_camera @ camera_in_world).translation, [0.0, 0.0, 0.0], atol=1e-12)


def test_siblings_meet_at_their_common_ancestor_without_the_edges_above_it() -> None:
    buffer = TransformBuffer()
    buffer.add(transform("world", "table", 5.0, (0.0, 0.0, 1.0)), static=False)  # no value at t = 1 s
    buffer.add(transform("table", "camera", 0.0, (0.0, 0.0, 0.5)), static=True)
    buffer.add(transform("table", "bin", 0.0, (0.3, 0.0, 0.0)), static=True)
    camera_in_bin = found(buffer.lookup("bin", "camera", 1 * SECOND))
    np.testing.assert_allclose(camera_in_bin.translation, [-0.3, 0.0, 0.5], atol=1e-12)


def test_a_stamp_between_two_samples_is_interpolated() -> None:
    buffer = TransformBuffer()
    buffer.add(transform("world", "camera", 1.0, (0.0, 0.0, 0.0)), static=False)
    buffer.add(transform("world", "camera", 2.0, (1.0, 0.0, 0.0), QUARTER_TURN_Z), static=False)
    middle = found(buffer.lookup("world", "camera", round(1.25 * SECOND)))
    np.testing.assert_allclose(middle.translation, [0.25, 0.0, 0.0], atol=1e-12)
    assert middle.rotation.magnitude() == pytest.approx(math.pi / 8)
    exact = found(buffer.lookup("world", "camera", 2 * SECOND))
    np.testing.assert_allclose(exact.translation, [1.0, 0.0, 0.0])
    latest = found(buffer.lookup("world", "camera", 0))  # stamp 0: the newest
    np.testing.assert_allclose(latest.translation, [1.0, 0.0, 0.0])


def test_extrapolation_is_refused_and_only_the_future_is_worth_waiting_for() -> None:
    buffer = TransformBuffer(cache_time=10.0)
    buffer.add(transform("world", "camera", 20.0, (0.0, 0.0, 0.0)), static=False)
    buffer.add(transform("world", "camera", 21.0, (0.0, 0.0, 0.0)), static=False)
    future = buffer.lookup("world", "camera", 22 * SECOND)
    past = buffer.lookup("world", "camera", 19 * SECOND)
    assert isinstance(future, LookupFailure) and future.may_arrive
    assert "newest transform to 'camera' is at 21.000 s" in future.reason
    assert isinstance(past, LookupFailure) and not past.may_arrive
    unknown = buffer.lookup("world", "gripper", 21 * SECOND)
    assert isinstance(unknown, LookupFailure) and unknown.may_arrive
    assert unknown.reason == "no transform from 'gripper' to 'world': frame 'gripper' is unknown"
    buffer.add(transform("map", "odom", 0.0, (0.0, 0.0, 0.0)), static=True)
    apart = buffer.lookup("world", "odom", 0)
    assert isinstance(apart, LookupFailure) and "not connected" in apart.reason


def test_old_samples_are_dropped_after_the_cache_time_and_past_the_cap() -> None:
    buffer = TransformBuffer(cache_time=1.0)
    for step in range(MAX_SAMPLES_PER_FRAME + 50):
        buffer.add(transform("world", "camera", step * 1e-6, (0.0, 0.0, 0.0)), static=False)
    oldest_kept = 50 * 1000  # ns: the first 50 samples went over the cap
    assert isinstance(buffer.lookup("world", "camera", oldest_kept - 1), LookupFailure)
    assert isinstance(buffer.lookup("world", "camera", oldest_kept), Transform)
    buffer.add(transform("world", "camera", 100.0, (0.0, 0.0, 0.0)), static=False)
    assert isinstance(buffer.lookup("world", "camera", 98 * SECOND), LookupFailure)


@pytest.mark.parametrize(
    ("bad", "why"),
    [
        (transform("world", "world", 0.0, (0.0, 0.0, 0.0)), "cannot be its own parent"),
        (transform("", "camera", 0.0, (0.0, 0.0, 0.0)), "needs a parent frame_id"),
        (transform("world", "camera", 0.0, (math.nan, 0.0, 0.0)), "non-finite"),
        (transform("world", "camera", 0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.7)), "quaternion norm 1.7"),
        (transform("camera", "world", 0.0, (0.0, 0.0, 0.0)), "would close a loop"),
    ],
)
def test_a_bad_transform_is_refused_with_a_reason(bad: StampedTransform, why: str) -> None:
    buffer = TransformBuffer()
    buffer.add(transform("world", "camera", 0.0, (0.0, 0.0, 1.0)), static=True)
    problem = buffer.add(bad, static=True)
    assert problem is not None and why in problem
    np.testing.assert_allclose(found(buffer.lookup("world", "camera", 0)).translation, [0.0, 0.0, 1.0])


def test_poses_and_their_covariance_move_together() -> None:
    camera = Transform.of((1.0, 2.0, 3.0), QUARTER_TURN_Z)
    poses = np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], [np.nan, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]])
    moved = transform_poses(camera, poses)
    np.testing.assert_allclose(moved[0, :3], [1.0, 3.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(moved[0, 3:], QUARTER_TURN_Z, atol=1e-12)
    assert np.isnan(moved[1, 0])  # left for the input rules to drop
    covariance = np.diag([0.04, 0.0001, 0.0, 0.09, 0.0, 0.0])  # long along the camera's x and about its x
    rotated = rotate_covariance(camera, covariance)
    np.testing.assert_allclose(np.diag(rotated), [0.0001, 0.04, 0.0, 0.0, 0.09, 0.0], atol=1e-12)
    assert np.linalg.eigvalsh(rotated) == pytest.approx(np.linalg.eigvalsh(covariance), abs=1e-12)
    again = Rotation.from_quat(QUARTER_TURN_Z).inv()
    back = rotate_covariance(Transform(again, np.zeros(3)), rotated)
    np.testing.assert_allclose(back, covariance, atol=1e-12)


def test_inputs_wait_for_late_transforms_up_to_the_timeout() -> None:
    buffer = TransformBuffer()
    wait: TransformWait[str] = TransformWait("world")
    wait.add("late", {"camera"}, 5 * SECOND, now=100.0)
    wait.add("never", {"nowhere"}, 5 * SECOND, now=100.0)
    assert wait.ready(buffer, now=100.1, timeout=0.5) == []
    buffer.add(transform("world", "camera", 5.0, (0.0, 0.0, 1.0)), static=False)
    (late,) = wait.ready(buffer, now=100.2, timeout=0.5)
    assert late.item == "late" and late.unresolved == {}
    np.testing.assert_allclose(late.transforms["camera"].translation, [0.0, 0.0, 1.0])
    (never,) = wait.ready(buffer, now=100.5, timeout=0.5)
    assert never.item == "never" and never.transforms == {}
    why = "no transform from 'nowhere' to 'world': frame 'nowhere' is unknown (waited 0.5 s)"
    assert never.unresolved == {"nowhere": why}
    assert len(wait) == 0
