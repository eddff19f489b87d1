"""The README and docs/ tell the truth about the code: links, commands, options, parameters, the example.

- every relative link (and image) of ``README.md`` and ``docs/*.md`` names an existing file, and
  its ``#anchor``, if any, a heading of that file (GitHub's anchor rule);
- every ``physics-mapper <command>`` written in them is a subcommand of
  :func:`physics_mapper.cli.build_parser`, and every ``--option`` written after it (same code span,
  or same command line of a code block) is one of that subcommand's options; an inline
  ```--option``` on its own is an option of some subcommand, or of another tool named in
  :data:`OTHER_TOOLS_OPTIONS`; after ``physics-mapper bench NAME``, the options are those of the
  benchmark ``benchmarks/NAME.py`` (its ``--help``);
- the parameter table of ``docs/node.md`` names exactly the node's parameters
  (``scene_file`` and :data:`physics_mapper.ros.node.PARAMETERS`);
- the README stays a short guide, and its first ``python`` block runs from the repository root;
- every dotted name of the package (``physics_mapper.mapping.mapper.Mapper.tick``) written in the
  docs, ``BENCHMARKS.md`` or a docstring (of the package, ``msg_adapters/``, ``benchmarks/``,
  ``test/``) names a module, or something a module defines.
"""

from __future__ import annotations

import argparse
import ast
import functools
import importlib
import importlib.util
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import REPO

from physics_mapper.cli import build_parser

README = REPO / "README.md"
DOCS = sorted((REPO / "docs").glob("*.md"))
PAGES = [README, *DOCS]
#: Where dotted names are written: the pages, BENCHMARKS.md, and the docstrings of these folders' files.
NAMING_PAGES = [*PAGES, REPO / "BENCHMARKS.md"]
DOCSTRING_FOLDERS = ("physics_mapper", "msg_adapters", "benchmarks", "test")
#: A dotted name of the package; one after a ``/`` or ``-`` is part of a file name (``launch/...``).
DOTTED_NAME = re.compile(r"(?<![\w./-])physics_mapper(?:\.[A-Za-z_]\w*)+")
#: File names that read like dotted names (``physics_mapper.launch.py``, ``physics_mapper.rviz``).
FILE_SUFFIXES = (".py", ".rviz")
README_MAX_LINES = 260
#: Options of other tools (ROS, pip, colcon, rosdep, Ray) that the docs write on their own.
OTHER_TOOLS_OPTIONS = {
    "--ros-args",
    "--params-file",
    "--break-system-packages",
    "--system-site-packages",
    "--from-paths",
    "--ignore-src",
    "--packages-select",
    "--head",
    "--port",
    "--address",
}

FENCE = re.compile(r"^```")
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
INLINE_CODE = re.compile(r"`([^`\n]+)`")
COMMAND = re.compile(r"physics-mapper\s+([a-z][a-z_-]*)")
#: ``physics-mapper bench NAME``: the benchmark's name.
BENCHMARK = re.compile(r"physics-mapper\s+bench\s+([a-z][a-z0-9_]*)")
OPTION = re.compile(r"(?<![\w-])(--[a-z][a-z0-9-]*)")


def page_id(path: Path) -> str:
    return str(path.relative_to(REPO))


def prose_and_code(text: str) -> tuple[list[str], list[str]]:
    """The lines outside code blocks, and the logical lines inside them (backslash continuations joined)."""
    prose: list[str] = []
    code: list[str] = []
    in_code, pending = False, ""
    for line in text.splitlines():
        if FENCE.match(line):
            in_code = not in_code
            continue
        if not in_code:
            prose.append(line)
        elif line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
        else:
            code.append(pending + line)
            pending = ""
    return prose, code


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every heading anchor of a Markdown file (duplicates numbered as GitHub does)."""
    prose, _ = prose_and_code(path.read_text())
    seen: dict[str, int] = {}
    found: set[str] = set()
    for line in prose:
        match = re.match(r"^#{1,6}\s+(.*)$", line)
        if match is None:
            continue
        base = slug(match.group(1))
        count = seen.get(base, 0)
        seen[base] = count + 1
        found.add(base if count == 0 else f"{base}-{count}")
    return found


def links(path: Path) -> Iterator[str]:
    prose, _ = prose_and_code(path.read_text())
    for line in prose:
        # Links inside inline code are code, not links.
        yield from LINK.findall(INLINE_CODE.sub("", line))


def test_the_docs_pages_exist() -> None:
    names = {path.name for path in DOCS}
    assert {
        "README.md",
        "scene-files.md",
        "meshes.md",
        "node.md",
        "search.md",
        "bags-and-evaluation.md",
        "limits.md",
        "experiments.md",
        "layout.md",
        "development.md",
    } <= names


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_relative_link_resolves(page: Path) -> None:
    broken = []
    for target in links(page):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):
            continue  # http:, https:, mailto:
        file_part, _, anchor = target.partition("#")
        destination = (page.parent / file_part).resolve() if file_part else page
        if not destination.exists():
            broken.append(f"{target}: no such file")
        elif anchor and (destination.suffix != ".md" or anchor not in anchors(destination)):
            broken.append(f"{target}: no heading #{anchor}")
    assert broken == []


def subcommands() -> dict[str, set[str]]:
    """Every subcommand of ``physics-mapper`` and its option strings."""
    parser = build_parser()
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    choices: dict[str, argparse.ArgumentParser] = action.choices
    return {
        name: {option for sub_action in sub._actions for option in sub_action.option_strings}
        for name, sub in choices.items()
    }


def command_texts(page: Path) -> Iterator[str]:
    """The inline code spans and the code-block lines of a page: where commands are written."""
    prose, code = prose_and_code(page.read_text())
    for line in prose:
        yield from INLINE_CODE.findall(line)
    yield from code


def written_commands(text: str) -> Iterator[tuple[str, list[str]]]:
    """Each ``physics-mapper <command>`` of a text and the options written after it.

    Options stop at the next command, a shell comment, ``&&``, ``|``, ``;`` or ``--ros-args``
    (what follows it is for ROS, not for our parser).
    """
    for match in COMMAND.finditer(text):
        rest = text[match.end() :]
        rest = re.split(r"physics-mapper\s|\s#|&&|\||;", rest, maxsplit=1)[0]
        options = OPTION.findall(rest)
        if "--ros-args" in options:
            options = options[: options.index("--ros-args") + 1]
        yield match.group(1), options


@functools.cache
def benchmark_options(name: str) -> frozenset[str] | None:
    """The options of the benchmark ``benchmarks/NAME.py`` (from its ``--help``), or None for no such benchmark."""
    script = REPO / "benchmarks" / f"{name}.py"
    if not script.is_file():
        return None
    shown = subprocess.run(
        [sys.executable, str(script), "--help"], capture_output=True, text=True, timeout=120, check=False
    )
    assert shown.returncode == 0, shown.stderr
    return frozenset(OPTION.findall(shown.stdout))


def benchmarks_named(page: Path) -> set[str]:
    """The benchmarks a page runs with ``physics-mapper bench NAME``."""
    return {name for text in command_texts(page) for name in BENCHMARK.findall(text)}


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_command_and_option_written_exists(page: Path) -> None:
    known = subcommands()
    wrong = []
    for text in command_texts(page):
        named = BENCHMARK.findall(text)
        for command, options in written_commands(text):
            if command not in known:
                wrong.append(f"physics-mapper {command}: no such command")
                continue
            allowed = set(known[command])
            if command == "bench" and named:
                benchmark = benchmark_options(named.pop(0))
                if benchmark is None:
                    wrong.append(f"physics-mapper bench: no benchmark in {text!r}")
                    continue
                allowed |= benchmark
            wrong += [f"physics-mapper {command} {o}: no such option" for o in options if o not in allowed]
    assert wrong == []


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_option_written_alone_exists(page: Path) -> None:
    benchmarks = [benchmark_options(name) or frozenset() for name in benchmarks_named(page)]
    every_option = set().union(*subcommands().values(), *benchmarks) | OTHER_TOOLS_OPTIONS
    prose, _ = prose_and_code(page.read_text())
    alone = {span.split()[0].split("=")[0] for line in prose for span in INLINE_CODE.findall(line)}
    assert sorted(o for o in alone if OPTION.fullmatch(o) and o not in every_option) == []


def test_the_option_checks_see_a_wrong_option() -> None:
    text = ".venv/bin/physics-mapper solve p.yaml --jsn && physics-mapper nod --ros-args --params-file x"
    assert list(written_commands(text)) == [("solve", ["--jsn"]), ("nod", ["--ros-args"])]
    known = subcommands()
    assert "--jsn" not in known["solve"]
    assert "nod" not in known


def node_parameters() -> set[str]:
    """The node's declared parameters, without starting ROS."""
    from physics_mapper.ros.node import PARAMETERS

    return {"scene_file", *(spec.name for spec in PARAMETERS)}


def documented_parameters() -> set[str]:
    """The names in the first column of docs/node.md's parameter table."""
    names: set[str] = set()
    in_table = False
    for line in (REPO / "docs" / "node.md").read_text().splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if line.startswith("|") and cells[0] == "parameter":
            in_table = True
        elif in_table and line.startswith("|"):
            names |= set(re.findall(r"`([a-z_]+)`", cells[0]))
        elif in_table:
            break
    return names


def test_the_node_parameter_table_names_exactly_the_declared_parameters() -> None:
    documented = documented_parameters()
    assert documented, "docs/node.md has no table whose first column is 'parameter'"
    declared = node_parameters()
    assert sorted(documented - declared) == [], "documented but not declared"
    assert sorted(declared - documented) == [], "declared but not documented"


def test_the_readme_is_a_short_guide() -> None:
    assert len(README.read_text().splitlines()) <= README_MAX_LINES


def test_the_readme_python_example_runs(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    match = re.search(r"^```python\n(.*?)^```", README.read_text(), re.MULTILINE | re.DOTALL)
    assert match is not None, "README.md has no python block"
    monkeypatch.chdir(REPO)
    exec(compile(match.group(1), "<README.md python example>", "exec"), {"__name__": "readme_example"})
    printed = capsys.readouterr().out.split()
    assert printed[:2] == ["(5,", "4,"], printed  # the pyramid's answer, C544


def _layout_lists(room: str, module: str, layout: str) -> bool:
    """Whether docs/layout.md names ``room/module``: in its room's table, or as ``room/module``."""
    if f"`{room}/{module}`" in layout or f"`{room}/{module}`," in layout:
        return True
    heading = f"`physics_mapper/{room}/`"
    if heading not in layout:
        return any(f"`{room}/" in line and module in line for line in layout.splitlines())
    table = layout.split(heading, 1)[1].split("\n\n", 2)[1]
    return f"| `{module}` |" in table


def test_the_layout_page_names_every_module() -> None:
    """A module nobody can find from the docs is one a newcomer cannot place (``commands/``: one module
    per subcommand, named by it, but for their shared ``files``)."""
    layout = (REPO / "docs" / "layout.md").read_text()
    package = REPO / "physics_mapper"
    missing = [
        f"{path.parent.name}/{path.stem}"
        for path in sorted(package.glob("*/*.py"))
        if path.stem != "__init__"
        and (path.parent.name != "commands" or path.stem == "files")
        and not _layout_lists(path.parent.name, path.stem, layout)
    ]
    assert missing == []


def docstrings(path: Path) -> Iterator[str]:
    """The module's, classes' and functions' docstrings of a Python file."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            text = ast.get_docstring(node, clean=False)
            if text:
                yield text


def dotted_names() -> dict[str, set[str]]:
    """Every dotted name of the package written in the pages and docstrings, and where."""
    texts = {page_id(page): page.read_text() for page in NAMING_PAGES}
    for folder in DOCSTRING_FOLDERS:
        for path in sorted((REPO / folder).rglob("*.py")):
            texts[page_id(path)] = "\n".join(docstrings(path))
    found: dict[str, set[str]] = {}
    for where, text in texts.items():
        for name in DOTTED_NAME.findall(text):
            if not name.endswith(FILE_SUFFIXES):
                found.setdefault(name, set()).add(where)
    return found


def resolves(name: str) -> bool:
    """Whether ``name`` is a module of the package, or an attribute (at any depth) of one."""
    parts = name.split(".")
    if parts[-1] == "__main__":  # importing it runs the command line
        return importlib.util.find_spec(name) is not None
    for length in range(len(parts), 0, -1):
        try:
            found: object = importlib.import_module(".".join(parts[:length]))
        except ModuleNotFoundError:
            continue
        for attribute in parts[length:]:
            if not hasattr(found, attribute):
                return False
            found = getattr(found, attribute)
        return True
    return False


def test_every_dotted_name_written_resolves() -> None:
    unresolved = {name: sorted(where) for name, where in dotted_names().items() if not resolves(name)}
    assert unresolved == {}


def test_the_name_check_sees_a_name_that_moved() -> None:
    assert resolves("physics_mapper.mapping.mapper.Mapper.tick")
    assert resolves("physics_mapper.__main__") and resolves("physics_mapper.msg_adapters.results")
    assert not resolves("physics_mapper.mapper.Mapper.tick")  # the module moved to mapping/
    assert not resolves("physics_mapper.mapping.mapper.Mapper.no_such_method")
    assert DOTTED_NAME.findall("see physics_mapper.scoring; launch/physics_mapper.launch.py") == [
        "physics_mapper.scoring"
    ]
