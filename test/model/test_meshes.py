"""Mesh shapes: loading, mass properties, the two rules on meshes, decomposition and its cache, errors.

Real meshes, real pybullet: small meshes made by :mod:`mesh_builders`, and pybullet_data's mug
with pybullet's own convex decomposition of it (so no test waits for CoACD on the mug).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pybullet
import pytest
import yaml
from conftest import REPO, SCENES
from core_builders import cli
from mesh_builders import (
    MUG_FILE,
    MUG_PARTS,
    TROUGH_WALL,
    box_mesh,
    floor_scene_dict,
    load_inline,
    mesh_object,
    trough_mesh,
    write_mesh,
)
from scipy.spatial.transform import Rotation

from physics_mapper.model.decomposition import CACHE_ENVIRONMENT_VARIABLE, cache_directory
from physics_mapper.model.geometry import (
    IDENTITY,
    Pose,
    compose_poses,
    inverse_pose,
    make_pose,
    quaternion_about_axis,
    rotate_vector,
    rotation_angle,
    translation_distance,
)
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.meshes import MAX_MESH_VERTICES
from physics_mapper.model.resources import resolve_resource, resource_uri
from physics_mapper.model.scene import Box, Cylinder, Mesh, Plane, Scene, SearchParams, Sphere, bounding_radius
from physics_mapper.model.scene_files import SceneError, load_scene
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.strategy import solve

PARAMS = SearchParams()
BOX_SIZE = (0.2, 0.1, 0.05)
BOX_MASS = 0.3
#: A pose in a mesh file's frame, far from its origin and turned about no particular axis.
OFFSET = Pose((0.1, -0.05, 0.02), quaternion_about_axis((0.3, 1.0, 0.2), 0.7))
#: Height of the test table's top.
TABLE_TOP = 0.6
DATA = REPO / "test" / "data"


def rules(scene: Scene, poses: list[Pose]) -> tuple[Any, Any]:
    """(Rule 1's collision or None, Rule 2's settling) of one configuration, with the default thresholds."""
    with PhysicsChecker(scene) as checker:
        collision = checker.find_collision(poses, PARAMS.penetration_threshold)
        return collision, checker.settle(poses, PARAMS.settle_time, PARAMS.angular_weight)


def mesh_of(scene: Scene, index: int) -> Mesh:
    shape = scene.objects[index].shape
    assert isinstance(shape, Mesh)
    return shape


def inertia_in_pybullet(checker: PhysicsChecker, index: int) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, inertia tensor about the centre of mass in the body frame, centre of mass) as pybullet holds them."""
    uid, client = checker.world.object_uids[index], checker.client_id
    mass, _, diagonal, position, orientation = pybullet.getDynamicsInfo(uid, -1, physicsClientId=client)[:5]
    axes = Rotation.from_quat(orientation).as_matrix()
    return mass, axes @ np.diag(diagonal) @ axes.T, np.array(position)


# --- poses and frames --------------------------------------------------------------------------


def test_composing_and_inverting_poses_agree_with_scipy() -> None:
    a, b = OFFSET, make_pose((-0.3, 0.2, 0.9), quaternion_about_axis((1.0, -2.0, 0.5), 2.1))
    composed = compose_poses(a, b)
    rotation_a, rotation_b = Rotation.from_quat(a.orientation), Rotation.from_quat(b.orientation)
    assert np.allclose(composed.position, rotation_a.apply(b.position) + a.position)
    assert rotation_angle(composed.orientation, tuple((rotation_a * rotation_b).as_quat())) < 1e-9
    back = compose_poses(a, inverse_pose(a))
    assert translation_distance(back, Pose((0.0, 0.0, 0.0))) < 1e-12
    assert rotation_angle(back.orientation, IDENTITY) < 1e-7
    assert np.allclose(rotate_vector(a.orientation, (1.0, 2.0, 3.0)), rotation_a.apply((1.0, 2.0, 3.0)))


# --- mass properties against closed forms ------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".obj", ".stl"])
def test_a_box_mesh_has_the_mass_centre_of_mass_and_inertia_of_shape_box(tmp_path: Path, suffix: str) -> None:
    write_mesh(box_mesh(BOX_SIZE), tmp_path / f"box{suffix}")
    density = BOX_MASS / math.prod(BOX_SIZE)
    scene = load_inline(
        floor_scene_dict(
            {"name": "box", "shape": "box", "size": list(BOX_SIZE), "mass": BOX_MASS},
            mesh_object("by_mass", f"box{suffix}", mass=BOX_MASS),
            mesh_object("by_density", f"box{suffix}", density=density),
        ),
        tmp_path,
    )
    assert scene.objects[2].mass == pytest.approx(BOX_MASS, rel=1e-6)
    primitive = load_inline(
        floor_scene_dict({"name": "b", "shape": "box", "size": list(BOX_SIZE), "density": density}), tmp_path
    )
    assert primitive.objects[0].mass == pytest.approx(BOX_MASS)  # density works for every shape
    properties = mesh_of(scene, 1).geometry.mass_properties
    assert properties is not None and properties.source == "mesh"
    assert properties.volume == pytest.approx(math.prod(BOX_SIZE), rel=1e-6)
    x, y, z = BOX_SIZE
    closed_form = BOX_MASS / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])
    assert np.allclose(properties.inertia_tensor(BOX_MASS), closed_form, atol=1e-9)
    with PhysicsChecker(scene) as checker:
        reference = inertia_in_pybullet(checker, 0)
        for index in (1, 2):
            mass, tensor, centre = inertia_in_pybullet(checker, index)
            assert mass == pytest.approx(reference[0], rel=1e-6)
            assert np.allclose(tensor, reference[1], atol=1e-9) and np.allclose(tensor, closed_form, atol=1e-9)
            assert np.allclose(centre, reference[2], atol=1e-9)
        # Dropped the same way, side by side: the same fall, tumble and rest.
        start = quaternion_about_axis((1.0, 1.0, 0.0), 0.4)
        poses = [make_pose((x, 0.0, 0.3), start) for x in (0.0, 1.0, 2.0)]
        settled = checker.settle(poses, 1.0, PARAMS.angular_weight).settled_poses
    for offset, pose in enumerate(settled[1:], start=1):
        assert translation_distance(compose_poses(Pose((-float(offset), 0.0, 0.0)), pose), settled[0]) < 1e-5
        assert rotation_angle(pose.orientation, settled[0].orientation) < 1e-4


def test_a_mesh_off_its_frame_origin_has_its_centre_of_mass_where_its_solid_is(tmp_path: Path) -> None:
    """The pose is the file's frame; the centre of mass and principal axes come from the solid, wherever it is."""
    write_mesh(box_mesh(BOX_SIZE, OFFSET), tmp_path / "offset_box.obj")
    scene = load_inline(
        floor_scene_dict(
            {"name": "box", "shape": "box", "size": list(BOX_SIZE), "mass": BOX_MASS},
            mesh_object("mesh", "offset_box.obj", mass=BOX_MASS),
        ),
        tmp_path,
    )
    properties = mesh_of(scene, 1).geometry.mass_properties
    assert properties is not None
    assert np.allclose(properties.centre_of_mass, OFFSET.position, atol=1e-9)
    turn = Rotation.from_quat(OFFSET.orientation).as_matrix()
    x, y, z = BOX_SIZE
    closed_form = BOX_MASS / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])
    assert np.allclose(properties.inertia_tensor(BOX_MASS), turn @ closed_form @ turn.T, atol=1e-9)
    # The mesh posed so that its box is where the primitive box is (1 m aside): they fall alike.
    box_pose = make_pose((0.0, 0.0, 0.3), quaternion_about_axis((1.0, 1.0, 0.0), 0.4))
    mesh_pose = compose_poses(make_pose((1.0, 0.0, 0.3), box_pose.orientation), inverse_pose(OFFSET))
    _, settling = rules(scene, [box_pose, mesh_pose])
    box_after, mesh_box_after = settling.settled_poses[0], compose_poses(settling.settled_poses[1], OFFSET)
    assert box_after.position[2] == pytest.approx(mesh_box_after.position[2], abs=1e-4)  # both flat on the floor
    assert math.dist(box_after.position[:2], (mesh_box_after.position[0] - 1.0, mesh_box_after.position[1])) < 0.005
    assert rotation_angle(box_after.orientation, mesh_box_after.orientation) < math.radians(3.0)
    # At rest where it was placed, an off-centre mesh does not move: no spurious jitter from the frames.
    _, resting = rules(
        scene, [Pose((0.0, 0.0, z / 2.0)), compose_poses(Pose((1.0, 0.0, z / 2.0)), inverse_pose(OFFSET))]
    )
    assert max(resting.jitters) < 0.001


def test_a_scaled_unit_cube_mesh_is_the_box_of_its_scale(tmp_path: Path) -> None:
    write_mesh(box_mesh((1.0, 1.0, 1.0)), tmp_path / "cube.obj")
    scene = load_inline(
        floor_scene_dict(mesh_object("brick", "cube.obj", scale=list(BOX_SIZE), density=1000.0)), tmp_path
    )
    assert scene.objects[0].mass == pytest.approx(1000.0 * math.prod(BOX_SIZE))
    low, high = mesh_of(scene, 0).geometry.bounds
    assert low == pytest.approx((-0.1, -0.05, -0.025)) and high == pytest.approx((0.1, 0.05, 0.025))
    collision, _ = rules(scene, [Pose((0.0, 0.0, 0.025 - 0.01))])
    assert collision is not None and collision.depth == pytest.approx(0.01, abs=1e-6)


def test_bounding_radius_covers_every_shape_from_its_frame_origin(tmp_path: Path) -> None:
    write_mesh(box_mesh(BOX_SIZE, OFFSET), tmp_path / "offset_box.obj")
    mesh = mesh_of(load_inline(floor_scene_dict(mesh_object("m", "offset_box.obj")), tmp_path), 0)
    corners = box_mesh(BOX_SIZE, OFFSET).vertices
    assert bounding_radius(mesh) == pytest.approx(float(np.linalg.norm(corners, axis=1).max()))
    assert bounding_radius(Box((0.2, 0.1, 0.05))) == pytest.approx(math.sqrt(0.04 + 0.01 + 0.0025) / 2.0)
    assert bounding_radius(Sphere(0.05)) == 0.05
    assert bounding_radius(Cylinder(0.03, 0.08)) == pytest.approx(0.05)
    assert bounding_radius(Plane()) is None


# --- the rules on a real mug (pybullet_data's, with pybullet's own convex decomposition) ----------------


@pytest.fixture(scope="module")
def mug_scene() -> Scene:
    table = {"name": "table", "shape": "box", "size": [1.0, 1.0, 0.05], "pose": {"position": [0, 0, TABLE_TOP - 0.025]}}
    mug = mesh_object("mug", MUG_FILE, collision="decomposition", parts=MUG_PARTS, mass=0.3)
    return load_inline(floor_scene_dict(mug, static=(table,)), Path.cwd())


def resting_on_table(scene: Scene, orientation: tuple[float, float, float, float]) -> Pose:
    """The mug turned by ``orientation`` and lowered until its lowest point touches the table."""
    points = np.vstack([part.vertices for part in mesh_of(scene, 0).geometry.parts])
    lowest = min(rotate_vector(orientation, (float(x), float(y), float(z)))[2] for x, y, z in points)
    return make_pose((0.0, 0.0, TABLE_TOP - lowest), orientation)


def test_a_mug_upright_on_a_table_is_valid(mug_scene: Scene) -> None:
    upright = resting_on_table(mug_scene, IDENTITY)
    assert upright.position[2] == pytest.approx(TABLE_TOP)  # the mug's frame is at its base
    collision, settling = rules(mug_scene, [upright])
    assert collision is None
    assert settling.is_stable(PARAMS.jitter_threshold)


def test_a_mug_tilted_20_degrees_onto_its_handle_is_unstable(mug_scene: Scene) -> None:
    # The handle points along +y: turning about -x by 20 degrees lowers the handle's side.
    tilted = resting_on_table(mug_scene, quaternion_about_axis((1.0, 0.0, 0.0), -math.radians(20.0)))
    handle = rotate_vector(tilted.orientation, (0.0, 0.08, 0.05))
    assert handle[2] < rotate_vector(tilted.orientation, (0.0, -0.04, 0.05))[2]  # the handle's side is down
    collision, settling = rules(mug_scene, [tilted])
    assert collision is None  # it only touches the table
    assert not settling.is_stable(PARAMS.jitter_threshold)
    assert rotation_angle(settling.settled_poses[0].orientation, IDENTITY) < math.radians(5.0)  # fell back upright


def test_a_mug_pushed_2_cm_into_the_table_collides_with_the_table(mug_scene: Scene) -> None:
    pushed = resting_on_table(mug_scene, IDENTITY)
    pushed = make_pose((0.0, 0.0, pushed.position[2] - 0.02))
    collision, _ = rules(mug_scene, [pushed])
    assert collision is not None
    assert collision.pair == ("mug", "table")
    assert collision.depth == pytest.approx(0.02, abs=1e-4)


def test_fallback_refine_lifts_a_mug_pushed_into_the_table_back_onto_it(mug_scene: Scene) -> None:
    pushed = RankedHypotheses.from_weighted([Hypothesis(make_pose((0.0, 0.0, TABLE_TOP - 0.02)), 1.0)])
    with PhysicsChecker(mug_scene) as checker:
        result = solve(checker, [pushed], replace(mug_scene.search, fallback="refine", deadline=10.0))
    assert not result.valid and result.fallback_used and result.settled_poses is not None
    settled = result.settled_poses[0]
    assert settled.position[2] == pytest.approx(TABLE_TOP, abs=0.001)
    assert rotation_angle(settled.orientation, IDENTITY) < math.radians(1.0)


# --- concave objects: decomposition against the convex hull -----------------------------------------


CUBE_EDGE = 0.04


def trough_with_cube(tmp_path: Path, collision: str, **keys: Any) -> Scene:
    write_mesh(trough_mesh(), tmp_path / "trough.obj")
    cube = {"name": "cube", "shape": "box", "size": [CUBE_EDGE] * 3, "mass": 0.05}
    trough = mesh_object("trough", "trough.obj", collision=collision, mass=0.4, **keys)
    return load_inline(floor_scene_dict(trough, cube), tmp_path)


CUBE_IN_TROUGH = [Pose((0.0, 0.0, 0.0)), Pose((0.0, 0.0, TROUGH_WALL + CUBE_EDGE / 2.0))]


def test_a_trough_holding_a_cube_is_valid_with_a_decomposition(tmp_path: Path) -> None:
    scene = trough_with_cube(tmp_path, "decomposition")
    assert len(mesh_of(scene, 0).geometry.parts) > 1
    collision, settling = rules(scene, CUBE_IN_TROUGH)
    assert collision is None
    assert settling.is_stable(PARAMS.jitter_threshold)


def test_a_trough_holding_a_cube_collides_as_a_convex_hull(tmp_path: Path) -> None:
    collision, _ = rules(trough_with_cube(tmp_path, "convex_hull"), CUBE_IN_TROUGH)
    assert collision is not None and collision.pair == ("trough", "cube")  # the hull fills the cavity


def test_a_cube_through_the_trough_wall_collides_with_its_decomposition(tmp_path: Path) -> None:
    scene = trough_with_cube(tmp_path, "decomposition")
    through_wall = [CUBE_IN_TROUGH[0], Pose((0.06 - 0.005, 0.0, 0.03))]
    collision, _ = rules(scene, through_wall)
    assert collision is not None and collision.pair == ("trough", "cube")


def test_a_static_triangle_mesh_trough_holds_a_cube_and_its_walls_collide(tmp_path: Path) -> None:
    write_mesh(trough_mesh(), tmp_path / "trough.obj")
    trough = mesh_object("trough", "trough.obj", collision="triangle_mesh")
    cube = {"name": "cube", "shape": "box", "size": [CUBE_EDGE] * 3, "mass": 0.05}
    scene = load_inline(floor_scene_dict(cube, static=(trough,)), tmp_path)
    collision, settling = rules(scene, [CUBE_IN_TROUGH[1]])
    assert collision is None and settling.is_stable(PARAMS.jitter_threshold)
    collision, _ = rules(scene, [Pose((0.06 - 0.005, 0.0, 0.03))])
    assert collision is not None and collision.pair == ("cube", "trough")


# --- the decomposition cache --------------------------------------------------------------------------


@pytest.fixture
def own_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A cache folder of this test's own."""
    monkeypatch.setenv(CACHE_ENVIRONMENT_VARIABLE, str(tmp_path / "cache"))
    return tmp_path / "cache" / "decompositions"


def load_trough(folder: Path, count: int = 1) -> tuple[Scene, list[str]]:
    lines: list[str] = []
    objects = [mesh_object(f"trough_{i}", "trough.obj", collision="decomposition", mass=0.4) for i in range(count)]
    return load_inline(floor_scene_dict(*objects), folder, lines.append), lines


def test_the_cache_is_used_on_the_second_load_and_the_folder_is_reported(tmp_path: Path, own_cache: Path) -> None:
    write_mesh(trough_mesh(), tmp_path / "trough.obj")
    assert cache_directory() == own_cache
    first, lines = load_trough(tmp_path)
    decomposition = mesh_of(first, 0).geometry.decomposition
    assert decomposition is not None and not decomposition.from_cache and decomposition.method == "coacd"
    assert len(lines) == 2 and lines[0].startswith("decomposing ") and str(own_cache) in lines[0]
    assert decomposition.file.parent == own_cache and decomposition.file.is_file()
    second, lines = load_trough(tmp_path)
    again = mesh_of(second, 0).geometry.decomposition
    assert lines == []  # no decomposition, nothing to report
    assert again is not None and again.from_cache and again.file == decomposition.file
    assert [p.vertices.tolist() for p in again.parts] == [p.vertices.tolist() for p in decomposition.parts]


def test_a_scene_decomposes_a_mesh_used_by_several_objects_once(tmp_path: Path, own_cache: Path) -> None:
    write_mesh(trough_mesh(), tmp_path / "trough.obj")
    scene, lines = load_trough(tmp_path, count=3)
    assert sum(line.startswith("decomposing") for line in lines) == 1
    assert len({id(mesh_of(scene, i).geometry) for i in range(3)}) == 1
    assert len(list(own_cache.iterdir())) == 1


def test_a_changed_mesh_file_is_decomposed_again(tmp_path: Path, own_cache: Path) -> None:
    path = write_mesh(trough_mesh(), tmp_path / "trough.obj")
    before = mesh_of(load_trough(tmp_path)[0], 0).geometry.decomposition
    path.write_text(path.read_text() + "# edited\n")  # same shape, other bytes: another key
    scene, lines = load_trough(tmp_path)
    after = mesh_of(scene, 0).geometry.decomposition
    assert before is not None and after is not None
    assert lines[0].startswith("decomposing") and not after.from_cache and after.file != before.file
    assert len(list(own_cache.iterdir())) == 2


def test_a_damaged_cache_file_is_decomposed_again(tmp_path: Path, own_cache: Path) -> None:
    write_mesh(trough_mesh(), tmp_path / "trough.obj")
    decomposition = mesh_of(load_trough(tmp_path)[0], 0).geometry.decomposition
    assert decomposition is not None
    decomposition.file.write_text("o part_0\nf 1 2 3\n")  # a face without vertices
    scene, lines = load_trough(tmp_path)
    again = mesh_of(scene, 0).geometry.decomposition
    assert lines[0].startswith("decomposing")
    assert again is not None and not again.from_cache and len(again.parts) == len(decomposition.parts)


def test_vhacd_decomposes_into_a_cache_file_of_its_own(tmp_path: Path, own_cache: Path) -> None:
    write_mesh(trough_mesh(), tmp_path / "trough.obj")
    keys = {"collision": "decomposition", "mass": 0.4}
    coacd = load_inline(floor_scene_dict(mesh_object("t", "trough.obj", **keys)), tmp_path)
    vhacd = load_inline(
        floor_scene_dict(mesh_object("t", "trough.obj", decomposition={"method": "vhacd"}, **keys)), tmp_path
    )
    by_coacd, by_vhacd = mesh_of(coacd, 0).geometry.decomposition, mesh_of(vhacd, 0).geometry.decomposition
    assert by_coacd is not None and by_vhacd is not None
    assert by_vhacd.method == "vhacd" and len(by_vhacd.parts) > 1 and by_vhacd.file != by_coacd.file


# --- package:// files and the URIs RViz gets -------------------------------------------------------------


def test_package_urls_find_pybullet_data_and_the_ament_index(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mug = resolve_resource(MUG_FILE, None)
    assert mug.is_file() and mug.parts[-3:] == ("pybullet_data", "objects", "mug.obj")
    assert resource_uri(MUG_FILE, mug) == mug.resolve().as_uri()  # not an ament package: RViz needs file://
    prefix = tmp_path / "install"
    index = prefix / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True)
    (index / "my_objects").touch()
    (prefix / "share" / "my_objects").mkdir()
    mesh = write_mesh(box_mesh(BOX_SIZE), prefix / "share" / "my_objects" / "box.stl")
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    url = "package://my_objects/box.stl"
    assert resolve_resource(url, None) == mesh
    assert resource_uri(url, mesh) == url  # RViz finds it through the ament index too
    scene = load_inline(floor_scene_dict(mesh_object("box", url)), tmp_path)
    assert mesh_of(scene, 0).uri == url and mesh_of(scene, 0).file == mesh.resolve()


# --- bad mesh files and keys: one error naming the scene file, the key, the mesh file and the problem ------


OBJ_TETRAHEDRON = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def too_many_vertices() -> str:
    """An OBJ strip of triangles using one vertex more than allowed."""
    count = MAX_MESH_VERTICES + 1
    vertices = "".join(f"v {i} {i % 2} {i % 3}\n" for i in range(count))
    return vertices + "".join(f"f {i} {i + 1} {i + 2}\n" for i in range(1, count - 1))


#: Case -> (mesh file name, its content, extra object keys, the key the error names, text of the problem).
BAD_MESHES: dict[str, tuple[str, str | bytes | None, dict[str, Any], str, str]] = {
    "missing file": ("absent.obj", None, {}, "objects[0].file", "absent.obj: missing file"),
    "empty file": ("empty.obj", "", {}, "objects[0].file", "empty.obj: empty file"),
    "not a mesh, binary": (
        "binary.obj",
        bytes(range(256)) * 8,
        {},
        "objects[0].file",
        "not a mesh: an OBJ file is text",
    ),
    "not a mesh, text": ("text.obj", "hello, this is not a mesh\n", {}, "objects[0].file", "not a mesh: no triangles"),
    "not a mesh, STL": ("noise.stl", bytes(range(256)) * 8, {}, "objects[0].file", "not a mesh"),
    "non-finite vertices": (
        "nan.obj",
        OBJ_TETRAHEDRON.replace("v 0 1 0", "v 0 nan 0"),
        {},
        "objects[0].file",
        "non-finite vertex coordinates (NaN or Inf) at vertex 3",
    ),
    "infinite vertices": (
        "inf.obj",
        OBJ_TETRAHEDRON.replace("v 1 0 0", "v inf 0 0"),
        {},
        "objects[0].file",
        "at vertex 2",
    ),
    "flat": ("flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n", {}, "objects[0].file", "degenerate"),
    "zero-area triangles": ("line.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", {}, "objects[0].file", "degenerate"),
    "face index out of range": ("bad.obj", OBJ_TETRAHEDRON + "f 1 2 9\n", {}, "objects[0].file", "not a mesh"),
    "too many vertices": ("big.obj", too_many_vertices(), {}, "objects[0].file", "too many vertices: 100001"),
    "unsupported format": ("mug.dae", OBJ_TETRAHEDRON, {}, "objects[0].file", "unsupported mesh format '.dae'"),
    "open mesh with density": (
        "open.obj",
        "\n".join(OBJ_TETRAHEDRON.splitlines()[:-1]) + "\n",
        {"density": 500.0},
        "objects[0].file",
        "not a closed mesh (3 open edges): density needs its volume",
    ),
    "mass and density": ("t.obj", OBJ_TETRAHEDRON, {"mass": 1.0, "density": 2.0}, "objects[0].density", "not both"),
    "negative scale": ("t.obj", OBJ_TETRAHEDRON, {"scale": [1, -1, 1]}, "objects[0].scale[1]", "must be positive"),
    "triangle mesh object": (
        "t.obj",
        OBJ_TETRAHEDRON,
        {"collision": "triangle_mesh"},
        "objects[0].collision",
        "must be one of convex_hull, decomposition, got 'triangle_mesh'",
    ),
    "parts with a hull": ("t.obj", OBJ_TETRAHEDRON, {"parts": "t.obj"}, "objects[0].parts", "only with collision"),
    "missing parts file": (
        "t.obj",
        OBJ_TETRAHEDRON,
        {"collision": "decomposition", "parts": "none.obj"},
        "objects[0].parts",
        "none.obj: missing file",
    ),
    "parts file without faces": (
        "t.obj",
        OBJ_TETRAHEDRON,
        {"collision": "decomposition", "parts": "scene.yaml"},
        "objects[0].parts",
        "no faces, so no convex part",
    ),
    "vhacd threshold": (
        "t.obj",
        OBJ_TETRAHEDRON,
        {"collision": "decomposition", "decomposition": {"method": "vhacd", "threshold": 0.1}},
        "objects[0].decomposition.threshold",
        "only for method: coacd",
    ),
    "unknown method": (
        "t.obj",
        OBJ_TETRAHEDRON,
        {"collision": "decomposition", "decomposition": {"method": "magic"}},
        "objects[0].decomposition.method",
        "must be one of coacd, vhacd",
    ),
    "unknown package": ("package://no_such_package/m.obj", None, {}, "objects[0].file", "'no_such_package'"),
}


def bad_mesh_scene(tmp_path: Path, case: str) -> Path:
    name, content, keys, _, _ = BAD_MESHES[case]
    if isinstance(content, str):
        (tmp_path / name).write_text(content)
    elif isinstance(content, bytes):
        (tmp_path / name).write_bytes(content)
    scene = floor_scene_dict(mesh_object("thing", name, **keys))
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(scene, sort_keys=False))
    return path


@pytest.mark.parametrize("case", sorted(BAD_MESHES), ids=lambda case: case.replace(" ", "-"))
def test_a_bad_mesh_gives_one_error_naming_scene_key_file_and_problem(tmp_path: Path, case: str) -> None:
    path = bad_mesh_scene(tmp_path, case)
    _, _, _, key, problem = BAD_MESHES[case]
    with pytest.raises(SceneError) as raised:
        load_scene(path, lambda _: None)
    assert (raised.value.source, raised.value.key) == (str(path), key)
    assert problem in raised.value.problem


def test_a_mesh_key_on_a_box_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump({"objects": [{"name": "b", "shape": "box", "size": [1, 1, 1], "scale": 2}]}))
    with pytest.raises(SceneError, match=r"objects\[0\]\.scale: only for shape: mesh"):
        load_scene(path)


@pytest.mark.parametrize("case", ["missing file", "empty file", "not a mesh, binary", "non-finite vertices"])
def test_solve_prints_one_error_line_and_exits_2_for_a_bad_mesh(tmp_path: Path, case: str) -> None:
    scene = bad_mesh_scene(tmp_path, case)
    problem = tmp_path / "problem.yaml"
    problem.write_text(yaml.safe_dump({"scene": str(scene), "hypotheses": {"thing": [{"position": [0, 0, 0.1]}]}}))
    _, _, _, key, text = BAD_MESHES[case]
    completed = cli("solve", problem)
    assert completed.returncode == 2
    assert completed.stdout == ""
    assert completed.stderr.startswith(f"physics-mapper solve: error: {scene}: {key}: {tmp_path}")
    assert text in completed.stderr
    assert completed.stderr.count("\n") == 1  # one line, no traceback


# --- the shipped mesh scenes, their bags and the decompose command ---------------------------------------


MESH_SCENES = ("tabletop.yaml", "tray_pile.yaml", "jenga_tower.yaml")


@pytest.mark.parametrize("scene_file", MESH_SCENES)
def test_a_shipped_mesh_scene_is_valid_at_its_ground_truth(scene_file: str) -> None:
    scene = load_scene(SCENES / scene_file)
    assert all(isinstance(model.shape, Mesh) for model in scene.objects)
    assert scene.ground_truth is not None
    collision, settling = rules(scene, list(scene.ground_truth))
    assert collision is None
    assert settling.is_stable(scene.search.jitter_threshold)


def test_the_shipped_mesh_scenes_are_a_cluttered_tabletop_a_pile_in_a_tray_and_a_tower() -> None:
    tabletop, tray, tower = (load_scene(SCENES / name) for name in MESH_SCENES)
    assert 8 <= len(tabletop.objects) <= 12
    assert {"mug", "duck"} <= set(tabletop.object_names)
    tray_body = next(body for body in tray.static if body.name == "tray")
    assert isinstance(tray_body.shape, Mesh) and tray_body.shape.collision == "triangle_mesh"
    assert tray.ground_truth is not None
    # Piled: some objects rest on others, well above the tray's floor (1 cm).
    assert sum(pose.position[2] > 0.04 for pose in tray.ground_truth) >= 2
    assert len(tower.objects) >= 12 and tower.ground_truth is not None
    assert max(pose.position[2] for pose in tower.ground_truth) > 0.1  # four layers of 3 cm blocks


def test_replay_offline_searches_a_shipped_mesh_bag(capsys: pytest.CaptureFixture[str]) -> None:
    from physics_mapper.cli import main

    arguments = ["replay", str(DATA / "tabletop"), "--scene", str(SCENES / "tabletop.yaml"), "--offline"]
    status = main([*arguments, "--deadline", "0.2"])
    assert status == 0
    assert capsys.readouterr().out.startswith("10 snapshots")  # how many got a map depends on the machine's speed


def test_decompose_reports_the_cache_and_each_decomposition(tmp_path: Path, own_cache: Path) -> None:
    write_mesh(trough_mesh(), tmp_path / "trough.obj")
    scene = tmp_path / "scene.yaml"
    scene.write_text(yaml.safe_dump(floor_scene_dict(mesh_object("trough", "trough.obj", collision="decomposition"))))
    first, second = cli("decompose", scene), cli("decompose", scene)
    assert first.returncode == second.returncode == 0
    assert first.stdout.splitlines()[0] == f"decomposition cache: {own_cache}"
    assert "convex parts (coacd, computed in" in first.stdout and "decomposing" in first.stderr
    assert "convex parts (coacd, from the cache)" in second.stdout and second.stderr == ""
