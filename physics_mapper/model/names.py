"""Object names as ROS topic names: every object's name becomes part of the node's topics.

The node subscribes to ``hypotheses/<name>`` and ``hypotheses/<name>/weights`` and publishes
``~/objects/<name>/pose`` and ``~/objects/<name>/settled_pose``, so a scene's object names are
checked here, once, when the scene is loaded, and ``solve``, ``replay`` and the node accept
exactly the same names. A name is one or more *tokens* of ASCII letters, digits and ``_``, joined
by single ``/``; no token starts with a digit (ROS's rule for topic name tokens). ``{`` and ``}``
(rcl's substitutions), ``~``, spaces, dots and non-ASCII letters are refused. Two objects whose
topics would coincide (``a`` and ``a/weights``: the second's poses are the first's weights) are
refused too, naming both.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

#: Longest object name, characters: the longest topic made of it,
#: ``/<namespace>/physics_mapper/objects/<name>/settled_pose``, must stay within
#: ROS's 247 characters for a full topic name, which leaves 82 for the namespace.
MAX_OBJECT_NAME_LENGTH = 128
#: What ROS allows in a topic name token, the first character not a digit.
_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
#: The node's topics made of an object's name, relative to the node (``~/`` dropped): kept equal to
#: ``physics_mapper.mapping.topics`` by a test.
DERIVED_TOPICS = ("hypotheses/{}", "hypotheses/{}/weights", "objects/{}/pose", "objects/{}/settled_pose")


def object_name_problem(name: str) -> str | None:
    """Say why ``name`` cannot be an object's name (module docstring), or return None."""
    if len(name) > MAX_OBJECT_NAME_LENGTH:
        return f"longer than the {MAX_OBJECT_NAME_LENGTH} characters an object name may have (topics are made of it)"
    for token in name.split("/"):
        if not token:
            return "not a ROS topic name: empty part (a leading, trailing or doubled '/')"
        if not _TOKEN.match(token):
            bad = next((c for c in token if not (c.isascii() and (c.isalnum() or c == "_"))), None)
            if bad is not None:
                return f"not a ROS topic name: {bad!r} is not allowed (only ASCII letters, digits, '_' and '/')"
            return f"not a ROS topic name: its part {token!r} starts with a digit"
    return None


def derived_topics(name: str) -> tuple[str, ...]:
    """The node's topics (relative, ``~/`` dropped) made of object ``name``."""
    return tuple(pattern.format(name) for pattern in DERIVED_TOPICS)


def topic_clash(names: Sequence[str]) -> tuple[str, str, str] | None:
    """The first two objects sharing a derived topic, and that topic; None if every topic is one object's."""
    owner: dict[str, str] = {}
    for name in names:
        for topic in derived_topics(name):
            other = owner.setdefault(topic, name)
            if other != name:
                return other, name, topic
    return None
