"""The tests are laid out like the rooms, and every module of the package is named by a test.

Every test file is ``test/<room>/test_*.py``: a room of ``physics_mapper`` (or ``msg_adapters``),
``api`` (the package's top level) or ``project`` (the project's shape: layout, docs, packaging). The
helpers the tests share stay beside ``conftest.py`` at ``test/``, which pytest puts on ``sys.path``
for every folder below it. A module is named by a test when its dotted name
(``physics_mapper.search.groups``) appears in a test file, or when its room's ``README.md`` in
``test/<room>/`` says which test file covers it (a list item naming the module and the file).
"""

from __future__ import annotations

import re

from conftest import REPO

TESTS = REPO / "test"
PACKAGE = REPO / "physics_mapper"
#: Test folders that are no room of the package.
OTHER_FOLDERS = {"api", "project"}
#: A README list item: modules' dotted names, then the test files that cover them.
COVERED = re.compile(r"`(physics_mapper(?:\.\w+)+)`")
TEST_FILE = re.compile(r"`(test_\w+\.py)`")


def rooms() -> set[str]:
    return {path.parent.name for path in PACKAGE.glob("*/__init__.py")} | {"msg_adapters"}


def modules() -> list[str]:
    """The dotted name of every module: rooms' modules, msg_adapters', and the package's top-level ones."""
    names = [f"physics_mapper.{p.parent.name}.{p.stem}" for p in PACKAGE.glob("*/*.py") if p.stem != "__init__"]
    names += [f"physics_mapper.msg_adapters.{p.stem}" for p in (REPO / "msg_adapters").glob("*.py")]
    names += [f"physics_mapper.{p.stem}" for p in PACKAGE.glob("*.py") if p.stem != "__init__"]
    return sorted(name for name in names if not name.endswith(".__init__"))


def covered_by_readmes() -> dict[str, set[str]]:
    """Module -> the test files a room's README.md says cover it (files that exist)."""
    existing = {path.name for path in TESTS.rglob("test_*.py")}
    covered: dict[str, set[str]] = {}
    for readme in TESTS.glob("*/README.md"):
        for item in re.split(r"\n(?=- )", readme.read_text()):  # a list item, with its continuation lines
            files = set(TEST_FILE.findall(item)) & existing
            for module in COVERED.findall(item) if files else []:
                covered.setdefault(module, set()).update(files)
    return covered


def uncovered(names: list[str]) -> list[str]:
    texts = [path.read_text() for path in TESTS.rglob("test_*.py")]
    readmes = covered_by_readmes()
    named = [name for name in names if any(re.search(rf"\b{re.escape(name)}\b", text) for text in texts)]
    return [name for name in names if name not in readmes and name not in named]


def test_every_test_file_is_in_a_room_folder() -> None:
    misplaced = [
        str(path.relative_to(TESTS))
        for path in TESTS.rglob("test_*.py")
        if path.parent.parent != TESTS or path.parent.name not in rooms() | OTHER_FOLDERS
    ]
    assert misplaced == []


def test_every_module_is_named_by_a_test() -> None:
    assert uncovered(modules()) == []


def test_a_module_no_test_names_is_found() -> None:
    name = ".".join(["physics_mapper", "search", "no_such_module"])  # written whole, this file would name it
    assert uncovered([name, "physics_mapper.search.groups"]) == [name]
