"""The scale benchmark: joint and grouped searches side by side, the time-to-answer plot, node memory.

Run: ``.venv/bin/python benchmarks/scale.py [--seeds N] [--node-minutes M] [--png PATH] [--quick]``,
the same as ``physics-mapper bench --scale``. Prints the markdown table and the targets that
BENCHMARKS.md records ("Scale"), writes the PNG, then samples a 50-object node's memory for
``--node-minutes`` minutes (10 by default; 0 skips it). Progress goes to stderr. The full suite
takes about 15 minutes plus the node run on an otherwise idle 2-core machine.
"""

from __future__ import annotations

import sys

from physics_mapper.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", "--scale", *sys.argv[1:]]))
