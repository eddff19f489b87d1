"""``physics-mapper solve``: offline search on a problem file."""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

from physics_mapper.commands.files import check_output_folder, input_file, load_problem_file, write_output
from physics_mapper.model.scene_files import search_with_overrides
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.report import result_dict, result_summary, trace_entry_dict, trace_tree
from physics_mapper.search.strategy import solve

HELP = "search a problem file (scene + hypotheses) for the best physically valid configuration"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("problem", type=input_file, help="problem YAML: a scene plus hypotheses per object")
    parser.add_argument("--trace", type=Path, metavar="FILE.json", help="write the visited nodes, in order, as JSON")
    parser.add_argument("--json", action="store_true", help="print the whole result as JSON instead of text")
    parser.add_argument("--tree", action="store_true", help="also print the search tree (paper Fig. 4)")
    parser.add_argument(
        "--deadline", type=float, metavar="SECONDS", help="override the problem's search.deadline (wall-clock seconds)"
    )


def run(args: argparse.Namespace) -> int:
    if args.trace is not None:
        check_output_folder(args.trace)
    problem = load_problem_file(args.problem, "solve")
    params = problem.scene.search
    if args.deadline is not None:
        params = search_with_overrides(params, {"deadline": args.deadline}, "--deadline", key="")
    with PhysicsChecker(problem.scene) as checker:
        result = solve(checker, problem.hypotheses, replace(params, trace_limit=None))  # the whole trace
    if args.trace is not None:
        write_output(args.trace, json.dumps([trace_entry_dict(e) for e in result.trace], indent=1) + "\n")
    if args.json:
        print(json.dumps(result_dict(result, problem.scene.object_names), indent=1))
        return 0
    if args.tree:
        print(trace_tree(result.trace, result.groups, problem.scene.object_names))
        print()
    print(result_summary(result, params.fallback))
    return 0
