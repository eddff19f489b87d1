"""physics_mapper: physically consistent multi-object maps from weighted pose hypotheses (Wagle & Correll 2010).

Solving a problem file from Python::

    import physics_mapper as pm

    problem = pm.load_problem("config/problems/pyramid.yaml")
    with pm.PhysicsChecker(problem.scene) as checker:
        result = pm.solve(checker, problem.hypotheses, problem.scene.search)
    print(result.code, result.valid, result.probability, result.jitter)

Rooms, data flowing one way (messages -> ``msg_adapters`` -> ``mapping`` -> model/physics/search and back):

* ``model``: the ROS-free scene model and its files; ``physics``: the two rules in pybullet;
  ``search``: Algorithm 1, interaction groups and the strategies;
* ``mapping``: the node's ROS-free logic (input rules, one tick, topic names);
* ``ros``: the rclpy shells (the node, the publisher, the bag player); ``bags``: rosbag2 I/O;
* ``evaluation``: offline search of recorded snapshots, scoring and reports;
* ``perception``: the simulated particle filters; ``experiments``: the paper's figures;
  ``bench``: cost measurements; ``commands`` and ``cli``: the ``physics-mapper`` command line.

The top-level ``msg_adapters`` package converts ROS messages to these types and back.

The names below are imported when first used, so that ``import physics_mapper`` stays cheap (the
command line and the node start before numpy and pybullet are loaded).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from physics_mapper.model.scene import Problem, Scene, SearchParams
    from physics_mapper.model.scene_files import load_problem, load_scene
    from physics_mapper.physics.checker import PhysicsChecker
    from physics_mapper.search.results import SearchResult
    from physics_mapper.search.strategy import solve

#: The public names, each with the module it lives in.
_PUBLIC = {
    "load_scene": "physics_mapper.model.scene_files",
    "load_problem": "physics_mapper.model.scene_files",
    "Scene": "physics_mapper.model.scene",
    "Problem": "physics_mapper.model.scene",
    "SearchParams": "physics_mapper.model.scene",
    "PhysicsChecker": "physics_mapper.physics.checker",
    "solve": "physics_mapper.search.strategy",
    "SearchResult": "physics_mapper.search.results",
}

__all__ = [
    "PhysicsChecker",
    "Problem",
    "Scene",
    "SearchParams",
    "SearchResult",
    "load_problem",
    "load_scene",
    "solve",
]


def __getattr__(name: str) -> Any:
    """Import a public name's module on first use (PEP 562)."""
    if name not in _PUBLIC:
        raise AttributeError(f"module 'physics_mapper' has no attribute {name!r}")
    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
