"""Pictures of a scene: pybullet's software renderer (TinyRenderer) on the scene's bodies at given poses.

No window and no GPU: the world is built from visual shapes only (nothing is simulated), in its own
DIRECT connection. Meshes are drawn from their files (with their textures, tinted), primitives as
themselves, a plane as a large thin square. The camera looks at the objects from the front and above,
far enough to hold them all.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.bullet import pybullet
from physics_mapper.model.geometry import Pose, compose_poses
from physics_mapper.model.scene import Box, Cylinder, Mesh, Plane, Scene, Shape, Sphere, bounding_radius

#: Side of the square drawn for a plane, metres, and its thickness.
PLANE_SIZE, PLANE_THICKNESS = 4.0, 0.002
STATIC_RGBA = (0.72, 0.66, 0.58, 1.0)
#: Object colours, cycled (tab10-like, opaque).
OBJECT_RGBA = (
    (0.84, 0.25, 0.22, 1.0),
    (0.95, 0.76, 0.15, 1.0),
    (0.22, 0.47, 0.78, 1.0),
    (0.30, 0.69, 0.34, 1.0),
    (0.90, 0.50, 0.15, 1.0),
    (0.58, 0.40, 0.74, 1.0),
    (0.55, 0.55, 0.55, 1.0),
    (0.15, 0.70, 0.72, 1.0),
    (0.89, 0.47, 0.76, 1.0),
    (0.55, 0.34, 0.29, 1.0),
)
#: Direction from the objects towards the camera (front, a little to the right, from above).
VIEW_DIRECTION = (0.3, -0.85, 0.6)
FIELD_OF_VIEW_DEGREES = 40.0
#: How much wider than the objects the picture is.
MARGIN = 1.8


def _visual_shape(client: int, shape: Shape, rgba: Sequence[float]) -> int:
    if isinstance(shape, Mesh):
        return int(
            pybullet.createVisualShape(
                pybullet.GEOM_MESH,
                fileName=str(shape.file),
                meshScale=list(shape.scale),
                rgbaColor=list(rgba),
                physicsClientId=client,
            )
        )
    if isinstance(shape, Box):
        half = [s / 2.0 for s in shape.size]
        return int(
            pybullet.createVisualShape(
                pybullet.GEOM_BOX, halfExtents=half, rgbaColor=list(rgba), physicsClientId=client
            )
        )
    if isinstance(shape, Sphere):
        return int(
            pybullet.createVisualShape(
                pybullet.GEOM_SPHERE, radius=shape.radius, rgbaColor=list(rgba), physicsClientId=client
            )
        )
    if isinstance(shape, Cylinder):
        return int(
            pybullet.createVisualShape(
                pybullet.GEOM_CYLINDER,
                radius=shape.radius,
                length=shape.length,
                rgbaColor=list(rgba),
                physicsClientId=client,
            )
        )
    assert isinstance(shape, Plane)
    half = [PLANE_SIZE / 2.0, PLANE_SIZE / 2.0, PLANE_THICKNESS / 2.0]
    return int(
        pybullet.createVisualShape(pybullet.GEOM_BOX, halfExtents=half, rgbaColor=list(rgba), physicsClientId=client)
    )


def _place(client: int, shape: Shape, pose: Pose, rgba: Sequence[float]) -> None:
    if isinstance(shape, Plane):  # its top face is the plane
        pose = compose_poses(pose, Pose((0.0, 0.0, -PLANE_THICKNESS / 2.0)))
    pybullet.createMultiBody(
        baseMass=0.0,
        baseVisualShapeIndex=_visual_shape(client, shape, rgba),
        basePosition=pose.position,
        baseOrientation=pose.orientation,
        physicsClientId=client,
    )


def object_color(index: int) -> tuple[float, float, float, float]:
    """The colour object ``index`` is drawn in (also for legends)."""
    return OBJECT_RGBA[index % len(OBJECT_RGBA)]


def render_scene(scene: Scene, poses: Sequence[Pose], width: int = 640, height: int = 480) -> NDArray[np.uint8]:
    """An RGB picture (height x width x 3) of the scene's static bodies and its objects at ``poses``."""
    client = pybullet.connect(pybullet.DIRECT)
    try:
        for body in scene.static:
            _place(client, body.shape, body.pose, STATIC_RGBA)
        for index, (model, pose) in enumerate(zip(scene.objects, poses, strict=True)):
            _place(client, model.shape, pose, object_color(index))
        centres = np.array([pose.position for pose in poses])
        target = centres.mean(axis=0)
        reach = max(
            float(np.linalg.norm(centre - target)) + (bounding_radius(model.shape) or 0.0)
            for centre, model in zip(centres, scene.objects, strict=True)
        )
        distance = MARGIN * reach / math.tan(math.radians(FIELD_OF_VIEW_DEGREES / 2.0))
        direction = np.array(VIEW_DIRECTION) / np.linalg.norm(VIEW_DIRECTION)
        eye = target + distance * direction
        view = pybullet.computeViewMatrix(eye.tolist(), target.tolist(), [0.0, 0.0, 1.0], physicsClientId=client)
        projection = pybullet.computeProjectionMatrixFOV(
            FIELD_OF_VIEW_DEGREES, width / height, distance / 20.0, distance * 4.0, physicsClientId=client
        )
        _, _, pixels, _, _ = pybullet.getCameraImage(
            width, height, view, projection, renderer=pybullet.ER_TINY_RENDERER, physicsClientId=client
        )
    finally:
        pybullet.disconnect(physicsClientId=client)
    rgb: NDArray[np.uint8] = np.reshape(np.asarray(pixels, dtype=np.uint8), (height, width, 4))[:, :, :3]
    return rgb
