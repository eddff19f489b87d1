"""``physics-mapper bench NAME [ARGS]``: run the benchmark ``benchmarks/NAME.py`` on this machine.

Every benchmark is one script in ``benchmarks/``, in the checkout or installed with the shipped
files (``share/physics_mapper/benchmarks/``); ``bench NAME ARGS`` runs it as
``python benchmarks/NAME.py ARGS`` would, in this process, and ``bench`` alone lists them. A
benchmark prints its figures; it writes files (plots) only into the folder its ``-o`` names.
"""

from __future__ import annotations

import argparse
import runpy
import sys
from pathlib import Path

from physics_mapper.model.errors import InputError
from physics_mapper.model.shipped import shipped_path

HELP = "run a benchmark of benchmarks/ (NAME, then its own options; without NAME: the list)"
#: The line that makes a file of ``benchmarks/`` a benchmark rather than a module the benchmarks share.
SCRIPT_MARK = '\nif __name__ == "__main__":\n'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", nargs="?", help="the benchmark, e.g. physics_costs, scale, crowded, mesh_costs")
    parser.add_argument(
        "arguments", nargs=argparse.REMAINDER, metavar="ARG", help="the benchmark's own options (NAME --help)"
    )


def benchmarks() -> dict[str, Path]:
    """Every benchmark of the shipped ``benchmarks/`` folder, by name."""
    folder = shipped_path("benchmarks")
    return {path.stem: path for path in sorted(folder.glob("*.py")) if SCRIPT_MARK in path.read_text(encoding="utf-8")}


def run(args: argparse.Namespace) -> int:
    found = benchmarks()
    if args.name is None:
        print("\n".join(found))
        return 0
    if args.name not in found:
        raise InputError(f"no benchmark {args.name!r}; the benchmarks are: {', '.join(found)}")
    script = found[args.name]
    saved = sys.argv, sys.path[:]
    sys.argv = [str(script), *args.arguments]
    sys.path.insert(0, str(script.parent))  # as for a script: the modules beside it import by name
    try:
        runpy.run_path(str(script), run_name="__main__")
    except SystemExit as exit_:  # argparse's --help and usage errors, a script's sys.exit
        if isinstance(exit_.code, str):
            print(exit_.code, file=sys.stderr)
        return exit_.code if isinstance(exit_.code, int) else int(exit_.code is not None)
    finally:
        sys.argv, sys.path[:] = saved
    return 0
