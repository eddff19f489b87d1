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
#: Mass range of a movable object, kg. Measured (``benchmarks/mass_bounds.py``): a 10 cm cube resting
#: on the floor keeps J = 6e-5 from 1e-9 kg to 3e11 kg, and falls over at 1e12 kg (J = 0.65); the
#: upper bound keeps a factor 300 from that, the lower one is a milligram.
MIN_MASS = 1e-6
MAX_MASS = 1e9
#: Density range of a mesh given ``density:``, kg/m^3: below the lightest solids (aerogel, about 1)
#: and above the densest (osmium, 22,600) by a margin; the mass it gives must also be in range.
MIN_DENSITY = 0.1
MAX_DENSITY = 1e5
#: Heaviest-to-lightest mass ratio of two objects beyond which a loaded scene gets a warning: measured
#: (``benchmarks/mass_bounds.py``), a 10 cm cube resting on another of 1 kg has J = 0.0005 at a ratio of
#: 10, 0.004 at 30, 0.010 (the default jitter threshold) at 60 and 0.023 at 100: Bullet's contact
#: solver lets a heavy body sink through a light one, so a valid stack is rejected as unstable.
MAX_MASS_RATIO = 30.0
#: Metres a movable mesh may span (its largest extent) before a loaded scene gets a warning: the household
#: objects the product maps are smaller, and a file in centimetres or millimetres read as metres (no
#: ``scale``) is 100 or 1000 times too large: pybullet_data's duck, 1.65 m across without the 0.05 its URDF
#: gives, made a bin of 12 whose every tick had its refined map, 40 cm from the truth.
MAX_UNWARNED_MESH_EXTENT = 1.0
#: Hypotheses per object that a problem file may bring; more keep the heaviest, as the node's
#: ``max_hypotheses_per_object`` (default the same) does with messages.
MAX_HYPOTHESES_PER_OBJECT = 100
#: Hypotheses per object any search takes, whatever ``max_hypotheses_per_object`` says: the heaviest are
#: kept. Grouping compares every hypothesis of one object with every one of another, and the collision
#: table holds a number per pair, so the cost of a search's set-up grows with the square of this
#: (measured in ``BENCHMARKS.md``, "Input caps": 1000 x 1000 hypotheses are grouped in milliseconds;
#: 100,000 x 100,000 would need 224 GiB at once).
MAX_SEARCHED_HYPOTHESES = 1000
#: Most movable objects and most static bodies in a scene. The node's start-up, its per-tick work and
#: its shutdown grow with the objects (a subscription pair, two latched publishers and a marker each);
#: measured at the cap (``BENCHMARKS.md``, "Input caps").
MAX_OBJECTS = 128
MAX_STATIC_BODIES = 256
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


def printable(text: str) -> str:
    """``text`` with line breaks, escape sequences and every other unprintable character escaped as in a
    Python literal (``\\n``, ``\\x1b``): input quoted on a terminal, in a log or a report stays one
    line and shows what it holds."""
    return text if text.isprintable() else "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
