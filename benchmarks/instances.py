"""Bins of identical objects as an estimator reports them: identities, maps and time per tick, in one run.

Run: ``.venv/bin/python benchmarks/instances.py [--frames 30] [--particles 300] [--sizes 6 12 24] [--shapes box
cylinder mesh jenga flat] [--object YAML] [--layers 1 2] [--seed 0] [--scaled | --deadline S] [-o DIR]``, or
``physics-mapper bench instances`` with the same options. ``--object`` bins a part of your own: a scene file's
object entry, e.g. ``'{name: mug, shape: mesh, file: "package://pybullet_data/objects/mug.obj", collision:
decomposition, parts: "package://pybullet_data/objects/mug_col.obj", mass: 0.3}'`` (the mesh's frame need
not be at its centre).

For each bin (N identical objects of one shape, in one or two layers, in a bin of four walls on a
floor; ``count: N`` in the scene file; the shapes: 8 cm cubes, cylinders, pybullet_data's lego parts, its jenga
blocks, 15 x 5 x 3 cm, and its random object 002, flat, 12 x 9 x 3 cm), ``physics-mapper generate`` writes three
bags from the same seed, so with the same particle-filter hypotheses (the faults draw from a stream of their own):

* **faulty**: ``--format detections`` at 2 Hz with the estimator's faults: order shuffled, 10 % misses,
  10 % false positives (half in the air, half inside the walls or the floor), 5 % double detections,
  3-5 results per detection, 25 % with a wrong pose (3 cm off) first, the best result scored 0.7 to 0.95,
  no ids;
* **identified**: the faulty bag's very detections (the same draws: ids draw nothing), each true object's
  with a tracker's stable ``Detection3D.id`` (``--ids stable``; a double or a false positive gets an id of
  its own): the same estimator with identities given, the reference for the position error by identity;
* **named**: the same particle-filter hypotheses as PoseArrays per object name, in a stable order,
  without any fault (no wrong pose first either): what a user gets from a faultless estimator that
  names every object.

Each bag is replayed offline as the node would tick (``replay_offline``: each snapshot searched to the scene's
deadline, 0.2 s, the node's default, or with ``--scaled`` to that deadline scaled to this machine, 0.2 s x
reference / 6.3 ms, the reference measured again just before each bag's replay (this machine's speed drifts: its
reference went from 8 to 15 ms within a second, and from 13 to 7 ms within minutes), or with ``--deadline S``
for S seconds (a long search tells which snapshots' hypotheses hold a valid configuration at all); the next
snapshots following the map chosen: the map remembered, instances confirmed by valid maps, left-out tentative
ones ended) and scored by identity (:mod:`physics_mapper.evaluation.identity`, matched within its gate, half the
spacing of the lego parts). Printed per bin: identity
switches, IDF1 of the faulty, the identified and the named bag (the identified bag is the faulty one with a
tracker's ids: what the faulty bag's IDF1 falls short of it is identity lost in association), MOTA, false positives
in the map (map objects matched to no true object within the gate) and
among them the false objects (matched to none within the object's largest extent: a false detection or a second
instance of one object; the others are true objects placed beyond the gate), misses, snapshots with a valid map
(and among them the previous map's, :mod:`physics_mapper.mapping.previous_map`) and the snapshots without one
(numbered from 0, in spans: ``0-4, 12``), those of the named bag (the
same hypotheses without the estimator's faults: how many snapshots they allow a valid map within the deadline at
all), those with the refined map instead (``fallback: refine``: a physically consistent map where no
configuration of the hypotheses was found valid) and among them those that keep Rule 1 and Rule 2 (the map's
deepest overlap, and a settling from rest at the map: :func:`within_rules`), the double detections of the faulty
bag and how many of them the map holds once and twice or more (:func:`double_detections`: a second instance of an
object detected twice is what it must not hold), the position error by identity
of the faulty, the identified and the named bag, and the share of ticks whose search finished within the
deadline (else it stopped there with its best so far), and each bag's deadline. The reference settling
(``crowded.py``'s: Rule 2 on the shipped ``stack`` problem's three cubes with pybullet's own solver, the median of
9, measured in this run) is printed first: deadlines scale with it (0.2 s at 6.3 ms).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from crowded import ReferenceSettling, scaled_deadline

from physics_mapper.bags.storage import Bag, detections_from_cdr, read_bag
from physics_mapper.cli import main as cli_main
from physics_mapper.evaluation.identity import identity_metrics, record_frames
from physics_mapper.evaluation.scoring import ObjectClasses
from physics_mapper.evaluation.snapshot_results import SnapshotResult, replay_offline, snapshot_result_dict
from physics_mapper.evaluation.snapshots import input_topics
from physics_mapper.mapping.association import Observation
from physics_mapper.mapping.detection_data import DetectionData, detection_array_data
from physics_mapper.mapping.detections import RECORDED_DETECTIONS_TOPIC
from physics_mapper.model.extents import body_box, shape_extents
from physics_mapper.model.geometry import ORIGIN
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import load_scene
from physics_mapper.physics.checker import PhysicsChecker

REPO = Path(__file__).resolve().parent.parent
#: Objects per layer along x and y for each count and layer number.
GRIDS = {(6, 1): (3, 2), (6, 2): (3, 1), (12, 1): (4, 3), (12, 2): (3, 2), (24, 1): (6, 4), (24, 2): (4, 3)}
SHAPES: dict[str, dict[str, Any]] = {
    "box": {"shape": "box", "size": [0.08, 0.08, 0.08], "mass": 0.2},
    "cylinder": {"shape": "cylinder", "radius": 0.035, "length": 0.08, "mass": 0.2},
    "mesh": {"shape": "mesh", "file": "package://pybullet_data/lego/lego.obj", "scale": 0.1, "mass": 0.01},
    # Long and flat parts: half their largest extent reaches past their neighbours and a layer.
    "jenga": {"shape": "mesh", "file": "package://pybullet_data/jenga/jenga.obj", "scale": [0.15, 0.05, 0.03],
              "mass": 0.05},
    "flat": {"shape": "mesh", "file": "package://pybullet_data/random_urdfs/002/002.obj", "scale": 0.015,
             "collision": "convex_hull", "mass": 0.1},
}  # fmt: skip
FAULTS = [
    "--format", "detections", "--shuffle", "--miss", "0.1", "--false-positives", "0.1", "--air-share", "0.5",
    "--double", "0.05", "--results", "3-5", "--wrong-first", "0.25", "--confidence", "0.7-0.95",
]  # fmt: skip
#: The bags of one bin and their ``generate`` options (module docstring).
BAGS = {"faulty": FAULTS, "identified": [*FAULTS, "--ids", "stable"], "named": []}
GAP = 0.01  # metres between neighbours
DEADLINE = 0.2  # s, the node's default
#: Metres a double detection's results lie from the detection's at most (``generate``'s offset is 6 mm).
DOUBLE_OFFSET_LIMIT = 0.05


def _box(entry: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The object's axis-aligned box at the origin (corners, m), read through a one-object scene."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "one.yaml"
        path.write_text(yaml.safe_dump({"frame_id": "world", "objects": [{"name": "o", **entry}]}))
        low, high = body_box(load_scene(path).objects[0].shape, ORIGIN)
    return np.asarray(low, dtype=float), np.asarray(high, dtype=float)


def bin_scene(shape: str, entry: dict[str, Any], count: int, layers: int) -> dict[str, Any]:
    """A scene document: ``count`` instances of ``entry`` (a scene file's object keys but ``name``), named
    ``shape``, in columns of ``layers`` in a bin, their truth: each body's box in its cell, resting 1 mm above
    the one below (a mesh's frame need not be at its centre)."""
    low, high = _box(entry)
    size = tuple(float(v) for v in high - low)
    nx, ny = GRIDS[(count, layers)]
    pitch = (size[0] + GAP, size[1] + GAP)
    truth: dict[str, Any] = {}
    index = 0
    for layer in range(layers):
        for j in range(ny):
            for i in range(nx):
                index += 1
                x = (i - (nx - 1) / 2) * pitch[0] - (low[0] + high[0]) / 2
                y = (j - (ny - 1) / 2) * pitch[1] - (low[1] + high[1]) / 2
                z = size[2] * layer - low[2] + 0.001
                truth[f"{shape}_{index}"] = {"position": [float(x), float(y), float(z)], "orientation": [0, 0, 0, 1]}
    half = (nx * pitch[0] / 2 + 0.02, ny * pitch[1] / 2 + 0.02)
    height = size[2] * 0.6
    walls = [
        {"name": "wall_x_low", "shape": "box", "size": [0.02, 2 * half[1] + 0.04, height],
         "pose": {"position": [-half[0] - 0.01, 0.0, height / 2]}},
        {"name": "wall_x_high", "shape": "box", "size": [0.02, 2 * half[1] + 0.04, height],
         "pose": {"position": [half[0] + 0.01, 0.0, height / 2]}},
        {"name": "wall_y_low", "shape": "box", "size": [2 * half[0], 0.02, height],
         "pose": {"position": [0.0, -half[1] - 0.01, height / 2]}},
        {"name": "wall_y_high", "shape": "box", "size": [2 * half[0], 0.02, height],
         "pose": {"position": [0.0, half[1] + 0.01, height / 2]}},
    ]  # fmt: skip
    return {
        "frame_id": "world",
        "static": [{"name": "floor", "shape": "plane"}, *walls],
        "objects": [{"name": shape, **entry, "count": count}],
        "ground_truth": truth,
        "search": {
            "probability_threshold": 0.0002,
            "penetration_threshold": 0.01,
            "jitter_threshold": 0.02,
            "angular_weight": 0.1,
            "settle_time": 0.5,
            "deadline": DEADLINE,
            "fallback": "refine",
        },
    }


def _generate(scene_file: Path, bag: Path, extra: list[str], frames: int, particles: int, seed: int) -> None:
    arguments = [
        "generate", str(scene_file), "-o", str(bag), "--iterations", str(frames), "--particles", str(particles),
        "--sigma", "0.005", "--period", "0.5", "--seed", str(seed), *extra,
    ]  # fmt: skip
    errors = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(errors):
        code = cli_main(arguments)
    if code != 0:  # e.g. the bag is already there (a second run with the same -o)
        raise SystemExit(f"physics-mapper {' '.join(arguments)} failed:\n{errors.getvalue().strip()}")


def replay(scene: Scene, bag: Path, deadline: float) -> dict[str, Any]:
    """The offline replay's figures of one bag, each snapshot searched for ``deadline`` seconds (module docstring)."""
    recorded = read_bag(bag, input_topics(scene))
    results = replay_offline(recorded, scene, deadline)
    objects = ObjectClasses.of(scene)
    records = [snapshot_result_dict(r, objects) for r in results]
    frames = record_frames(records)
    identity = identity_metrics(frames, objects)
    size = max(float(np.max(shape_extents(o.shape))) for o in scene.objects)
    loose = identity_metrics(frames, objects, size)
    doubles = double_detections(recorded, results, records, size)
    assert identity is not None and loose is not None
    finished = sum(1 for r in results if r.search is not None and not r.search.stats.stopped_at_deadline)
    refined = [r for r in results if r.search is not None and r.search.fallback == "refine"]
    with PhysicsChecker(scene) as checker:
        refined_within_rules = sum(1 for r in refined if within_rules(checker, r))
    return {
        "deadline": deadline,
        "snapshots": len(results),
        "valid": sum(1 for r in results if r.search is not None and r.search.valid),
        "without_valid": [k for k, r in enumerate(results) if r.search is None or not r.search.valid],
        "refined": len(refined),
        "refined_within_rules": refined_within_rules,
        "previous_map": sum(1 for r in results if r.search is not None and r.search.previous_map),
        "finished": finished,
        "identity": identity,
        "false_objects": loose["false_positives"],
        "doubles": doubles,
    }


def double_detections(
    bag: Bag, results: list[SnapshotResult], records: list[dict[str, Any]], size: float
) -> tuple[int, int, int]:
    """The double detections of a bag and how the maps hold their objects: (doubles, held once, held twice or
    more). The bag does not say which detection is which; the simulator makes a double by moving a
    detection's results (the same scores) by one horizontal offset (:func:`_doubled`), and its object is the
    true object nearest where the detection puts it (:func:`_where_seen`). The map holds that object as many
    times as it has map objects whose nearest true object it is, within ``size`` metres (the object's
    largest extent: a second instance of it lies there). Once is one instance; none, a miss the misses
    count."""
    arrays = [
        (message.time_ns, detection_array_data(detections_from_cdr(message.raw, bag.definitions)))
        for message in bag.on(RECORDED_DETECTIONS_TOPIC)
    ]
    doubles = once = twice = 0
    for result, record in zip(results, records, strict=True):
        array = next((data for time_ns, data in reversed(arrays) if time_ns <= result.snapshot.time_ns), None)
        positions = record["positions"]
        if array is None or positions["truth"] is None or positions["map"] is None:
            continue
        truth = np.asarray(positions["truth"], dtype=float)
        held = [_nearest(truth, np.asarray(p, dtype=float), size) for p in positions["map"].values()]
        for detection in _doubled(array.detections):
            index = _nearest(truth, _where_seen(detection), size)
            doubles += 1
            once += index is not None and held.count(index) == 1
            twice += index is not None and held.count(index) > 1
    return doubles, once, twice


def _doubled(detections: tuple[DetectionData, ...]) -> list[DetectionData]:
    """One of each pair of detections whose results are the same but for one horizontal offset (at most
    :data:`DOUBLE_OFFSET_LIMIT` metres): the simulator's double detections."""
    found = []
    for k, first in enumerate(detections):
        for second in detections[k + 1 :]:
            if len(first.scores) != len(second.scores) or not np.array_equal(first.scores, second.scores):
                continue
            moved = np.asarray(second.poses, dtype=float)[:, :3] - np.asarray(first.poses, dtype=float)[:, :3]
            offset = moved[0]
            if (
                np.allclose(moved, offset, atol=1e-9)
                and offset[2] == 0.0
                and np.linalg.norm(offset) <= DOUBLE_OFFSET_LIMIT
            ):
                found.append(first)
    return found


def _where_seen(detection: DetectionData) -> np.ndarray:
    """Where a detection puts its object (m): its central result's position, as the association places a new
    track (:attr:`~physics_mapper.mapping.association.Observation.central`: a wrong pose ranked first,
    centimetres off, does not pull it away)."""
    poses = np.asarray(detection.poses, dtype=float)
    return np.asarray(Observation("", poses[:, :3], poses[:, 3:], np.asarray(detection.scores)).place())


def _nearest(truth: np.ndarray, position: np.ndarray, within: float) -> int | None:
    """The index of the true position nearest ``position``, if within ``within`` metres."""
    distances = np.linalg.norm(truth - position, axis=1)
    index = int(np.argmin(distances))
    return index if distances[index] <= within else None


def spans(indices: list[int]) -> str:
    """Ascending indices as spans, ``0-4, 12, 14``; ``none`` for no index."""
    runs: list[list[int]] = []
    for index in indices:
        if runs and index == runs[-1][-1] + 1:
            runs[-1].append(index)
        else:
            runs.append([index])
    return ", ".join(f"{run[0]}-{run[-1]}" if len(run) > 1 else f"{run[0]}" for run in runs) or "none"


def bag_deadline(reference: ReferenceSettling | None, fixed: float) -> float:
    """Seconds each snapshot of a bag is searched: ``fixed``, or with a ``reference``, the node's deadline scaled to
    the reference settling measured now, just before the bag's replay (module docstring)."""
    return fixed if reference is None else scaled_deadline(reference.measure())


def within_rules(checker: PhysicsChecker, result: SnapshotResult) -> bool:
    """Whether a snapshot's map (its settled poses, the objects it leaves out parked) keeps Rule 1 and Rule 2
    with the scene's thresholds: a physically consistent map, though no configuration of the hypotheses."""
    assert result.code is not None and result.settled is not None
    params = checker.scene.search
    present = [i for i, rank in enumerate(result.code) if not result.snapshot.hypotheses[i].is_absent(rank)]
    poses = [result.settled[i] for i in present]
    deepest = max(checker.contact_depths(present, poses).values(), default=0.0)
    settling = checker.settle(poses, params.settle_time, params.angular_weight, objects=present)
    return deepest <= params.penetration_threshold and settling.is_stable(params.jitter_threshold)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=30, help="frames per bag (default: 30, at 2 Hz)")
    parser.add_argument(
        "--particles", type=int, default=300, help="particles of the simulated estimator per object (default: 300)"
    )
    parser.add_argument("--sizes", type=int, nargs="+", default=[6, 12, 24], help="objects per bin (default: 6 12 24)")
    parser.add_argument("--shapes", nargs="+", help=f"of {', '.join(SHAPES)} (default: all, or --object's alone)")
    parser.add_argument(
        "--layers", type=int, nargs="+", default=[1, 2], help="layers of objects per bin (default: 1 2)"
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the simulated estimator and its faults (default: 0)"
    )
    searched = parser.add_mutually_exclusive_group()
    searched.add_argument(
        "--scaled", action="store_true", help="search each snapshot to the deadline scaled to this machine's reference"
    )
    searched.add_argument(
        "--deadline",
        type=float,
        help="search each snapshot this many seconds (a long one: which snapshots hold a valid map)",
    )
    parser.add_argument(
        "--object",
        metavar="YAML",
        help="one more shape: a scene file's object entry, e.g. '{name: mug, shape: mesh, file: "
        "package://pybullet_data/objects/mug.obj, collision: decomposition, parts: "
        "package://pybullet_data/objects/mug_col.obj, mass: 0.3}' (without --shapes, the only one)",
    )
    parser.add_argument("-o", "--output", type=Path, help="keep the scenes and bags here (default: a temporary folder)")
    args = parser.parse_args()
    shapes = dict(SHAPES)
    if args.object is not None:
        name, entry = _object_entry(args.object)
        shapes[name] = entry
        args.shapes = args.shapes or [name]
    args.shapes = args.shapes or list(SHAPES)
    unknown = [shape for shape in args.shapes if shape not in shapes]
    if unknown:
        parser.error(f"unknown shapes {unknown}: {sorted(shapes)} (or one more with --object)")
    with ReferenceSettling() as settling, tempfile.TemporaryDirectory() as temporary:
        reference = settling.measure()
        fixed = args.deadline or DEADLINE
        each = "to that deadline scaled to a reference measured beside each bag" if args.scaled else f"{fixed:g} s"
        print(f"reference settling (stack, Rule 2): {reference * 1000:.1f} ms; the {DEADLINE} s deadline scaled to "
              f"this machine is {scaled_deadline(reference):.2f} s; each snapshot searched {each}")  # fmt: skip
        header = (
            "| bin | objects | switches | IDF1, faulty / identified / named | MOTA | FP in map (false objects) "
            "| misses | valid maps (previous map's) | snapshots without one | valid maps, named "
            "| refined maps (within Rules 1 and 2) | double detections: held once / twice "
            "| error by identity, faulty / identified / named [cm] | ticks finished within the deadline "
            "| deadline, faulty / identified / named [s] |"
        )
        print(header)
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |" + " ---: |" * 6)
        folder = args.output or Path(temporary)
        folder.mkdir(parents=True, exist_ok=True)
        for shape in args.shapes:
            for count in args.sizes:
                for layers in args.layers:
                    name = f"{shape}_{count}x{layers}"
                    scene_file = folder / f"{name}.yaml"
                    document = bin_scene(shape, shapes[shape], count, layers)
                    scene_file.write_text(yaml.safe_dump(document, sort_keys=False))
                    scene = load_scene(scene_file)
                    for bag, extra in BAGS.items():
                        _generate(scene_file, folder / f"{name}_{bag}", extra, args.frames, args.particles, args.seed)
                    replays = [
                        replay(scene, folder / f"{name}_{bag}", bag_deadline(settling if args.scaled else None, fixed))
                        for bag in ("faulty", "identified", "named")
                    ]
                    faulty, references = replays[0], replays[1:]
                    errors = " / ".join(_cm(r["identity"]["identity_error_m"]) for r in replays)
                    idf1 = " / ".join(f"{r['identity']['idf1']:.3f}" for r in replays)
                    deadlines = " / ".join(f"{r['deadline']:.2f}" for r in replays)
                    i, n = faulty["identity"], faulty["snapshots"]
                    print(
                        f"| {shape}, {layers} layer(s) | {count} | {i['switches']} | {idf1} | "
                        f"{i['mota']:.3f} | {i['false_positives']} ({faulty['false_objects']}) | {i['misses']} | "
                        f"{faulty['valid']}/{n} ({faulty['previous_map']}) | {spans(faulty['without_valid'])} | "
                        f"{references[1]['valid']}/{references[1]['snapshots']} | "
                        f"{faulty['refined']} ({faulty['refined_within_rules']}) | {_doubles(faulty['doubles'])} | "
                        f"{errors} | "
                        f"{faulty['finished']}/{n} | {deadlines} |",
                        flush=True,
                    )


def _object_entry(text: str) -> tuple[str, dict[str, Any]]:
    """``--object``'s YAML: the shape's name (its ``name``, else ``object``) and its other keys."""
    try:
        entry = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise SystemExit(f"--object: not YAML: {error}") from None
    if not isinstance(entry, dict) or "shape" not in entry:
        raise SystemExit(f"--object: a scene file's object entry (a mapping with 'shape') is needed, not {text!r}")
    name = str(entry.pop("name", "object"))
    return name, entry


def _doubles(counts: tuple[int, int, int]) -> str:
    doubles, once, twice = counts
    return f"{doubles}: {once} / {twice}"


def _cm(metres: float | None) -> str:
    return "-" if metres is None else f"{metres * 100:.2f}"


if __name__ == "__main__":
    main()
