"""``physics-mapper sweep``: ``evaluate`` over a grid of search settings; the best as node parameters."""

from __future__ import annotations

import argparse

from physics_mapper.commands.evaluate import (
    add_batch_arguments,
    command_line,
    exit_code,
    load_scene_and_search,
    run_batch_command,
)
from physics_mapper.model.errors import EXIT_FAILURE

HELP = "evaluate bags over a grid of search settings: table, heat maps, and the best as a node parameters file"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_batch_arguments(parser, "sweep")
    parser.add_argument(
        "--grid",
        action="append",
        required=True,
        metavar="KEY=V1,V2,...",
        help="a search key and the values to try; repeat for more keys (every combination is evaluated)",
    )
    parser.add_argument(
        "--criterion",
        choices=("settled", "chosen", "valid"),
        default="settled",
        help="best setting: lowest error of the settled map (default) or of the chosen hypotheses, a snapshot "
        "without a map counting with C11..1's; or the highest share of valid maps",
    )


def run(args: argparse.Namespace) -> int:
    from physics_mapper.evaluation.reports import ReportContext, write_sweep
    from physics_mapper.evaluation.settings import grid_settings

    scene, params = load_scene_and_search(args)
    fixed = [assignment.partition("=")[0].strip() for assignment in args.set]
    settings = grid_settings(params, args.grid, fixed)
    batch = run_batch_command(args, scene, settings)
    if batch is None:
        return EXIT_FAILURE
    context = ReportContext(command_line(args), args.scene)
    output, params_file = write_sweep(batch, context, args.criterion, args.output)
    best = output.summary["best"]
    if best is None:
        print(f"{len(settings)} settings: none has results from every usable bag, no best")
    else:
        overall = output.summary["settings"][best["index"]]["overall"]
        print(
            f"{len(settings)} settings; best by {output.summary['criterion']['name']}: #{best['index']} {best['label']}"
        )
        print(f"  valid map in {100.0 * overall['valid_share']:.0f} % of {overall['snapshots']} snapshots")
        print(
            f"  node parameters: {params_file}" if params_file else f"  no node parameters: {best['params_file_error']}"
        )
    print(f"report: {output.markdown} (and {output.json.name}, {output.png.name})")
    return exit_code(batch)
