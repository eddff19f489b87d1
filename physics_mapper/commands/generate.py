"""``physics-mapper generate``: a scene's ground truth -> particle-filter hypotheses -> a rosbag2 bag."""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from physics_mapper.commands.files import input_file
from physics_mapper.model.errors import InputError

if TYPE_CHECKING:
    import numpy as np

    from physics_mapper.bags.storage import BagWriter
    from physics_mapper.model.geometry import Pose
    from physics_mapper.model.scene import Scene
    from physics_mapper.perception.particle_filter import TrackerSettings

HELP = "simulate noisy measurements and a particle filter per object; write the hypotheses to a bag"

#: Bag time of the first iteration, nanoseconds (fixed, so that a seed reproduces the bag exactly).
START_TIME_NS = 1_000_000_000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # Tracker defaults live in TrackerSettings; an option left out (None) keeps them.
    parser.add_argument("scene", type=input_file, help="scene YAML with a ground_truth: section")
    parser.add_argument("-o", "--output", type=Path, required=True, metavar="BAG", help="bag directory to create")
    parser.add_argument("--runs", type=int, default=1, help="independent particle-filter runs (default: 1)")
    parser.add_argument(
        "--sigma", type=float, metavar="METRES", help="measurement noise sigma per position axis (default: 0.03)"
    )
    parser.add_argument(
        "--sigma-rotation",
        type=float,
        metavar="RADIANS",
        help="measurement noise sigma per rotation axis (default: 0.0524, 3 degrees)",
    )
    parser.add_argument("--particles", type=int, help="particles per object (default: 1000)")
    parser.add_argument("--iterations", type=int, help="measurement updates per run (default: 10)")
    parser.add_argument("--top-m", type=int, help="hypotheses per object and iteration (default: 5)")
    parser.add_argument(
        "--seed", type=int, default=0, help="random seed; run k uses child k of SeedSequence(seed) (default: 0)"
    )
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap", help="bag format (default: mcap)")
    parser.add_argument(
        "--period", type=float, default=0.5, metavar="SECONDS", help="bag time between iterations (default: 0.5)"
    )
    parser.add_argument(
        "--format",
        choices=("pose-arrays", "detections"),
        default="pose-arrays",
        help="hypotheses as a PoseArray and weights per object (default), or one vision_msgs/Detection3DArray "
        "on /detections per iteration, scores as weights, as a pose estimator publishes them",
    )


_SETTING_OPTIONS = {
    "particles": "particles",
    "iterations": "iterations",
    "sigma_position": "sigma",
    "sigma_rotation": "sigma_rotation",
    "top_m": "top_m",
}


def run(args: argparse.Namespace) -> int:
    from physics_mapper.bags.storage import BagError, BagWriter
    from physics_mapper.model.scene_files import load_scene
    from physics_mapper.model.scene_loading import load_stoppably
    from physics_mapper.perception.particle_filter import run_generators, settle_ground_truth

    scene = load_stoppably(args.scene, load_scene)
    if scene.ground_truth is None:
        raise InputError(f"{args.scene}: ground_truth: missing: generate needs every object's true pose")
    settings = _settings(args)
    period_ns = _period_ns(args.period, len(scene.objects))
    detections = args.format == "detections"
    truth = settle_ground_truth(scene, scene.ground_truth)
    try:
        with BagWriter(args.output, args.storage) as writer:
            for run_index, rng in enumerate(run_generators(args.seed, args.runs)):
                _write_run(writer, scene, truth, settings, rng, run_index, period_ns, detections)
                print(f"generate: run {run_index + 1}/{args.runs} written", file=sys.stderr)
    except BagError as error:
        raise InputError(str(error)) from None
    print(
        f"wrote {args.output} ({args.storage}): {args.runs} run(s) x {settings.iterations} iterations, "
        f"{len(scene.objects)} objects x {settings.top_m} hypotheses, "
        f"sigma {settings.sigma_position} m, seed {args.seed}"
    )
    return 0


def _period_ns(period: float, objects: int) -> int:
    """``--period`` in whole nanoseconds; InputError if iterations would collide, a warning if they would merge.

    An iteration writes 2 * objects + 1 messages at consecutive nanoseconds, so the next one
    must start at least that many nanoseconds later. Offline replay takes messages less than
    BURST_GAP_NS apart as one burst, so a shorter gap between iterations puts several into one snapshot.
    """
    from physics_mapper.evaluation.snapshots import BURST_GAP_NS
    from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND

    if not (math.isfinite(period) and period > 0.0):
        raise InputError(f"--period must be positive and finite, got {period}")
    period_ns = round(period * NANOSECONDS_PER_SECOND)
    messages = 2 * objects + 1
    if period_ns < messages:
        raise InputError(
            f"--period {period:g} s is {period_ns} ns: an iteration's {messages} messages take {messages} ns "
            f"(1 ns apart), so iterations would collide; use at least {messages} ns"
        )
    if period_ns - (messages - 1) < BURST_GAP_NS:
        print(
            f"generate: warning: --period {period:g} s leaves less than "
            f"{BURST_GAP_NS / NANOSECONDS_PER_SECOND:g} s between "
            "iterations: offline replay takes several iterations as one snapshot",
            file=sys.stderr,
        )
    return period_ns


def _settings(args: argparse.Namespace) -> TrackerSettings:
    """Tracker settings from the options given; InputError for values out of range."""
    from physics_mapper.perception.particle_filter import TrackerSettings, tracker_settings_problem

    given = {setting: getattr(args, option) for setting, option in _SETTING_OPTIONS.items()}
    settings = replace(TrackerSettings(), **{setting: value for setting, value in given.items() if value is not None})
    problem = tracker_settings_problem(settings)
    if problem is None and args.runs < 1:
        problem = f"--runs must be at least 1, got {args.runs}"
    if problem is None and args.seed < 0:
        problem = f"--seed must not be negative, got {args.seed}"
    if problem is not None:
        raise InputError(problem)
    return settings


def _write_run(
    writer: BagWriter,
    scene: Scene,
    truth: tuple[Pose, ...],
    settings: TrackerSettings,
    rng: np.random.Generator,
    run_index: int,
    period_ns: int,
    detections: bool,
) -> None:
    """One particle-filter run: per iteration, every object's hypotheses and weights (``detections``: one
    Detection3DArray of them, each object's class id as the scene's ``class_map`` gives it), then the ground truth.

    Iteration k of run r is stamped START_TIME_NS + (r * iterations + k) * period_ns; within an
    iteration the messages get distinct, increasing bag times (1 ns apart) so their order is unambiguous.
    """
    from physics_mapper.bags.storage import POSE_ARRAY, pose_array_cdr
    from physics_mapper.mapping.topics import GROUND_TRUTH_TOPIC
    from physics_mapper.perception.particle_filter import track

    for iteration, snapshot in enumerate(track(scene, truth, settings, rng)):
        stamp = START_TIME_NS + (run_index * settings.iterations + iteration) * period_ns
        if detections:
            detected = [(scene.class_of(model.name), h) for model, h in zip(scene.objects, snapshot, strict=True)]
            writer.write_detections(stamp, stamp, scene.frame_id, detected)
        for index, (model, hypotheses) in enumerate(zip(scene.objects, snapshot, strict=True)):
            if not detections:
                writer.write_hypotheses(stamp + 2 * index, stamp, scene.frame_id, model.name, hypotheses)
        truth_raw = pose_array_cdr(stamp, scene.frame_id, truth)
        writer.write(GROUND_TRUTH_TOPIC, POSE_ARRAY, stamp + 2 * len(scene.objects), truth_raw)
