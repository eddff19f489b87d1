"""Size caps on what comes from outside: input files, their numbers, and text quoted back to users.

Each cap has a row in the table of docs/limits.md. Caps keep a bad or
hostile input from costing unbounded time or memory, or from being copied into every message.
"""

from __future__ import annotations

#: Largest YAML input file (scene, problem), bytes. PyYAML reads about 0.2 MB/s here, so a file
#: at the cap loads in about 10 s; 50 objects x 100 hypotheses written out one per line is 0.4 MB.
MAX_FILE_BYTES = 2 * 1024 * 1024
#: Deepest nesting of lists and mappings in a YAML input file (scene files need 5 levels).
MAX_YAML_DEPTH = 32
#: Largest absolute coordinate (m) of a static body, a ground-truth pose or a workspace corner, and
#: largest body size. pybullet computes in double precision: measured, a 5 cm fall and a resting
#: contact are resolved as at the origin up to 1e10 m, and lost at 1e15 m.
MAX_COORDINATE = 1e7
#: Hypotheses per object that a problem file may bring; more keep the heaviest, as the node's
#: ``max_hypotheses_per_object`` (default the same) does with messages.
MAX_HYPOTHESES_PER_OBJECT = 100
#: Longest body name or ``frame_id`` in a scene file, characters.
MAX_NAME_LENGTH = 256
#: Characters of an input's own text (a frame_id, a YAML value) quoted in an error or a diagnostic.
MAX_QUOTED_TEXT = 80
#: Characters of a key path (``hypotheses.cube[3].position``) named in a file error.
MAX_KEY_TEXT = 200
#: Characters of any one diagnostics string (a status message or a key-value's value).
MAX_DIAGNOSTIC_TEXT = 1000


def clipped(text: str, limit: int) -> str:
    """``text`` itself if it has at most ``limit`` characters, else its start, ``...`` and its length."""
    if len(text) <= limit:
        return text
    ending = f"... ({len(text)} characters)"
    return text[: max(0, limit - len(ending))] + ending
