"""``physics-mapper``: one entry point, one module per subcommand (SPEC section 5).

Exit codes: 0 success, 1 a run-time failure, 2 bad arguments or input files, 3 a report written
without some of its bags (``evaluate``, ``sweep``), 130 stopped by Ctrl-C.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from physics_mapper.commands import COMMANDS, command_module
from physics_mapper.core.errors import EXIT_BAD_INPUT, EXIT_INTERRUPTED, InputError
from physics_mapper.core.scene_files import SceneError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="physics-mapper",
        description="Physically consistent multi-object maps from weighted pose hypotheses (Wagle & Correll 2010).",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        module = command_module(name)
        sub = subparsers.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(sub)
        sub.set_defaults(run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.run(args))
    except (SceneError, InputError) as error:
        print(f"physics-mapper {args.command}: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
