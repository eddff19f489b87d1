"""The node's classes set every attribute in ``__init__``: a configured node and a released one have the same fields.

Read from the source (AST): an assignment to ``self.<name>`` in any method but ``__init__`` must
name an attribute that ``__init__`` (of the class or of a base class in the same module) or the
class body (a dataclass field) already set.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import physics_mapper

ROS = Path(physics_mapper.__file__).parent / "ros"
#: The node and the modules it is made of.
NODE_MODULES = (
    "node",
    "managed_node",
    "parameters",
    "node_scene",
    "node_inputs",
    "node_subscriptions",
    "node_diagnostics",
    "map_publishers",
)


def self_attributes(function: ast.FunctionDef) -> set[str]:
    """The names of ``self.<name>`` assigned anywhere in ``function``."""
    names: set[str] = set()
    for node in ast.walk(function):
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, ast.AnnAssign | ast.AugAssign):
            targets = [node.target]
        else:
            continue
        for target in targets:
            for part in ast.walk(target):
                if isinstance(part, ast.Attribute) and isinstance(part.value, ast.Name) and part.value.id == "self":
                    names.add(part.attr)
    return names


def attributes_set_late(source: str) -> list[str]:
    """``Class.method sets self.name`` for every attribute first set outside ``__init__``."""
    classes = {node.name: node for node in ast.walk(ast.parse(source)) if isinstance(node, ast.ClassDef)}

    def set_early(cls: ast.ClassDef) -> set[str]:
        names = {
            item.target.id for item in cls.body if isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name)
        }
        for base in cls.bases:
            if isinstance(base, ast.Name) and base.id in classes:
                names |= set_early(classes[base.id])
        for item in cls.body:
            if isinstance(item, ast.FunctionDef) and item.name == "__init__":
                names |= self_attributes(item)
        return names

    late = []
    for cls in classes.values():
        early = set_early(cls)
        for item in cls.body:
            if isinstance(item, ast.FunctionDef) and item.name != "__init__":
                late += [f"{cls.name}.{item.name} sets self.{name}" for name in sorted(self_attributes(item) - early)]
    return late


@pytest.mark.parametrize("module", NODE_MODULES)
def test_node_sets_every_attribute_in_init(module: str) -> None:
    assert attributes_set_late((ROS / f"{module}.py").read_text()) == []


def test_the_check_finds_an_attribute_set_late() -> None:
    source = (
        "class A:\n    def __init__(self):\n        self.a = 1\n\n"
        "    def later(self):\n        self.a = 2\n        self.b = 3\n"
    )
    assert attributes_set_late(source) == ["A.later sets self.b"]


def test_node_module_is_a_page_long() -> None:
    assert len((ROS / "node.py").read_text().splitlines()) <= 300
