"""``physics-mapper generate``: a scene's ground truth -> particle-filter hypotheses -> a rosbag2 bag."""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from physics_mapper.commands.files import input_file, load_scene_file
from physics_mapper.model.errors import InputError

if TYPE_CHECKING:
    import numpy as np

    from physics_mapper.bags.storage import BagWriter
    from physics_mapper.model.geometry import Pose
    from physics_mapper.model.scene import Scene
    from physics_mapper.perception.detection_faults import DetectionFaults, DetectionSimulator
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
    faults = parser.add_argument_group(
        "estimator faults (--format detections; rates are probabilities per object and frame)"
    )
    faults.add_argument("--shuffle", action="store_true", help="detections in a random order in every frame")
    faults.add_argument("--miss", type=float, default=0.0, metavar="P", help="an object is not detected (default: 0)")
    faults.add_argument(
        "--false-positives",
        type=float,
        default=0.0,
        metavar="P",
        help="detections of nothing, Binomial(objects, P) per frame (default: 0)",
    )
    faults.add_argument(
        "--air-share",
        type=float,
        default=0.5,
        metavar="SHARE",
        help="share of false positives in the air; the rest inside static bodies (default: 0.5)",
    )
    faults.add_argument(
        "--double", type=float, default=0.0, metavar="P", help="an object is detected twice (default: 0)"
    )
    faults.add_argument(
        "--double-offset",
        type=float,
        default=0.006,
        metavar="METRES",
        help="horizontal offset of a double detection (default: 0.006)",
    )
    faults.add_argument(
        "--wrong-first",
        type=float,
        default=0.0,
        metavar="P",
        help="a detection's first result is a wrong pose (default: 0)",
    )
    faults.add_argument(
        "--wrong-offset",
        type=float,
        default=0.03,
        metavar="METRES",
        help="how far a wrong pose is from the object's most likely one (default: 0.03)",
    )
    faults.add_argument(
        "--results",
        type=_result_range,
        metavar="N|MIN-MAX",
        help="results per detection, drawn uniformly in MIN-MAX (default: --top-m)",
    )
    faults.add_argument(
        "--confidence",
        type=_confidence_range,
        metavar="LOW-HIGH",
        help="scale each detection's scores so that its best is a confidence drawn in LOW-HIGH "
        "(default: scores are the normalised weights)",
    )
    faults.add_argument(
        "--ids",
        choices=("none", "stable", "reassigned"),
        default="none",
        help="Detection3D.id: empty, a tracker's id per object, or one that changes (default: none)",
    )
    faults.add_argument(
        "--id-change",
        type=float,
        default=0.1,
        metavar="P",
        help="--ids reassigned: an object gets a new id in a frame (default: 0.1)",
    )


def _result_range(text: str) -> tuple[int, int]:
    """``N`` or ``MIN-MAX`` as (MIN, MAX)."""
    low, _, high = text.partition("-")
    try:
        return int(low), int(high or low)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N or MIN-MAX, got {text!r}") from None


def _confidence_range(text: str) -> tuple[float, float]:
    """``LOW-HIGH`` as (LOW, HIGH)."""
    low, _, high = text.partition("-")
    try:
        return float(low), float(high)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LOW-HIGH, got {text!r}") from None


_SETTING_OPTIONS = {
    "particles": "particles",
    "iterations": "iterations",
    "sigma_position": "sigma",
    "sigma_rotation": "sigma_rotation",
    "top_m": "top_m",
}


def run(args: argparse.Namespace) -> int:
    from physics_mapper.bags.storage import BagError, BagWriter
    from physics_mapper.perception.detection_faults import DetectionSimulator
    from physics_mapper.perception.particle_filter import fault_generator, run_generators, settle_ground_truth

    scene = load_scene_file(args.scene, "generate")
    if scene.ground_truth is None:
        raise InputError(f"{args.scene}: ground_truth: missing: generate needs every object's true pose")
    settings = _settings(args)
    period_ns = _period_ns(args.period, len(scene.objects))
    faults = _faults(args, settings.sigma_position)
    truth = settle_ground_truth(scene, scene.ground_truth)
    try:
        with BagWriter(args.output, args.storage) as writer:
            for run_index, rng in enumerate(run_generators(args.seed, args.runs)):
                estimator = None
                if faults is not None:
                    estimator = DetectionSimulator(
                        scene, truth, faults, fault_generator(args.seed, run_index), settings.top_m
                    )
                _write_run(writer, scene, truth, settings, rng, run_index, period_ns, estimator)
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


_FAULT_OPTIONS = ("shuffle", "miss", "false_positives", "double", "wrong_first", "results", "confidence")


def _faults(args: argparse.Namespace, sigma_position: float) -> DetectionFaults | None:
    """The estimator's faults for ``--format detections`` (None for PoseArrays), false positives scattered
    by the measurement's ``sigma_position``; InputError for a fault option without it or a value out of range."""
    from physics_mapper.perception.detection_faults import DetectionFaults, faults_problem

    if args.format != "detections":
        given = [option for option in _FAULT_OPTIONS if getattr(args, option) not in (None, False, 0.0)]
        if args.ids != "none":
            given.append("ids")
        if given:
            raise InputError(f"--{given[0].replace('_', '-')} is for --format detections")
        return None
    low, high = args.results if args.results is not None else (None, None)
    faults = DetectionFaults(
        shuffle=args.shuffle,
        miss=args.miss,
        false_positive=args.false_positives,
        air_share=args.air_share,
        double=args.double,
        double_offset=args.double_offset,
        wrong_first=args.wrong_first,
        wrong_offset=args.wrong_offset,
        results_min=low,
        results_max=high,
        confidence=args.confidence,
        ids=args.ids,
        id_change=args.id_change,
        sigma_position=sigma_position,
    )
    problem = faults_problem(faults)
    if problem is not None:
        raise InputError(problem)
    return faults


def _write_run(
    writer: BagWriter,
    scene: Scene,
    truth: tuple[Pose, ...],
    settings: TrackerSettings,
    rng: np.random.Generator,
    run_index: int,
    period_ns: int,
    estimator: DetectionSimulator | None,
) -> None:
    """One particle-filter run: per iteration, every object's hypotheses and weights (with an ``estimator``:
    one Detection3DArray of its detections made of them, faults and all), then the ground truth.

    Iteration k of run r is stamped START_TIME_NS + (r * iterations + k) * period_ns; within an
    iteration the messages get distinct, increasing bag times (1 ns apart) so their order is unambiguous.
    """
    from physics_mapper.bags.storage import POSE_ARRAY, pose_array_cdr
    from physics_mapper.mapping.topics import GROUND_TRUTH_TOPIC
    from physics_mapper.perception.particle_filter import track

    for iteration, snapshot in enumerate(track(scene, truth, settings, rng)):
        stamp = START_TIME_NS + (run_index * settings.iterations + iteration) * period_ns
        if estimator is not None:
            detected = [(d.class_id, d.hypotheses, d.id) for d in estimator.frame(snapshot)]
            writer.write_detections(stamp, stamp, scene.frame_id, detected)
        for index, (model, hypotheses) in enumerate(zip(scene.objects, snapshot, strict=True)):
            if estimator is None:
                writer.write_hypotheses(stamp + 2 * index, stamp, scene.frame_id, model.name, hypotheses)
        truth_raw = pose_array_cdr(stamp, scene.frame_id, truth)
        writer.write(GROUND_TRUTH_TOPIC, POSE_ARRAY, stamp + 2 * len(scene.objects), truth_raw)
