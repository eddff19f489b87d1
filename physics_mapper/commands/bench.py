"""``physics-mapper bench``: what the physics checks and the search cost on a problem, on this machine.

``--scale`` runs the scale benchmark instead (``physics_mapper.bench.scale``): the seeded
suite searched by the joint and the grouped search side by side, a PNG of the time to the answer
against N, and the memory of a node searching a 50-object scene for ``--node-minutes`` minutes.
``--crowded`` runs the crowded benchmark (``physics_mapper.bench.crowded``): packed scenes searched by
the conflict-directed, the grouped and the joint search side by side, with a PNG of the time to the
answer against N.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import yaml

from physics_mapper.commands.files import load_problem_file
from physics_mapper.model.errors import InputError
from physics_mapper.model.shipped import shipped_path

HELP = (
    "time the physics checks and an exhaustive search on a problem file, or (--scale) the scale benchmark, "
    "or (--crowded) the crowded benchmark"
)

#: The node memory figure's scene: 50 cubes in small pyramids, 100 hypotheses each (the node's most), T = 0, so the
#: search goes on for the whole run.
NODE_CASE_HYPOTHESES = 100
#: RSS the issue allows the node over ten minutes, bytes (200 MB, decimal megabytes as the issue writes them).
NODE_MEMORY_TARGET = 200 * 10**6


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "problem",
        type=Path,
        nargs="?",
        help="problem YAML (default: the shipped config/problems/pyramid.yaml)",
    )
    parser.add_argument("--repeats", type=int, default=50, help="timed repetitions per figure (default: 50)")
    scale = parser.add_argument_group("scale benchmark (--scale)")
    scale.add_argument("--scale", action="store_true", help="run the scale benchmark instead (no PROBLEM)")
    scale.add_argument("--seeds", type=int, default=3, help="problems per (layout, N, M) (default: 3)")
    scale.add_argument(
        "--node-minutes", type=float, default=10.0, help="minutes of the node memory run; 0 skips it (default: 10)"
    )
    scale.add_argument(
        "--png",
        type=Path,
        default=Path("benchmarks/scale.png"),
        help="time to answer plot (default: benchmarks/scale.png)",
    )
    scale.add_argument(
        "--groups-png",
        type=Path,
        default=Path("benchmarks/scale_groups.png"),
        help="a suite scene's interaction groups (default: benchmarks/scale_groups.png)",
    )
    scale.add_argument("--quick", action="store_true", help="a small suite (N 3, 6, 10; M 5; 1 seed), to try it out")
    crowded = parser.add_argument_group("crowded benchmark (--crowded; --seeds and --quick apply too)")
    crowded.add_argument("--crowded", action="store_true", help="run the crowded benchmark instead (no PROBLEM)")
    crowded.add_argument(
        "--crowded-png",
        type=Path,
        default=Path("benchmarks/crowded.png"),
        help="time to answer plot (default: benchmarks/crowded.png)",
    )
    crowded.add_argument(
        "--search-png",
        type=Path,
        default=Path("docs/crowded_search.png"),
        help="one crowded search, candidate by candidate (default: docs/crowded_search.png)",
    )


def run(args: argparse.Namespace) -> int:
    if args.scale:
        return run_scale(args)
    if args.crowded:
        return run_crowded(args)
    if args.repeats < 1:
        raise InputError(f"--repeats must be at least 1, got {args.repeats}")
    path = args.problem or shipped_path("config/problems/pyramid.yaml")
    problem = load_problem_file(path, "bench")
    from physics_mapper.bench.physics_costs import costs_text, measure

    scene = problem.scene
    print(
        f"{path}: {len(scene.objects)} objects, {len(scene.static)} static bodies, "
        f"settle_time {scene.search.settle_time} s; medians of {args.repeats} runs"
    )
    print(costs_text(measure(problem, args.repeats)))
    return 0


def run_scale(args: argparse.Namespace) -> int:
    """The suite's table, the targets, the plot, then the node's memory; progress on stderr."""
    if args.seeds < 1:
        raise InputError(f"--seeds must be at least 1, got {args.seeds}")
    if args.node_minutes < 0:
        raise InputError(f"--node-minutes must not be negative, got {args.node_minutes:g}")
    from physics_mapper.bench import scale
    from physics_mapper.bench.scale_suite import scale_problem

    if args.quick:
        cases = scale.suite_cases(sizes=(3, 6, 10), hypotheses=(5,), seeds=1)
    else:
        cases = scale.suite_cases(seeds=args.seeds)
    started = time.monotonic()

    def progress(done: int, total: int, run: scale.ProblemRun) -> None:
        times = " ".join(f"{s} {scale._seconds(run.runs[s].answer_time)}" for s in scale.STRATEGIES)
        print(f"[{done}/{total} {time.monotonic() - started:.0f} s] {run.case.label}: {times}", file=sys.stderr)

    problems, memory = scale.run_suite(cases, progress)
    figures = [scale.cell_figures(cell, memory) for cell in scale.by_cell(problems)]
    print(f"{len(problems)} problems, {args.seeds if not args.quick else 1} per (layout, N, M); {_load()}")
    print(scale.figures_table(figures))
    print()
    print(scale.targets_text(scale.targets(problems)))
    for path in (args.png, args.groups_png):
        path.parent.mkdir(parents=True, exist_ok=True)
    scale.plot_time_to_answer(problems, args.png)
    scale.plot_groups(scale_problem(scale.GROUPS_PICTURE), args.groups_png)
    print(f"\nplots: {args.png}, {args.groups_png}")
    if args.node_minutes > 0:
        print()
        print(node_memory_text(args.node_minutes))
    return 0


def run_crowded(args: argparse.Namespace) -> int:
    """The crowded suite's table, the targets and the plot; progress on stderr."""
    if args.seeds < 1:
        raise InputError(f"--seeds must be at least 1, got {args.seeds}")
    from physics_mapper.bench import crowded

    if args.quick:
        cases = crowded.suite_cases(sizes=(10, 20), hypotheses=(5,), seeds=1)
    else:
        cases = crowded.suite_cases(seeds=args.seeds)
    started = time.monotonic()

    def progress(done: int, total: int, run: crowded.ProblemRun) -> None:
        times = " ".join(f"{s} {crowded._seconds(run.runs[s].answer_time)}" for s in crowded.STRATEGIES)
        print(f"[{done}/{total} {time.monotonic() - started:.0f} s] {run.case.label}: {times}", file=sys.stderr)

    problems = crowded.run_suite(cases, progress)
    reduced = crowded.run_suite(crowded.REDUCED, progress)
    from physics_mapper.bench import scale

    scale_cases = scale.suite_cases(sizes=(3, 6, 10), hypotheses=(5,), seeds=1) if args.quick else scale.suite_cases()

    def scale_progress(done: int, total: int) -> None:
        print(f"[scale suite {done}/{total} {time.monotonic() - started:.0f} s]", file=sys.stderr)

    checked = crowded.scale_check(scale_cases, scale_progress)
    print(f"{len(problems)} problems, {1 if args.quick else args.seeds} per (layout, N, M); {_load()}")
    print("Three numbers: conflict / grouped / joint.")
    print(crowded.figures_table(problems))
    print()
    print(crowded.targets_text(problems, reduced))
    print(crowded.scale_text(checked))
    from physics_mapper.bench.crowded_picture import plot_search

    for path in (args.crowded_png, args.search_png):
        path.parent.mkdir(parents=True, exist_ok=True)
    crowded.plot_time_to_answer(problems, args.crowded_png)
    plot_search(args.search_png)
    print(f"\nplots: {args.crowded_png}, {args.search_png}")
    return 0


def _load() -> str:
    try:
        return "load average " + Path("/proc/loadavg").read_text().split()[0]
    except OSError:
        return "load average unknown"


def node_memory_text(minutes: float) -> str:
    """Run the node on 50 objects for ``minutes`` minutes with unchanged inputs; its RSS over time."""
    from physics_mapper.bench.scale_suite import ScaleCase, problem_document, scale_problem
    from physics_mapper.ros.node_memory import sample_node_memory

    problem = scale_problem(ScaleCase("pyramids", 50, NODE_CASE_HYPOTHESES, 0)).problem
    document = problem_document(problem)
    with tempfile.TemporaryDirectory(prefix="physics_mapper_memory_") as folder:
        directory = Path(folder)
        scene_document = {key: value for key, value in document.items() if key != "hypotheses"}
        (directory / "scene.yaml").write_text(yaml.safe_dump(scene_document))
        (directory / "problem.yaml").write_text(yaml.safe_dump(document))
        parameters = {"probability_threshold": 0.0, "max_age": 86400.0}
        interval = max(1.0, minutes * 60.0 / 40.0)

        def report(sample: object) -> None:
            print(f"node memory: {sample}", file=sys.stderr)

        samples = sample_node_memory(
            directory / "scene.yaml",
            directory / "problem.yaml",
            parameters,
            minutes * 60.0,
            interval,
            directory / "node.log",
            report,
        )
    mb = [sample.rss / 1e6 for sample in samples]
    verdict = "met" if max(sample.rss for sample in samples) < NODE_MEMORY_TARGET else "missed"
    middle = samples[len(samples) // 2]
    return (
        f"node, 50 objects (pyramids, M = {NODE_CASE_HYPOTHESES}, T = 0, unchanged inputs), {minutes:g} min: "
        f"RSS {mb[0]:.0f} MB at the start, {middle.rss / 1e6:.0f} MB after {middle.elapsed:.0f} s, "
        f"{mb[-1]:.0f} MB at the end, {max(mb):.0f} MB at most (target < 200 MB: {verdict})"
    )
